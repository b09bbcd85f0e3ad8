"""An independent generator of robot datasets with joint angles and hidden joint zero offsets (numpy only).

Written as a robotics user's own script would be: its own forward kinematics from the robots' published
data, its own rotations and its own numeric inverse kinematics, without any code of ``handeye``, so that a
test can check handeye's robot kinematics and its ``joint_offsets`` effect against data whose mistakes (if
any) are not handeye's own.

Kinematics (lengths in mm, joint angles in degrees):

``kr60ha``
    KUKA KR 60 HA, the joint chain of ROS-Industrial's ``kuka_experimental``
    (``kuka_kr60_support/urdf/kr60ha_macro.xacro``): joint j at origin ``o_j`` (in the parent link, no
    rotation) turning about ``axis_j``; ``tool0`` (KUKA's $FLANGE) ``rpy = (0, 90 deg, 0)`` after link 6.
    The URDF's joint angles are KUKA's A1..A6.
``ur5e``, ``ur10e``
    Universal Robots' published standard DH parameters (d1, a2, a3, d4, d5, d6; alpha = 90, 0, 0, 90,
    -90, 0 deg); ``T_j = Rz(theta_j) Tz(d_j) Tx(a_j) Rx(alpha_j)``, theta = the joint angle.  The base
    is the controller's base frame (the DH frame 0), the flange the DH frame 6.

The cell: a laser-line sensor on the flange (``X`` = sensor2flange, 100-200 mm off the flange, turned);
a sphere fixed in the robot base (centre ``c``).  The controller reports ``F_i = FK(q_i)`` (nominal) for
the joint angles ``q_i`` it reports, but the robot really stands at ``FK(q_i + delta)``: the hidden joint
zero offsets ``delta``.  The sensor measures ``p_i = (FK(q_i + delta) X)^-1 c`` + N(0, noise^2) per
component.  The sphere centre is seen 180-300 mm in front of the sensor (``z``), ``|x|, |y| < 40`` mm.

Poses: a working configuration per robot looks at the sphere; every pose is a sensor pose looking at the
sphere from another direction (tilt up to ``TILT`` deg, any azimuth, a turn about the view axis up to
``TURN`` deg), reached by damped Newton inverse kinematics started at the working configuration.

Two more hidden robot errors, optional (``make(..., lengths=..., compliance=...)``), both written from
their definitions here, not from handeye's code:

link lengths (mm)
    Every joint j has a fixed translation: for the KR 60 HA the joint origin ``o_j`` (in the parent link,
    before joint j's rotation), for a UR the ``Tz(d_j) Tx(a_j)`` of its DH link (``(a_j, 0, d_j)`` in the
    frame after ``Rz(theta_j)``). A length error adds to that translation, only in the components that are
    nonzero in the nominal model (|value| > 1e-6 mm). Names (:func:`length_names`): KR 60 HA ``j{j}_{x|y|z}``
    (``j3_x`` the error of the 850 mm), UR ``d{j}`` and ``a{j}`` (true a2 = a2 + error).
joint compliance (deg per metre)
    Gravity bends the shoulder and the elbow (joints 2, 3) by ``dq_j = c_j * lever_j(q)``, with
    ``lever_j(q) = ((p_F - o_j) x g) . a_j / 1000`` (m): ``g = (0, 0, -1)`` in the base (z up), ``p_F`` the
    flange origin, ``o_j`` a point on joint j's axis, ``a_j`` its unit direction (the KR 60 HA's URDF axis
    carried to the base; a UR's DH z axis of frame j-1), all at the nominal configuration q. The gravity
    torque turns the joint the way it pulls, whatever the joint's sign convention: ``c > 0`` sags.

All combined: the robot really stands at ``FK_lengths(q + delta + dq(q))`` (:func:`true_forward`), ``dq``
from the nominal q, while it reports q and the nominal ``FK(q)``.

Public: :func:`make` (draw a cell, write its folder, return the truth), :func:`forward` (FK, nominal or
with length errors), :func:`true_forward`, :func:`joint_axes`, :func:`lever`, :func:`deflection`,
:func:`length_names`, :func:`inverse_kinematics`, :func:`chain_residuals`, :func:`expected_sd` (own
linearised sd of hidden robot errors fitted with the sensor pose and the centre), :func:`fit_robot_errors`
(own least-squares fit of chosen robot errors to the measured points), :func:`read`, and the rotation
helpers.
"""
from __future__ import annotations

import csv
import math
import pathlib
import tomllib

import numpy as np

#: KR 60 HA joint chain (URDF, converted to mm): origin of joint j in link j-1, axis of joint j
KR60HA_ORIGINS = ((0.0, 0.0, 0.0), (350.0, 0.0, 815.0), (850.0, 0.0, 0.0), (465.0, 0.0, 145.0),
                  (355.0, 0.0, 0.0), (170.0, 0.0, 0.0))
KR60HA_AXES = ((0, 0, -1), (0, 1, 0), (0, 1, 0), (-1, 0, 0), (0, 1, 0), (-1, 0, 0))
#: UR standard DH (mm): d1, a2, a3, d4, d5, d6 (Universal Robots, "DH parameters for calculations of
#: kinematics and dynamics")
UR_DH = {"ur5e": (162.5, -425.0, -392.2, 133.3, 99.7, 99.6),
         "ur10e": (180.7, -612.7, -571.55, 174.15, 119.85, 116.55)}
UR_ALPHA = (90.0, 0.0, 0.0, 90.0, -90.0, 0.0)
#: joint limits (deg) the poses keep inside (a little inside the robots' own)
LIMITS = {"kr60ha": ((-185, 185), (-135, 35), (-120, 158), (-350, 350), (-119, 119), (-350, 350)),
          "ur5e": ((-360, 360),) * 6, "ur10e": ((-360, 360),) * 6}
#: working configuration (deg): the flange looks down at a table in front of the robot
WORKING = {"kr60ha": (0.0, -50.0, 100.0, 0.0, 40.0, 0.0),
           "ur5e": (0.0, -110.0, 100.0, -80.0, -90.0, 0.0),
           "ur10e": (0.0, -110.0, 100.0, -80.0, -90.0, 0.0)}
#: the unit gravity direction in the robot base (base z up)
GRAVITY = (0.0, 0.0, -1.0)
#: the joints that bend under gravity (compliance parameters ``j2``, ``j3``)
COMPLIANT = ("j2", "j3")
#: a nominal length or offset is a parameter when |value| > this (mm)
NONZERO = 1e-6
CONVENTION = {"kr60ha": "kuka", "ur5e": "ur", "ur10e": "ur"}
MODELS = tuple(WORKING)
DIAMETER = 50.0
TILT, TURN = 50.0, 90.0
#: the sphere centre in the sensor frame: |x|, |y| <= HALF, z in STANDOFF (mm)
HALF, STANDOFF = 30.0, (190.0, 290.0)


# ----------------------------------------------------------------------------- rotations
def rodrigues(axis, deg):
    """Rotation by ``deg`` degrees about ``axis`` (3, any length), Rodrigues' formula (3x3)."""
    x, y, z = (float(v) for v in axis)
    norm = math.sqrt(x * x + y * y + z * z)
    x, y, z = x / norm, y / norm, z / norm
    t = math.radians(deg)
    s, c = math.sin(t), math.cos(t)
    v = 1.0 - c  # I + s K + v K^2, written out (K the cross-product matrix of the unit axis)
    return np.array([[c + v * x * x, v * x * y - s * z, v * x * z + s * y],
                     [v * x * y + s * z, c + v * y * y, v * y * z - s * x],
                     [v * x * z - s * y, v * y * z + s * x, c + v * z * z]])


def rot_x(deg):
    """Rotation about x by ``deg`` degrees (3x3)."""
    return rodrigues((1, 0, 0), deg)


def rot_y(deg):
    """Rotation about y by ``deg`` degrees (3x3)."""
    return rodrigues((0, 1, 0), deg)


def rot_z(deg):
    """Rotation about z by ``deg`` degrees (3x3)."""
    return rodrigues((0, 0, 1), deg)


def transform(R, t):
    """4x4 homogeneous transform from R (3x3) and t (3, mm)."""
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, t
    return T


def inverse(T):
    """Inverse of a rigid 4x4 transform."""
    R, t = T[:3, :3], T[:3, 3]
    return transform(R.T, -R.T @ t)


def rotation_vector(R):
    """Rotation matrix -> rotation vector (radians, angle in [0, pi]); stable near 0 and near pi."""
    cos = np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0)
    angle = math.acos(cos)
    if angle < 1e-9:
        return np.zeros(3)
    if angle > math.pi - 1e-6:  # near pi: the axis from R + I (its largest column)
        B = (R + np.eye(3)) / 2.0
        k = int(np.argmax(np.diag(B)))
        axis = B[:, k] / math.sqrt(B[k, k])
        return axis * angle
    w = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    return w * angle / (2.0 * math.sin(angle))


def kuka_angles(R):
    """Rotation matrix -> KUKA (A, B, C) in degrees, ``R = Rz(A) Ry(B) Rx(C)``; A, C in [-180, 180]."""
    cb = math.hypot(R[0, 0], R[1, 0])
    b = math.atan2(-R[2, 0], cb)
    if cb > 1e-10:
        a, c = math.atan2(R[1, 0], R[0, 0]), math.atan2(R[2, 1], R[2, 2])
    else:
        a, c = math.atan2(-R[0, 1], R[1, 1]), 0.0
    return np.degrees([a, b, c])


def pose_row(T, convention):
    """A flange or sensor pose (4x4) as the controller writes it: KUKA x,y,z,A,B,C or UR x,y,z,rx,ry,rz."""
    if convention == "kuka":
        return np.concatenate([T[:3, 3], kuka_angles(T[:3, :3])])
    if convention == "ur":
        return np.concatenate([T[:3, 3], rotation_vector(T[:3, :3])])
    raise ValueError(f"unknown convention {convention!r}")


# ----------------------------------------------------------------------------- kinematics
def _kr60ha(q, origins=KR60HA_ORIGINS):
    """KR 60 HA flange in the base (4x4) from A1..A6 (deg): the URDF chain, then tool0 rpy (0, 90, 0)."""
    T = np.eye(4)
    for origin, axis, angle in zip(origins, KR60HA_AXES, q):
        T = T @ transform(np.eye(3), origin) @ transform(rodrigues(axis, angle), np.zeros(3))
    return T @ transform(rot_y(90.0), np.zeros(3))


def _dh(theta, d, a, alpha):
    """One standard DH link: ``Rz(theta) Tz(d) Tx(a) Rx(alpha)`` (deg, mm)."""
    return transform(rot_z(theta), (0.0, 0.0, d)) @ transform(rot_x(alpha), (a, 0.0, 0.0))


def _ur_links(params):
    """UR (d_j, a_j) of joints 1..6 from (d1, a2, a3, d4, d5, d6)."""
    d1, a2, a3, d4, d5, d6 = params
    return [d1, 0.0, 0.0, d4, d5, d6], [0.0, a2, a3, 0.0, 0.0, 0.0]


def _ur(q, params, ds=None, as_=None):
    """UR flange (DH frame 6) in the base (DH frame 0) from the joint angles (deg); ``ds``, ``as_`` the
    six d_j and a_j when given (default from ``params``)."""
    if ds is None:
        ds, as_ = _ur_links(params)
    T = np.eye(4)
    for theta, d, a, alpha in zip(q, ds, as_, UR_ALPHA):
        T = T @ _dh(theta, d, a, alpha)
    return T


def length_names(model):
    """The length-error parameters of ``model``: its nominal nonzero translation components, in chain order.

    KR 60 HA ``j2_x, j2_z, j3_x, j4_x, j4_z, j5_x, j6_x``; UR ``d1, a2, a3, d4, d5, d6``.
    """
    if model == "kr60ha":
        return tuple(f"j{j}_{'xyz'[k]}" for j, o in enumerate(KR60HA_ORIGINS, 1) for k in range(3)
                     if abs(o[k]) > NONZERO)
    if model in UR_DH:
        ds, as_ = _ur_links(UR_DH[model])
        return tuple(name for j in range(6) for name, v in ((f"d{j + 1}", ds[j]), (f"a{j + 1}", as_[j]))
                     if abs(v) > NONZERO)
    raise ValueError(f"unknown robot model {model!r}")


def _checked_lengths(model, lengths):
    """``{"j3_x": 0.3}`` checked against :func:`length_names` (a dict of floats; None -> {})."""
    allowed = length_names(model)
    out = {}
    for name, value in (lengths or {}).items():
        if name not in allowed:
            raise ValueError(f"lengths: {name!r} is not a nonzero nominal length of {model} ({', '.join(allowed)})")
        out[name] = float(value)
    return out


def forward(model, q, lengths=None):
    """Forward kinematics: the flange in the robot base (4x4, mm) of joint angles ``q`` (6, deg).

    Parameters
    ----------
    model : str
        One of :data:`MODELS`.
    q : array_like (6,)
        Joint angles, degrees.
    lengths : dict, optional
        Length errors (mm) by :func:`length_names` name; None: the nominal robot.
    """
    lengths = _checked_lengths(model, lengths) if lengths else {}
    if model == "kr60ha":
        origins = np.array(KR60HA_ORIGINS, float)
        for name, value in lengths.items():
            origins[int(name[1]) - 1, "xyz".index(name[3])] += value
        return _kr60ha(q, origins)
    if model in UR_DH:
        ds, as_ = _ur_links(UR_DH[model])
        for name, value in lengths.items():
            (ds if name[0] == "d" else as_)[int(name[1]) - 1] += value
        return _ur(q, None, ds, as_)
    raise ValueError(f"unknown robot model {model!r}")


def joint_axes(model, q):
    """The joints' axes in the base at the nominal configuration ``q``: (points (6, 3) mm, unit directions
    (6, 3)). KR 60 HA: the origin of joint j and its URDF axis carried to the base; UR: the origin and z
    axis of DH frame j-1 (what theta_j turns about)."""
    points, dirs = [], []
    T = np.eye(4)
    if model == "kr60ha":
        for origin, axis, angle in zip(KR60HA_ORIGINS, KR60HA_AXES, q):
            T = T @ transform(np.eye(3), origin)
            points.append(T[:3, 3].copy())
            dirs.append(T[:3, :3] @ (np.asarray(axis, float) / np.linalg.norm(axis)))
            T = T @ transform(rodrigues(axis, angle), np.zeros(3))
    elif model in UR_DH:
        ds, as_ = _ur_links(UR_DH[model])
        for theta, d, a, alpha in zip(q, ds, as_, UR_ALPHA):
            points.append(T[:3, 3].copy())
            dirs.append(T[:3, 2].copy())
            T = T @ _dh(theta, d, a, alpha)
    else:
        raise ValueError(f"unknown robot model {model!r}")
    return np.array(points), np.array(dirs)


def lever(model, q, joint):
    """Gravity's lever about joint ``joint`` (1..6) at the nominal ``q``: ``((p_F - o_j) x g) . a_j / 1000``
    (m), the torque a unit weight at the flange puts on the joint, signed along the joint's own axis."""
    points, dirs = joint_axes(model, q)
    p_flange = forward(model, q)[:3, 3]
    return float(np.cross(p_flange - points[joint - 1], GRAVITY) @ dirs[joint - 1]) / 1000.0


def deflection(model, q, compliance):
    """The joints' gravity deflection (6, deg) at the nominal ``q``: ``c_j * lever_j(q)`` for the joints
    in ``compliance`` (``{"j2": c2, "j3": c3}``, deg/m), zero elsewhere."""
    dq = np.zeros(6)
    for name, c in (compliance or {}).items():
        if name not in COMPLIANT:
            raise ValueError(f"compliance: unknown joint {name!r} ({', '.join(COMPLIANT)})")
        dq[int(name[1]) - 1] = float(c) * lever(model, q, int(name[1]))
    return dq


def true_forward(model, q, offsets=None, lengths=None, compliance=None):
    """Where the robot really stands when it reports ``q``: ``FK_lengths(q + offsets + dq(q))`` (4x4).

    ``offsets`` a 6-vector or a ``{"j2": ...}`` dict (deg), ``lengths`` (mm) and ``compliance`` (deg/m)
    dicts; the deflection ``dq`` from the nominal ``q``.
    """
    delta = offsets if offsets is not None and not isinstance(offsets, dict) else _offsets_vector(offsets)
    q = np.asarray(q, float)
    return forward(model, q + np.asarray(delta, float) + deflection(model, q, compliance), lengths)


def _pose_error(T, target):
    """6-vector: position error (mm) and rotation error (rotation vector, rad, scaled by 1000 mm)."""
    dR = target[:3, :3] @ T[:3, :3].T
    return np.concatenate([target[:3, 3] - T[:3, 3], 1000.0 * rotation_vector(dR)])


def inverse_kinematics(model, target, seed, iterations=100):
    """Joint angles (deg) whose nominal flange is ``target`` (4x4), by damped Newton from ``seed``.

    Returns
    -------
    ndarray (6,) or None
        The angles, or None if not converged to 1e-7 mm (rotation as 1000 mm x rad).
    """
    q = np.array(seed, float)
    h = 1e-6
    for _ in range(iterations):
        e = _pose_error(forward(model, q), target)
        if np.linalg.norm(e) < 1e-7:
            return q
        J = np.empty((6, 6))
        for j in range(6):
            dq = np.zeros(6)
            dq[j] = h
            J[:, j] = -(_pose_error(forward(model, q + dq), target) - e) / h
        lam = 1e-3 * np.trace(J.T @ J) / 6.0
        step = np.linalg.solve(J.T @ J + lam * np.eye(6), J.T @ e)
        q = q + np.clip(step, -10.0, 10.0)
    return None


# ----------------------------------------------------------------------------- the cell
def _offsets_vector(offsets):
    """``{"j2": 0.05, ...}`` (deg) -> a 6-vector; None -> zeros."""
    delta = np.zeros(6)
    for name, value in (offsets or {}).items():
        if name not in {f"j{k}" for k in range(1, 7)}:
            raise ValueError(f"offsets: unknown joint {name!r} (j1..j6)")
        delta[int(name[1]) - 1] = float(value)
    return delta


def _draw_sensor(rng):
    """sensor2flange (4x4): 110-200 mm off the flange, looking roughly along the flange's z, turned."""
    R = rot_z(rng.uniform(-180, 180)) @ rot_y(rng.uniform(-20, 20)) @ rot_x(rng.uniform(-20, 20))
    t = np.array([rng.uniform(-60, 60), rng.uniform(-60, 60), rng.uniform(110, 170)])
    return transform(R, t)


def _draw_working(rng, model):
    """The working configuration of this cell (deg): the robot's own, moved a little."""
    jitter = np.array([25.0, 5.0, 5.0, 10.0, 5.0, 30.0])
    return np.asarray(WORKING[model], float) + rng.uniform(-jitter, jitter)


def _view(rng, R0, centre, tilt=TILT):
    """A sensor pose (4x4) looking at ``centre``: tilted (up to ``tilt`` deg) from ``R0``'s view axis,
    turned about it."""
    tilt = tilt * math.sqrt(rng.uniform())
    azimuth = rng.uniform(0, 360)
    n = R0 @ np.array([math.cos(math.radians(azimuth)), math.sin(math.radians(azimuth)), 0.0])
    R = rodrigues(n, tilt) @ R0 @ rot_z(rng.uniform(-TURN, TURN))
    p = np.array([rng.uniform(-HALF, HALF), rng.uniform(-HALF, HALF), rng.uniform(*STANDOFF)])
    return transform(R, centre - R @ p)


def _usable(model, q):
    """Inside the joint limits and away from the wrist (and, for a UR, the elbow) singularity."""
    lo, hi = np.array(LIMITS[model], float).T
    if np.any(q < lo + 2.0) or np.any(q > hi - 2.0):
        return False
    if abs(math.sin(math.radians(q[4]))) < math.sin(math.radians(10.0)):
        return False
    return model == "kr60ha" or abs(math.sin(math.radians(q[2]))) > math.sin(math.radians(10.0))


def _in_view(p):
    """The sphere centre ``p`` (sensor frame, mm) is where the sensor sees it (with a margin for noise)."""
    return abs(p[0]) < 40.0 and abs(p[1]) < 40.0 and 180.0 < p[2] < 300.0


def draw_cell(model, seed, n=40, offsets=None, lengths=None, compliance=None, tilt=TILT):
    """Draw one cell and its poses (no noise); see the module docstring.

    ``lengths`` (mm), ``compliance`` (deg/m): the hidden length errors and gravity compliance
    (:func:`true_forward`); ``tilt`` (deg): how far the view directions spread from the working one
    (wider: the flange's reach varies more).

    Returns
    -------
    dict
        ``model``, ``sensor`` (4x4 sensor2flange), ``centre`` (3, base, mm), ``offsets`` (6, deg),
        ``lengths`` (dict, mm), ``compliance`` (dict, deg/m), ``joints`` (n, 6 reported angles, deg),
        ``flanges`` (n, 4, 4 nominal FK of the reported angles), ``points`` (n, 3: the true sphere centre
        in the sensor frame).
    """
    if model not in MODELS:
        raise ValueError(f"unknown robot model {model!r}; one of {MODELS}")
    rng = np.random.default_rng(seed)
    delta = _offsets_vector(offsets)
    lengths = _checked_lengths(model, lengths)
    compliance = {k: float(v) for k, v in (compliance or {}).items()}
    deflection(model, np.zeros(6), compliance)  # checks the names
    X = _draw_sensor(rng)
    working = _draw_working(rng, model)
    S0 = forward(model, working) @ X
    centre = S0[:3, :3] @ np.array([0.0, 0.0, 240.0]) + S0[:3, 3]
    joints, points = [], []
    for _ in range(50 * n):
        if len(joints) == n:
            break
        target = _view(rng, S0[:3, :3], centre, tilt) @ inverse(X)
        q = inverse_kinematics(model, target, working)
        if q is None or not _usable(model, q):
            continue
        p = (inverse(true_forward(model, q, delta, lengths, compliance) @ X) @ np.append(centre, 1.0))[:3]
        if _in_view(p):
            joints.append(q)
            points.append(p)
    if len(joints) < n:
        raise RuntimeError(f"{model}, seed {seed}: only {len(joints)} of {n} poses found")
    joints = np.array(joints)
    return {"model": model, "sensor": X, "centre": centre, "offsets": delta, "lengths": lengths,
            "compliance": compliance, "tilt": tilt, "joints": joints,
            "flanges": np.array([forward(model, q) for q in joints]), "points": np.array(points)}


# ----------------------------------------------------------------------------- files
def _vec(values, digits=9):
    """A TOML array of floats."""
    return "[" + ", ".join(f"{float(v):.{digits}f}" for v in values) + "]"


def _setup_text(cell, convention, noise):
    """The text of ``setup.toml``."""
    sensor_pose = pose_row(cell["sensor"], convention)
    return "\n".join([
        "[robot]", f'convention = "{convention}"', f'model = "{cell["model"]}"', "",
        "[sphere]", f"diameter = {DIAMETER}", f"center = {_vec(cell['centre'])}", "",
        "[noise]", f"centre_mm = {noise}", "",
        "[truth]", f"sensor_pose = {_vec(sensor_pose, 12)}", ""])


def _header(convention):
    """The header of ``measurements.csv``."""
    angles = ["a", "b", "c"] if convention == "kuka" else ["rx", "ry", "rz"]
    return ["id", "x", "y", "z", *angles, "xs", "ys", "zs"] + [f"j{k}" for k in range(1, 7)]


def make(folder, robot, seed, n=40, offsets=None, noise=0.02, convention=None, lengths=None, compliance=None,
         tilt=TILT):
    """Draw a cell, write its dataset folder (``setup.toml``, ``measurements.csv``), return the truth.

    Parameters
    ----------
    folder : str or pathlib.Path
        Created if missing.
    robot : str
        One of :data:`MODELS` (``kr60ha``, ``ur5e``, ``ur10e``).
    seed : int
        Seed of ``numpy.random.default_rng``.
    n : int
        Number of poses.
    offsets : dict, optional
        Hidden joint zero offsets, degrees, e.g. ``{"j2": 0.05, "j3": -0.03}``; the robot really stands
        at FK(q + offsets) while it reports q and FK(q).
    noise : float
        sd (mm) per component of the measured sphere centre.
    convention : str, optional
        ``kuka`` or ``ur``; default the robot's own (KUKA for kr60ha, UR for the URs).
    lengths : dict, optional
        Hidden errors of the nominal nonzero lengths (mm) by :func:`length_names` name, e.g.
        ``{"j3_x": 0.3}`` or ``{"a2": -0.2}``.
    compliance : dict, optional
        Hidden gravity compliance of joints 2 and 3 (deg/m), e.g. ``{"j2": 0.02, "j3": 0.01}``.
    tilt : float
        Spread of the view directions (deg, default :data:`TILT`).

    The files are what they always were: ``[truth]`` holds ``sensor_pose`` only (the hidden robot errors
    are returned, not written: handeye's ``[truth]`` has no keys for lengths or compliance).

    Returns
    -------
    dict
        :func:`draw_cell`'s truth plus ``measured`` (n, 3), ``convention``, ``noise``, ``folder``.
    """
    folder = pathlib.Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    convention = convention or CONVENTION[robot]
    cell = draw_cell(robot, seed, n, offsets, lengths, compliance, tilt)
    rng = np.random.default_rng([seed, 1])
    measured = cell["points"] + rng.normal(0.0, noise, cell["points"].shape)
    with open(folder / "measurements.csv", "w", newline="") as f:
        out = csv.writer(f)
        out.writerow(_header(convention))
        for i, (F, p, q) in enumerate(zip(cell["flanges"], measured, cell["joints"])):
            out.writerow([f"p{i:03d}"] + [repr(float(v)) for v in (*pose_row(F, convention), *p, *q)])
    (folder / "setup.toml").write_text(_setup_text(cell, convention, noise))
    return {**cell, "measured": measured, "convention": convention, "noise": noise, "folder": folder}


def read(folder):
    """A dataset folder back (own parser): ``setup`` (dict), ``poses`` (n, 6), ``xs`` (n, 3), ``joints`` (n, 6)."""
    folder = pathlib.Path(folder)
    setup = tomllib.loads((folder / "setup.toml").read_text())
    with open(folder / "measurements.csv", newline="") as f:
        rows = list(csv.reader(f))
    values = np.array([[float(v) for v in row[1:]] for row in rows[1:]])
    return {"setup": setup, "header": rows[0], "poses": values[:, :6], "xs": values[:, 6:9], "joints": values[:, 9:15]}


def chain_residuals(truth, measured=None, true_robot=True):
    """Per row, how far the chain misses (n, 3, mm, base): ``F X p - c``.

    With ``true_robot`` the flange is the true one (:func:`true_forward`: offsets, length errors,
    compliance; closes to the noise), else the reported FK(q) (misses by what the hidden errors move the
    sensor).
    """
    measured = truth["measured"] if measured is None else measured
    out = []
    for q, p in zip(truth["joints"], measured):
        if true_robot:
            F = true_forward(truth["model"], q, truth["offsets"], truth.get("lengths"), truth.get("compliance"))
        else:
            F = forward(truth["model"], q)
        S = F @ truth["sensor"]
        out.append(S[:3, :3] @ p + S[:3, 3] - truth["centre"])
    return np.array(out)


def _hat(w):
    """The cross-product matrix of a 3-vector."""
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


def _chain_jacobian(truth, parameters, centre=True, step=1e-4):
    """The chain ``r_i = F_i X p_i - c`` (base, mm) differentiated at the truth: (3n, k) and the column names.

    Columns: the sensor pose (3 rotations about the sensor's axes, rad, and 3 translations, mm), the centre
    (3, mm; only with ``centre``) and ``parameters``, named ``offsets.jk`` (deg), ``lengths.<name>`` (mm) or
    ``compliance.jk`` (deg/m), by central differences of :func:`true_forward`.
    """
    model, X = truth["model"], truth["sensor"]
    offsets, lengths, compliance = truth["offsets"], dict(truth.get("lengths") or {}), dict(truth.get("compliance") or {})
    cols = {f"_sensor{k}": [] for k in range(6)} | {f"_centre{k}": [] for k in range(3 if centre else 0)}
    cols |= {n: [] for n in parameters}
    for q, p in zip(truth["joints"], truth["points"]):
        F = true_forward(model, q, offsets, lengths, compliance)
        R = F[:3, :3]
        Xp = X[:3, :3] @ p
        for k in range(3):  # X -> X (I + [e]x) and X -> X + R_X e: the chain's change, per unit
            e = np.zeros(3)
            e[k] = 1.0
            cols[f"_sensor{k}"].append(R @ X[:3, :3] @ (_hat(e) @ p))
            cols[f"_sensor{k + 3}"].append(R @ X[:3, :3] @ e)
            if centre:
                cols[f"_centre{k}"].append(-e)
        for name in parameters:
            kind, key = name.split(".")
            values = []
            for sign in (1.0, -1.0):
                off, ln, co = np.array(offsets, float), dict(lengths), dict(compliance)
                if kind == "offsets":
                    off[int(key[1]) - 1] += sign * step
                elif kind == "lengths":
                    ln[key] = ln.get(key, 0.0) + sign * step
                elif kind == "compliance":
                    co[key] = co.get(key, 0.0) + sign * step
                else:
                    raise ValueError(f"unknown parameter {name!r}")
                Fk = true_forward(model, q, off, ln, co)
                values.append(Fk[:3, :3] @ Xp + Fk[:3, :3] @ X[:3, 3] + Fk[:3, 3])
            cols[name].append((values[0] - values[1]) / (2 * step))
    names = list(cols)
    return np.stack([np.concatenate(cols[n]) for n in names], axis=1), names


def expected_sd(truth, parameters, noise=None, step=1e-4, centre=True):
    """Own linearised 1-sd of hidden robot errors fitted together with the sensor pose (and the centre).

    The chain's Jacobian at the truth (:func:`_chain_jacobian`: the sensor pose, the centre unless
    ``centre`` is False -- a known centre -- and ``parameters``); the noise is isotropic, so
    ``sd = noise * sqrt(diag((J^T J)^-1))``.

    Returns
    -------
    dict
        name -> sd; and ``"_unexplained"`` -> name -> the fraction of that column's size left after
        projecting out the sensor pose, the centre and the other parameters (0: absorbed).
    """
    noise = truth["noise"] if noise is None else noise
    J, names = _chain_jacobian(truth, parameters, centre, step)
    cov = np.linalg.pinv(J.T @ J)
    out = {n: noise * math.sqrt(max(cov[i, i], 0.0)) for i, n in enumerate(names) if n in parameters}
    left = {}
    for i, n in enumerate(names):
        if n not in parameters:
            continue
        others = np.delete(J, i, axis=1)
        fit = others @ np.linalg.lstsq(others, J[:, i], rcond=None)[0]
        left[n] = float(np.linalg.norm(J[:, i] - fit) / max(np.linalg.norm(J[:, i]), 1e-300))
    out["_unexplained"] = left
    return out


def fit_robot_errors(truth, parameters, centre=False, iterations=8):
    """Own least-squares fit of robot errors to the measured points (Gauss-Newton with this module's
    kinematics): the sensor pose free, the centre free with ``centre`` (else the true one), the robot errors
    named in ``parameters`` (``offsets.jk``, ``lengths.<name>``, ``compliance.jk``) free and every other one
    held at zero (the nominal robot) -- the model a calibration that estimates just these fits. Starts at
    the truth.

    Returns
    -------
    dict
        name -> (estimate, 1 sd from the fit's own residual, 1 sd from the generator's noise) for every name of
        ``parameters``; ``"_sigma"`` -> the fit's residual sd per component (mm).
    """
    planted = {f"offsets.j{k + 1}": v for k, v in enumerate(truth["offsets"])}
    planted |= {f"lengths.{k}": v for k, v in (truth.get("lengths") or {}).items()}
    planted |= {f"compliance.{k}": v for k, v in (truth.get("compliance") or {}).items()}
    values = {n: planted.get(n, 0.0) for n in parameters}
    X, c = truth["sensor"].copy(), np.array(truth["centre"], float)
    measured = truth["measured"]

    def cell():
        offsets = np.zeros(6)
        lengths, compliance = {}, {}
        for name, v in values.items():
            kind, key = name.split(".")
            if kind == "offsets":
                offsets[int(key[1]) - 1] = v
            else:
                (lengths if kind == "lengths" else compliance)[key] = v
        return {"model": truth["model"], "sensor": X, "centre": c, "offsets": offsets, "lengths": lengths,
                "compliance": compliance, "joints": truth["joints"], "points": measured, "measured": measured}

    for _ in range(iterations):
        J, names = _chain_jacobian(cell(), list(parameters), centre)
        r = chain_residuals(cell()).ravel()
        delta = -np.linalg.lstsq(J, r, rcond=None)[0]
        w, dt = delta[:3], delta[3:6]
        X = X.copy()
        X[:3, 3] = X[:3, 3] + X[:3, :3] @ dt
        if np.linalg.norm(w) > 0:
            X[:3, :3] = X[:3, :3] @ rodrigues(w, math.degrees(np.linalg.norm(w)))
        if centre:
            c = c + delta[6:9]
        for i, name in enumerate(names):
            if name in values:
                values[name] += delta[i]
        if np.abs(delta).max() < 1e-9:  # converged: the central differences' own noise leaves steps of ~1e-11
            break  # (mm, rad, deg, deg/m) that never fall below 1e-12; the estimates are compared at 0.1 sd
    J, names = _chain_jacobian(cell(), list(parameters), centre)
    r = chain_residuals(cell()).ravel()
    sigma = math.sqrt(float(r @ r) / (len(r) - J.shape[1]))
    cov = np.linalg.pinv(J.T @ J)
    out = {n: (values[n], sigma * math.sqrt(cov[i, i]), truth["noise"] * math.sqrt(cov[i, i]))
           for i, n in enumerate(names) if n in values}
    out["_sigma"] = sigma
    return out
