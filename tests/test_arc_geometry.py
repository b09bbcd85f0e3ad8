"""The geometric cause of an exclusion (model/geometry/arc_geometry.py): a profile cut by the measuring
window -- a short, one-sided arc near the sphere's equator -- is named (and, judged in its own metric,
kept); a good profile excluded for another reason (a robot pose error) gets no geometric cause."""
from __future__ import annotations

import shutil

import numpy as np
import pytest

import handeye
from handeye.model.geometry import arc_geometry, circle


def _rewrite(folder, change=None):
    """Empty xs, ys, zs (centres from the profiles); ``change(fields)`` edits a row in place."""
    lines = (folder / "measurements.csv").read_text().splitlines()
    header = lines[0].split(",")
    rows = [line.split(",") for line in lines[1:]]
    for r in rows:
        for c in ("xs", "ys", "zs"):
            r[header.index(c)] = ""
        if change is not None:
            change(r, header)
    (folder / "measurements.csv").write_text("\n".join([lines[0]] + [",".join(r) for r in rows]) + "\n")
    return {r[0]: folder / r[header.index("profile")] for r in rows}


@pytest.fixture(scope="module")
def simulated(tmp_path_factory):
    folder = tmp_path_factory.mktemp("arc") / "sim"
    handeye.simulate(folder, seed=1, profiles=True)
    return folder


def _near_equator(folder):
    """The id of the sample whose laser plane passes nearest the sphere's centre (smallest |ys|)."""
    lines = (folder / "measurements.csv").read_text().splitlines()
    header = lines[0].split(",")
    rows = [line.split(",") for line in lines[1:]]
    return min(rows, key=lambda r: abs(float(r[header.index("ys")])) if abs(float(r[header.index("ys")])) > 5 else 99)[0]


def test_a_window_cut_arc_is_named(simulated, tmp_path):
    """A window-cut arc near the equator: its centre's geometry is named (short, one-sided, its sd along
    y many times the others'); since issue 39 the screening weighs each centre by its covariance, so
    this good but poorly determined centre is kept (its error is within its own sd), not excluded as a
    gross error, and the calibration uses it at its small weight."""
    folder = tmp_path / "d"
    shutil.copytree(simulated, folder)
    ident = _near_equator(folder)
    path = _rewrite(folder)[ident]
    pts = np.loadtxt(path, delimiter=",", skiprows=1)
    fitted = circle.geometric(pts[:, 0], pts[:, 1])
    angle = np.degrees(np.arctan2(pts[:, 0] - fitted.x, fitted.z - pts[:, 1]))  # 0: the point nearest the sensor
    cut = pts[(angle > 30) & (angle < 68)]  # 38 deg on one side: the window's edge
    np.savetxt(path, cut, fmt="%.9f", delimiter=",", header="x,z", comments="")
    data = handeye.load_dataset(folder)
    k = data.ids.index(ident)
    (named,) = arc_geometry.causes(data.profiles, data.sphere_diameter / 2, data.side, [k]).values()
    assert named.startswith("short (38 deg), one-sided")
    assert "mm from the equator: the centre's sd along y is" in named
    r = handeye.calibrate(folder, no_loo=True)
    assert r.converged and ident not in [e.id for e in r.excluded], r.summary()


def test_a_robot_pose_error_on_a_good_profile_gets_no_geometric_cause(simulated, tmp_path):
    folder = tmp_path / "d"
    shutil.copytree(simulated, folder)
    ident = _near_equator(folder)

    def shift(fields, header):
        if fields[0] == ident:
            fields[header.index("x")] = repr(float(fields[header.index("x")]) + 2.0)

    _rewrite(folder, shift)
    r = handeye.calibrate(folder, no_loo=True)
    (e,) = r.excluded
    assert e.id == ident and e.geometry is None and "profile explains" not in e.reason


def test_describe_measures_the_arc():
    t = np.radians(np.linspace(10, 50, 200))
    pts = np.column_stack([20 * np.sin(t), 240 - 20 * np.cos(t)])
    pts[:, 1] += np.random.default_rng(0).normal(0, 0.01, len(pts))
    g = arc_geometry.describe(pts, 25.0)
    assert g.span_deg == pytest.approx(40, abs=0.5) and g.one_sided and g.n_points == 200
    assert g.equator_mm == pytest.approx(15.0, abs=0.1) and g.radius_mm == pytest.approx(20, abs=0.05)
    both = np.column_stack([20 * np.sin(t - 0.5), 240 - 20 * np.cos(t - 0.5)])
    assert not arc_geometry.describe(both, 25.0).one_sided


def test_a_cause_needs_the_numbers():
    good = arc_geometry.ArcGeometry(700, 120.0, False, 15.0, 26.0, np.array([0.003, 0.004, 0.003]))
    bad = arc_geometry.ArcGeometry(160, 38.0, True, 5.5, 29.5, np.array([0.01, 0.9, 0.02]))
    assert arc_geometry.cause(good, [good] * 5, 30.0) is None
    text = arc_geometry.cause(bad, [good] * 5, 30.0)
    assert text.startswith("short (38 deg), one-sided, few-point (160) arc 5.5 mm from the equator: the centre's sd "
                           "along y is 0.9 mm (225x")
    assert arc_geometry.cause(bad, [good] * 5, 30.0, error_mm=40.0) is None  # a 40 mm error is not the arc's
    assert arc_geometry.cause(bad, [], 30.0) is None
