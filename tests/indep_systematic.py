"""An independent generator of systematic errors for the verdict's rate study (numpy and the standard library only).

Written from README.md's "Dataset format" and "Any cell" sections (``setup.toml``, ``measurements.csv``,
profile files; ``[sensor] mount``, ``[sphere] mount``, ``[positioner] axes``, ``[noise]``, ``[robot]`` joints)
and from the geometry of a laser-line sensor, without any code of ``handeye``: its rotations and pose columns
come from tests/indep_cells.py, its robots from tests/indep_robots.py, its slips from tests/indep_cells.py
(both written the same way), so that a study can measure handeye against mistakes that are not its own.

Frames and units (mm; angles in degrees unless said):

* ``F_i`` the flange in the robot base (4x4) of pose i, as the controller reports it (in the cell's
  convention, ``indep_cells.pose_values``); ``sensor`` the sensor frame in its mount's frame (the flange for
  ``eye_in_hand`` and ``positioner``, the base for ``eye_to_hand``); ``centre`` the sphere centre in its
  mount's frame (base, flange, or the positioner's table = the base at zero angles).
* Sensor frame: the laser plane is y = 0, x along the line, z the measuring direction; the sphere centre is
  seen at ``p = (x, side * f * R, z)`` with |x| <= 25 mm, f in [0.15, 0.85], z in [170, 280] + R.  A profile
  is the arc of the circle of radius ``sqrt(R^2 - y^2)`` about ``(x, z)`` that faces the sensor, 60-170 deg
  of it, points 0.08-0.2 mm apart, each coordinate with N(0, point_sd^2), point_sd 0.01-0.04 mm.
* The chains: ``eye_in_hand`` ``F_i X p_i = c``; ``eye_to_hand`` ``S p_i = F_i c``; ``positioner``
  ``F_i X p_i = table2base(theta_i) c`` with two revolute axes (e1 a horizontal tilt, e2 the table's turn),
  ``table2base = A_1(theta_1) A_2(theta_2)``, ``A_j(t) x = R(d_j, t)(x - q_j) + q_j``; the axes written are
  the true ones (a calibrated positioner).
* Noise, 0.02-0.1 mm: rows with centres (mode ``centre``): N(0, noise^2) per component of the measured centre,
  stated as ``[noise] centre_mm``; profile rows (mode ``profile``, xs,ys,zs left out): the robot's
  repeatability, N(0, noise^2) per axis of each reported flange position, stated as ``[noise] robot_mm``,
  plus the profile points' own noise.

The classes (:data:`CLASSES`), each drawn from its seed across the three mounts, the four conventions, centres
given and profile-only, centre known or estimated, 12-40 poses, noise 0.02-0.1 mm:

``clean`` nothing wrong (half of the pose lists ordered as smooth tours); ``clean-robot`` tests/indep_robots.py
without robot errors (joints given); ``scale`` the sensor's coordinates times 1 +- (0.2-0.5 %) (centres: all
three; profiles: x and z of every point); ``diameter`` profile cells whose declared diameter is 1-3 % off;
``taught-centre`` ``[sphere] center`` written 1-2 mm off the true one (the pose calibrated, the centre held);
``joint-offsets`` zero offsets of 0.05-0.1 deg on one or two of joints 2-5, ``link-lengths`` 0.3-0.6 mm on one
or two of the lengths neither the sensor nor the centre absorbs (tests/indep_robots.py, joints given);
``pairing-shift`` a smooth tour whose measurements are paired with the next (or previous) row's pose;
``non-arc`` profile cells of an edge target (a corner of two planes, or a step: two parallel lines) declared
as a sphere; ``slip`` the setup slips of tests/indep_cells.py, round robin.

Public: :func:`make` (draw a cell of a class, write its folder, return its :class:`Truth`), :class:`Truth`
(its ``wrong(result)`` and ``distance(result)``), :func:`read_back` (a folder read with this module's own
parser: flanges, centres or circle-fitted profiles) and :func:`chain_residuals` (the chain at the truth).
"""
from __future__ import annotations

import csv
import dataclasses
import math
import pathlib
import tomllib

import indep_cells as ic
import indep_robots as ir
import numpy as np

CLASSES = ("clean", "clean-robot", "scale", "diameter", "taught-centre", "joint-offsets", "link-lengths",
           "pairing-shift", "non-arc", "slip")
#: the classes with nothing wrong in them: any exit but 0 at the truth is a false alarm
CLEAN = ("clean", "clean-robot")
MOUNTS = ("eye_in_hand", "eye_to_hand", "positioner")
#: the issue's "wrong": more than 3 reported sd AND more than 0.2 mm / 0.05 deg from the truth
WRONG_SD, WRONG_MM, WRONG_DEG = 3.0, 0.2, 0.05
#: the sensor's view: |x| <= X_HALF, y = side * f * R with f in Y_FRACTION, z in STANDOFF + R (mm); f from
#: near the equator (0.15: the side still settled by the data, README "calibrate": 0.1 R is where it is not)
#: to a small cut (0.85: a circle of half the sphere's radius)
X_HALF, Y_FRACTION, STANDOFF = 25.0, (0.15, 0.85), (170.0, 280.0)
#: half the angle (deg) a profile's arc spans about the direction to the sensor: from a profile cut short by
#: the measuring window (60 deg of arc) to nearly the whole half circle the sensor sees (170 deg)
ARC_HALF = (30.0, 85.0)
#: lengths neither the sensor nor the centre absorbs (tests/indep_robots.py names): along the last axis
#: (KR 60 HA j6_x, UR d6) the sensor takes it, so the sensor's truth itself would move
LENGTHS = {"kr60ha": ("j2_x", "j3_x", "j4_x", "j4_z"), "ur5e": ("a2", "a3", "d4", "d5"),
           "ur10e": ("a2", "a3", "d4", "d5")}
OFFSET_JOINTS = ("j2", "j3", "j4", "j5")
_MOUNT_KEYS = {"eye_in_hand": ("flange", "world"), "eye_to_hand": ("world", "flange"),
               "positioner": ("flange", "positioner")}


# ----------------------------------------------------------------------------- the cell's draw
@dataclasses.dataclass(frozen=True)
class Spec:
    """What is drawn for a cell before its geometry: class, seed, mount, convention, mode ('centre' or
    'profile'), centre known, number of poses, noise (mm), tour ('random' or 'smooth'), diameter (mm)."""

    kind: str
    seed: int
    mount: str
    convention: str
    mode: str
    centre_known: bool
    n: int
    noise: float
    tour: str
    diameter: float


def draw_spec(kind, seed):
    """The :class:`Spec` of cell ``seed`` of class ``kind`` (seeded by both)."""
    rng = np.random.default_rng([CLASSES.index(kind), seed])
    mount = str(rng.choice(MOUNTS))
    convention = str(rng.choice(ic.CONVENTIONS))
    mode = "profile" if kind in ("diameter", "non-arc") else str(rng.choice(["centre", "profile"]))
    centre_known = kind == "taught-centre" or bool(rng.random() < 0.5)
    tour = "smooth" if kind == "pairing-shift" or (kind == "clean" and rng.random() < 0.5) else "random"
    return Spec(kind, seed, mount, convention, mode, centre_known, int(rng.integers(12, 41)),
                round(float(rng.uniform(0.02, 0.1)), 4), tour, round(float(rng.uniform(25.0, 80.0)), 3))


def _views(rng, n, tour, spin_max):
    """Per pose (n, 6): tilt (deg, 0-40), azimuth (deg), spin (deg), and the sphere's place in the view as
    fractions x in [-1, 1], y in [0, 1], z in [0, 1].  ``smooth``: each a smooth function of i / n (one loop
    of the azimuth), with a small jitter, so that neighbouring rows are neighbouring poses."""
    if tour == "random":
        return np.column_stack([40.0 * np.sqrt(rng.uniform(size=n)), rng.uniform(0, 360, n),
                                rng.uniform(-spin_max, spin_max, n), rng.uniform(-1, 1, n), rng.uniform(0, 1, n),
                                rng.uniform(0, 1, n)])
    u = np.arange(n) / n
    ph = rng.uniform(0, 2 * math.pi, 6)
    k = rng.integers(1, 3, 3)
    jitter = rng.normal(scale=[0.5, 2.0, 2.0, 0.02, 0.02, 0.02], size=(n, 6))
    cols = np.column_stack([22.0 + 15.0 * np.sin(2 * math.pi * k[0] * u + ph[0]), math.degrees(ph[1]) + 360.0 * u,
                            0.8 * spin_max * np.sin(2 * math.pi * u + ph[2]), 0.9 * np.sin(2 * math.pi * k[1] * u + ph[3]),
                            0.5 + 0.45 * np.sin(2 * math.pi * u + ph[4]), 0.5 + 0.45 * np.cos(2 * math.pi * k[2] * u + ph[5])])
    return np.clip(cols + jitter, [0, -1e9, -180, -1, 0, 0], [40, 1e9, 180, 1, 1, 1])


def _seen_at(view, radius, side):
    """The sphere centre in the sensor frame (3, mm) for a view's fractions."""
    f = Y_FRACTION[0] + view[4] * (Y_FRACTION[1] - Y_FRACTION[0])
    return np.array([X_HALF * view[3], side * f * radius, STANDOFF[0] + radius + view[5] * (STANDOFF[1] - STANDOFF[0])])


def _frame(z_dir, spin):
    """A rotation (3x3) whose z axis is ``z_dir`` (any length), turned ``spin`` deg about it."""
    z = np.asarray(z_dir, float) / np.linalg.norm(z_dir)
    helper = np.array([0.0, 0.0, 1.0]) if abs(z[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z]) @ ic.rot_z(spin)


def _tilted(direction, tilt, azimuth):
    """``direction`` (unit) tilted by ``tilt`` deg towards the azimuth ``azimuth`` (deg) about it."""
    R = _frame(direction, azimuth)
    return ic.axis_angle(R[:, 1], tilt) @ direction


def axis_motion(point, direction, deg):
    """4x4 of a revolute axis (point mm, direction, base) turned by ``deg``: ``x -> R(d, deg)(x - q) + q``."""
    R = ic.axis_angle(direction, deg)
    q = np.asarray(point, float)
    return ic.transform(R, q - R @ q)


def table2base(axes, angles):
    """The positioner's table in the base (4x4) at the axis angles (deg): ``A_1(t1) A_2(t2)`` (base first)."""
    T = np.eye(4)
    for ax, t in zip(axes, angles):
        T = T @ axis_motion(ax["point"], ax["direction"], t)
    return T


# ----------------------------------------------------------------------------- geometry of the three mounts
def _sensor_on_flange(rng):
    """sensor2flange (4x4): any orientation, 80-250 mm off the flange."""
    d = rng.normal(size=3)
    return ic.transform(ic.random_rotation(rng), d / np.linalg.norm(d) * rng.uniform(80.0, 250.0))


def _positioner_axes(rng):
    """Two axes 1.0-1.2 m in front of the robot: e1 horizontal (the tilt), e2 vertical at zero (the turn)."""
    az, rho = math.radians(rng.uniform(-40, 40)), rng.uniform(1000.0, 1200.0)
    q1 = np.array([rho * math.cos(az), rho * math.sin(az), rng.uniform(-100.0, 250.0)])
    d1 = ic.rot_z(rng.uniform(-30, 30)) @ np.array([-math.sin(az), math.cos(az), 0.0])
    return [dict(name="e1", point=q1, direction=d1),
            dict(name="e2", point=q1 + [0.0, 0.0, rng.uniform(-50.0, 100.0)], direction=np.array([0.0, 0.0, 1.0]))]


def _layout(rng, spec):
    """The cell's fixed parts: ``sensor`` (4x4, mount frame), ``centre`` (3, mount frame), ``axes`` (positioner
    or None), ``down`` (the nominal view direction in the base: the sensor's z, or for a fixed sensor the
    stick's direction from the flange to the sphere)."""
    axes = None
    if spec.mount == "eye_to_hand":
        az, rho = math.radians(rng.uniform(-50, 50)), rng.uniform(1100.0, 1400.0)
        where = np.array([rho * math.cos(az), rho * math.sin(az), rng.uniform(350.0, 800.0)])
        heading, dip = math.atan2(-where[1], -where[0]), math.radians(rng.uniform(15, 45))
        z = np.array([math.cos(dip) * math.cos(heading), math.cos(dip) * math.sin(heading), -math.sin(dip)])
        sensor = ic.transform(_frame(z, rng.uniform(-180, 180)), where)
        stick = np.array([rng.uniform(-0.4, 0.4), rng.uniform(-0.4, 0.4), 1.0])
        centre, down = stick / np.linalg.norm(stick) * rng.uniform(100.0, 250.0), -z
    elif spec.mount == "positioner":
        sensor, axes = _sensor_on_flange(rng), _positioner_axes(rng)
        phi, r = rng.uniform(-math.pi, math.pi), rng.uniform(80.0, 200.0)
        centre = axes[1]["point"] + [r * math.cos(phi), r * math.sin(phi), rng.uniform(80.0, 200.0)]
        down = np.array([0.0, 0.0, -1.0])
    else:
        sensor = _sensor_on_flange(rng)
        az, rho = rng.uniform(-math.pi, math.pi), rng.uniform(600.0, 1400.0)
        centre = np.array([rho * math.cos(az), rho * math.sin(az), rng.uniform(-200.0, 700.0)])
        down = _tilted(np.array([0.0, 0.0, -1.0]), rng.uniform(0, 30), rng.uniform(0, 360))
    return dict(mount=spec.mount, sensor=sensor, centre=np.asarray(centre, float), axes=axes, down=down)


def _positioner_angles(rng, n, tour):
    """Axis angles (n, 2, deg, rounded to 0.01): e1 in [-45, 45], e2 in [-180, 180]; smooth on a tour."""
    if tour == "smooth":
        u = np.arange(n) / n
        return np.column_stack([40.0 * np.sin(2 * math.pi * u + rng.uniform(0, 6.3)), -170.0 + 340.0 * u]).round(2)
    return np.column_stack([rng.uniform(-45, 45, n), rng.uniform(-180, 180, n)]).round(2)


def _pose(layout, view, p, angles):
    """One pose: ``(F, target2sensor)``, the true flange (4x4, base) and the sphere mount's frame in the sensor
    frame (4x4), for a view (tilt, azimuth, spin), the sphere seen at ``p`` and the positioner's angles."""
    X, c = layout["sensor"], layout["centre"]
    if layout["mount"] == "eye_to_hand":  # a fixed sensor: the flange turns the stick (flange -> sphere) towards it
        u = _tilted(layout["down"], view[0], view[1])
        a = c / np.linalg.norm(c)
        R = ic.axis_angle(u, view[2]) @ _align(a, u)
        F = ic.transform(R, X[:3, :3] @ p + X[:3, 3] - R @ c)
        return F, ic.inverse(X) @ F
    T = np.eye(4) if layout["axes"] is None else table2base(layout["axes"], angles)
    nominal = layout["down"]
    if layout["axes"] is not None:  # look at the table from its side, from above
        normal = T[:3, :3] @ layout["axes"][1]["direction"]
        nominal = -(normal + [0.0, 0.0, 1.0]) / np.linalg.norm(normal + [0.0, 0.0, 1.0])
    Rs = _frame(_tilted(nominal, view[0], view[1]), view[2])
    target = T[:3, :3] @ c + T[:3, 3]
    S = ic.transform(Rs, target - Rs @ p)
    return S @ ic.inverse(X), ic.inverse(S) @ T


def _align(u, v):
    """The smallest rotation taking unit u onto unit v (3x3)."""
    axis = np.cross(u, v)
    s, cos = np.linalg.norm(axis), float(u @ v)
    if s < 1e-12:
        return np.eye(3) if cos > 0 else ic.axis_angle(np.cross(u, [1.0, 0.0, 0.0] if abs(u[0]) < 0.9 else [0, 1, 0]), 180)
    return ic.axis_angle(axis, math.degrees(math.atan2(s, cos)))


def _geometry(rng, spec, layout, radius, side, accept=None):
    """Every pose of the cell: ``flanges`` (n, 4, 4, true, base), ``target2sensor`` (n, 4, 4: the sphere
    mount's frame in the sensor frame), ``points`` (n, 3: the true sphere centre in the sensor frame), ``angles``
    (n, 2, deg, or None).  ``accept(target2sensor, p)``: a view it refuses is drawn again (random)."""
    spin_max = 180.0 if accept is None else 50.0
    views = _views(rng, spec.n, spec.tour, spin_max)
    angles = _positioner_angles(rng, spec.n, spec.tour) if layout["axes"] is not None else None
    flanges, moves, points = [], [], []
    for i in range(spec.n):
        for attempt in range(500):
            view = views[i] if attempt == 0 else _views(rng, 1, "random", spin_max)[0]
            p = _seen_at(view, radius, side)
            F, M = _pose(layout, view, p, None if angles is None else angles[i])
            if accept is None or accept(M, p):
                break
        else:
            raise RuntimeError(f"{spec}: no view of pose {i} sees the target")
        flanges.append(F)
        moves.append(M)
        points.append(p)
    return dict(flanges=np.array(flanges), target2sensor=np.array(moves), points=np.array(points), angles=angles)


# ----------------------------------------------------------------------------- what the sensor measures
def arc(rng, centre_xz, r, point_sd):
    """A sphere's profile: the arc (60-170 deg, :data:`ARC_HALF`) of the circle (centre (x, z), radius r, mm) that faces the
    sensor's origin, points 0.08-0.2 mm apart, each coordinate with N(0, point_sd^2); (k, 2) array of (x, z)."""
    cx, cz = centre_xz
    half = math.radians(rng.uniform(*ARC_HALF))
    phi = math.atan2(-cz, -cx) + np.linspace(-half, half, max(30, int(2 * half * r / rng.uniform(0.08, 0.2))))
    pts = np.column_stack([cx + r * np.cos(phi), cz + r * np.sin(phi)])
    return pts + rng.normal(scale=point_sd, size=pts.shape)


@dataclasses.dataclass(frozen=True)
class EdgeTarget:
    """A target that is no sphere, in its mount's frame: ``point`` (mm) on its edge, ``edge`` (unit) the edge's
    direction, ``normals`` (2, 3) of its two faces (towards the sensor), ``step`` (mm): 0 for a corner (two
    planes meeting in the edge), else the depth of a step (two parallel faces, the second ``step`` farther)."""

    point: np.ndarray
    edge: np.ndarray
    normals: np.ndarray
    step: float


def edge_target(rng, target2sensor, p, kind):
    """An :class:`EdgeTarget` at the sensor-frame point ``p`` of the first pose (``target2sensor`` its 4x4):
    the edge within 20 deg of the sensor's y (across the laser plane), the faces towards the sensor; ``kind``
    'corner' (faces 25-50 deg either side of the bisector) or 'step' (3-8 mm deep)."""
    M = ic.inverse(target2sensor)
    edge = ic.axis_angle([0.0, 0.0, 1.0], rng.uniform(-20, 20)) @ [0.0, 1.0, 0.0]
    bisector = _tilted(np.array([0.0, 0.0, -1.0]), rng.uniform(0, 15), rng.uniform(0, 360))
    bisector -= (bisector @ edge) * edge
    bisector /= np.linalg.norm(bisector)
    if kind == "corner":
        alpha = rng.uniform(25.0, 50.0)
        normals, step = [ic.axis_angle(edge, a) @ bisector for a in (alpha, -alpha)], 0.0
    else:
        normals, step = [bisector, bisector], rng.uniform(3.0, 8.0)
    return EdgeTarget(M[:3, :3] @ p + M[:3, 3], M[:3, :3] @ edge, np.array([M[:3, :3] @ n for n in normals]), step)


def _edge_in_sensor(target, target2sensor):
    """The target's point, edge and normals in the sensor frame."""
    R, t = target2sensor[:3, :3], target2sensor[:3, 3]
    return R @ target.point + t, R @ target.edge, target.normals @ R.T


def edge_visible(target, target2sensor):
    """Whether the laser plane cuts the edge (|edge_y| > 0.4) and both faces face the sensor (cos > 0.3)."""
    q, e, normals = _edge_in_sensor(target, target2sensor)
    facing = [float(n @ -q) / np.linalg.norm(q) for n in normals]
    return abs(e[1]) > 0.4 and min(facing) > 0.3


def edge_profile(rng, target, target2sensor, point_sd):
    """The profile of an :class:`EdgeTarget` (k, 2 points (x, z), mm): the laser plane y = 0 cut with its
    faces, 12-20 mm either side of where it crosses the edge, points 0.08-0.2 mm apart, with noise."""
    q, e, normals = _edge_in_sensor(target, target2sensor)
    crossing = q - q[1] / e[1] * e
    half = rng.uniform(12.0, 20.0)
    x = np.linspace(crossing[0] - half, crossing[0] + half, int(2 * half / rng.uniform(0.08, 0.2)))
    depth = [0.0, target.step]
    zs = [(n @ (q - d * n) - n[0] * x) / n[2] for n, d in zip(normals, depth)]
    if target.step == 0.0:
        z = np.maximum(*zs)  # a convex corner: the faces meet in the edge nearest the sensor
    else:
        across = np.cross(e, normals[0])
        z = np.where((x - crossing[0]) * across[0] + (zs[0] - crossing[2]) * across[2] > 0, zs[1], zs[0])
    pts = np.column_stack([x, z])
    return pts + rng.normal(scale=point_sd, size=pts.shape)


# ----------------------------------------------------------------------------- the truth and its verdict
@dataclasses.dataclass(frozen=True)
class Truth:
    """One cell: its :class:`Spec`, its folder, the true ``sensor`` (4x4, in its mount's frame, mm), the true
    ``centre`` (3, mm, in the sphere mount's frame; an edge target's point), the ``unknowns`` a user would pass
    (``sensor`` with a centre given, else ``sensor+sphere``), what was ``planted`` (name -> value), and ``data``
    (the drawn arrays, for self-checks: :func:`chain_residuals`)."""

    spec: Spec
    folder: pathlib.Path
    sensor: np.ndarray
    centre: np.ndarray
    unknowns: str
    planted: dict
    data: dict = dataclasses.field(default_factory=dict, repr=False, compare=False)

    def distance(self, result):
        """How far a calibration's pose lies from the truth: ``mm`` (translation), ``deg`` (rotation angle),
        ``z`` (6: the error of tx, ty, tz (mm, the mount's frame) and of the rotation about the sensor's axes
        (R_true^T R) over the reported 1-sd of each; inf where no sd is reported), ``z_t``, ``z_r`` (their
        largest |z| per block)."""
        d = result.to_dict()
        T = np.asarray(d["sensor_matrix"], float)
        dt = T[:3, 3] - self.sensor[:3, 3]
        w = np.degrees(ic.rotvec_from_matrix(self.sensor[:3, :3].T @ T[:3, :3]))
        error = np.concatenate([dt, w])
        sd = np.full(6, np.nan)
        cov = d.get("covariance") or {}
        names = list(cov.get("names") or [])
        for k, name in enumerate(("tx", "ty", "tz", "wx", "wy", "wz")):
            if name in names:
                i = names.index(name)
                sd[k] = math.sqrt(max(float(cov["matrix"][i][i]), 0.0)) * (1.0 if k < 3 else math.degrees(1.0))
        with np.errstate(divide="ignore", invalid="ignore"):
            z = np.where(sd > 0, error / sd, np.inf)
        return dict(mm=float(np.linalg.norm(dt)), deg=float(np.linalg.norm(w)), z=z,
                    z_t=float(np.max(np.abs(z[:3]))), z_r=float(np.max(np.abs(z[3:]))))

    def wrong(self, result):
        """The issue's criterion on the pose of ``result``: beyond 3 reported sd AND beyond 0.2 mm in
        translation, or beyond 3 sd AND 0.05 deg in rotation (whatever the exit; an exit 0 with it is the
        worst bug)."""
        d = self.distance(result)
        return bool((d["z_t"] > WRONG_SD and d["mm"] > WRONG_MM) or (d["z_r"] > WRONG_SD and d["deg"] > WRONG_DEG))


# ----------------------------------------------------------------------------- sphere cells
def _observe(rng, spec, geometry, radius):
    """What the sensor and the controller report, per pose: ``rows`` (dicts of id, F reported, centre or
    profile, angles), the injected ``centre_noise`` (n, 3, sensor frame) and ``robot_noise`` (n, 3, base), the
    ``scale`` (1 + s; s planted in the scale class only), the edge target (non-arc) or None."""
    n = spec.n
    scale = 1.0
    if spec.kind == "scale":
        scale += float(rng.choice([-1.0, 1.0]) * rng.uniform(0.002, 0.005))
    centre_noise = rng.normal(scale=spec.noise, size=(n, 3)) if spec.mode == "centre" else np.zeros((n, 3))
    robot_noise = rng.normal(scale=spec.noise, size=(n, 3)) if spec.mode == "profile" else np.zeros((n, 3))
    point_sd = float(rng.uniform(0.01, 0.04))
    rows = []
    for i in range(n):
        F = geometry["flanges"][i].copy()
        F[:3, 3] += robot_noise[i]
        row = dict(id=f"r{i + 1:03d}", F=F, centre=None, profile=None,
                   angles=None if geometry["angles"] is None else geometry["angles"][i])
        p = geometry["points"][i]
        if spec.kind == "non-arc":
            row["profile"] = edge_profile(rng, geometry["edge"], geometry["target2sensor"][i], point_sd)
        elif spec.mode == "centre":
            row["centre"] = scale * p + centre_noise[i]
        else:
            row["profile"] = scale * arc(rng, (p[0], p[2]), math.sqrt(radius**2 - p[1] ** 2), point_sd)
        rows.append(row)
    return rows, dict(centre_noise=centre_noise, robot_noise=robot_noise, scale=scale, point_sd=point_sd)


def _paired(rows, shift):
    """Each row's pose (flange, axis angles) with the measurement of the row ``shift`` later (+-1): one row
    fewer, the ids the measurements'."""
    if shift > 0:
        poses, measured = rows[:-1], rows[1:]
    else:
        poses, measured = rows[1:], rows[:-1]
    return [dict(m, F=p["F"], angles=p["angles"]) for p, m in zip(poses, measured)]


def _sphere_cell(folder, spec):
    """Draw and write a cell of one of the sphere classes (not the robot or slip ones); its :class:`Truth`."""
    rng = np.random.default_rng([CLASSES.index(spec.kind), spec.seed, 1])
    layout = _layout(rng, spec)
    side, radius = int(rng.choice([-1, 1])), spec.diameter / 2.0
    accept, holder = None, {}
    if spec.kind == "non-arc":
        shape = str(rng.choice(["corner", "step"]))

        def accept(M, p):
            holder.setdefault("edge", edge_target(rng, M, p, shape))
            return edge_visible(holder["edge"], M)

    geometry = _geometry(rng, spec, layout, radius, side, accept)
    geometry["edge"] = holder.get("edge")
    rows, noise = _observe(rng, spec, geometry, radius)
    planted, written = {}, dict(diameter=spec.diameter, centre=layout["centre"] if spec.centre_known else None)
    if spec.kind == "scale":
        planted["sensor_scale"] = noise["scale"] - 1.0
    elif spec.kind == "diameter":
        planted["diameter_error"] = float(rng.choice([-1.0, 1.0]) * rng.uniform(0.01, 0.03))
        written["diameter"] = round(spec.diameter * (1.0 + planted["diameter_error"]), 4)
    elif spec.kind == "taught-centre":
        u = rng.normal(size=3)
        planted["centre_offset_mm"] = (u / np.linalg.norm(u) * rng.uniform(1.0, 2.0)).tolist()
        written["centre"] = layout["centre"] + planted["centre_offset_mm"]
    elif spec.kind == "pairing-shift":
        planted["shift"] = int(rng.choice([-1, 1]))
        rows = _paired(rows, planted["shift"])
    elif spec.kind == "non-arc":
        planted["target"] = shape
    start = _start(rng, layout["sensor"]) if rng.random() < 0.5 else None
    _write(folder, spec, layout, rows, dict(written, side=side, start=start))
    keep = slice(None) if spec.kind != "pairing-shift" else (slice(None, -1) if planted["shift"] > 0 else slice(1, None))
    data = dict(mount=spec.mount, axes=layout["axes"], side=side, radius=radius, rows=rows,
                flanges=geometry["flanges"][keep], target2sensor=geometry["target2sensor"][keep],
                points=geometry["points"][keep], centre_noise=noise["centre_noise"][keep],
                robot_noise=noise["robot_noise"][keep], point_sd=noise["point_sd"])
    return Truth(spec, pathlib.Path(folder), layout["sensor"], layout["centre"],
                 "sensor" if spec.centre_known else "sensor+sphere", planted, data)


def _start(rng, T):
    """A CAD start pose (4x4) 2-5 mm and 1-3 deg off ``T``."""
    d = rng.normal(size=3)
    return ic.transform(ic.axis_angle(rng.normal(size=3), rng.uniform(1.0, 3.0)) @ T[:3, :3],
                        T[:3, 3] + d / np.linalg.norm(d) * rng.uniform(2.0, 5.0))


def _toml_vec(values, digits=9):
    return "[" + ", ".join(f"{float(v):.{digits}f}" for v in values) + "]"


def _setup_text(spec, layout, written):
    """The text of ``setup.toml`` (no ``[truth]``: a user's own cell)."""
    sensor_mount, sphere_mount = _MOUNT_KEYS[spec.mount]
    lines = [f"# tests/indep_systematic.py: {spec.kind}, seed {spec.seed}", "[robot]",
             f'convention = "{spec.convention}"', "", "[sensor]", f'mount = "{sensor_mount}"']
    if written["start"] is not None:
        lines.append(f"start_pose = {_toml_vec(ic.pose_values(written['start'], spec.convention), 12)}")
    lines += ["", "[sphere]", f'mount = "{sphere_mount}"', f"diameter = {written['diameter']!r}"]
    if written["centre"] is not None:
        lines.append(f"center = {_toml_vec(written['centre'])}")
    if layout["axes"] is not None:
        items = [f'{{ name = "{a["name"]}", point = {_toml_vec(a["point"])}, direction = {_toml_vec(a["direction"], 12)} }}'
                 for a in layout["axes"]]
        lines += ["", "[positioner]", "axes = [\n    " + ",\n    ".join(items) + ",\n]"]
    if spec.mode == "profile":
        lines += ["", "[profile]", f"side = {written['side']}"]
    key = "centre_mm" if spec.mode == "centre" else "robot_mm"
    return "\n".join(lines + ["", "[noise]", f"{key} = {spec.noise}", ""])


def _write(folder, spec, layout, rows, written):
    """Write ``setup.toml``, ``measurements.csv`` and ``profiles/<id>.csv`` (header ``x,z``)."""
    folder = pathlib.Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "setup.toml").write_text(_setup_text(spec, layout, written))
    axis_names = [a["name"] for a in layout["axes"]] if layout["axes"] is not None else []
    header = ["id", "x", "y", "z", *ic.ANGLE_COLUMNS[spec.convention]]
    header += ["xs", "ys", "zs"] if spec.mode == "centre" else ["profile"]
    digits = 12 if spec.convention in ("abb", "ur") else 9
    if spec.mode == "profile":
        (folder / "profiles").mkdir(exist_ok=True)
    with open(folder / "measurements.csv", "w", newline="") as f:
        out = csv.writer(f)
        out.writerow(header + axis_names)
        for row in rows:
            pose = ic.pose_values(row["F"], spec.convention)
            values = [f"{v:.9f}" for v in pose[:3]] + [f"{v:.{digits}f}" for v in pose[3:]]
            if spec.mode == "centre":
                values += [f"{v:.9f}" for v in row["centre"]]
            else:
                name = f"profiles/{row['id']}.csv"
                lines = ["x,z"] + [f"{x:.6f},{z:.6f}" for x, z in row["profile"]]
                (folder / name).write_text("\n".join(lines) + "\n")
                values.append(name)
            values += [f"{t:.2f}" for t in (row["angles"] if axis_names else [])]
            out.writerow([row["id"], *values])


# ----------------------------------------------------------------------------- robot and slip cells
def _robot_cell(folder, spec):
    """A cell of tests/indep_robots.py (sensor on the flange, joints given): clean, or with joint offsets of
    0.05-0.1 deg on one or two of joints 2-5, or length errors of 0.3-0.6 mm on one or two lengths of
    :data:`LENGTHS`; the centre given or left to be estimated; its :class:`Truth`."""
    rng = np.random.default_rng([CLASSES.index(spec.kind), spec.seed, 2])
    model = str(rng.choice(ir.MODELS))
    convention = "kuka" if model != "kr60ha" and rng.random() < 0.25 else ir.CONVENTION[model]
    planted, offsets, lengths = {"robot": model}, None, None
    if spec.kind == "joint-offsets":
        joints = rng.choice(OFFSET_JOINTS, size=int(rng.integers(1, 3)), replace=False)
        offsets = {str(j): float(rng.choice([-1.0, 1.0]) * rng.uniform(0.05, 0.1)) for j in joints}
        planted["joint_offsets"] = offsets
    elif spec.kind == "link-lengths":
        names = rng.choice(LENGTHS[model], size=int(rng.integers(1, 3)), replace=False)
        lengths = {str(k): float(rng.choice([-1.0, 1.0]) * rng.uniform(0.3, 0.6)) for k in names}
        planted["link_lengths"] = lengths
    made = ir.make(folder, model, seed=50000 + 1000 * CLASSES.index(spec.kind) + spec.seed, n=spec.n,
                   offsets=offsets, noise=spec.noise, convention=convention, lengths=lengths)
    if not spec.centre_known:
        setup = pathlib.Path(folder) / "setup.toml"
        setup.write_text("\n".join(line for line in setup.read_text().splitlines() if not line.startswith("center =")) + "\n")
    spec = dataclasses.replace(spec, mount="eye_in_hand", convention=convention, mode="centre", tour="random")
    return Truth(spec, pathlib.Path(folder), made["sensor"], made["centre"],
                 "sensor" if spec.centre_known else "sensor+sphere", planted, dict(robot=made))


#: the setup slips of tests/indep_cells.py, one per cell in turn
SLIP_NAMES = tuple(ic.SLIPS)


def _slip_cell(folder, spec):
    """A setup slip of tests/indep_cells.py (its own cell: sensor on the flange, centre given); its
    :class:`Truth` (the true pose of the cell the slip was written from)."""
    name = SLIP_NAMES[spec.seed % len(SLIP_NAMES)]
    slip = ic.SLIPS[name](folder, 70000 + spec.seed, n_poses=spec.n, sigma=spec.noise)
    spec = dataclasses.replace(spec, mount="eye_in_hand", convention=slip.cell.convention, centre_known=True,
                               mode="profile" if slip.cell.notes["profiles"] == "profile" else "centre", tour="random")
    return Truth(spec, pathlib.Path(folder), slip.cell.X, slip.cell.centre, "sensor",
                 {"slip": name, "description": slip.description}, dict(slip=slip))


def make(folder, kind, seed):
    """Draw cell ``seed`` of class ``kind`` (one of :data:`CLASSES`), write its dataset folder, return its
    :class:`Truth` (``truth.wrong(result)`` judges a calibration of it)."""
    if kind not in CLASSES:
        raise ValueError(f"class {kind!r}: one of {CLASSES}")
    spec = draw_spec(kind, seed)
    if kind in ("clean-robot", "joint-offsets", "link-lengths"):
        return _robot_cell(folder, spec)
    if kind == "slip":
        return _slip_cell(folder, spec)
    return _sphere_cell(folder, spec)


# ----------------------------------------------------------------------------- reading back, on its own
def fit_circle(points):
    """A circle through (k, 2) points (x, z): the algebraic (Kasa) fit refined by Gauss-Newton on the
    geometric distances; ``(x_c, z_c, r)`` (mm)."""
    x, z = points[:, 0], points[:, 1]
    A = np.column_stack([x, z, np.ones_like(x)])
    a, b, c = np.linalg.lstsq(A, x**2 + z**2, rcond=None)[0]
    p = np.array([a / 2, b / 2, math.sqrt(c + a * a / 4 + b * b / 4)])
    for _ in range(20):
        dx, dz = x - p[0], z - p[1]
        d = np.hypot(dx, dz)
        J = np.column_stack([-dx / d, -dz / d, -np.ones_like(d)])
        step = np.linalg.lstsq(J, -(d - p[2]), rcond=None)[0]
        p += step
        if np.abs(step).max() < 1e-12:
            break
    return tuple(float(v) for v in p)


def read_back(folder):
    """A folder read with this module's own parser: ``setup`` (dict), ``convention``, ``ids``, ``flanges``
    (n, 4, 4), ``measured`` (n, 3: the centre columns, or from each profile's circle, ``[profile] side`` and
    ``[sphere] diameter``), ``angles`` (n, k, deg), ``profiles`` (list of (m, 2) or None)."""
    folder = pathlib.Path(folder)
    setup = tomllib.loads((folder / "setup.toml").read_text())
    conv = setup.get("robot", {}).get("convention", "kuka")
    names = [a["name"] for a in setup.get("positioner", {}).get("axes", [])]
    with open(folder / "measurements.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    radius = setup["sphere"]["diameter"] / 2.0
    flanges, measured, profiles = [], [], []
    for row in rows:
        flanges.append(ic.pose_matrix([float(row[k]) for k in ("x", "y", "z", *ic.ANGLE_COLUMNS[conv])], conv))
        prof = np.loadtxt(folder / row["profile"], delimiter=",", skiprows=1, ndmin=2) if row.get("profile") else None
        profiles.append(prof)
        if row.get("xs"):
            measured.append([float(row[k]) for k in ("xs", "ys", "zs")])
        else:
            xc, zc, r = fit_circle(prof)
            measured.append([xc, setup["profile"]["side"] * math.sqrt(max(radius**2 - r**2, 0.0)), zc])
    angles = np.array([[float(r[k]) for k in names] for r in rows]).reshape(len(rows), len(names))
    return dict(setup=setup, convention=conv, ids=[r["id"] for r in rows], flanges=np.array(flanges),
                measured=np.array(measured), angles=angles, profiles=profiles)


def chain_residuals(truth, back=None):
    """Per row of the written files (own reading, :func:`read_back`, or ``back`` as it returns), how far the
    chain misses at the truth (n, 3, mm, base): ``F X m - c`` (sensor on the flange), ``F X m -
    table2base(theta) c`` (positioner), ``S m - F c`` (fixed sensor).  At the truth of a clean cell: the
    injected noise, turned into the base (centres), or the robot's noise and the circle fit's own error
    (profiles)."""
    back = read_back(truth.folder) if back is None else back
    X, c = truth.sensor, np.append(truth.centre, 1.0)
    axes = truth.data.get("axes")
    out = []
    for i, (F, m) in enumerate(zip(back["flanges"], back["measured"])):
        m = np.append(m, 1.0)
        if truth.spec.mount == "eye_to_hand":
            out.append((X @ m - F @ c)[:3])
        else:
            target = table2base(axes, back["angles"][i]) @ c if axes is not None else c
            out.append((F @ X @ m - target)[:3])
    return np.array(out)
