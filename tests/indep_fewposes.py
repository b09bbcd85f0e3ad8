"""An independent generator of few-pose cells (numpy and the standard library only; no ``handeye``).

Issue 39's "few poses" finding: with 6-8 robot poses at 0.1-0.3 mm noise, a setup slip or a
systematic effect that many poses would reveal can hide in the noise, and the calibrated pose lands
several reported sd from the truth. This module draws such cells as a user's own script would, from
the dataset format of the README (``setup.toml``, ``measurements.csv``), with the geometry of
:mod:`tests.indep_mounts` (itself independent of handeye) and its own faults and writer.

Frames and units (mm, degrees): as :mod:`tests.indep_mounts`. ``eye_in_hand``: the sensor on the
flange (``X`` sensor2flange), the sphere fixed in the base (``c``, base), ``F_i X p_i = c``;
``fixed``: the sensor fixed in the cell (``S`` sensor2base), the sphere on a stick on the flange
(``c`` in the flange frame), ``S p_i = F_i c``. ``p_i`` the true centre in the sensor frame; the file's
``xs, ys, zs`` = ``p_i`` (times ``1 + SCALE`` for the class ``scale``) + N(0, noise^2) per component.

Classes (:data:`CLASSES`), each a mistake a user makes on a few-pose cell:

``clean``
    nothing wrong: the answer must be right and nothing must be excluded or refused.
``centre``
    the taught sphere centre ``[sphere] center`` is :data:`CENTRE_MM` off in a random direction
    (a centre touched up with a worn tool).
``gross``
    two rows' measured centres are :data:`GROSS_MM` off, each in a random direction (two profiles
    of a spatter, or two misprinted rows).
``scale``
    the sensor's coordinates are scaled by ``1 + SCALE`` (:data:`SCALE`: 0.2 %, a sensor whose
    calibration drifted).

Public: :func:`make` (draw one cell, write its folder, return the truth and what was planted),
:func:`cell_seeds` (the seeds of a class's cells), :func:`pose_error` (translation mm, rotation deg,
and per component in the reported sd, from the truth) and :func:`wrong` (the issue's definition of a
wrong answer). Seeded (``numpy.random.default_rng(seed)``).
"""
from __future__ import annotations

import math
import pathlib

import indep_mounts as im
import numpy as np

CLASSES = ("clean", "centre", "gross", "scale")
MOUNTS = ("eye_in_hand", "fixed")
#: The few-pose range of the finding: 6-8 poses, 0.1-0.3 mm per component.
N_POSES = (6, 8)
NOISE_MM = (0.1, 0.3)
#: The planted faults' sizes (the finding's).
CENTRE_MM = 1.0
GROSS_MM = 3.0
GROSS_ROWS = 2
SCALE = 0.002
#: The issue's definition of a wrong answer: farther than this many reported sd in some component
#: and farther than these floors (mm, deg) in translation or rotation.
WRONG_SD = 3.0
WRONG_FLOOR = (0.2, 0.05)

_BUILD = {"eye_in_hand": "eye_in_hand", "fixed": "eye_to_hand"}
_SEED_BASE = {"clean": 39_000, "centre": 39_100, "gross": 39_200, "scale": 39_300}


def cell_seeds(kind, count, first=0):
    """The seeds of ``count`` cells of class ``kind`` (from the ``first``-th): disjoint between classes."""
    return [_SEED_BASE[kind] + first + k for k in range(count)]


def _unit_random(rng):
    v = rng.normal(size=3)
    return v / np.linalg.norm(v)


def _vec(values, digits=9):
    return "[" + ", ".join(f"{float(v):.{digits}f}" for v in values) + "]"


def _setup_text(mount, seed, noise, sensor, centre_written, start):
    lines = [f"# few-pose independent cell (tests/indep_fewposes.py): {mount}, seed {seed}", "[sensor]"]
    if mount == "fixed":
        lines.append('mount = "world"')
    if start is not None:
        lines.append(f"start_pose = {_vec(start, 3)}")
    lines += ["", "[sphere]", f"diameter = {im.DIAMETER}"]
    if mount == "fixed":
        lines.append('mount = "flange"')
    lines += [f"center = {_vec(centre_written)}", "", "[noise]", f"centre_mm = {noise:.4f}", ""]
    return "\n".join(lines) + "\n"


def _csv_text(flanges, measured):
    rows = ["id,x,y,z,a,b,c,xs,ys,zs"]
    for i, (F, xs) in enumerate(zip(flanges, measured)):
        rows.append(",".join([f"p{i + 1:02d}", *(f"{v:.9f}" for v in im.pose_values(F)), *(f"{v:.9f}" for v in xs)]))
    return "\n".join(rows) + "\n"


def make(folder, kind, mount, seed, **drawn):
    """Draw one few-pose cell of class ``kind`` on ``mount``, write its folder, return the truth.

    Parameters
    ----------
    folder : path
        Created if missing; ``setup.toml`` and ``measurements.csv`` are written into it.
    kind : {"clean", "centre", "gross", "scale"}
    mount : {"eye_in_hand", "fixed"}
    seed : int
    **drawn
        What is otherwise drawn from ``seed``: ``n_poses`` (int, in :data:`N_POSES`), ``noise`` (the
        per-component sd of the measured centres, mm, stated in ``[noise] centre_mm``; in
        :data:`NOISE_MM`), ``scale`` (the sensor's scale error, for any class: default :data:`SCALE` for
        ``scale``, else 0), ``circle_y`` (with a scale: the centre's y as a triangulation sensor
        reconstructs it, from the radius of the scaled circle, ``sqrt(R^2 - scale^2 (R^2 - y^2))``,
        instead of scaled with x and z), ``noise_seed`` (the seed of the noise alone: the same cell geometry, another
        draw of its noise; default ``seed``).

    Returns
    -------
    dict
        ``folder``, ``kind``, ``mount``, ``seed``, ``n``, ``noise``, ``sensor`` (4x4 in its mount's frame:
        the flange, or the base for ``fixed``), ``centre`` (3, true, mm), ``centre_written`` (3, as in the
        file), ``bad_rows`` (ids of the rows given a gross error), ``scale``.
    """
    if kind not in CLASSES or mount not in MOUNTS:
        raise ValueError(f"class {kind!r} / mount {mount!r}: one of {CLASSES} / {MOUNTS}")
    rng = np.random.default_rng(seed)
    n = int(rng.integers(N_POSES[0], N_POSES[1] + 1))
    noise = float(rng.uniform(*NOISE_MM))
    n, noise = int(drawn.get("n_poses", n)), float(drawn.get("noise", noise))
    cell = im._BUILDERS[_BUILD[mount]](rng, n)
    scale = 1.0 + float(drawn.get("scale", SCALE if kind == "scale" else 0.0))
    if drawn.get("noise_seed") is not None:
        rng = np.random.default_rng([seed, int(drawn["noise_seed"])])
    seen = scale * cell["points"]
    if drawn.get("circle_y"):  # y from the circle the scaled profile gives: R^2 - y^2 = r^2 grows by scale^2
        radius, y = im.DIAMETER / 2.0, cell["points"][:, 1]
        seen[:, 1] = np.sign(y) * np.sqrt(radius**2 - scale**2 * (radius**2 - y**2))
    measured = seen + rng.normal(scale=noise, size=cell["points"].shape)
    bad = []
    if kind == "gross":
        bad = sorted(int(i) for i in rng.choice(n, size=GROSS_ROWS, replace=False))
        for i in bad:
            measured[i] += GROSS_MM * _unit_random(rng)
    centre_written = cell["centre"] + (CENTRE_MM * _unit_random(rng) if kind == "centre" else 0.0)
    start = im._rough_start(rng, cell["sensor"]) if seed % 2 == 0 else None
    folder = pathlib.Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "setup.toml").write_text(_setup_text(mount, seed, noise, cell["sensor"], centre_written, start))
    (folder / "measurements.csv").write_text(_csv_text(cell["flanges"], measured))
    return dict(folder=folder, kind=kind, mount=mount, seed=seed, n=n, noise=noise, sensor=cell["sensor"],
                centre=cell["centre"], centre_written=centre_written, bad_rows=[f"p{i + 1:02d}" for i in bad],
                scale=scale)


def _rotvec(R):
    """Rotation vector (rad) of a 3x3 rotation (angle below pi)."""
    angle = math.acos(max(-1.0, min(1.0, (np.trace(R) - 1.0) / 2.0)))
    if angle < 1e-12:
        return 0.5 * np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    axis = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]]) / (2.0 * math.sin(angle))
    return angle * axis


def pose_error(estimate, truth, sd_mm, sd_deg):
    """How far a reported pose is from the truth.

    Parameters
    ----------
    estimate, truth : ndarray, shape (4, 4)
        Sensor in its mount's frame (mm).
    sd_mm : array_like, shape (3,)
        Reported 1-sd of the translation (mm, the mount's frame).
    sd_deg : array_like, shape (3,)
        Reported 1-sd of the rotation about the estimate's own (sensor) axes, degrees.

    Returns
    -------
    dict
        ``mm`` (translation error), ``deg`` (rotation angle), ``sd`` (the largest component's
        |error| / reported sd: translation per axis, rotation about the sensor's axes).
    """
    dt = truth[:3, 3] - estimate[:3, 3]
    dw = np.degrees(_rotvec(estimate[:3, :3].T @ truth[:3, :3]))
    z = np.abs(np.concatenate([dt, dw])) / np.maximum(np.concatenate([sd_mm, sd_deg]), 1e-300)
    return {"mm": float(np.linalg.norm(dt)), "deg": float(np.linalg.norm(dw)), "sd": float(np.max(z))}


def wrong(error):
    """The issue's wrong answer: beyond :data:`WRONG_SD` reported sd and beyond a floor of :data:`WRONG_FLOOR`."""
    return error["sd"] > WRONG_SD and (error["mm"] > WRONG_FLOOR[0] or error["deg"] > WRONG_FLOOR[1])
