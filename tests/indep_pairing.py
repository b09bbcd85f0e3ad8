"""An independent generator of pairing shifts: smooth robot tours whose measurements sit one row off.

Written from the dataset format of the README (``measurements.csv``, ``setup.toml``, a ``profile`` column
naming a CSV of laser-line points ``x,z`` in the sensor's y = 0 plane), with numpy and the standard library
and :mod:`indep_mounts` (itself independent of handeye) for the cells' frames; no code of ``handeye``.

A robot program measures the sphere along a *tour*: each pose a small motion from the previous one, as a
taught path goes (a rotation of 2-10 deg about an axis through a point near the sphere, the flange moving
5-30 mm relative to the sphere's mount: the base, or the positioner's table). A logger that writes each
measurement one row late (or early) pairs every pose with its neighbour's measurement: a *pairing shift*.

* ``shift = +1``: row i holds pose i and the measurement taken at pose i+1 (the issue's "each pose paired
  with the next row's measurement"); ``-1``: the measurement taken at pose i-1. The file has one row fewer
  than the tour (the pose without a measurement is dropped).
* ``order = "tour"``: the rows in the tour's order; ``"shuffled"``: the tour's poses in a random order
  before the shift (a shift of a shuffled list pairs unrelated poses).
* Mounts as :mod:`indep_mounts`: ``eye_in_hand`` (sensor on the flange, sphere in the base),
  ``eye_to_hand`` (sensor fixed in the cell, sphere on a stick on the flange), ``positioner`` (sensor on
  the flange, sphere on a two-axis table that indexes to a few configurations, the robot following it:
  the tour is smooth relative to the table).
* ``profiles``: each row's measurement is a profile file (xs, ys, zs left out): the arc of the circle the
  laser plane cuts from the sphere, 60-90 points over 100-140 deg facing the sensor, with the sphere
  centre on the sensor's -y side (``[profile] side = -1``, the default) 0.2-0.8 R from the plane.
* Noise: per component of a centre (or per coordinate of a profile point), 0.02-0.1 mm, stated as
  ``[noise] centre_mm``.

Public: :func:`make` (draw a tour, write the folder, return the truth), :func:`step_sizes` (the tour's
steps, to check the generator), :data:`MOUNTS`.
"""
from __future__ import annotations

import math
import pathlib

import indep_mounts as im
import numpy as np

MOUNTS = im.MOUNTS
#: A tour's step: rotation (deg) and the flange's translation relative to the sphere's mount (mm).
STEP_DEG, STEP_MM = (2.0, 10.0), (5.0, 30.0)
#: The sensor's view for profile rows: the centre on the -y side, 0.2-0.8 R from the laser plane.
PROFILE_Y = (0.2, 0.8)
NOISE = (0.02, 0.1)


# ----------------------------------------------------------------------------- own rotations
def quaternion_matrix(q):
    """Unit quaternion (w, x, y, z) -> rotation matrix (3x3)."""
    w, x, y, z = np.asarray(q, float) / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def turn(axis, deg):
    """Rotation (3x3) by ``deg`` about ``axis`` (any length), through the half-angle quaternion."""
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    h = math.radians(deg) / 2.0
    return quaternion_matrix([math.cos(h), *(math.sin(h) * a)])


def angle_between(Ra, Rb):
    """Angle (deg) of the rotation taking Ra to Rb."""
    c = (np.trace(Ra.T @ Rb) - 1.0) / 2.0
    return math.degrees(math.acos(min(1.0, max(-1.0, c))))


# ----------------------------------------------------------------------------- the tours
def _in_view(p, profiles):
    """The centre p (sensor frame, mm) in the working range; for profile rows on the -y side."""
    if not im.in_view(p):
        return False
    return not profiles or -PROFILE_Y[1] * im.DIAMETER / 2 <= p[1] <= -PROFILE_Y[0] * im.DIAMETER / 2


class _Cell:
    """One drawn cell: its frames and how a relative flange pose G (flange in the sphere mount's frame)
    becomes a flange pose, a seen centre and whether the pose is one to take."""

    def __init__(self, mount, rng, profiles):
        self.mount, self.rng, self.profiles = mount, rng, profiles
        while True:
            first = im._BUILDERS[mount](rng, 1)  # the cell's frames and one pose that sees the sphere
            if _in_view(first["points"][0], profiles):
                break
        self.cell = first
        self.angles = None if first["angles"] is None else first["angles"][0]
        self.G0 = self.relative(first["flanges"][0], self.angles)

    def table(self, angles):
        return np.eye(4) if angles is None else im.table2base(self.cell["axes"], angles)

    def relative(self, F, angles):
        return im.inverse(self.table(angles)) @ F

    def seen(self, G):
        """The sphere centre in the sensor frame at the relative flange pose G (mm)."""
        c = self.cell
        if self.mount == "eye_to_hand":
            return (im.inverse(c["sensor"]) @ G @ np.append(c["centre"], 1.0))[:3]
        return (im.inverse(G @ c["sensor"]) @ np.append(c["centre"], 1.0))[:3]

    def sphere(self, G):
        """The sphere centre in the mount's frame where G sees it (the pivot of a tour's turn)."""
        c = self.cell
        return (G @ np.append(c["centre"], 1.0))[:3] if self.mount == "eye_to_hand" else np.asarray(c["centre"], float)

    def takes(self, G, angles):
        """Whether a robot could take the pose and the sensor sees the sphere there."""
        F = self.table(angles) @ G
        if not im._reachable(F) or not _in_view(self.seen(G), self.profiles):
            return False
        c = self.cell
        if self.mount == "eye_in_hand":
            return (F @ c["sensor"])[2, 2] < -math.cos(math.radians(60.0))
        if self.mount == "eye_to_hand":
            stick = F[:3, :3] @ im.unit(c["centre"])
            return float(stick @ -c["sensor"][:3, 2]) > math.cos(math.radians(55.0))
        z = (F @ c["sensor"])[:3, 2]
        normal = self.table(angles)[:3, :3] @ c["axes"][1]["direction"]
        return -float(z @ normal) > math.cos(math.radians(75.0)) and z[2] < -0.2

    def step(self, G):
        """A small motion of the relative flange pose: a turn of 2-10 deg about an axis through a point
        near the sphere, and the flange moved 5-30 mm (None when the draw is not a small motion)."""
        rng = self.rng
        R = turn(rng.normal(size=3), rng.uniform(*STEP_DEG))
        q = self.sphere(G) + rng.normal(scale=30.0, size=3)
        out = G.copy()
        out[:3, :3] = R @ G[:3, :3]
        out[:3, 3] = R @ (G[:3, 3] - q) + q + rng.normal(scale=4.0, size=3)
        moved = float(np.linalg.norm(out[:3, 3] - G[:3, 3]))
        return out if STEP_MM[0] <= moved <= STEP_MM[1] else None


def _index(cell, angles):
    """A positioner's next table configuration (degrees): e1 in [-45, 45], e2 anywhere."""
    return np.array([cell.rng.uniform(-45.0, 45.0), cell.rng.uniform(-180.0, 180.0)]).round(2)


def tour(mount, rng, n, profiles=False):
    """A smooth tour of ``n`` poses (module docstring).

    Returns
    -------
    cell : dict
        :mod:`indep_mounts`' cell of ``mount`` (``sensor``, ``centre``, ``axes``, ``nominal``).
    flanges : ndarray (n, 4, 4)
        Flange in the base, mm.
    points : ndarray (n, 3)
        The exact sphere centre in the sensor frame, mm.
    angles : ndarray (n, 2) or None
        Positioner axis angles, degrees.
    """
    while True:
        cell = _Cell(mount, rng, profiles)
        G, angles = cell.G0, cell.angles
        rel, table = [G], [angles]
        configurations = max(4, n // 3)
        stuck = 0
        while len(rel) < n and stuck < 3000:
            if mount == "positioner" and len(rel) % math.ceil(n / configurations) == 0 and table[-1] is angles:
                angles = _index(cell, angles)  # the table indexes; the robot follows it (G unchanged)
            nxt = cell.step(rel[-1])
            if nxt is not None and cell.takes(nxt, angles):
                rel.append(nxt)
                table.append(angles)
                stuck = 0
            else:
                stuck += 1
        if len(rel) == n:
            break
    flanges = np.array([cell.table(a) @ g for g, a in zip(rel, table)])
    points = np.array([cell.seen(g) for g in rel])
    return cell.cell, flanges, points, (None if mount != "positioner" else np.array(table))


def step_sizes(flanges, angles, axes):
    """Per step of a tour: the turn (deg) and the flange's move (mm) relative to the sphere's mount."""
    rel = [im.inverse(im.table2base(axes, a)) @ F if angles is not None else F
           for F, a in zip(flanges, angles if angles is not None else [None] * len(flanges))]
    return np.array([(angle_between(a[:3, :3], b[:3, :3]), np.linalg.norm(b[:3, 3] - a[:3, 3]))
                     for a, b in zip(rel[:-1], rel[1:])])


# ----------------------------------------------------------------------------- writing
def _arc(rng, p, noise):
    """Profile points (k, 2: x, z in the laser plane, mm) of the sphere centred at p (sensor frame), the arc
    that faces the sensor, with ``noise`` (mm) on each coordinate."""
    R = im.DIAMETER / 2
    r = math.sqrt(R * R - p[1] * p[1])
    half = math.radians(rng.uniform(50.0, 70.0))
    phi = np.linspace(-half, half, int(rng.integers(60, 91)))
    pts = np.column_stack([p[0] + r * np.sin(phi), p[2] - r * np.cos(phi)])
    return pts + rng.normal(scale=noise, size=pts.shape)


def _rows(cell, flanges, points, angles, measured, shift, profile_names):
    """The CSV text: row i holds pose i and the measurement of pose i + shift."""
    names = ["e1", "e2"] if angles is not None else []
    head = ["id", "x", "y", "z", "a", "b", "c"] + (["profile"] if profile_names else ["xs", "ys", "zs"]) + names
    lines = [",".join(head)]
    for i in range(len(flanges)):
        j = i + shift
        if not 0 <= j < len(flanges):
            continue
        meas = [profile_names[j]] if profile_names else [f"{v:.9f}" for v in measured[j]]
        extra = [f"{t:.2f}" for t in angles[i]] if names else []
        lines.append(",".join([f"m{i + 1:03d}", *(f"{v:.9f}" for v in im.pose_values(flanges[i])), *meas, *extra]))
    return "\n".join(lines) + "\n"


def make(folder, mount, seed, n=24, shift=0, order="tour", profiles=False, centre_known=None, noise=None):
    """Draw a tour of ``mount``, write its dataset folder with the measurements ``shift`` rows off, return the truth.

    Parameters
    ----------
    folder : path
    mount : {"eye_in_hand", "eye_to_hand", "positioner"}
    seed : int
        Seed of ``numpy.random.default_rng``.
    n : int
        Poses of the tour (the file has ``n - |shift|`` rows).
    shift : {0, 1, -1}
        Row i holds pose i and the measurement of pose i + shift.
    order : {"tour", "shuffled"}
    profiles : bool
        Write each measurement as a profile file instead of xs, ys, zs.
    centre_known : bool or None
        Write ``[sphere] center`` (never on a positioner, whose axes are estimated with it); None: drawn.
    noise : float or None
        mm per component (centres) or per coordinate (profile points); None: drawn in 0.02-0.1.

    Returns
    -------
    dict
        ``folder``, ``mount``, ``seed``, ``shift``, ``order``, ``profiles``, ``noise``, ``centre_known``,
        ``sensor`` (4x4 in its mount's frame), ``sensor_pose`` (KUKA), ``sphere_center``, ``axes``,
        ``flanges``, ``angles``, ``points`` (in the tour's or the shuffled order, before the shift).
    """
    rng = np.random.default_rng(seed)
    cell, flanges, points, angles = tour(mount, rng, n, profiles)
    noise = float(rng.uniform(*NOISE)) if noise is None else float(noise)
    if centre_known is None:
        centre_known = bool(rng.integers(2))
    centre_known = centre_known and mount != "positioner"
    if order == "shuffled":
        perm = rng.permutation(n)
        flanges, points = flanges[perm], points[perm]
        angles = None if angles is None else angles[perm]
    folder = pathlib.Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    names = None
    measured = points + rng.normal(scale=noise, size=points.shape)
    if profiles:
        (folder / "profiles").mkdir(exist_ok=True)
        names = []
        for i, p in enumerate(points):
            pts = _arc(rng, p, noise)
            names.append(f"profiles/m{i + 1:03d}.csv")
            (folder / names[-1]).write_text("x,z\n" + "".join(f"{x:.6f},{z:.6f}\n" for x, z in pts))
    start = im._rough_start(rng, cell["sensor"]) if rng.integers(2) else None
    (folder / "setup.toml").write_text(im._setup_text(cell, mount, seed, round(noise, 4), start, centre_known, False))
    (folder / "measurements.csv").write_text(_rows(cell, flanges, points, angles, measured, shift, names))
    return dict(folder=folder, mount=mount, seed=seed, shift=shift, order=order, profiles=profiles, noise=noise,
                centre_known=centre_known, sensor=cell["sensor"], sensor_pose=im.pose_values(cell["sensor"]),
                sphere_center=cell["centre"], axes=cell["axes"], flanges=flanges, angles=angles, points=points)
