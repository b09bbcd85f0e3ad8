"""Effects' parameters stay physical and their sd is right: the sphere_radius sd that calibrate
reports against a Monte Carlo over the noise of simulated data with known truth, and a radius
smaller than a circle measured on the sphere refused."""
import dataclasses

import numpy as np
import pytest

import handeye
from handeye.model import effects
from handeye.model.chain.pose import pose_from_transform, transform_from_pose
from handeye.model.fit import extended
from handeye.model.simulation import simulate as sim

DIAMETER = 25.4
RADIUS_STRUCTURE = extended.Structure(centre=False, data_effects=("sphere_radius",))


def _views(n=10, nearest=None, seed=0):
    """Flange poses (KUKA) of the thesis strategy on a 25.4 mm sphere; ``nearest`` puts the
    fifth laser plane that far (mm) from the sphere's equator."""
    setup = sim.Setup(diameter=DIAMETER)
    rng = np.random.default_rng(seed)
    ids, rots = zip(*sim.thesis_orientations(n, 90))
    seen = np.array([sim.random_view(setup, rng) for _ in rots])
    if nearest is not None:
        seen[4, 1] = setup.side * nearest
    flanges = sim.flanges_for_views(setup, np.array(rots), seen)
    return setup, list(ids), np.array([pose_from_transform(f) for f in flanges])


def _replicate(template, made):
    """``template`` (a loaded dataset of the same poses) with a replicate's measurements."""
    return dataclasses.replace(template, flange_poses=made.flange_poses, centre_in_sensor=made.centre_in_sensor,
                               profiles=None, reconstructed=None)


@pytest.mark.parametrize("dr_true, nearest", [pytest.param(-0.3, None, marks=pytest.mark.slow(
    sibling="test_the_sphere_radius_sd_agrees_with_a_monte_carlo[0.0-1.0]")), (0.0, 1.0)])
def test_the_sphere_radius_sd_agrees_with_a_monte_carlo(tmp_path, dr_true, nearest):
    """Ten poses, 25.4 mm sphere, known truth: the reported 1 sd of dr against the spread of dr
    over 200 noise realisations of the same poses (the same estimator, diagnose's extended fit
    that calibrate --effects runs). Measured: ratio 1.11 and 1.06 here (0.99 with 36 poses; 1.4 with a plane 0.5 mm from the
    equator, where y's own noise grows like r/|y|: the note says so)."""
    setup, ids, flanges = _views(nearest=nearest)
    truth = {"sphere_radius": dr_true}
    first = sim.simulate(setup, seed=1, effects=truth, flange_poses=flanges, ids=ids)
    folder = sim.write(first, tmp_path / "mc", profiles=False)
    # keep_all: the screening runs the model without the effect, in which a 0.3 mm radius error makes
    # the plane nearest the equator (the sample that carries dr) an outlier
    reported = handeye.calibrate(folder, effects="sphere_radius", no_loo=True, keep_all=True)
    assert reported.converged and not reported.excluded
    (radius,) = reported.effects
    sd_reported = radius.std["dr"]
    assert abs(radius.parameters["dr"] - dr_true) < 4 * sd_reported
    assert "1 sd of the linearised fit" in radius.note and "equator" in radius.note  # it says why it is small
    template = handeye.load_dataset(folder)
    start = transform_from_pose(setup.sensor_pose)
    estimates, sds = [], []
    for seed in range(1, 201):
        made = sim.simulate(setup, seed=seed, effects=truth, flange_poses=flanges, ids=ids)
        prob = extended.Samples(_replicate(template, made))
        mask = np.ones(len(ids), bool)
        fit = prob.fit(RADIUS_STRUCTURE, mask, prob.point(RADIUS_STRUCTURE, start))
        estimates.append(fit.params["sphere_radius"][0])
        sds.append(fit.uncertainty(mask)[0][-1])
        if seed == 1:  # the same numbers as calibrate's
            assert fit.params["sphere_radius"][0] == pytest.approx(radius.parameters["dr"], abs=1e-7)
            assert sds[-1] == pytest.approx(sd_reported, rel=1e-4)
    spread = float(np.std(estimates, ddof=1))
    assert abs(np.mean(estimates) - dr_true) < 4 * spread / np.sqrt(len(estimates))  # unbiased
    ratio = spread / float(np.sqrt(np.mean(np.square(sds))))
    assert 0.8 < ratio < 1.25, ratio  # sd of the ratio ~ 5 % with 200 realisations
    assert 0.6 < sd_reported / spread < 1.6  # this one dataset's figure too


def test_a_fit_that_wants_a_sphere_smaller_than_a_measured_circle_is_not_a_calibration(tmp_path):
    """A plane 0.3 mm from the equator and an unmodelled centre offset: the fitted radius runs
    into that sample's circle (its corrected y becomes 0, the derivative infinite), where the
    linearised sd came out as 1e-9 mm and calibrate said converged. Now: not converged, why,
    and no sd."""
    setup, ids, flanges = _views(nearest=0.3)
    made = sim.simulate(setup, seed=1, effects={"sphere_center": [0.5, 0.3, -0.4]}, flange_poses=flanges, ids=ids)
    folder = sim.write(made, tmp_path / "pinned", profiles=True)
    r = handeye.calibrate(folder, effects="sphere_radius", no_loo=True)
    assert not r.converged
    assert "smaller than a circle measured on it" in r.message and ids[4] in r.message
    assert r.to_dict()["effects"][0]["std"]["dr"] is None
    assert "no sd" in r.effects[0].note and "NOT CONVERGED" in r.summary()
    ok = handeye.calibrate(folder, no_loo=True)  # without the effect it is an ordinary (biased) fit
    assert ok.converged


def test_a_radius_below_a_profiles_circle_is_implausible():
    ids, r, sd = ["a", "b"], np.array([12.0, 12.6]), np.array([0.01, 0.02])
    assert effects.implausible("sphere_radius", [0.0], 12.7, (ids, r, sd)) is None
    assert effects.implausible("sphere_radius", [-0.1], 12.7, (ids, r, sd)) is None  # 12.6 = r: within its sd
    why = effects.implausible("sphere_radius", [-0.2], 12.7, (ids, r, sd))  # 12.5 < 12.6 - 3 x 0.02
    assert why is not None and "'b'" in why and "no larger than the sphere" in why
    assert effects.implausible("sphere_radius", [-0.2], 12.7) is None  # without the data: the limit only
    assert effects.implausible("sphere_radius", [-3.0], 12.7, (ids, r, sd)) is not None
    assert effects.implausible("sensor_scale", [0.001], 12.7, (ids, r, sd)) is None


def test_calibrate_checks_the_radius_against_every_profile(tmp_path, monkeypatch):
    """calibrate hands every profile's circle (used or excluded) to the check: a sample whose
    profile shows a circle larger than the fitted sphere makes the result not converged."""
    from handeye.app.engine import describe

    s = handeye.simulate(tmp_path / "p", seed=2, n_poses=10, diameter=DIAMETER, profiles=True)
    ok = handeye.calibrate(s.path, effects="sphere_radius", no_loo=True)
    assert ok.converged
    ids, r, sd = describe.circles_shown(handeye.load_dataset(s.path), np.ones(10, bool))
    assert len(ids) == 10 and np.all(r < DIAMETER / 2) and np.all(sd > 0)
    big = r.copy()
    big[3] = DIAMETER / 2 + 0.5  # as if sample 3's profile showed a circle larger than the sphere
    monkeypatch.setattr(describe, "circles_shown", lambda dataset, mask: (ids, big, sd))
    r = handeye.calibrate(s.path, effects="sphere_radius", no_loo=True)
    assert not r.converged and repr(ids[3]) in r.message and "circle" in r.message


def test_the_requests_effect_lists_are_the_catalogues():
    """``--effects`` takes every continuous effect of the catalogue, and the cell stage fits exactly its data effects
    with the positioner's axes: the request's two lists are the catalogue's, not a copy that can drift."""
    from handeye.app.engine import request

    assert set(request.DATA_EFFECTS) == {e.NAME for e in effects.catalogue("data")}
    assert set(request.EFFECTS) == {e.NAME for e in effects.catalogue() if e.KIND in ("data", "centre", "robot")}
