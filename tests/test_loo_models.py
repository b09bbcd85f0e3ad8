"""Leave-one-out refits the model that was asked for (centre, measurement, points: its
residual, weights and unknowns), and every RMS in the report says what it measures."""
import numpy as np
import pytest

import handeye
from handeye.app.engine import robust
from handeye.model.datasets import observations
from handeye.model.fit import global_fit
from handeye.model.fit.calibration import CalibrationModel


@pytest.fixture(scope="module")
def profiled(tmp_path_factory):
    """A 12-pose simulated dataset with profiles (so all three residual models apply)."""
    return handeye.simulate(tmp_path_factory.mktemp("loo") / "d", seed=5, n_poses=12, profiles=True).path


@pytest.fixture(scope="module")
def fits(profiled):
    return {kind: handeye.calibrate(profiled, model=kind, method="lm") for kind in observations.MODEL_KINDS}


def _reference_loo(dataset, res, kind, i):
    """Sample i's leave-one-out error the slow, obvious way: build the model of the other used
    samples from the dataset, fit it with plain least squares from the reported fit, carry i's
    measured centre through the refitted chain."""
    keep = np.array([r.used for r in res.residuals])
    keep[i] = False
    other = observations.build(dataset.subset(keep), kind, "local", res.unknowns, res.robot_sigma_mm,
                               observations.Anchor(res.sphere_centre, _anchor(dataset)))
    x = robust.least_squares(other, other.point_from(res.sensor2flange, res.sphere_centre), max_iter=400).x
    for _ in range(3):  # Newton with the exact Hessian: the minimum to rounding
        step = -np.linalg.solve(other.cost_hessian(x), other.gradient(x))
        x = other.retract(x, step)
    assert np.linalg.norm(step) < 1e-9  # mm and rad
    t2 = other.sensor2flange(x)
    seen = dataset.flange2base()[i] @ t2 @ np.append(dataset.centre_in_sensor[i], 1.0)
    return float(np.linalg.norm(seen[:3] - other.sphere_centre(x)))


def _anchor(dataset):
    """The pose the centre model turns profiled centres' weights at: the plain centre model's lowest minimum on
    every sample (app/engine/prepare.py), from its own closed-form search here."""
    return global_fit.centre_minima(dataset.motions(), dataset.centre_in_sensor, dataset.sphere_centre).best.sensor2flange


@pytest.mark.parametrize("kind", ["centre", "measurement", "points"])
def test_each_leave_one_out_error_is_a_refit_of_the_model_asked_for(profiled, fits, kind):
    dataset = handeye.load_dataset(profiled)
    res = fits[kind]
    assert res.converged and res.loo["model"] == kind and res.loo["unknowns"] == "sensor"
    assert res.loo["weighted"] == (kind != "points")  # centre and measurement rows are whitened with profiles
    for i in (0, 5, 11):
        assert res.residuals[i].loo_error_mm == pytest.approx(_reference_loo(dataset, res, kind, i), abs=1e-6)


def test_the_three_models_give_three_leave_one_out_errors(fits):
    per_sample = {k: np.array([r.loo_error_mm for r in f.residuals]) for k, f in fits.items()}
    # before, every model reported the plain centre model's refits: identical numbers
    assert np.max(np.abs(per_sample["points"] - per_sample["centre"])) > 1e-4
    assert np.max(np.abs(per_sample["measurement"] - per_sample["centre"])) > 1e-6
    before = {f.before.loo_error_mm for f in fits.values()}
    assert len(before) == 1  # the before fit is the plain centre model whatever --model says
    for f in fits.values():  # the same kind of figure: mm of a sphere centre, near the residual's size
        assert 0.5 * f.rms_mm < f.loo_error_mm < 3 * f.rms_mm


def test_an_unknown_sphere_centre_is_refitted_too(profiled):
    dataset = handeye.load_dataset(profiled)
    res = handeye.calibrate(profiled, model="points", method="lm", unknowns="sensor+sphere")
    assert res.loo["unknowns"] == "sensor+sphere"
    assert res.residuals[3].loo_error_mm == pytest.approx(_reference_loo(dataset, res, "points", 3), abs=1e-6)


def test_the_deletion_formula_refits_the_same_model(profiled, monkeypatch):
    """Above LOO_EXACT_UP_TO samples the deletion formula replaces the refits: for a points
    model (profiles as groups of rows, whitening-free) and a whitened centre model it agrees
    with the exact refits to the linearisation's error."""
    dataset = handeye.load_dataset(profiled)
    truth = handeye.load_dataset(profiled).truth["sensor_pose"]
    from handeye.model.chain.pose import transform_from_pose

    predictor = CalibrationModel.from_dataset(dataset, "local", "sensor")
    for kind in ("points", "centre"):
        model = observations.build(dataset, kind, "local", "sensor",
                                   at=observations.Anchor(sensor2flange=transform_from_pose(truth)))
        mask = np.ones(len(dataset), bool)
        mask[4] = False
        x = robust.least_squares(robust._subset(model, mask), model.point_from(transform_from_pose(truth))).x
        exact = robust.leave_one_out(model, x, mask, predictor)
        monkeypatch.setattr(robust, "LOO_EXACT_UP_TO", 3)
        fast = robust.leave_one_out(model, x, mask, predictor)
        monkeypatch.undo()
        assert np.isnan(exact[4]) and np.isnan(fast[4])
        assert np.nanmax(np.abs(fast - exact)) < 1e-3 * np.nanmax(exact), kind


def test_a_measurement_or_points_model_needs_its_predictor():
    f2b = np.tile(np.eye(4), (4, 1, 1))
    model = CalibrationModel.from_circles(f2b, np.ones((4, 3)), 30.0, np.zeros(3), "local")
    with pytest.raises(ValueError, match="predictor"):
        robust.leave_one_out(model, model.point_from(np.eye(4)))


def test_every_rms_says_what_it_measures(fits):
    points = fits["points"]
    text = points.summary()
    assert "RMS residual" in text and "per sphere centre" in text
    obj = points.objective
    assert obj["model"] == "points" and not obj["weighted"] and obj["unit"] == "mm"
    assert obj["rows"] > 1000 and obj["rms"] == pytest.approx(points.sigma_mm, rel=0.01)
    assert f"RMS {obj['rms']:.4f} mm per profile point" in text
    assert "the points model refitted" in text
    # the figure it minimised is not the per-centre RMS it reports first
    assert abs(obj["rms"] - points.rms_mm) > 1e-3
    d = points.to_dict()
    for key in ("rms_what", "objective", "loo", "rms_note"):
        assert d[key], key
    assert d["before"]["model"] == "centre" and d["before"]["weighted"] is False
    measured = fits["measurement"]
    assert measured.objective["weighted"] and measured.objective["unit"] == "sd"
    assert "weighted RMS" in measured.summary() and "sd per circle" in measured.summary()


def test_why_the_before_and_the_keep_all_rms_differ(profiled):
    """Same samples, two objectives: the before fit minimises the per-centre RMS itself, so a
    --keep-all fit with another objective has a larger one, and the report says why."""
    for kind in ("measurement", "points"):
        r = handeye.calibrate(profiled, model=kind, method="lm", keep_all=True, no_loo=True)
        assert r.n_used == r.before.n
        assert r.rms_mm >= r.before.rms_mm - 1e-9
        assert r.rms_note is not None and "minimises" in r.rms_note and "excluded" not in r.rms_note
        assert "why they differ:" in r.summary()
    plain = handeye.calibrate("thesis-sim", keep_all=True, no_loo=True)  # no profiles: one objective
    assert plain.model == "centre" and plain.rms_note is None
    assert plain.rms_mm == pytest.approx(plain.before.rms_mm, abs=1e-9)
    assert "why they differ" not in plain.summary()


def test_excluded_samples_are_named_as_the_reason(tmp_path):
    real = handeye.calibrate("thesis-real", no_loo=True)
    assert "excluded sample(s) (x+22.5" in real.rms_note and "minimises" not in real.rms_note
    assert real.loo is None and real.to_dict()["loo"] is None


def test_the_result_says_how_its_leave_one_out_was_made(profiled, fits, monkeypatch):
    """The unweighted centre model with the centre known: 'in closed form' at any size (thesis-sim here, and with
    LOO_EXACT_UP_TO below its samples); a whitened model: refits up to LOO_EXACT_UP_TO, the deletion formula above."""
    from handeye.app.engine import robust

    assert "closed form" in handeye.calibrate("thesis-sim").loo["method"]
    assert "closed form" not in fits["centre"].loo["method"] and "exact refit" in fits["centre"].loo["method"]
    monkeypatch.setattr(robust, "LOO_EXACT_UP_TO", 3)
    assert "closed form" in handeye.calibrate("thesis-sim").loo["method"]
    assert "deletion formula" in handeye.calibrate(profiled, model="centre").loo["method"]
