"""The pieces that make the default pipeline linear in the data agree with the exact ones."""
import numpy as np
import pytest

import handeye
from handeye.app import bench, robust
from handeye.app import calibrate as engine
from handeye.model.calibration import CalibrationModel


def test_deletion_formula_leave_one_out_matches_exact_refits(monkeypatch):
    f2b, xs, centre, start = bench.simulated_case(300, seed=3)
    model = CalibrationModel(f2b, xs, centre, "local")
    mask = np.ones(300, bool)
    mask[[5, 17]] = False
    x = robust.least_squares(robust._subset(model, mask), model.point_from(start)).x  # the fit on the mask
    exact = robust.leave_one_out(model, x, mask)
    monkeypatch.setattr(robust, "LOO_EXACT_UP_TO", 10)
    fast = robust.leave_one_out(model, x, mask)
    assert np.array_equal(np.isnan(exact), np.isnan(fast))
    assert np.nanmax(np.abs(fast - exact)) < 1e-5 * np.nanmax(exact)  # measured: ~3e-8 mm of 0.07 mm


def test_the_callback_problem_for_ipopt_agrees_with_the_sx_one(monkeypatch):
    from handeye import solvers
    from handeye.model import calibration

    f2b, xs, centre, start = bench.simulated_case(60, seed=1)
    model = CalibrationModel(f2b, xs, centre, "matrix")
    sx = solvers.solve(solvers.Problem(n=12, nlp=model.nlp()), model.point_from(start), "ipopt")
    monkeypatch.setattr(calibration, "NLP_CALLBACK_ABOVE", 10)
    cb = solvers.solve(solvers.Problem(n=12, nlp=model.nlp()), model.point_from(start), "ipopt")
    assert sx.converged and cb.converged
    assert np.max(np.abs(model.sensor2flange(sx.x) - model.sensor2flange(cb.x))) < 1e-9


def test_large_datasets_default_to_lm_and_say_so(tmp_path, monkeypatch):
    monkeypatch.setattr(engine, "LARGE", 10)
    r = handeye.calibrate("thesis-sim", no_loo=True)
    assert r.method == "lm" and any("default method is lm" in w for w in r.warnings)
    assert handeye.calibrate("thesis-sim", no_loo=True, method="ipopt").method == "ipopt"
    assert handeye.calibrate("thesis-sim", no_loo=True, rotation="matrix").method == "ipopt"
    monkeypatch.undo()
    small = handeye.calibrate("thesis-sim", no_loo=True)
    assert small.method == "ipopt" and np.allclose(small.sensor2flange, r.sensor2flange, atol=1e-9)


@pytest.mark.parametrize("many", [False, True])
def test_screening_finds_the_same_gross_errors_one_at_a_time_or_together(monkeypatch, many):
    d = handeye.load_dataset("thesis-real")
    from handeye.model.pose import transform_from_pose

    if many:
        monkeypatch.setattr(robust, "LOO_EXACT_UP_TO", 5)
    s = robust.screen(d, "sensor", transform_from_pose(d.start_pose))
    assert {"x+22.5", "x+45", "x*+90", "y*+112.5"} <= {e.id for e in s.excluded}
