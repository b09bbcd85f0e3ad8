"""An independent generator of hand-eye datasets for three cell mounts (numpy and the standard library only).

Written as a robotics user's own script would be, from the dataset format of the brief (``[sensor] mount``,
``[sphere] mount``, ``[positioner] axes``), with its own rotation code and without any code of ``handeye``,
so that a test can check handeye against data whose mistakes (if any) are not handeye's own.

Frames and units (everything in mm; angles in degrees unless said):

* ``base``: the robot base frame; ``F_i`` (4x4) the flange in the base for pose i (``flange2base``), from a
  KUKA pose ``(x, y, z, A, B, C)``: ``F = Trans(x, y, z) Rz(A) Ry(B) Rx(C)``, A, C in [-180, 180],
  B in [-90, 90].
* Sensor frame: a laser-line sensor; the laser plane is y = 0, x runs along the line, z is the measuring
  direction (the sphere centre is seen at z = 170-280 mm, |x| <= 30 mm, |y| <= 20 mm).  ``p_i`` the true
  sphere centre in the sensor frame; the file's ``xs, ys, zs`` = ``p_i`` (times 1.005 with the hidden
  effect ``sensor_scale``) + N(0, noise^2) per component.  No robot noise: ``[noise] centre_mm`` is
  the whole per-component sd through the chain.

The three mounts and their chains:

``eye_in_hand``
    sensor on the flange (``X`` = sensor2flange), sphere fixed in the base (``c``):
    ``F_i X p_i = c``.
``eye_to_hand``
    sensor fixed in the base (``S`` = sensor2base), sphere on a stick on the flange (``c`` in the flange
    frame): ``S p_i = F_i c``.
``positioner``
    sensor on the flange (``X``), sphere on the table of a two-axis positioner (KUKA KP1-V-like: e1 a
    horizontal tilt axis, e2 the table's turn axis, vertical at zero angles).  Axis j: point ``q_j`` and
    unit direction ``d_j`` in the base at all-zero angles; ``A_j(t) x = R(d_j, t)(x - q_j) + q_j``;
    ``table2base(t1, t2) = A_1(t1) A_2(t2)``; ``c`` the centre at zero angles in the base:
    ``F_i X p_i = table2base(theta_i) c``.  The file's ``[positioner]`` axes are nominal (CAD, rounded);
    the truth differs by 1-3 mm in point (across the axis) and 0.2-0.5 deg in direction.

Public: :func:`make` (draw one cell, write its folder, return the truth), :func:`read` (a folder back,
own parser), :func:`chain_residuals` (per row, the chain at the truth, mm), and the rotation helpers
(:func:`rot_x`, :func:`rodrigues`, :func:`kuka_matrix`, :func:`kuka_angles`, ...).  Seeded
(``numpy.random.default_rng(seed)``).
"""
from __future__ import annotations

import csv
import math
import pathlib
import tomllib

import numpy as np

MOUNTS = ("eye_in_hand", "eye_to_hand", "positioner")
EFFECTS = (None, "sensor_scale")
SENSOR_SCALE = 1.005
DIAMETER = 50.0
#: where the sphere centre may be in the sensor frame (mm): |x| <= X_HALF, |y| <= Y_HALF, z in STANDOFF
X_HALF, Y_HALF, STANDOFF = 30.0, 20.0, (170.0, 280.0)


# ----------------------------------------------------------------------------- rotations
def rot_x(deg):
    """Rotation about x by ``deg`` degrees (3x3)."""
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(deg):
    """Rotation about y by ``deg`` degrees (3x3)."""
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(deg):
    """Rotation about z by ``deg`` degrees (3x3)."""
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rodrigues(axis, deg):
    """Rotation by ``deg`` degrees about ``axis`` (3, any length; right-hand rule), Rodrigues' formula.

    Returns
    -------
    ndarray (3, 3)
        ``I + sin(t) K + (1 - cos(t)) K^2`` with K the cross-product matrix of the unit axis.
    """
    k = np.asarray(axis, float)
    k = k / np.linalg.norm(k)
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    t = math.radians(deg)
    return np.eye(3) + math.sin(t) * K + (1.0 - math.cos(t)) * K @ K


def kuka_matrix(a, b, c):
    """KUKA A, B, C (degrees) -> ``R = Rz(A) Ry(B) Rx(C)`` (3x3)."""
    return rot_z(a) @ rot_y(b) @ rot_x(c)


def kuka_angles(R):
    """Rotation matrix -> KUKA (A, B, C) in degrees: A, C in [-180, 180], B in [-90, 90].

    At B = +-90 (gimbal lock) only A -/+ C is defined; C = 0 is returned then.
    """
    cb = math.hypot(R[0, 0], R[1, 0])
    b = math.atan2(-R[2, 0], cb)
    if cb > 1e-10:
        a, c = math.atan2(R[1, 0], R[0, 0]), math.atan2(R[2, 1], R[2, 2])
    else:
        a, c = math.atan2(-R[0, 1], R[1, 1]), 0.0
    return np.degrees([a, b, c])


def transform(R, t):
    """4x4 homogeneous transform from R (3x3) and t (3, mm)."""
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, t
    return T


def inverse(T):
    """Inverse of a rigid 4x4 transform."""
    R, t = T[:3, :3], T[:3, 3]
    return transform(R.T, -R.T @ t)


def pose_matrix(pose):
    """KUKA pose ``(x, y, z, A, B, C)`` (mm, degrees) -> 4x4 ``Trans(x, y, z) Rz(A) Ry(B) Rx(C)``."""
    p = np.asarray(pose, float)
    return transform(kuka_matrix(*p[3:]), p[:3])


def pose_values(T):
    """4x4 -> KUKA pose ``[x, y, z, A, B, C]`` (mm, degrees)."""
    return np.concatenate([T[:3, 3], kuka_angles(T[:3, :3])])


def rotation_angle(R):
    """Angle of the rotation R (degrees, 0-180)."""
    return math.degrees(math.acos(max(-1.0, min(1.0, (np.trace(R) - 1.0) / 2.0))))


def unit(v):
    """``v / |v|`` (a float array)."""
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


def _align(u, v):
    """The smallest rotation taking the unit vector u onto the unit vector v (3x3)."""
    axis = np.cross(u, v)
    s, c = np.linalg.norm(axis), float(np.dot(u, v))
    if s < 1e-12:
        if c > 0:
            return np.eye(3)
        other = np.array([1.0, 0.0, 0.0]) if abs(u[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
        return rodrigues(np.cross(u, other), 180.0)
    return rodrigues(axis, math.degrees(math.atan2(s, c)))


def _perpendicular(rng, d):
    """A random unit vector perpendicular to the unit vector d."""
    v = rng.normal(size=3)
    v -= np.dot(v, d) * d
    return unit(v)


def _look(z_dir, spin):
    """Sensor orientation (3x3, sensor in base) whose z axis is ``z_dir``, turned ``spin`` deg about it."""
    z = unit(z_dir)
    helper = np.array([0.0, 0.0, 1.0]) if abs(z[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    x = unit(np.cross(helper, z))
    R0 = np.column_stack([x, np.cross(z, x), z])
    return R0 @ rot_z(spin)


def _tilted(rng, d, max_deg, min_deg=0.0):
    """The unit vector d turned by an angle in [min_deg, max_deg] about a random perpendicular axis."""
    return rodrigues(_perpendicular(rng, d), rng.uniform(min_deg, max_deg)) @ d


# ----------------------------------------------------------------------------- positioner
def axis_motion(point, direction, deg):
    """4x4 of the revolute axis (point mm, direction any length, base frame) turned by ``deg``:
    ``x -> R(d, deg)(x - point) + point``."""
    R = rodrigues(direction, deg)
    q = np.asarray(point, float)
    return transform(R, q - R @ q)


def table2base(axes, angles):
    """Table pose in the base (4x4) at the axis angles (degrees): ``A_1(t1) A_2(t2) ...`` (base first).

    Parameters
    ----------
    axes : list of dict
        ``{"name", "point" (3, mm, base, zero angles), "direction" (3)}``, base-first.
    angles : sequence of float
        One angle per axis, degrees.
    """
    T = np.eye(4)
    for ax, t in zip(axes, angles):
        T = T @ axis_motion(ax["point"], ax["direction"], t)
    return T


# ----------------------------------------------------------------------------- views
def seen_at(rng):
    """A sphere centre in the sensor frame (3, mm) in the working range: |x| <= 30, |y| <= 20, z 170-280."""
    return np.array([rng.uniform(-X_HALF, X_HALF), rng.uniform(-Y_HALF, Y_HALF), rng.uniform(*STANDOFF)])


def in_view(p, margin=1e-9):
    """Whether the sensor-frame point p (mm) is in front of the sensor within its working range."""
    return (abs(p[0]) <= X_HALF + margin and abs(p[1]) <= Y_HALF + margin
            and STANDOFF[0] - margin <= p[2] <= STANDOFF[1] + margin)


def _reachable(F):
    """Whether a flange pose (4x4, base) is one a 6-axis arm of ~1.6 m reach could take (mm)."""
    r = np.linalg.norm(F[:3, 3])
    return 350.0 <= r <= 1800.0 and F[2, 3] >= -500.0


def _sensor_on_flange(rng):
    """sensor2flange (4x4): random orientation, 100-200 mm in front of the flange, the flange out of view."""
    while True:
        q = unit(rng.normal(size=4))
        w, x, y, z = q
        R = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                      [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                      [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
        d = rng.normal(size=3)
        d[2] = abs(d[2]) + 0.5
        X = transform(R, unit(d) * rng.uniform(100.0, 200.0))
        flange_in_sensor = inverse(X)[:3, 3]
        if flange_in_sensor[2] < 40.0 and rotation_angle(R) > 20.0:  # the flange behind or beside the sensor
            return X


def _view_pose(rng, X, centre, down, max_tilt):
    """A flange pose (4x4) whose sensor (X on the flange) sees ``centre`` (base, mm) in range.

    The sensor's z is ``down`` tilted by 0-``max_tilt`` deg in a random direction, turned any angle about
    itself.  Returns ``(F, p)``: the flange in the base and the centre in the sensor frame (mm).
    """
    while True:
        Rs = _look(_tilted(rng, unit(down), max_tilt), rng.uniform(-180.0, 180.0))
        p = seen_at(rng)
        F = transform(Rs, centre - Rs @ p) @ inverse(X)
        if _reachable(F):
            return F, p


# ----------------------------------------------------------------------------- the three cells
def _eye_in_hand(rng, n):
    """Sensor on the flange, sphere in the base 800-1500 mm from the base.

    Returns
    -------
    dict
        ``sensor`` (4x4 sensor2flange), ``centre`` (3, base, mm), ``flanges`` (n, 4, 4), ``points``
        (n, 3, sensor frame, mm); ``angles``, ``axes``, ``nominal`` None.
    """
    X = _sensor_on_flange(rng)
    while True:
        az, rho = math.radians(rng.uniform(-70.0, 70.0)), rng.uniform(800.0, 1250.0)
        centre = np.array([rho * math.cos(az), rho * math.sin(az), rng.uniform(-150.0, 450.0)])
        if 800.0 <= np.linalg.norm(centre) <= 1500.0:
            break
    flanges, points = [], []
    for i in range(n):
        F, p = _view_pose(rng, X, centre, [0.0, 0.0, -1.0], 10.0 if i == 0 else 55.0)
        flanges.append(F)
        points.append(p)
    return dict(sensor=X, centre=centre, flanges=np.array(flanges), points=np.array(points), angles=None,
                axes=None, nominal=None)


def _fixed_sensor(rng):
    """sensor2base (4x4) of a sensor on a stand 1.1-1.4 m from the base, looking back at the workspace
    15-45 deg below horizontal; the middle of its range is then 0.85-1.25 m from the base."""
    az, rho = math.radians(rng.uniform(-50.0, 50.0)), rng.uniform(1100.0, 1400.0)
    where = np.array([rho * math.cos(az), rho * math.sin(az), rng.uniform(350.0, 800.0)])
    heading = math.atan2(-where[1], -where[0]) + math.radians(rng.uniform(-20.0, 20.0))
    dip = math.radians(rng.uniform(15.0, 45.0))
    z = np.array([math.cos(dip) * math.cos(heading), math.cos(dip) * math.sin(heading), -math.sin(dip)])
    return transform(_look(z, rng.uniform(-180.0, 180.0)), where)


def _eye_to_hand(rng, n):
    """Sensor fixed in the base, sphere on a 100-250 mm stick on the flange.

    The stick (flange -> sphere) points towards the sensor within 50 deg (the flange stays behind the
    sphere, out of the laser's way) and the flange turns any angle about it.

    Returns
    -------
    dict
        ``sensor`` (4x4 sensor2base), ``centre`` (3, flange frame, mm), ``flanges`` (n, 4, 4, base),
        ``points`` (n, 3, sensor frame, mm); ``angles``, ``axes``, ``nominal`` None.
    """
    S = _fixed_sensor(rng)
    c_f = unit([rng.uniform(-0.4, 0.4), rng.uniform(-0.4, 0.4), 1.0]) * rng.uniform(100.0, 250.0)
    towards_sensor = -S[:3, 2]
    flanges, points = [], []
    while len(flanges) < n:
        p = seen_at(rng)
        c_base = S[:3, :3] @ p + S[:3, 3]
        u = _tilted(rng, towards_sensor, 10.0 if not flanges else 50.0)  # stick direction in the base
        R = rodrigues(u, rng.uniform(-180.0, 180.0)) @ _align(unit(c_f), u)
        F = transform(R, c_base - R @ c_f)
        if _reachable(F):
            flanges.append(F)
            points.append(p)
    return dict(sensor=S, centre=c_f, flanges=np.array(flanges), points=np.array(points), angles=None,
                axes=None, nominal=None)


def _positioner_axes(rng):
    """Nominal (CAD, rounded) and true axes of a KP1-V-like positioner 1.05-1.2 m from the base.

    Returns
    -------
    nominal, truth : list of dict
        ``{"name", "point" (3, mm, base, zero angles), "direction" (3)}``; the nominal directions are
        rounded to 3 decimals (not exactly unit), the true ones unit, 0.2-0.5 deg off, the true points
        1-3 mm off across the true axis.
    """
    az, rho = math.radians(rng.uniform(-40.0, 40.0)), rng.uniform(1050.0, 1200.0)
    q1 = np.array([rho * math.cos(az), rho * math.sin(az), rng.uniform(-100.0, 250.0)])
    d1 = rot_z(rng.uniform(-30.0, 30.0)) @ np.array([-math.sin(az), math.cos(az), 0.0])
    q2 = q1 + np.array([0.0, 0.0, rng.uniform(-50.0, 100.0)])
    nominal = [dict(name="e1", point=np.round(q1), direction=np.round(d1, 3)),
               dict(name="e2", point=np.round(q2), direction=np.array([0.0, 0.0, 1.0]))]
    truth = []
    for ax in nominal:
        d = _tilted(rng, unit(ax["direction"]), 0.5, 0.2)
        q = ax["point"] + _perpendicular(rng, d) * rng.uniform(1.0, 3.0)
        truth.append(dict(name=ax["name"], point=q, direction=d))
    return nominal, truth


def _positioner_angles(rng, n):
    """Axis angles (n, 2, degrees): n // 2 (>= 6) configurations, each visited by about two robot poses;
    e1 in [-60, 60], e2 in [-180, 180], drawn jointly."""
    k = max(6, n // 2)
    while True:
        conf = np.column_stack([rng.uniform(-60.0, 60.0, k), rng.uniform(-180.0, 180.0, k)]).round(2)
        if min(len(np.unique(conf[:, 0])), len(np.unique(conf[:, 1]))) >= 3:
            return conf[np.arange(n) % k]


def _positioner(rng, n):
    """Sensor on the flange, sphere on a post on the table of a two-axis positioner.

    The sphere is 100-200 mm off the e2 axis and 80-200 mm above the table's centre; the sensor looks
    at it from the table's side (within 75 deg of the table's normal) and from above the horizon.

    Returns
    -------
    dict
        ``sensor`` (4x4 sensor2flange), ``centre`` (3, base at zero angles, mm), ``flanges`` (n, 4, 4),
        ``points`` (n, 3, sensor frame), ``angles`` (n, 2, degrees), ``axes`` (true), ``nominal``.
    """
    X = _sensor_on_flange(rng)
    nominal, axes = _positioner_axes(rng)
    phi, r = rng.uniform(-math.pi, math.pi), rng.uniform(100.0, 200.0)
    centre = axes[1]["point"] + np.array([r * math.cos(phi), r * math.sin(phi), rng.uniform(80.0, 200.0)])
    angles = _positioner_angles(rng, n)
    flanges, points = [], []
    for theta in angles:
        T = table2base(axes, theta)
        c_i, normal = T[:3, :3] @ centre + T[:3, 3], T[:3, :3] @ axes[1]["direction"]
        down = -unit(normal + np.array([0.0, 0.0, 1.0]))
        while True:
            F, p = _view_pose(rng, X, c_i, down, 40.0)
            z = (F @ X)[:3, 2]
            if -np.dot(z, normal) > math.cos(math.radians(75.0)) and z[2] < -0.2:
                break
        flanges.append(F)
        points.append(p)
    return dict(sensor=X, centre=centre, flanges=np.array(flanges), points=np.array(points), angles=angles,
                axes=axes, nominal=nominal)


_BUILDERS = {"eye_in_hand": _eye_in_hand, "eye_to_hand": _eye_to_hand, "positioner": _positioner}
_MOUNT_KEYS = {"eye_in_hand": ("flange", "world"), "eye_to_hand": ("world", "flange"),
               "positioner": ("flange", "positioner")}


# ----------------------------------------------------------------------------- writing
def _num(v, digits=9):
    return f"{float(v):.{digits}f}"


def _vec(values, digits=9):
    return "[" + ", ".join(_num(v, digits) for v in values) + "]"


def _axes_toml(axes, digits=9):
    """The TOML inline array of axes ``[ { name = .., point = [..], direction = [..] }, ... ]``."""
    items = [f'{{ name = "{a["name"]}", point = {_vec(a["point"], digits)}, direction = {_vec(a["direction"], digits)} }}'
             for a in axes]
    return "[\n    " + ",\n    ".join(items) + ",\n]"


def _rough_start(rng, T):
    """A start pose (KUKA, mm/deg) 2-5 mm and 1-3 deg off the 4x4 ``T``, rounded as typed from a drawing."""
    R = rodrigues(rng.normal(size=3), rng.uniform(1.0, 3.0)) @ T[:3, :3]
    t = T[:3, 3] + unit(rng.normal(size=3)) * rng.uniform(2.0, 5.0)
    return np.round(pose_values(transform(R, t)), 1)


def _setup_text(cell, mount, seed, noise, start, centre_known, explicit):
    """The text of ``setup.toml`` for a drawn cell (see the module docstring for the keys)."""
    sensor_mount, sphere_mount = _MOUNT_KEYS[mount]
    lines = [f"# independent test cell (tests/indep_mounts.py): {mount}, seed {seed}", "[sensor]"]
    if explicit or sensor_mount != "flange":
        lines.append(f'mount = "{sensor_mount}"')
    if start is not None:
        lines.append(f"start_pose = {_vec(start, 3)}")
    lines += ["", "[sphere]", f"diameter = {DIAMETER}"]
    if explicit or sphere_mount != "world":
        lines.append(f'mount = "{sphere_mount}"')
    if centre_known:
        lines.append(f"center = {_vec(cell['centre'])}")
    if cell["nominal"] is not None:
        lines += ["", "[positioner]", f"axes = {_axes_toml(cell['nominal'], 3)}"]
    lines += ["", "[noise]", f"centre_mm = {noise}", "", "[truth]",
              f"sensor_pose = {_vec(pose_values(cell['sensor']))}", f"sphere_center = {_vec(cell['centre'])}"]
    if cell["axes"] is not None:
        lines.append(f"axes = {_axes_toml(cell['axes'])}")
    return "\n".join(lines) + "\n"


def _csv_text(cell, measured):
    """The text of ``measurements.csv``: id, the flange's KUKA pose, the measured centre, axis angles."""
    names = [a["name"] for a in cell["axes"]] if cell["axes"] is not None else []
    rows = [",".join(["id", "x", "y", "z", "a", "b", "c", "xs", "ys", "zs", *names])]
    for i, F in enumerate(cell["flanges"]):
        extra = [_num(t, 2) for t in cell["angles"][i]] if names else []
        rows.append(",".join([f"m{i + 1:03d}", *(_num(v) for v in pose_values(F)), *(_num(v) for v in measured[i]),
                              *extra]))
    return "\n".join(rows) + "\n"


# ----------------------------------------------------------------------------- the public functions
def make(folder, mount, seed, n=30, centre_known=True, start=None, noise=0.05, effect=None, explicit=None):
    """Draw one cell of ``mount``, write it as a dataset folder, return the truth.

    Parameters
    ----------
    folder : path
        Created if missing; ``setup.toml`` and ``measurements.csv`` are written into it.
    mount : {"eye_in_hand", "eye_to_hand", "positioner"}
    seed : int
        Seed of ``numpy.random.default_rng``; everything drawn follows from it.
    n : int
        Number of robot poses (rows).
    centre_known : bool
        Write ``[sphere] center`` (else it is omitted, to be estimated).
    start : bool or None
        Write a rough ``[sensor] start_pose`` (2-5 mm, 1-3 deg off the truth); None: in half of the seeds
        (those with ``seed // 2`` even, so independent of the seed's parity).
    noise : float
        Per-component sd (mm) of the measured centre, in the sensor frame; written as ``[noise] centre_mm``.
    effect : {None, "sensor_scale"}
        Hidden effect: ``"sensor_scale"`` multiplies the sensor's coordinates by 1.005 before the noise.
    explicit : bool or None
        Write the default mount keys too (``mount = "flange"`` / ``"world"``); None: drawn (half of the
        seeds).  Non-default mounts are always written.

    Returns
    -------
    dict
        ``folder``, ``mount``, ``seed``, ``sensor`` (4x4, sensor in its mount's frame: flange or base),
        ``sensor_pose`` (KUKA, mm/deg), ``sphere_center`` (3, mm, in the sphere's mount frame),
        ``axes`` / ``nominal_axes`` (positioner: list of {name, point, direction}; else None),
        ``flanges`` (n, 4, 4, base), ``angles`` (n, 2, deg, or None), ``points`` (n, 3, exact, sensor
        frame), ``measured`` (n, 3, written), ``noise``, ``effect``, ``start`` (KUKA 6 or None),
        ``centre_known``, ``explicit``, ``sensor_mount``, ``sphere_mount``.
    """
    if mount not in MOUNTS:
        raise ValueError(f"mount {mount!r}: one of {MOUNTS}")
    if effect not in EFFECTS:
        raise ValueError(f"effect {effect!r}: one of {EFFECTS}")
    rng = np.random.default_rng(seed)
    cell = _BUILDERS[mount](rng, n)
    start = (seed // 2) % 2 == 0 if start is None else bool(start)
    explicit = (seed // 4) % 2 == 0 if explicit is None else bool(explicit)
    start_pose = _rough_start(rng, cell["sensor"]) if start else None
    scale = SENSOR_SCALE if effect == "sensor_scale" else 1.0
    measured = scale * cell["points"] + rng.normal(scale=noise, size=cell["points"].shape)
    folder = pathlib.Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "setup.toml").write_text(_setup_text(cell, mount, seed, noise, start_pose, centre_known, explicit))
    (folder / "measurements.csv").write_text(_csv_text(cell, measured))
    sensor_mount, sphere_mount = _MOUNT_KEYS[mount]
    return dict(folder=folder, mount=mount, seed=seed, sensor=cell["sensor"], sensor_pose=pose_values(cell["sensor"]),
                sphere_center=cell["centre"], axes=cell["axes"], nominal_axes=cell["nominal"], flanges=cell["flanges"],
                angles=cell["angles"], points=cell["points"], measured=measured, noise=noise, effect=effect,
                start=start_pose, centre_known=centre_known, explicit=explicit, sensor_mount=sensor_mount,
                sphere_mount=sphere_mount)


def read(folder):
    """Read a dataset folder back with this module's own parser.

    Returns
    -------
    dict
        ``setup`` (the parsed TOML), ``ids``, ``flanges`` (n, 4, 4, base, from the KUKA columns),
        ``measured`` (n, 3, sensor frame, mm), ``angles`` (n, k, degrees; k = 0 without a positioner),
        ``axis_names``.
    """
    folder = pathlib.Path(folder)
    setup = tomllib.loads((folder / "setup.toml").read_text())
    with open(folder / "measurements.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    names = [a["name"] for a in setup.get("positioner", {}).get("axes", [])]
    flanges = np.array([pose_matrix([float(r[k]) for k in "xyzabc"]) for r in rows])
    measured = np.array([[float(r[k]) for k in ("xs", "ys", "zs")] for r in rows])
    angles = np.array([[float(r[k]) for k in names] for r in rows]).reshape(len(rows), len(names))
    return dict(setup=setup, ids=[r["id"] for r in rows], flanges=flanges, measured=measured, angles=angles,
                axis_names=names)


def chain_residuals(folder):
    """Per row, how far the chain misses at the truth of ``[truth]`` (n, 3, mm, base frame).

    ``eye_in_hand``: ``F X xs - c``; ``eye_to_hand``: ``S xs - F c``; ``positioner``:
    ``F X xs - table2base(theta) c``, with the true axes.  At the truth, and without a hidden effect, each
    component is N(0, centre_mm^2): the rotations keep the sensor's isotropic noise isotropic.
    """
    data = read(folder)
    setup = data["setup"]
    truth = setup["truth"]
    T = pose_matrix(truth["sensor_pose"])
    c = np.append(truth["sphere_center"], 1.0)
    sensor_mount = setup["sensor"].get("mount", "flange")
    out = []
    for i, (F, xs) in enumerate(zip(data["flanges"], data["measured"])):
        x = np.append(xs, 1.0)
        if sensor_mount == "world":
            out.append((T @ x - F @ c)[:3])
        else:
            target = table2base(truth["axes"], data["angles"][i]) @ c if "axes" in truth else c
            out.append((F @ T @ x - target)[:3])
    return np.array(out)


def exact_points(folder):
    """Per row, where the sphere centre truly is in the sensor frame (n, 3, mm), from the files' truth."""
    data = read(folder)
    setup = data["setup"]
    truth = setup["truth"]
    T = pose_matrix(truth["sensor_pose"])
    c = np.append(truth["sphere_center"], 1.0)
    out = []
    for i, F in enumerate(data["flanges"]):
        if setup["sensor"].get("mount", "flange") == "world":
            out.append((inverse(T) @ F @ c)[:3])
        else:
            target = table2base(truth["axes"], data["angles"][i]) @ c if "axes" in truth else c
            out.append((inverse(F @ T) @ target)[:3])
    return np.array(out)
