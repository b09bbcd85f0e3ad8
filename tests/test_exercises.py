"""The notebooks' exercise cells and checks, and the student edition without solutions.

Every exercise has a cell of its own (tagged ``exercise``) that runs unanswered and calls the
notebook's check; every worked solution ends by passing its own answer to that check
(``assert check_exercise(N, ...).correct``), which the kernel runs of tests/test_notebooks.py
execute -- so each check is driven by the solution code. Here: each check rejects a wrong
answer without stating the right one, says "not answered yet" to None, and the student edition
keeps no solution text and still runs under a kernel.
"""
import importlib.util
import json
import pathlib
import re

import notebook_scripts
import numpy as np
import pytest

from handeye.app.present import exercises

ROOT = pathlib.Path(__file__).resolve().parents[1]
NOTEBOOKS = sorted((ROOT / "notebooks").glob("*.ipynb"))
KEYS = [(name, k + 1) for name, keys in exercises.EXERCISES.items() for k in range(len(keys))]


def _cells(path):
    return json.loads(path.read_text())["cells"]


def _source(cell):
    return "".join(cell["source"])


def _tagged(cells, tag):
    return [c for c in cells if tag in c.get("metadata", {}).get("tags", [])]


def _wrong(key):
    """An answer of the right form that is wrong."""
    e = key.expected
    if key.kind in ("number", "vector"):
        return np.asarray(e, dtype=float) * 1.5 + 1.0
    if key.kind == "axis":
        v = np.asarray(e, dtype=float)
        return np.cross(v, [1.0, 0, 0] if abs(v[0]) < 0.9 else [0, 1.0, 0])  # perpendicular
    if key.kind == "range":
        return e[1] * 10 + 1
    if key.kind == "set":
        return set(list(e)[1:]) | {"bogus"}
    if isinstance(e, str):
        return e.replace("+", "-")
    if isinstance(e, tuple):
        return tuple(not x for x in e)
    return e + 1


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.name for p in NOTEBOOKS])
def test_every_exercise_has_a_cell_that_checks_it_and_runs_unanswered(path):
    cells = _cells(path)
    keys = exercises.EXERCISES[path.stem]
    mine, solutions = _tagged(cells, "exercise"), _tagged(cells, "solution")
    assert len(mine) == len(solutions) == len(keys), path.name
    for k, (cell, solution) in enumerate(zip(mine, solutions), start=1):
        text = _source(cell)
        assert "your turn" in text.lower() and "answer = None" in text and f"check_exercise({k}, answer)" in text
        shown = "".join("".join(o.get("data", {}).get("text/plain", "")) for o in cell["outputs"])
        assert f"exercise {k}: not answered yet" in shown, (path.name, k, shown)
        assert re.search(rf"^assert check_exercise\({k}, .+\)\.correct", _source(solution), flags=re.M), (path.name, k)
    assert 'check_exercise = checker("' + path.stem + '")' in _source(next(c for c in cells if c["cell_type"] == "code"))


def test_every_notebook_has_its_answer_keys():
    assert set(exercises.EXERCISES) == {p.stem for p in NOTEBOOKS}


@pytest.mark.parametrize("name, number", KEYS, ids=[f"{n}-{k}" for n, k in KEYS])
def test_a_check_accepts_the_key_and_rejects_a_wrong_answer_without_giving_it(name, number):
    key = exercises.EXERCISES[name][number - 1]
    check = exercises.checker(name)
    assert check(number, None).status == "not answered yet" and not check(number, None).correct
    right = key.expected if key.kind != "range" else sum(key.expected) / 2
    assert check(number, right).correct, repr(check(number, right))
    wrong = check(number, _wrong(key))
    assert wrong.status == "wrong" and "hint" in wrong.message
    said = wrong.message.split(":", 1)[1]  # after "exercise N:"
    assert key.hint and not re.search(rf"(?<![\w.]){re.escape(str(key.expected))}(?![\w.])", said), said
    odd = check(number, "not a number" if not isinstance(key.expected, str) else 3.0)
    assert odd.status == "wrong"


def test_the_checks_compare_with_tolerances_and_forms():
    check = exercises.checker("least_squares")
    assert check(1, ["TX", "tz"]).correct and not check(1, ["tx"]).correct and "form" in check(1, 3).message
    assert check(2, 12.6).correct and not check(2, 14).correct
    assert check(3, 0.003).correct and not check(3, 0.5).correct
    he = exercises.checker("hand_eye_calibration")
    assert he(4, -np.array([-0.058, 0.988, 0.143])).correct  # an axis: either sign
    assert he(1, "a+c").correct and not he(1, "A - C").correct
    assert exercises.checker("discrepancy_thesis_real")(4, np.float64(32.0)).correct
    with pytest.raises(KeyError):
        exercises.checker("no_such_notebook")


def _student():
    return notebook_scripts.load("student")


def test_the_student_edition_has_no_solutions_and_clears_the_exercise_cells(tmp_path):
    pytest.importorskip("nbformat")
    written = _student().student_edition(tmp_path)
    assert sorted(p.name for p in written) == [p.name for p in NOTEBOOKS]
    assert (tmp_path / "README.md").exists() and (tmp_path / "notation.md").exists()
    for path in NOTEBOOKS:
        original, student = _cells(path), _cells(tmp_path / path.name)
        text = "\n".join(_source(c) for c in student)
        assert not _tagged(student, "solution") and "<details>" not in text and "### Solutions" not in text
        taught = "\n".join(_source(c) for c in original if not _tagged([c], "solution"))
        for solution in _tagged(original, "solution"):  # no line of its own (a line the teaching cells share may stay)
            lines = [line for line in _source(solution).splitlines() if len(line.strip()) > 25 and line not in taught]
            assert lines and not any(line in text for line in lines), path.name
        mine = _tagged(student, "exercise")
        assert len(mine) == len(_tagged(original, "exercise")) and all(not c["outputs"] for c in mine)
        teaching = [c for c in original if c["cell_type"] == "code" and not c.get("metadata", {}).get("tags")]
        assert sum(1 for c in student if c["cell_type"] == "code" and not c.get("metadata", {}).get("tags")) == len(teaching)
        assert "Student edition" in _source(student[0])


@pytest.mark.slow(sibling="test_the_student_edition_has_no_solutions_and_clears_the_exercise_cells")
def test_the_student_edition_runs_in_a_kernel(tmp_path):
    pytest.importorskip("nbclient")
    pytest.importorskip("ipykernel")
    name = "constrained_optimality.ipynb"
    _student().student_edition(tmp_path / "edition", [name])
    spec = importlib.util.spec_from_file_location("notebook_execute", ROOT / "notebooks" / "execute.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    nb = module.execute(tmp_path / "edition" / name, cwd=tmp_path)
    assert not any(o.get("output_type") == "error" for c in nb.cells for o in c.get("outputs", []))
    shown = ["".join(o.get("data", {}).get("text/plain", "")) for c in _tagged(nb.cells, "exercise") for o in c.outputs]
    assert len(shown) == 5 and all("not answered yet" in s for s in shown)
