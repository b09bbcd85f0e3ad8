"""The depth bend against a generator handeye's authors did not write (tests/indep_linearity.py, written by a
helper from the README's dataset format: quadratic, cubic, sine and piecewise depth bends, a lateral one, clean
cells; sensor on the flange or fixed; poses at varied depths or at one). The rates over seeds are
``python tests/linearity_rates.py 30`` (the README's table)."""
import ast
import pathlib

import indep_linearity as il
import linearity_rates as lr
import numpy as np
import pytest


def test_generator_is_independent_of_handeye():
    tree = ast.parse(pathlib.Path(il.__file__).read_text())
    names = {a.name.split(".")[0] for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
    names |= {n.module.split(".")[0] for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) and n.module}
    assert "handeye" not in names and names <= {"__future__", "json", "math", "pathlib", "numpy", "indep_mounts"}, names


def test_the_generators_chain_closes_at_its_truth(tmp_path):
    """Its own check: the true centres close the chain to the robot's repeatability; the centres of the written,
    bent profiles do not (the bend is there)."""
    info = il.make(tmp_path / "c", 3, "quadratic", depth="varied", amplitude=0.25)
    worst_true, worst_fit = il.check(info, tmp_path / "c")
    assert worst_true < 0.05 and worst_fit > 3 * worst_true, (worst_true, worst_fit)


def test_a_clean_cell_has_no_bend_and_calibrates_at_the_truth(tmp_path):
    row = lr.cell("clean", 1, tmp_path)
    assert not row["applied"] and row["exit"] == 0 and row["at_truth"], row


@pytest.mark.slow(sibling="test_a_clean_cell_has_no_bend_and_calibrates_at_the_truth")
def test_bend_rates_over_seeds(tmp_path):
    """10 seeds of the clean class and of two bent ones: no clean cell corrected or away from the truth; where a
    bend is applied the correction lowers the median error, and at most a fifth of those cells still exit 0 away
    from the truth (measured: 2 of 11, sine seeds 0 and 5, 3.1 and 5.9 sd, which uncorrected were as far: the
    README's known limits)."""
    rows = [lr.cell(kind, seed, tmp_path) for kind in ("clean", "quadratic", "sine") for seed in range(10)]
    clean = [r for r in rows if r["kind"] == "clean"]
    assert not any(r["applied"] for r in clean) and all(r["at_truth"] for r in clean), clean
    applied = [r for r in rows if r["applied"]]
    assert sum(r["wrong"] for r in applied) <= len(applied) / 5, [r for r in applied if r["wrong"]]
    both = [r for r in applied if r["exit"] == 0 and r["uncorrected"]["exit"] == 0]
    assert len(both) >= 3, applied
    assert np.median([r["dist"]["mm"] for r in both]) < np.median([r["uncorrected"]["dist"]["mm"] for r in both])
