"""Every row consistent with itself (issue 25, part 3): a row that gives both the sensor's centre
xs, ys, zs and a profile must describe one cut of the sphere. A profile cell copied from the
neighbouring row is named with its row, excluded by calibrate and diagnose alike, and the
calibration lands at the truth; clean data are never flagged."""
import dataclasses

import numpy as np
import pytest

import handeye
from handeye.app.command import cli
from handeye.model.chain.pose import transform_from_pose
from handeye.model.common.rotation import rotvec_from_matrix, transform_distance
from handeye.model.datasets import consistency


def _swap_profiles(path, i, j):
    """Swap the ``profile`` cells of data lines i and j (0-based after the header)."""
    lines = (path / "measurements.csv").read_text().splitlines()
    a, b = lines[1 + i].split(","), lines[1 + j].split(",")
    a[-1], b[-1] = b[-1], a[-1]
    lines[1 + i], lines[1 + j] = ",".join(a), ",".join(b)
    (path / "measurements.csv").write_text("\n".join(lines) + "\n")


def _shift_profiles(path):
    """Every row gets the next row's profile (a column pasted one row off)."""
    lines = (path / "measurements.csv").read_text().splitlines()
    cells = [line.split(",") for line in lines[1:]]
    profiles = [c[-1] for c in cells]
    for c, p in zip(cells, profiles[1:] + profiles[:1]):
        c[-1] = p
    (path / "measurements.csv").write_text("\n".join([lines[0]] + [",".join(c) for c in cells]) + "\n")


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


@pytest.mark.slow(sibling="test_the_test_statistic_is_the_mahalanobis_distance_of_the_circles")
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


# -- calibrate and diagnose --------------------------------------------------------------------

def _errors_in_sd(r, truth):
    """|pose error| per component in units of the result's own 1-sd (translation, rotation)."""
    e = np.concatenate([r.sensor2flange[:3, 3] - truth[:3, 3],
                        np.degrees(rotvec_from_matrix(truth[:3, :3].T @ r.sensor2flange[:3, :3]))])
    return np.abs(e) / np.concatenate([r.std.sensor_translation_mm, r.std.sensor_rotation_deg])


def test_the_copy_paste_slip_is_named_excluded_and_the_calibration_lands_at_the_truth(tmp_path, capsys):
    s = handeye.simulate(tmp_path / "slip", seed=11, profiles=True, n_poses=24)
    truth = transform_from_pose(s.dataset.truth["sensor_pose"])
    _swap_profiles(s.path, 4, 5)
    ids = {s.dataset.ids[4]: 6, s.dataset.ids[5]: 7}  # id -> line in measurements.csv
    r = handeye.calibrate(s.path, no_loo=True)
    assert r.converged and r.model == "measurement"
    bad = [e for e in r.excluded if "contradicts itself" in e.reason]
    assert {e.id: e.row for e in bad} == ids and len(r.excluded) == 2
    for e in bad:
        assert f"row {e.row}" in e.reason and e.statistic > 100 and e.p_bonferroni < 1e-3
    assert r.n_used == len(s.dataset) - 2 and r.rms_mm < 0.06
    dt, dr = transform_distance(r.sensor2flange, truth)
    assert dt < 0.2 and dr < 0.05 and _errors_in_sd(r, truth).max() < 4  # without the check: 1.5 mm, 3.8 deg
    assert all(not x.used for x in r.residuals if x.id in ids)
    # diagnose fits the same observations and names the same rows with the same reasons
    d = handeye.diagnose(s.path)
    assert set(ids) <= set(d.outliers)
    assert {e.id: e.reason for e in d.inconsistent} == {e.id: e.reason for e in bad}
    assert all(not x.used for x in d.residuals if x.id in ids)
    assert d.to_dict()["inconsistent"][0]["row"] in ids.values()
    dt, dr = transform_distance(d.sensor2flange, truth)
    assert dt < 0.2 and dr < 0.05 and _errors_in_sd(d, truth).max() < 4
    # the command line: exit 0 with the rows named in the reports
    assert cli.main(["calibrate", str(s.path), "--no-loo"]) == cli.EXIT_OK
    out = capsys.readouterr().out
    assert "row 6" in out and "row 7" in out and "contradicts itself" in out
    assert cli.main(["diagnose", str(s.path)]) == cli.EXIT_OK
    out = capsys.readouterr().out
    assert "row 6" in out and "contradicts itself" in out
    # the closed-form baselines use the same observations
    k = handeye.calibrate(s.path, method="kim-cho")
    assert {e.id for e in k.excluded} == set(ids)


def test_the_slip_is_excluded_even_with_keep_all(tmp_path):
    s = handeye.simulate(tmp_path / "slip", seed=12, profiles=True, n_poses=12)
    _swap_profiles(s.path, 2, 3)
    r = handeye.calibrate(s.path, no_loo=True, keep_all=True)
    assert {e.id for e in r.excluded} == {s.dataset.ids[2], s.dataset.ids[3]}


def test_a_profile_column_shifted_by_one_row_is_bad_input_naming_the_rows(tmp_path, capsys):
    s = handeye.simulate(tmp_path / "shift", seed=13, profiles=True, n_poses=12)
    _shift_profiles(s.path)
    with pytest.raises(handeye.InputError, match=r"12 of the 12 rows .* contradict themselves .*: row 2 \('.*systematic slip"):
        handeye.calibrate(s.path, no_loo=True)
    assert cli.main(["calibrate", str(s.path)]) == cli.EXIT_BAD_INPUT
    assert "row 13" in capsys.readouterr().err
    assert cli.main(["diagnose", str(s.path)]) == cli.EXIT_BAD_INPUT


def test_a_centre_that_is_also_a_gross_error_keeps_one_record_with_both_reasons(tmp_path):
    s = handeye.simulate(tmp_path / "out", seed=6, profiles=True, n_poses=24, effect=["outlier=x+45"])
    r = handeye.calibrate(s.path, no_loo=True, model="centre")
    (e,) = r.excluded
    assert e.id == "x+45" and "improbable" in e.reason and "contradicts itself" in e.reason and e.residual_mm > 10


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_clean_datasets_with_centres_and_profiles_are_never_flagged(tmp_path, seed):
    kw = [dict(), dict(convention="ur", diameter=50.8, max_tilt=45), dict(diameter=25.4, max_tilt=60),
          dict(linearity=0.0016)][seed]
    s = handeye.simulate(tmp_path / "clean", seed=seed, profiles=True, n_poses=16, **kw)
    r = handeye.calibrate(s.path, no_loo=True)
    assert not any("contradicts itself" in e.reason for e in r.excluded)
    assert not consistency.check_rows(s.dataset).inconsistent


def test_the_embedded_datasets_have_no_row_to_check():
    for name in ("thesis-real", "thesis-sim"):
        assert consistency.check_rows(handeye.load_dataset(name)).checked == ()
