"""An independent generator of hand-eye datasets (numpy and the standard library only).

Written from the README's "Dataset format" and "Calibrate your own robot" sections and from the
definitions of the four robot conventions, without any code of ``handeye``, so that a test can
check handeye against data whose mistakes (if any) are not handeye's own.

Frames and units (everything in mm, angles as named):

* ``F_i`` (4x4) the flange in the robot base for pose i; ``X`` (4x4) the sensor in the flange
  (the unknown of the calibration, ``sensor2flange``); ``c`` the sphere centre in the base.
* Sensor frame: the laser plane is y = 0, x runs along the laser line, z is the measuring
  direction (stand-off about 150-300 mm), y = z cross x.  The sphere centre in the sensor frame
  is ``p_i = X^-1 F_i^-1 c = (xs, ys, zs)``; the plane y = 0 cuts the sphere in a circle of
  radius ``sqrt(R^2 - ys^2)`` about ``(xs, zs)``; a profile is the arc of that circle that
  faces the sensor's origin, as (x, z) points; ``sign(ys)`` is ``[profile] side``.
* Conventions of the flange poses (columns after ``x,y,z``):
  kuka ``a,b,c`` deg, R = Rz(A) Ry(B) Rx(C); fanuc ``w,p,r`` deg, R = Rz(R) Ry(P) Rx(W);
  abb ``q1,q2,q3,q4`` = unit quaternion w, x, y, z; ur ``rx,ry,rz`` rotation vector, rad.

Public functions: :func:`make_cell` (the truth and the noisy observations of one cell),
:func:`write_dataset` (a folder ``handeye calibrate`` reads), :func:`correct_dataset` (both in
one), the ``slip_*`` functions (a dataset with one user slip, returning a :class:`Slip`:
folder, description, the cell), :data:`SLIPS` (name -> function) and :func:`read_truth` (the true
``sensor2flange`` back from a folder's ``[truth]``).  Everything is seeded
(``numpy.random.default_rng(seed)``).
"""
from __future__ import annotations

import dataclasses
import math
import pathlib
import tomllib
import typing

import numpy as np

CONVENTIONS = ("kuka", "fanuc", "abb", "ur")
ANGLE_COLUMNS = {"kuka": ("a", "b", "c"), "fanuc": ("w", "p", "r"), "abb": ("q1", "q2", "q3", "q4"), "ur": ("rx", "ry", "rz")}


# ----------------------------------------------------------------------------- rotations
def rot_x(deg):
    """Rotation about x by ``deg`` degrees (3x3)."""
    t = math.radians(deg)
    c, s = math.cos(t), math.sin(t)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(deg):
    """Rotation about y by ``deg`` degrees (3x3)."""
    t = math.radians(deg)
    c, s = math.cos(t), math.sin(t)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(deg):
    """Rotation about z by ``deg`` degrees (3x3)."""
    t = math.radians(deg)
    c, s = math.cos(t), math.sin(t)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def kuka_matrix(a, b, c):
    """KUKA A, B, C (deg) -> R = Rz(A) Ry(B) Rx(C)."""
    return rot_z(a) @ rot_y(b) @ rot_x(c)


def kuka_angles(R):
    """R -> KUKA (A, B, C) in degrees, A, C in (-180, 180], B in [-90, 90] (C = 0 at B = +-90)."""
    cb = math.hypot(R[0, 0], R[1, 0])
    b = math.atan2(-R[2, 0], cb)
    if cb > 1e-12:
        a = math.atan2(R[1, 0], R[0, 0])
        c = math.atan2(R[2, 1], R[2, 2])
    else:  # gimbal lock: only A -/+ C is defined; take C = 0, then R = Rz(A) Ry(+-90)
        a = math.atan2(-R[0, 1], R[1, 1])
        c = 0.0
    return np.degrees([a, b, c])


def fanuc_matrix(w, p, r):
    """FANUC W, P, R (deg) -> R = Rz(R) Ry(P) Rx(W) (fixed axes X, then Y, then Z)."""
    return rot_z(r) @ rot_y(p) @ rot_x(w)


def fanuc_angles(R):
    """R -> FANUC (W, P, R) in degrees."""
    a, b, c = kuka_angles(R)
    return np.array([c, b, a])


def xyz_intrinsic_matrix(a, b, c):
    """Intrinsic X-Y'-Z'' angles (deg) -> R = Rx(a) Ry(b) Rz(c) (a convention no robot here uses)."""
    return rot_x(a) @ rot_y(b) @ rot_z(c)


def xyz_intrinsic_angles(R):
    """R -> intrinsic X-Y'-Z'' angles (deg) with R = Rx(a) Ry(b) Rz(c)."""
    cb = math.hypot(R[0, 0], R[0, 1])
    b = math.atan2(R[0, 2], cb)
    if cb > 1e-12:
        a = math.atan2(-R[1, 2], R[2, 2])
        c = math.atan2(-R[0, 1], R[0, 0])
    else:
        a = math.atan2(R[2, 1], R[1, 1])
        c = 0.0
    return np.degrees([a, b, c])


def quat_matrix(q):
    """Unit quaternion (w, x, y, z) -> R (normalised first)."""
    w, x, y, z = np.asarray(q, float) / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def quat_from_matrix(R):
    """R -> unit quaternion (w, x, y, z) with w >= 0 (Shepperd's method: the largest diagonal)."""
    t = np.trace(R)
    cand = [t, R[0, 0], R[1, 1], R[2, 2]]
    k = int(np.argmax(cand))
    if k == 0:
        s = 2.0 * math.sqrt(1.0 + t)
        q = [s / 4, (R[2, 1] - R[1, 2]) / s, (R[0, 2] - R[2, 0]) / s, (R[1, 0] - R[0, 1]) / s]
    elif k == 1:
        s = 2.0 * math.sqrt(1.0 + R[0, 0] - R[1, 1] - R[2, 2])
        q = [(R[2, 1] - R[1, 2]) / s, s / 4, (R[0, 1] + R[1, 0]) / s, (R[0, 2] + R[2, 0]) / s]
    elif k == 2:
        s = 2.0 * math.sqrt(1.0 + R[1, 1] - R[0, 0] - R[2, 2])
        q = [(R[0, 2] - R[2, 0]) / s, (R[0, 1] + R[1, 0]) / s, s / 4, (R[1, 2] + R[2, 1]) / s]
    else:
        s = 2.0 * math.sqrt(1.0 + R[2, 2] - R[0, 0] - R[1, 1])
        q = [(R[1, 0] - R[0, 1]) / s, (R[0, 2] + R[2, 0]) / s, (R[1, 2] + R[2, 1]) / s, s / 4]
    q = np.array(q)
    q /= np.linalg.norm(q)
    return -q if q[0] < 0 else q


def rotvec_matrix(v):
    """Rotation vector (rad; direction = axis, norm = angle) -> R (Rodrigues)."""
    v = np.asarray(v, float)
    th = float(np.linalg.norm(v))
    if th < 1e-15:
        return np.eye(3)
    k = v / th
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(th) * K + (1 - math.cos(th)) * K @ K


def rotvec_from_matrix(R):
    """R -> rotation vector (rad), angle in [0, pi]; via the quaternion (robust near 0 and pi)."""
    q = quat_from_matrix(R)
    s = float(np.linalg.norm(q[1:]))
    if s < 1e-15:
        return np.zeros(3)
    return 2.0 * math.atan2(s, q[0]) * q[1:] / s


def random_rotation(rng):
    """A rotation drawn uniformly on SO(3) (a random unit quaternion)."""
    q = rng.normal(size=4)
    return quat_matrix(q / np.linalg.norm(q))


def axis_angle(axis, deg):
    """Rotation about the unit vector ``axis`` by ``deg`` degrees."""
    a = np.asarray(axis, float)
    return rotvec_matrix(a / np.linalg.norm(a) * math.radians(deg))


def transform(R, t):
    """4x4 homogeneous transform from R (3x3) and t (3, mm)."""
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = t
    return T


def inverse(T):
    """Inverse of a rigid 4x4 transform."""
    R, t = T[:3, :3], T[:3, 3]
    return transform(R.T, -R.T @ t)


def angles_from_matrix(R, convention):
    """R -> the convention's orientation values (kuka/fanuc deg, abb w,x,y,z, ur rad)."""
    if convention == "kuka":
        return kuka_angles(R)
    if convention == "fanuc":
        return fanuc_angles(R)
    if convention == "abb":
        return quat_from_matrix(R)
    if convention == "ur":
        return rotvec_from_matrix(R)
    raise ValueError(convention)


def matrix_from_angles(values, convention):
    """The convention's orientation values -> R (inverse of :func:`angles_from_matrix`)."""
    v = np.asarray(values, float)
    if convention == "kuka":
        return kuka_matrix(*v)
    if convention == "fanuc":
        return fanuc_matrix(*v)
    if convention == "abb":
        return quat_matrix(v)
    if convention == "ur":
        return rotvec_matrix(v)
    raise ValueError(convention)


def pose_values(T, convention):
    """4x4 -> ``[x, y, z, <orientation>]`` in ``convention`` (mm; angles as the convention has them)."""
    return np.concatenate([T[:3, 3], angles_from_matrix(T[:3, :3], convention)])


def pose_matrix(values, convention):
    """``[x, y, z, <orientation>]`` in ``convention`` -> 4x4."""
    v = np.asarray(values, float)
    return transform(matrix_from_angles(v[3:], convention), v[:3])


def pose_error(T, T_true):
    """(translation error mm, rotation error deg) between two 4x4 sensor poses."""
    dt = float(np.linalg.norm(T[:3, 3] - T_true[:3, 3]))
    dR = T[:3, :3] @ T_true[:3, :3].T
    ang = math.degrees(math.acos(max(-1.0, min(1.0, (np.trace(dR) - 1.0) / 2.0))))
    return dt, ang


# ----------------------------------------------------------------------------- cells
@dataclasses.dataclass
class Cell:
    """One simulated robot cell and its observations (all mm, base frame unless said).

    convention: the robot convention of the files; X: sensor in flange (4x4, the truth);
    centre: sphere centre in the base (3,); diameter: sphere diameter; side: sign of ys;
    flanges: (n, 4, 4) flange in base; true_points: (n, 3) exact sphere centres in the sensor
    frame; measured: (n, 3) the same with noise; sigma: centre noise sd per component;
    profiles: per row an (k, 2) array of (x, z) points or None; modes: per row 'centre'
    (xs,ys,zs only), 'profile' (profile, xs,ys,zs empty) or 'both'; start: the CAD start
    pose (4x4) or None; state_noise: write ``[noise] centre_mm``; notes: what was drawn.
    """

    convention: str
    X: np.ndarray
    centre: np.ndarray
    diameter: float
    side: int
    flanges: np.ndarray
    true_points: np.ndarray
    measured: np.ndarray
    sigma: float
    profiles: list
    modes: list
    ids: list
    start: np.ndarray | None
    state_noise: bool
    notes: dict


def _mount(rng, kind):
    """Sensor in flange: 'random' (uniform orientation) or 'gimbal' (KUKA B within 1 deg of +-90,
    sometimes exactly); offset norm 50-300 mm in a random direction."""
    if kind == "gimbal":
        b = float(rng.choice([-1, 1])) * (90.0 - (0.0 if rng.random() < 0.3 else rng.uniform(0, 1.0)))
        R = kuka_matrix(rng.uniform(-180, 180), b, rng.uniform(-180, 180))
    else:
        R = random_rotation(rng)
    d = rng.normal(size=3)
    t = d / np.linalg.norm(d) * rng.uniform(50, 300)
    return transform(R, t)


def _profile(rng, centre_xz, r, point_sd, spacing, half_arc_deg):
    """The arc of the circle (centre (x, z), radius r, mm) facing the sensor origin: points at
    angles within +-half_arc_deg of the direction from the centre to the origin, ``spacing`` mm
    apart, each coordinate with N(0, point_sd^2) noise; (k, 2) array of (x, z)."""
    cx, cz = centre_xz
    phi0 = math.atan2(-cz, -cx)  # direction from the circle centre towards the sensor origin
    half = math.radians(half_arc_deg)
    k = max(12, int(2 * half * r / spacing))
    phi = phi0 + np.linspace(-half, half, k)
    pts = np.column_stack([cx + r * np.cos(phi), cz + r * np.sin(phi)])
    return pts + rng.normal(scale=point_sd, size=pts.shape)


def make_cell(seed, *, convention=None, n_poses=None, diameter=None, mount=None, start=None, profiles=None,
              sigma=None, side=None, spread=1.0, turn=(20.0, 60.0)):
    """Draw one cell (seeded).  Unset arguments are drawn:

    convention: 'kuka' | 'fanuc' | 'abb' | 'ur'; n_poses: 12-36; diameter: sphere diameter, mm
    (12.7-100); mount: 'random' | 'gimbal' (sensor near KUKA B = +-90 on the flange);
    start: bool, write a CAD ``start_pose`` (truth perturbed by <= 5 mm, <= 2 deg); profiles:
    'none' | 'profile' (every row a profile, xs,ys,zs empty) | 'both' (profile and centre) |
    'mixed' (rows of all three kinds); sigma: sd of the centre noise per component, mm
    (0.01-0.1); side: +1 | -1; spread: scale (0-1] of how far the sphere moves in the sensor's
    x and z between poses (1: +-30 mm in x, over the whole stand-off in z); turn: (min, max)
    degrees of the poses' rotations about the sensor's x, y (and z) axes away from the nominal.
    """
    rng = np.random.default_rng(seed)
    convention = convention or str(rng.choice(CONVENTIONS))
    n = int(n_poses or rng.integers(12, 37))
    diameter = float(diameter or round(float(rng.uniform(12.7, 100.0)), 3))
    R_s = diameter / 2
    mount = mount or ("gimbal" if rng.random() < 0.3 else "random")
    start = bool(rng.random() < 0.5) if start is None else start
    profiles = profiles or str(rng.choice(["none", "none", "profile", "both", "mixed"]))
    sigma = float(sigma or rng.uniform(0.01, 0.1))
    side = int(side or rng.choice([-1, 1]))
    X = _mount(rng, mount)

    # sphere somewhere in a robot's reach: 500-1500 mm from the base axis, -300..900 mm high
    rho, az = rng.uniform(500, 1500), rng.uniform(-math.pi, math.pi)
    centre = np.array([rho * math.cos(az), rho * math.sin(az), rng.uniform(-300, 900)])

    # nominal sensor orientation: z (measuring direction) within 30 deg of straight down
    tilt_axis = rng.normal(size=3)
    tilt_axis[2] = 0
    down = axis_angle(tilt_axis, rng.uniform(0, 30)) @ np.array([0.0, 0.0, -1.0])
    x0 = np.cross(down, rng.normal(size=3))
    x0 /= np.linalg.norm(x0)
    R0 = np.column_stack([x0, np.cross(down, x0), down])

    use_profiles = profiles != "none"
    frac = (0.3, 0.75) if use_profiles else (0.08, 0.9)  # |ys| / R: a profile needs a cut neither tiny nor central
    x_half = spread * max(4.0, min(30.0, 45.0 - 0.8 * R_s))
    z_lo, z_hi = 160.0 + R_s, 290.0 + 0.2 * R_s
    z_mid, z_half = (z_lo + z_hi) / 2, spread * (z_hi - z_lo) / 2

    flanges, points, angles = [], [], []
    for i in range(n):
        kind = i % 4 if i else -1
        small = rng.uniform(-5, 5, size=3)
        big = rng.choice([-1, 1], size=3) * rng.uniform(*turn, size=3)
        if kind == 0:
            a, b, g = big[0], small[1], small[2]
        elif kind == 1:
            a, b, g = small[0], big[1], small[2]
        elif kind == 2:
            a, b, g = big[0] * 0.6, big[1] * 0.6, rng.uniform(-30, 30)
        elif kind == 3:
            a, b, g = small[0], small[1], float(rng.choice([-1, 1])) * rng.uniform(turn[0], 1.5 * turn[1])
        else:
            a, b, g = small
        R_sensor = R0 @ rot_x(a) @ rot_y(b) @ rot_z(g)  # sensor orientation in the base
        p = np.array([rng.uniform(-x_half, x_half),
                      side * rng.uniform(*frac) * R_s,
                      z_mid + rng.uniform(-z_half, z_half)])
        S = transform(R_sensor, centre - R_sensor @ p)  # sensor in base: sees the centre at p
        flanges.append(S @ inverse(X))
        points.append(p)
        angles.append((a, b, g))
    flanges, points = np.array(flanges), np.array(points)
    measured = points + rng.normal(scale=sigma, size=points.shape)
    measured[:, 1] = np.where(np.sign(measured[:, 1]) == side, measured[:, 1], points[:, 1])

    point_sd = float(rng.uniform(0.01, 0.03))
    spacing = float(rng.uniform(0.08, 0.2))
    modes, profs = [], []
    for i in range(n):
        mode = {"none": "centre", "profile": "profile", "both": "both"}.get(profiles) or str(
            rng.choice(["centre", "profile", "both"]))
        modes.append(mode)
        if mode == "centre":
            profs.append(None)
            continue
        xs, ys, zs = measured[i]
        r = math.sqrt(R_s**2 - ys**2)
        profs.append(_profile(rng, (xs, zs), r, point_sd, spacing, rng.uniform(70, 88)))

    start_T = None
    if start:
        d = rng.normal(size=3)
        dt = d / np.linalg.norm(d) * rng.uniform(0, 5)
        start_T = transform(axis_angle(rng.normal(size=3), rng.uniform(0, 2)) @ X[:3, :3], X[:3, 3] + dt)
    width = 2 + len(str(n))
    ids = [f"p{i + 1:0{width}d}" for i in range(n)]
    notes = dict(seed=seed, mount=mount, profiles=profiles, n=n, sigma=sigma, diameter=diameter, side=side,
                 start=start, point_sd=point_sd, kuka_mount=kuka_angles(X[:3, :3]).round(3).tolist(),
                 angles=np.array(angles).round(1).tolist())
    return Cell(convention, X, centre, diameter, side, flanges, points, measured, sigma, profs, modes, ids, start_T,
                bool(rng.random() < 0.5), notes)


# ----------------------------------------------------------------------------- writing
def _num(v, digits=9):
    return f"{float(v):.{digits}f}"


def _toml_list(values, digits=9):
    return "[" + ", ".join(_num(v, digits) for v in values) + "]"


def _digits(convention):
    return {"kuka": 9, "fanuc": 9, "abb": 12, "ur": 12}[convention]


def write_dataset(cell, folder, *, declared=None, pose_writer=None, position_scale=1.0, profile_of=None):
    """Write ``cell`` as a dataset folder (``measurements.csv``, ``setup.toml``, ``profiles/``).

    declared: the convention written into ``setup.toml`` and the header (default the cell's);
    pose_writer: f(F 4x4, row index) -> orientation values to write (default the declared
    convention's own, i.e. correct data; a slip puts something else there); position_scale:
    factor on the flange positions (1e-3: metres); profile_of: f(row index) -> the row whose
    profile file this row names (default its own).  ``[truth] sensor_pose`` is always the true
    pose in the declared convention.  Returns the folder (``pathlib.Path``).
    """
    folder = pathlib.Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    conv = declared or cell.convention
    digits = _digits(conv)
    has_profiles = any(p is not None for p in cell.profiles)
    names = []
    if has_profiles:
        (folder / "profiles").mkdir(exist_ok=True)
        for i, pts in enumerate(cell.profiles):
            if pts is None:
                names.append("")
                continue
            name = f"profiles/{cell.ids[i]}.csv"
            lines = ["x,z"] + [f"{x:.6f},{z:.6f}" for x, z in pts]
            (folder / name).write_text("\n".join(lines) + "\n")
            names.append(name)
    header = ["id", "x", "y", "z", *ANGLE_COLUMNS[conv], "xs", "ys", "zs"] + (["profile"] if has_profiles else [])
    rows = [",".join(header)]
    rng = np.random.default_rng(cell.notes["seed"] + 7919)
    for i, F in enumerate(cell.flanges):
        if pose_writer is None:
            ang = angles_from_matrix(F[:3, :3], conv)
            if conv == "abb" and rng.random() < 0.2:
                ang = -ang  # q and -q are the same rotation; controllers give either
        else:
            ang = pose_writer(F, i)
        pos = F[:3, 3] * position_scale
        centre = ["", "", ""] if cell.modes[i] == "profile" else [_num(v) for v in cell.measured[i]]
        row = [cell.ids[i], *(_num(v, 12 if position_scale < 1 else 9) for v in pos), *(_num(v, digits) for v in ang),
               *centre]
        if has_profiles:
            row.append(names[profile_of(i) if profile_of else i])
        rows.append(",".join(row))
    (folder / "measurements.csv").write_text("\n".join(rows) + "\n")

    setup = [f"# independent test cell (tests/indep_cells.py), seed {cell.notes['seed']}",
             "[robot]", f'convention = "{conv}"', ""]
    if cell.start is not None:
        setup += ["[sensor]", f"start_pose = {_toml_list(pose_values(cell.start, conv), digits)}", ""]
    setup += ["[sphere]", f"diameter = {cell.diameter!r}", f"center = {_toml_list(cell.centre, 6)}", "",
              "[profile]", f"side = {cell.side}", ""]
    if cell.state_noise:
        noise = f"{max(cell.sigma, 0.02):.4f}"
        setup += ["[noise]", f"centre_mm = {noise}", f"robot_mm = {noise}", ""]
    setup += ["[truth]", f"sensor_pose = {_toml_list(pose_values(cell.X, conv), 12)}",
              f"sphere_center = {_toml_list(cell.centre, 6)}", ""]
    (folder / "setup.toml").write_text("\n".join(setup))
    return folder


def correct_dataset(folder, seed, **options):
    """A correct dataset in ``folder`` from :func:`make_cell` (``options`` as there); returns
    ``(folder, cell)``."""
    cell = make_cell(seed, **options)
    return write_dataset(cell, folder), cell


def read_truth(folder):
    """The true sensor in flange (4x4, mm) from ``setup.toml``'s ``[truth] sensor_pose`` (in its convention)."""
    doc = tomllib.loads((pathlib.Path(folder) / "setup.toml").read_text())
    conv = doc.get("robot", {}).get("convention", "kuka")
    return pose_matrix(doc["truth"]["sensor_pose"], conv)


def predicted_sd(cell):
    """1-sd of the sensor pose a least-squares fit of the centres would have (centre model,
    the cell's noise ``sigma`` per component, linearised at the truth): ``(translation mm,
    rotation deg)``, each the root of the trace of its 3x3 covariance block.  Rows whose
    centre comes from a profile alone count with twice the noise (the cut's radius carries
    the point noise into ys, amplified by r / |ys| <= 3.2)."""
    R_X = cell.X[:3, :3]
    blocks, weights = [], []
    for F, p, mode in zip(cell.flanges, cell.true_points, cell.modes):
        R_F = F[:3, :3]
        px = np.array([[0.0, -p[2], p[1]], [p[2], 0.0, -p[0]], [-p[1], p[0], 0.0]])
        blocks.append(np.hstack([R_F, -R_F @ R_X @ px]))  # d(F X p)/d(t_X, rotation about sensor axes)
        weights.append(0.25 if mode == "profile" else 1.0)
    J = np.vstack([w**0.5 * b for w, b in zip(weights, blocks)])
    cov = cell.sigma**2 * np.linalg.inv(J.T @ J)
    return float(np.sqrt(np.trace(cov[:3, :3]))), math.degrees(float(np.sqrt(np.trace(cov[3:, 3:]))))


def tolerance(cell, floor=(1.0, 0.5), k=6.0):
    """What counts as "at the truth": ``(mm, deg)`` = the larger of ``floor`` and ``k`` times
    :func:`predicted_sd` (noise only; a fit further off than that is not the noise's doing)."""
    sd_t, sd_r = predicted_sd(cell)
    return max(floor[0], k * sd_t), max(floor[1], k * sd_r)


def read_rows(folder):
    """A dataset folder read back with this module's own code (for self-checks): ``(convention,
    setup dict, list of rows)``; each row a dict with ``id``, ``F`` (4x4 flange in base),
    ``centre`` ((3,) or None) and ``profile`` ((k, 2) or None)."""
    folder = pathlib.Path(folder)
    setup = tomllib.loads((folder / "setup.toml").read_text())
    conv = setup.get("robot", {}).get("convention", "kuka")
    lines = (folder / "measurements.csv").read_text().splitlines()
    header = lines[0].split(",")
    rows = []
    for line in lines[1:]:
        cell = dict(zip(header, line.split(",")))
        pose = [float(cell[k]) for k in ("x", "y", "z", *ANGLE_COLUMNS[conv])]
        centre = None if cell["xs"] == "" else np.array([float(cell[k]) for k in ("xs", "ys", "zs")])
        prof = None
        if cell.get("profile"):
            prof = np.loadtxt(folder / cell["profile"], delimiter=",", skiprows=1, ndmin=2)
        rows.append(dict(id=cell["id"], F=pose_matrix(pose, conv), centre=centre, profile=prof))
    return conv, setup, rows


def describe(cell):
    """One line: what the cell is."""
    n = cell.notes
    return (f"seed {n['seed']}: {cell.convention}, {n['n']} poses, sphere {n['diameter']} mm, mount {n['mount']} "
            f"(KUKA {n['kuka_mount']}), |t| {np.linalg.norm(cell.X[:3, 3]):.0f} mm, profiles {n['profiles']}, "
            f"sigma {n['sigma']:.3f} mm, side {n['side']:+d}, start {'CAD' if n['start'] else 'none'}")


# ----------------------------------------------------------------------------- slips

class Slip(typing.NamedTuple):
    """What a ``slip_*`` function returns: the dataset folder, a one-line description of the
    slip, the cell it was written from (its truth, noise, poses) and, for a slip in one row,
    that row's id."""

    folder: pathlib.Path
    description: str
    cell: Cell
    row: str | None = None


def slip_fanuc_as_kuka(folder, seed, **options):
    """KUKA declared (columns a,b,c) but the values are FANUC W,P,R of the true rotation."""
    cell = make_cell(seed, **{**options, "convention": "kuka"})
    write_dataset(cell, folder, pose_writer=lambda F, i: fanuc_angles(F[:3, :3]))
    return Slip(pathlib.Path(folder), "FANUC W,P,R written under KUKA a,b,c", cell)


def slip_kuka_as_fanuc(folder, seed, **options):
    """FANUC declared (columns w,p,r) but the values are KUKA A,B,C in that order.  Read as
    written, R = Rz(C) Ry(B) Rx(A): the same misreading as :func:`slip_fanuc_as_kuka` from the
    other side (with the same seed, the same rotations; the header and [truth] differ)."""
    cell = make_cell(seed, **{**options, "convention": "fanuc"})
    write_dataset(cell, folder, pose_writer=lambda F, i: kuka_angles(F[:3, :3]))
    return Slip(pathlib.Path(folder), "KUKA A,B,C written under FANUC w,p,r", cell)


def slip_kuka_order(folder, seed, order=(1, 2, 0), **options):
    """KUKA declared; the a,b,c columns hold the true (A, B, C) in the order ``order`` (indices
    into (A, B, C); (2, 1, 0) is the FANUC/ABB-display order C, B, A)."""
    cell = make_cell(seed, **{**options, "convention": "kuka"})
    write_dataset(cell, folder, pose_writer=lambda F, i: kuka_angles(F[:3, :3])[list(order)])
    return Slip(pathlib.Path(folder), f"KUKA angles written in the order {''.join('ABC'[k] for k in order)}", cell)


def slip_abb_xyzw(folder, seed, **options):
    """ABB declared; the quaternion is written x, y, z, w instead of w, x, y, z."""
    cell = make_cell(seed, **{**options, "convention": "abb"})
    write_dataset(cell, folder, pose_writer=lambda F, i: np.roll(quat_from_matrix(F[:3, :3]), -1))
    return Slip(pathlib.Path(folder), "ABB quaternion written x,y,z,w", cell)


def slip_inverted(folder, seed, **options):
    """Flange poses inverted: every row holds the base in the flange (F^-1), in the declared
    convention (positions are those of F^-1 too)."""
    cell = make_cell(seed, **options)
    cell.flanges = np.array([inverse(F) for F in cell.flanges])
    write_dataset(cell, folder)
    return Slip(pathlib.Path(folder), f"flange poses inverted (base in flange), {cell.convention}", cell)


def slip_xyz_as_kuka(folder, seed, **options):
    """KUKA declared; the angles are intrinsic X-Y'-Z'' (R = Rx(a) Ry(b) Rz(c)), degrees."""
    cell = make_cell(seed, **{**options, "convention": "kuka"})
    write_dataset(cell, folder, pose_writer=lambda F, i: xyz_intrinsic_angles(F[:3, :3]))
    return Slip(pathlib.Path(folder), "intrinsic XYZ Euler angles written as KUKA a,b,c", cell)


def slip_radians(folder, seed, convention="kuka", **options):
    """KUKA or FANUC declared; the angles are in radians instead of degrees."""
    cell = make_cell(seed, **{**options, "convention": convention})
    write_dataset(cell, folder, pose_writer=lambda F, i: np.radians(angles_from_matrix(F[:3, :3], convention)))
    return Slip(pathlib.Path(folder), f"{convention} angles in radians", cell)


def slip_metres(folder, seed, **options):
    """Flange positions in metres instead of mm (setup.toml and the sensor's centres stay mm)."""
    cell = make_cell(seed, **options)
    write_dataset(cell, folder, position_scale=1e-3)
    return Slip(pathlib.Path(folder), f"flange positions in metres, {cell.convention}", cell)


def slip_profile_swap(folder, seed, similar=True, **options):
    """Every row has xs,ys,zs and a profile; one row names its neighbour's profile file while
    its xs,ys,zs are its own (a copy-paste slip).  similar: the rows are ordered so that the
    neighbour is the row whose sphere centre (sensor frame) is nearest -- the subtle case."""
    cell = make_cell(seed, **{**options, "profiles": "both"})
    d = np.linalg.norm(cell.true_points[:, None] - cell.true_points[None], axis=2)
    np.fill_diagonal(d, np.inf)
    rng = np.random.default_rng(seed + 1)
    if similar:
        k, j = np.unravel_index(int(np.argmin(d)), d.shape)
    else:
        k = int(rng.integers(len(cell.ids)))
        j = int(np.argmax(np.where(np.isfinite(d[k]), d[k], -1)))
    # put j right after k (a neighbour in the file); ids keep their pose
    order = [i for i in range(len(cell.ids)) if i != j]
    order.insert(order.index(k) + 1, j)
    for name in ("flanges", "true_points", "measured"):
        setattr(cell, name, getattr(cell, name)[order])
    cell.profiles = [cell.profiles[i] for i in order]
    cell.modes = [cell.modes[i] for i in order]
    cell.ids = [cell.ids[i] for i in order]
    row = order.index(k)
    write_dataset(cell, folder, profile_of=lambda i: row + 1 if i == row else i)
    description = f"row {cell.ids[row]} names {cell.ids[row + 1]}'s profile ({d[k, j]:.1f} mm from its own centre)"
    return Slip(pathlib.Path(folder), description, cell, cell.ids[row])


#: name -> f(folder, seed, **make_cell options) -> Slip (folder, description, cell, row)
SLIPS = {
    "fanuc-as-kuka": slip_fanuc_as_kuka,
    "kuka-as-fanuc": slip_kuka_as_fanuc,
    "kuka-order-BCA": slip_kuka_order,
    "kuka-order-BAC": lambda folder, seed, **options: slip_kuka_order(folder, seed, (1, 0, 2), **options),
    "abb-xyzw": slip_abb_xyzw,
    "inverted": slip_inverted,
    "xyz-as-kuka": slip_xyz_as_kuka,
    "radians-kuka": slip_radians,
    "radians-fanuc": lambda folder, seed, **options: slip_radians(folder, seed, "fanuc", **options),
    "metres": slip_metres,
    "profile-swap": slip_profile_swap,
    "profile-swap-far": lambda folder, seed, **options: slip_profile_swap(folder, seed, similar=False, **options),
}
