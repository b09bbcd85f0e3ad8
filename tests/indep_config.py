"""An independent generator of ABB-like cells whose poses lie on both sides of the wrist flip (numpy only).

Written as a user's own script would be, with no code of ``handeye``: an ABB IRB 4600-60/2.05 joint
chain from ROS-Industrial's ``abb_experimental`` (``irb4600_60_205_macro.xacro``; lengths in mm, joint
angles in degrees: joint j at origin ``o_j`` in the previous link, no rotation, turning about
``axis_j``; ``tool0`` after link 6 turned ``rpy = (0, 90 deg, 0)``), its own rotations, its own damped
Newton inverse kinematics.

The cell: a laser-line sensor on the flange (``X`` = sensor2flange), a sphere fixed in the base
(centre ``c``, seen 190-290 mm in front of the sensor). A spherical wrist reaches one flange pose with
``(j4, j5, j6)`` and with the wrist flipped, ``(j4 + 180, -j5, j6 + 180)``: each pose is reached
in its working wrist (j5 > 0), and ``flipped`` of them in the other (j5 < 0).

What the controller reports and where the robot stands (:func:`draw_cell`):

- the robot really stands at ``FK(q + delta)`` (``offsets``: hidden zero offsets, degrees);
- the controller reports ``F = B . FK(q) . C`` for the angles ``q`` it reports: ``B`` and ``C`` the
  constant base and flange transforms of its own calibrated model (``flange_turn`` = the angle of
  ``C`` about the flange's z, degrees; identity by default), applied to the true robot too (the
  controller's model is then right: ``B FK(q + delta) C``);
- ``order``: the joint columns written in another order (a permutation of 0..5), ``signs``: with
  another sign -- a user's slip the nominal-model gate must name;
- the sensor measures ``p = (B FK(q + delta) C X)^-1 c`` + N(0, noise^2) per component.

Public: :func:`forward`, :func:`inverse_kinematics`, :func:`draw_cell`, :func:`make` (write a folder),
:func:`quaternion` and the rotation helpers.
"""
from __future__ import annotations

import csv
import math
import pathlib

import numpy as np

#: IRB 4600-60/2.05 joint origins in the previous link (mm) and joint axes (the xacro's)
ORIGINS = ((0.0, 0.0, 495.0), (175.0, 0.0, 0.0), (0.0, 0.0, 900.0), (0.0, 0.0, 175.0), (960.0, 0.0, 0.0),
           (135.0, 0.0, 0.0))
AXES = ((0, 0, 1), (0, 1, 0), (0, 1, 0), (1, 0, 0), (0, 1, 0), (1, 0, 0))
#: the working configuration (deg): the flange looks down in front of the robot, wrist not flipped
WORKING = (0.0, 20.0, 10.0, 0.0, 60.0, 0.0)
#: joint limits kept inside (deg; the IRB 4600's own, a little narrowed)
LIMITS = ((-175, 175), (-85, 145), (-175, 65), (-395, 395), (-115, 115), (-395, 395))
DIAMETER = 50.0
#: the sphere centre in the sensor frame: |x|, |y| <= HALF, z in STANDOFF (mm)
HALF, STANDOFF = 30.0, (190.0, 290.0)
TILT, TURN = 40.0, 60.0


def rodrigues(axis, deg):
    """Rotation by ``deg`` degrees about ``axis`` (3, any length) (3x3)."""
    k = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    t = math.radians(deg)
    return np.eye(3) + math.sin(t) * K + (1 - math.cos(t)) * K @ K


def transform(R, t):
    """4x4 from R (3x3) and t (3, mm)."""
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, t
    return T


def inverse(T):
    """Inverse of a rigid 4x4."""
    return transform(T[:3, :3].T, -T[:3, :3].T @ T[:3, 3])


def angle_deg(R):
    """Rotation angle of R (deg)."""
    return math.degrees(math.acos(min(1.0, max(-1.0, (np.trace(R) - 1) / 2))))


def quaternion(R):
    """Unit quaternion (w, x, y, z), w >= 0, of R (ABB's q1..q4)."""
    w = math.sqrt(max(0.0, 1 + np.trace(R))) / 2
    if w > 0.1:
        q = np.array([w, (R[2, 1] - R[1, 2]) / (4 * w), (R[0, 2] - R[2, 0]) / (4 * w), (R[1, 0] - R[0, 1]) / (4 * w)])
    else:  # the largest diagonal
        i = int(np.argmax(np.diag(R)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = math.sqrt(max(0.0, 1 + R[i, i] - R[j, j] - R[k, k])) * 2
        q = np.zeros(4)
        q[0] = (R[k, j] - R[j, k]) / s
        q[1 + i] = s / 4
        q[1 + j] = (R[j, i] + R[i, j]) / s
        q[1 + k] = (R[k, i] + R[i, k]) / s
    q /= np.linalg.norm(q)
    return q if q[0] >= 0 else -q


def _turn(axis, deg):
    """4x4 rotation about a coordinate axis (0, 1, 2 for x, y, z) by ``deg`` degrees."""
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    T = np.eye(4)
    T[i, i], T[i, j], T[j, i], T[j, j] = c, -s, s, c
    return T


#: the joint origins as 4x4 translations, each joint's axis index, tool0 after link 6
_ORIGINS = [transform(np.eye(3), o) for o in ORIGINS]
_AXIS = [int(np.argmax(a)) for a in AXES]
_TOOL0 = _turn(1, 90.0)


def forward(q):
    """Flange in the base (4x4, mm) of the joint angles ``q`` (6, deg): the chain, then tool0."""
    T = np.eye(4)
    for o, a, angle in zip(_ORIGINS, _AXIS, q):
        T = T @ o @ _turn(a, angle)
    return T @ _TOOL0


def flipped(q):
    """The same flange pose with the wrist flipped: ``(j4 + 180, -j5, j6 + 180)``, j4, j6 kept in +-180."""
    q = np.array(q, float)
    q[3], q[4], q[5] = (q[3] + 360.0) % 360.0 - 180.0, -q[4], (q[5] + 360.0) % 360.0 - 180.0
    return q


def _error(T, target):
    dR = target[:3, :3] @ T[:3, :3].T
    w = np.array([dR[2, 1] - dR[1, 2], dR[0, 2] - dR[2, 0], dR[1, 0] - dR[0, 1]]) / 2
    return np.concatenate([target[:3, 3] - T[:3, 3], 1000.0 * w])


def inverse_kinematics(target, seed, iterations=60):
    """Joint angles (deg) whose flange is ``target`` (4x4), damped Newton from ``seed``; None if not
    converged to 1e-7 (mm, and 1000 mm x rad)."""
    q = np.array(seed, float)
    for _ in range(iterations):
        e = _error(forward(q), target)
        if np.linalg.norm(e) < 1e-7:
            return q
        J = np.empty((6, 6))
        for j in range(6):
            dq = np.zeros(6)
            dq[j] = 1e-6
            J[:, j] = -(_error(forward(q + dq), target) - e) / 1e-6
        step = np.linalg.solve(J.T @ J + 1e-3 * np.trace(J.T @ J) / 6 * np.eye(6), J.T @ e)
        q = q + np.clip(step, -10.0, 10.0)
    return None


def _usable(q):
    lo, hi = np.array(LIMITS, float).T
    return bool(np.all(q > lo) and np.all(q < hi) and abs(math.sin(math.radians(q[4]))) > math.sin(math.radians(15)))


def draw_cell(seed, n=32, flipped_n=8, offsets=None, flange_turn=0.0, tilt=TILT, turn=TURN):
    """One cell (module docstring), no noise.

    Returns
    -------
    dict
        ``sensor`` (4x4), ``centre`` (3), ``joints`` (n, 6, reported, deg), ``flip`` (n, bool: j5 < 0),
        ``reported`` (n, 4, 4: ``FK(q) C``), ``points`` (n, 3: the true centre in the sensor), ``C`` (4x4).
    """
    rng = np.random.default_rng(seed)
    delta = np.zeros(6) if offsets is None else np.asarray(offsets, float)
    C = transform(rodrigues((0, 0, 1), flange_turn), np.zeros(3))
    X = transform(rodrigues((0, 0, 1), rng.uniform(-180, 180)) @ rodrigues((1, 0, 0), rng.uniform(-15, 15)),
                  [rng.uniform(-50, 50), rng.uniform(-50, 50), rng.uniform(110, 160)])
    working = np.asarray(WORKING) + rng.uniform(-1, 1, 6) * (20, 5, 5, 10, 5, 30)
    S0 = forward(working) @ C @ X
    centre = S0[:3, :3] @ [0.0, 0.0, 240.0] + S0[:3, 3]
    joints = []
    while len(joints) < n:
        tilt_i, az = tilt * math.sqrt(rng.uniform()), rng.uniform(0, 360)
        axis = S0[:3, :3] @ [math.cos(math.radians(az)), math.sin(math.radians(az)), 0.0]
        R = rodrigues(axis, tilt_i) @ S0[:3, :3] @ rodrigues((0, 0, 1), rng.uniform(-turn, turn))
        p = [rng.uniform(-HALF, HALF), rng.uniform(-HALF, HALF), rng.uniform(*STANDOFF)]
        q = inverse_kinematics(transform(R, centre - R @ p) @ inverse(X) @ inverse(C), working)
        if q is not None and _usable(q) and _usable(flipped(q)):
            joints.append(q)
    joints = np.array(joints)
    flip = np.zeros(n, bool)
    flip[rng.choice(n, flipped_n, replace=False)] = True
    joints[flip] = [flipped(q) for q in joints[flip]]
    true = np.array([forward(q + delta) @ C for q in joints])
    points = np.array([(inverse(F @ X) @ np.append(centre, 1.0))[:3] for F in true])
    return {"sensor": X, "centre": centre, "joints": joints, "flip": flip, "C": C, "offsets": delta,
            "reported": np.array([forward(q) @ C for q in joints]), "points": points}


def make(folder, seed, n=32, flipped_n=8, offsets=None, flange_turn=0.0, noise=0.03, order=None, signs=None,
         tilt=TILT, turn=TURN, joints=True, cfx=False):
    """Draw a cell and write its folder (ABB convention, ball centres and j1..j6); return the truth.

    ``order`` (a permutation of 0..5): column k of the file holds joint ``order[k]``; ``signs`` (6 of
    +-1): each column's sign. Both default to the truth. Without ``joints`` the file has no j1..j6 and
    the setup no model; with ``cfx`` it has ABB's ``cfx`` column (bit 0: j5 < 0; every pose here has
    the wrist centre in front of axis 1 and of the lower arm, bits 1 and 2 clear).
    """
    folder = pathlib.Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    cell = draw_cell(seed, n, flipped_n, offsets, flange_turn, tilt, turn)
    rng = np.random.default_rng([seed, 7])
    measured = cell["points"] + rng.normal(0.0, noise, cell["points"].shape)
    order = list(range(6)) if order is None else list(order)
    signs = np.ones(6) if signs is None else np.asarray(signs, float)
    with open(folder / "measurements.csv", "w", newline="") as f:
        out = csv.writer(f)
        out.writerow(["id", "x", "y", "z", "q1", "q2", "q3", "q4", "xs", "ys", "zs"]
                     + [f"j{k}" for k in range(1, 7)] * joints + ["cfx"] * cfx)
        for i, (F, p, q) in enumerate(zip(cell["reported"], measured, cell["joints"])):
            written = list(signs * q[order]) * joints
            out.writerow([f"p{i:02d}"] + [repr(float(v)) for v in (*F[:3, 3], *quaternion(F[:3, :3]), *p, *written)]
                         + [str(int(q[4] < 0))] * cfx)
    X = cell["sensor"]
    vec = lambda v: "[" + ", ".join(f"{float(x):.9f}" for x in v) + "]"  # noqa: E731
    (folder / "setup.toml").write_text("\n".join([
        "[robot]", 'convention = "abb"', *['model = "irb4600"'] * joints, "", "[sphere]", f"diameter = {DIAMETER}",
        f"center = {vec(cell['centre'])}", "", "[noise]", f"centre_mm = {noise}", "",
        "[truth]", f"sensor_pose = {vec([*X[:3, 3], *quaternion(X[:3, :3])])}", ""]))
    return {**cell, "measured": measured, "folder": folder, "noise": noise}
