"""Small cells of every mount for the unit tests of model/chain/mounts.py and the cell stage (handeye's own
pose functions; the independent generator is tests/indep_mounts.py)."""
from __future__ import annotations

import pathlib

import numpy as np

from handeye.model.chain.mounts import Axis, table2base
from handeye.model.chain.pose import pose_from_transform, transform_from_pose

#: A KP1-V-like positioner: a tilt axis along x, the table's axis along z above it.
AXES = (Axis("e1", np.array([1200.0, 0.0, 200.0]), np.array([1.0, 0.0, 0.0])),
        Axis("e2", np.array([1200.0, 0.0, 250.0]), np.array([0.0, 0.0, 1.0])))
SENSOR_ON_FLANGE = (30.0, -20.0, 150.0, 10.0, 5.0, -170.0)
SENSOR_IN_WORLD = (900.0, 200.0, 600.0, 20.0, 170.0, 0.0)


def _view(rng):
    """A sensor orientation looking down with tilts up to 40 deg, and the sphere's point in the sensor."""
    rot = transform_from_pose(np.r_[0, 0, 0, rng.uniform(-180, 180), rng.uniform(-40, 40), rng.uniform(-40, 40) + 180])
    return rot[:3, :3], np.array([rng.uniform(-30, 30), rng.uniform(-30, 30), rng.uniform(180, 260)])


def cell(mount, seed=0, n=30, noise=0.05, angles=None):
    """Rows ``(flange pose KUKA (6,), xs (3,), axis angles (k,))`` and the truth of a cell.

    mount : {'eye_in_hand', 'eye_to_hand', 'positioner'}; ``angles`` (n, 2) fixes the positioner's.
    """
    rng = np.random.default_rng(seed)
    sensor = transform_from_pose(np.array(SENSOR_IN_WORLD if mount == "eye_to_hand" else SENSOR_ON_FLANGE))
    centre = np.array([10.0, 20.0, 180.0]) if mount == "eye_to_hand" else np.array([1200.0, 100.0, 300.0])
    rows = []
    for i in range(n):
        rot, seen = _view(rng)
        if mount == "eye_to_hand":
            at = (sensor @ np.append(seen, 1))[:3]
            flange = np.eye(4)
            flange[:3, :3] = rot
            flange[:3, 3] = at - rot @ centre
            xs = (np.linalg.inv(sensor) @ flange @ np.append(centre, 1))[:3]
            rows.append((pose_from_transform(flange), xs + rng.normal(0, noise, 3), np.zeros(0)))
            continue
        th = np.zeros(0)
        at = centre
        if mount == "positioner":
            th = np.array([rng.uniform(-50, 50), rng.uniform(-180, 180)]) if angles is None else np.asarray(angles[i])
            at = (table2base(AXES, th[None])[0] @ np.append(centre, 1))[:3]
        s2b = np.eye(4)
        s2b[:3, :3], s2b[:3, 3] = rot, at - rot @ seen
        rows.append((pose_from_transform(s2b @ np.linalg.inv(sensor)), seen + rng.normal(0, noise, 3), th))
    return rows, {"sensor": sensor, "centre": centre}


def write(folder, mount, rows, truth, centre_known=True, axes=AXES, extra_setup=""):
    """A dataset folder of :func:`cell`'s rows (``axes``: the nominal axes written for a positioner)."""
    folder = pathlib.Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    lines = ["[sensor]", f'mount = "{"world" if mount == "eye_to_hand" else "flange"}"', "[sphere]", "diameter = 50.0",
             f'mount = "{ {"eye_to_hand": "flange", "positioner": "positioner"}.get(mount, "world")}"']
    if centre_known:
        lines.append(f"center = {[float(v) for v in truth['centre']]}")
    names = []
    if mount == "positioner":
        names = [a.name for a in axes]
        lines += ["[positioner]", "axes = [" + ", ".join(
            f'{{ name = "{a.name}", point = {[float(v) for v in a.point]}, direction = {[float(v) for v in a.direction]} }}'
            for a in axes) + "]"]
    lines += ["[noise]", "centre_mm = 0.05", extra_setup]
    (folder / "setup.toml").write_text("\n".join(lines) + "\n")
    text = ",".join(["id", "x", "y", "z", "a", "b", "c", "xs", "ys", "zs", *names]) + "\n"
    for i, (pose, xs, th) in enumerate(rows):
        text += ",".join([f"p{i}", *(f"{v:.6f}" for v in pose), *(f"{v:.6f}" for v in xs), *(f"{v:.6f}" for v in th)])
        text += "\n"
    (folder / "measurements.csv").write_text(text)
    return folder
