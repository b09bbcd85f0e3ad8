"""The studies, in their quick versions (the full versions: `handeye study NAME`), and the
pose planner."""
import json

import numpy as np
import pytest
from test_figures import assert_readable

from handeye.app.command.cli import EXIT_BAD_INPUT, EXIT_OK, main
from handeye.model.design import bounds, planning
from handeye.model.simulation import simulate
from handeye.studies.study import STUDIES

#: The slowest quick studies (15-60 s here) run whole in the full suite only; the default tier
#: runs them on part of their design, a module constant narrowed: one of eight methods and
#: parametrisations of random starts (in this process, --jobs 1, where the narrowed constant
#: holds), one mount of three, two solvers of eight. Per study: the constant, its narrowed value,
#: extra arguments, and the summary's entries that follow (key None: the summary's own keys).
NARROWED = {
    "batch-equivalence": ("METHODS", ("newton", "lm"), [], ("methods", {"newton", "lm"})),
    "mounts": ("CELLS", (("eye-in-hand", "flange", "world", "sensor+sphere"),), [],
               (None, {"replicates", "eye-in-hand"})),
    "random-starts": ("SUPPORTED", {"lm": ("local",), "gn": (), "newton": (), "ipopt": ()}, ["--jobs", "1"],
                      ("methods", {"lm/local", "lm-fast/local"})),
}
#: The studies whose claims are statistics over many cells (accuracy, discrepancy power, start
#: poses, the thesis robot, circle fits, real data, the test function: 3-10 CPU-s each even quick)
#: run in the full suite only, like the other rate checks; in the default tier the study command,
#: its figures, summary and claims are exercised by the others (pose planning, classics, the
#: global guarantee, the honest default and the three narrowed above).
RATES = ("accuracy", "circle-fits", "discrepancy-power", "real-data", "start-poses", "testfunction", "thesis-robot")
#: the default-tier study a rate study names as its sibling
_RUNS = "test_quick_study_runs_and_its_claims_hold[pose-planning]"
#: Studies of 4-5 CPU-s each that tell one story the default tier's others share (the global guarantee's
#: second minima, the honest default's refusals): in the full suite since calibrate's search, which both run
#: on every cell, put the default tier over its budget.
WHOLE_ONLY = ("global-guarantee", "honest-default")


def _quick(names):
    def mark(n):
        if n in NARROWED:
            return pytest.mark.slow(sibling=f"test_narrowed_quick_study_runs_and_its_claims_hold[{n}]")
        return pytest.mark.slow(sibling=_RUNS) if n in RATES + WHOLE_ONLY else ()
    return [pytest.param(n, marks=mark(n)) for n in names]


@pytest.mark.parametrize("name", _quick(sorted(STUDIES)))
def test_quick_study_runs_and_its_claims_hold(tmp_path, capsys, name):
    _check_quick_study(tmp_path, name)


@pytest.mark.parametrize("name", sorted(NARROWED))
def test_narrowed_quick_study_runs_and_its_claims_hold(tmp_path, capsys, monkeypatch, name):
    import importlib

    constant, value, args, (key, entries) = NARROWED[name]
    module = importlib.import_module(STUDIES[name])
    assert getattr(module, constant) != value  # narrowed, not a no-op
    monkeypatch.setattr(module, constant, value)
    summary = _check_quick_study(tmp_path, name, args)
    assert set(summary if key is None else summary[key]) == entries


def _check_quick_study(tmp_path, name, args=()):
    assert main(["study", name, "--quick", "--out", str(tmp_path), *args]) == EXIT_OK
    folder = tmp_path / name
    assert (folder / "summary.json").is_file()
    assert list(folder.glob("*.png")) and list(folder.glob("*.csv")) and list(folder.glob("*.md"))
    for png in folder.glob("*.png"):  # one style (test_figures.py): at least 120 dpi and 1,000 px across
        assert_readable(png)
    return json.loads((folder / "summary.json").read_text())


def test_unknown_study_is_refused(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["study", "nonsense"])
    assert exc.value.code == EXIT_BAD_INPUT


def test_d_optimal_selection_beats_random_subsets():
    setup = simulate.Setup()
    ids, poses = planning.thesis_candidates(setup, setup.sphere_centre)
    info = bounds.information(poses, setup, setup.sphere_centre)
    chosen, value = planning.select(info, 10)
    assert len(set(chosen)) == 10
    rng = np.random.default_rng(0)
    for _ in range(50):
        other = rng.choice(len(ids), 10, replace=False)
        assert planning.logdet(info[other].sum(axis=0)) <= value + 1e-9


def test_plan_cli(tmp_path, capsys):
    out = tmp_path / "plan.csv"
    assert main(["plan", "--n", "6", "--dataset", "thesis-real", "--out", str(out), "--json"]) == EXIT_OK
    report = json.loads(capsys.readouterr().out)
    assert len(report["ids"]) == 6 and len(report["predicted_sd"]["sensor_translation_mm"]) == 3
    lines = out.read_text().splitlines()
    assert lines[0] == "id,x,y,z,a,b,c" and len(lines) == 7
    # the written pose list is a valid candidate list again
    assert main(["plan", "--n", "3", "--candidates", str(out)]) == EXIT_OK
    capsys.readouterr()
    assert main(["plan", "--n", "9", "--candidates", str(out)]) == EXIT_BAD_INPUT
    assert "cannot choose 9" in capsys.readouterr().err
    bad = tmp_path / "bad.csv"
    bad.write_text("id,x,y,z,a,b,c\nq1,1,2,3,4,5\n")
    assert main(["plan", "--candidates", str(bad)]) == EXIT_BAD_INPUT
    err = capsys.readouterr().err
    assert str(bad) in err and "row 2" in err
