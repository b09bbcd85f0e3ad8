"""Every row consistent with itself (issue 25, part 3): a row that gives both the sensor's centre
xs, ys, zs and a profile must describe one cut of the sphere."""
import dataclasses

import numpy as np
import pytest

import handeye
from handeye.model import consistency

# -- the pure function ------------------------------------------------------------------------

def test_a_circle_and_the_centre_it_came_from_agree():
    radius, sigma = 30.0, 0.05
    centres = np.array([[3.0, -10.0, 230.0], [-5.0, -0.2, 250.0], [0.0, -29.0, 220.0]])
    circles = np.column_stack([centres[:, 0], centres[:, 2], np.sqrt(radius**2 - centres[:, 1] ** 2)])
    cov = np.tile(np.diag([1e-6, 1e-6, 1e-6]), (3, 1, 1))
    diff, predicted, d2 = consistency.compare(circles, cov, centres, radius, sigma)
    np.testing.assert_allclose(diff, 0, atol=1e-12)
    np.testing.assert_allclose(predicted, circles)
    np.testing.assert_allclose(d2, 0, atol=1e-12)


def test_the_test_statistic_is_the_mahalanobis_distance_of_the_circles():
    radius, sigma = 30.0, 0.05
    centre = np.array([[2.0, -18.0, 240.0]])
    r_pred = np.sqrt(radius**2 - 18.0**2)  # 24 mm
    fitted = np.array([[2.1, 240.0, r_pred]])  # 0.1 mm off in x only
    cov_fit = np.diag([0.01**2, 0.02**2, 0.03**2])[None]
    diff, _, d2 = consistency.compare(fitted, cov_fit, centre, radius, sigma)
    np.testing.assert_allclose(diff, [[0.1, 0.0, 0.0]], atol=1e-12)
    # x: the fit's variance plus the stated centre variance
    np.testing.assert_allclose(d2, [0.1**2 / (0.01**2 + sigma**2)], rtol=1e-12)
    # the radius: the stated ys noise moves the predicted radius by (ys / r) dys
    fitted = np.array([[2.0, 240.0, r_pred + 0.1]])
    _, _, d2 = consistency.compare(fitted, cov_fit, centre, radius, sigma)
    np.testing.assert_allclose(d2, [0.1**2 / (0.03**2 + (18.0 / r_pred) ** 2 * sigma**2)], rtol=1e-12)


def test_near_the_equator_the_comparison_stays_well_conditioned():
    """At ys -> 0 a centre rebuilt from the profile (|y| = sqrt(R^2 - r^2)) is undefined or
    wildly off: here the fitted circle is, within its noise, larger than the sphere. The circles
    still compare: consistent as given, inconsistent 1 mm off in x."""
    radius, sigma = 30.0, 0.05
    centre = np.array([[1.0, -0.2, 240.0]])
    fitted = np.array([[1.0, 240.0, radius + 0.0005]])  # no real y from this circle
    cov_fit = np.diag([0.001, 0.001, 0.001])[None] ** 2
    diff, _, d2 = consistency.compare(fitted, cov_fit, centre, radius, sigma)
    assert np.all(np.isfinite(d2)) and np.linalg.norm(diff) < 0.002 and d2[0] < 3
    _, _, d2 = consistency.compare(fitted, cov_fit, centre + [1.0, 0.0, 0.0], radius, sigma)
    assert d2[0] > 100


def test_a_centre_whose_plane_misses_the_sphere_is_not_hidden_by_the_linearisation():
    radius, sigma = 30.0, 0.05
    fitted = np.array([[0.0, 240.0, 25.0]])
    cov_fit = np.diag([1e-4, 1e-4, 1e-4])[None]
    diff, predicted, d2 = consistency.compare(fitted, cov_fit, [[0.0, -30.5, 240.0]], radius, sigma)
    assert predicted[0, 2] == 0.0 and diff[0, 2] == pytest.approx(25.0) and d2[0] > 500


def test_check_rows_names_the_swapped_pair_and_nothing_else(tmp_path):
    s = handeye.simulate(tmp_path / "d", seed=3, profiles=True, n_poses=12)
    d = s.dataset
    clean = consistency.check_rows(d)
    assert len(clean.checked) == len(d) and not clean.inconsistent and clean.consistent.all()
    profiles = list(d.profiles)
    profiles[4], profiles[5] = profiles[5], profiles[4]
    slip = consistency.check_rows(dataclasses.replace(d, profiles=tuple(profiles)))
    assert [c.index for c in slip.inconsistent] == [4, 5]
    assert [c.row for c in slip.inconsistent] == [6, 7]  # lines of measurements.csv
    for c in slip.inconsistent:
        assert c.disagreement_mm > 1 and c.sd > 20 and c.p_bonferroni < 1e-3
        assert f"row {c.row}" in c.reason and repr(c.id) in c.reason
    assert list(slip.consistent) == [k not in (4, 5) for k in range(len(d))]


def test_rows_without_both_are_not_checked(tmp_path):
    s = handeye.simulate(tmp_path / "d", seed=4, profiles=True, n_poses=8)
    d = s.dataset
    assert consistency.check_rows(dataclasses.replace(d, profiles=None)).checked == ()
    rebuilt = dataclasses.replace(d, reconstructed=(True,) * len(d))
    assert consistency.check_rows(rebuilt).checked == ()


def test_centres_with_the_stated_noise_are_not_flagged(tmp_path):
    """The false-alarm rate where it could bite: the sensor's centres computed independently of
    the profile, with exactly the stated noise ([noise] centre_mm) -- 10 datasets x 5 draws."""
    rng = np.random.default_rng(0)
    flagged = checked = 0
    for seed in range(10):
        d = handeye.simulate(tmp_path / f"s{seed}", seed=seed, profiles=True, n_poses=24,
                             diameter=(59.94507, 50.8, 25.4)[seed % 3]).dataset
        for _ in range(5):
            noisy = d.centre_in_sensor + rng.normal(0.0, d.noise_centre_mm, d.centre_in_sensor.shape)
            c = consistency.check_rows(dataclasses.replace(d, centre_in_sensor=noisy))
            checked += len(c.checked)
            flagged += len(c.inconsistent)
    assert checked == 50 * 24 and flagged == 0
