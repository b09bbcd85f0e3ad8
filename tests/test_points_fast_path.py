"""The points model's fast path (issue 26) gives the same calibration as before, and the bench's
peers and points sections report what they measure (times are measured by `handeye bench`,
never asserted here)."""
import dataclasses

import numpy as np
import pytest

import handeye
from handeye.app.engine import robust
from handeye.app.tools import bench, bench_peers, bench_points
from handeye.model.common.rotation import matrix_from_rotvec, transform_distance
from handeye.model.datasets import observations
from handeye.model.fit import calibration
from handeye.model.fit.calibration import CalibrationModel
from handeye.model.simulation import simulate


@pytest.fixture(scope="module")
def small_scan(tmp_path_factory):
    """6 poses x ~40 profile points (240 rows), a known sphere centre."""
    folder = tmp_path_factory.mktemp("points") / "scan"
    setup = dataclasses.replace(simulate.Setup(), n_points=90)
    simulate.write(simulate.simulate(setup, seed=4, n_poses=6), folder, profiles=True)
    return folder


def _old_path(monkeypatch):
    """Before issue 26: the SX graph for IPOPT at any size, second derivatives row by row."""
    monkeypatch.setattr(calibration, "NLP_CALLBACK_ABOVE", 10**9)
    monkeypatch.setattr(CalibrationModel, "_profile_layout", lambda self: None)


def test_the_fast_path_gives_the_same_pose_and_leave_one_out_as_before(small_scan, monkeypatch):
    monkeypatch.setattr(calibration, "NLP_CALLBACK_ABOVE", 10)  # the callback, as above 120 rows
    new = handeye.calibrate(small_scan, model="points")
    with monkeypatch.context() as m:
        _old_path(m)
        old = handeye.calibrate(small_scan, model="points")
    assert new.converged and old.converged and new.excluded == old.excluded
    dt, dr = transform_distance(new.sensor2flange, old.sensor2flange)
    assert dt < 1e-8 and dr < 1e-8
    new_loo = np.array([r.loo_error_mm for r in new.residuals], float)
    old_loo = np.array([r.loo_error_mm for r in old.residuals], float)
    np.testing.assert_allclose(new_loo, old_loo, rtol=1e-7, atol=1e-9)


def _scipy_points_fit(f2b, profiles, radius, centre, start):
    """An independent fit: the points residual written out here, scipy's least squares."""
    from scipy.optimize import least_squares

    rows = np.concatenate([np.repeat(f2b[k : k + 1], len(p), axis=0) for k, p in enumerate(profiles)])
    pts = np.concatenate(profiles)
    p3 = np.column_stack([pts[:, 0], np.zeros(len(pts)), pts[:, 1]])

    def residual(v):
        rot = start[:3, :3] @ matrix_from_rotvec(v[3:])
        d = np.einsum("nij,nj->ni", rows[:, :3, :3], p3 @ rot.T + v[:3]) + rows[:, :3, 3] - centre
        return np.linalg.norm(d, axis=1) - radius

    res = least_squares(residual, np.r_[start[:3, 3], 0.0, 0.0, 0.0], xtol=1e-15, ftol=1e-15, gtol=1e-15)
    out = np.eye(4)
    out[:3, :3], out[:3, 3] = start[:3, :3] @ matrix_from_rotvec(res.x[3:]), res.x[:3]
    return out


def test_the_fast_path_agrees_with_an_independent_scipy_fit_and_refits(small_scan, monkeypatch):
    monkeypatch.setattr(calibration, "NLP_CALLBACK_ABOVE", 10)
    d = handeye.load_dataset(small_scan)
    r = handeye.calibrate(small_scan, model="points", keep_all=True)
    radius = d.sphere_diameter / 2
    ref = _scipy_points_fit(d.flange2base(), d.profiles, radius, d.sphere_centre, r.sensor2flange)
    dt, dr = transform_distance(ref, r.sensor2flange)
    assert dt < 1e-6 and dr < 1e-6
    model = observations.build(d, "points", "local", "sensor")
    x = model.point_from(r.sensor2flange)
    predictor = CalibrationModel.from_dataset(d, "local", "sensor")  # the measured centres
    loo = robust.leave_one_out(model, x, predictor=predictor)
    for i in (0, 3):  # the refit without profile i predicts i's centre through the chain
        keep = [k for k in range(len(d)) if k != i]
        t2 = _scipy_points_fit(d.flange2base()[keep], [d.profiles[k] for k in keep], radius, d.sphere_centre, ref)
        predicted = d.flange2base()[i] @ t2 @ np.append(predictor.centre_in_sensor[i], 1.0)
        assert loo[i] == pytest.approx(np.linalg.norm(predicted[:3] - d.sphere_centre), rel=1e-6, abs=1e-9)


@pytest.mark.parametrize("rotation", ["local", "matrix", "euler"])
def test_second_derivatives_per_profile_equal_row_by_row(small_scan, rotation):
    d = handeye.load_dataset(small_scan)
    model = observations.build(d, "points", rotation, "sensor+sphere")
    assert model._profile_layout() is not None
    x = model.point_from(handeye.calibrate(small_scan).sensor2flange)
    rows = observations.build(d, "points", rotation, "sensor+sphere")
    rows.groups = None  # no layout: every row on its own
    h, h_rows = model.cost_hessian(x), rows.cost_hessian(x)
    np.testing.assert_allclose(h, h_rows, rtol=1e-10, atol=1e-10 * np.abs(h_rows).max())
    stack = np.stack([x, x])  # a stack of points takes the row-by-row path
    np.testing.assert_allclose(model.cost_hessian(stack)[1], h_rows, rtol=1e-10, atol=1e-10 * np.abs(h_rows).max())


def test_a_profile_from_two_poses_is_evaluated_row_by_row(small_scan):
    d = handeye.load_dataset(small_scan)
    model = observations.build(d, "points", "local", "sensor")
    model.groups = np.zeros_like(model.groups)  # one "profile" across all poses
    assert model._profile_layout() is None


@pytest.mark.parametrize("peer,package", list(bench_peers.PEERS.items()))
def test_peers_reach_the_fast_paths_pose(peer, package):
    pytest.importorskip(package)
    res = bench.peers(reps=1)
    rows = {r["name"]: r for r in res["rows"]}
    fast, row = rows["fast"], rows[peer]
    assert row["installed"] and row["median_ms"] > 0
    assert row["distance_mm"] < 1e-5 and row["distance_deg"] < 1e-5  # Ceres' own tolerances: ~1e-6 mm
    assert row["cost"] == pytest.approx(fast["cost"], rel=1e-10)
    text = bench_peers.text(res)
    assert peer in text and "bandwidth floor" in text and "not installed" not in text.split(peer)[1].split("\n")[0]
    assert res["bandwidth"]["floor_us"] > 0 and res["bandwidth"]["bytes_per_solve"] > 0


@pytest.mark.parametrize("peer,package", list(bench_peers.PEERS.items()))
def test_a_missing_peer_says_not_installed(peer, package, without_package):
    without_package(package)
    res = bench.peers(reps=1)
    row = next(r for r in res["rows"] if r["name"] == peer)
    assert not row["installed"]
    line = next(t for t in bench_peers.text(res).splitlines() if t.strip().startswith(peer))
    assert "not installed" in line and package in line
    assert {r["name"] for r in res["rows"] if r["installed"]} >= {"fast", "scipy-exact"}


@pytest.mark.slow(sibling="test_a_profile_from_two_poses_is_evaluated_row_by_row")
def test_points_section_reports_both_runs_and_their_ratio(monkeypatch):
    monkeypatch.setattr(bench_points, "LINE_POINTS", 300)  # small: the section, not the timing, is tested
    res = bench_points.measure(reps=1)
    assert res["converged"] and res["points"] > 1000 and res["default_model"] == "measurement"
    assert res["ratio"] == pytest.approx(res["points_s"] / res["default_s"])
    text = bench_points.text(res)
    assert "--model points" in text and "ratio" in text and f"{res['points']:,}" in text
