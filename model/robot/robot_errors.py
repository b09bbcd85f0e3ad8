"""The robot's own errors: its kinematics with zero offsets, length errors and gravity deflection.

A nominal model (:mod:`handeye.model.robot.robots`) gives the flange pose the controller reports::

    T(q) = base . prod_j [O_j Rot(axis_j, qc_j) A_j] . flange,    qc = C q + theta

(``O_j`` the chain's joint origin, ``A_j`` DH's ``Tz(d) Tx(a) Rx(alpha)``, ``C`` the coupling).
The real arm differs by three kinds of error, each zero when absent, so the models nest:

``joint_offsets`` (``j1..j6``, degrees)
    zero offsets of the chain's joint angles: ``qc + delta``.
``link_lengths`` (mm)
    errors of the nominal lengths and offsets: the translation of each joint's fixed transform
    (``O_j``'s xyz in the parent link for a chain model; ``A_j``'s ``(a_j, 0, d_j)`` for a DH
    model) moved by ``e``, only in the components that are not zero in the nominal model (the
    lengths of the data sheet): ``O_j -> Trans(e) O_j``, ``A_j -> Trans(e) A_j``. Named
    ``j<k>_<x|y|z>`` (chain) and ``d<k>``, ``a<k>`` (DH). The base and the flange transform are
    not among them: a fixed sphere's centre absorbs every base error, the sensor pose every
    flange error.
``joint_compliance`` (``j2``, ``j3``; degrees per metre)
    gravity deflection of the shoulder and the elbow proportional to the load torque:
    ``qc_j + k_j l_j(q)`` with the lever ``l_j = ((p_F - o_j) x g) . a_j`` (metres) of the
    flange ``p_F`` about joint j's axis (point ``o_j``, direction ``a_j``) under gravity
    ``g = (0, 0, -1)`` of the robot base (a floor-mounted robot), all at the nominal pose: the
    torque of a load at the flange per unit weight. ``k_j`` is the joint's compliance times the
    load's weight; positive sags the load.

The pose with every error is ``T*(q) = base . prod_j [O*_j Rot(axis_j, qc*_j) A*_j] . flange``;
its derivatives are the chain's product rule, exact: a joint angle's is ``P_j O*_j Rot_j
[axis_j]x A*_j S_j`` (``P_j`` the product before joint j, ``S_j`` after it), a length's ``P_j
E_c O*_j ...`` with ``E_c`` the translation generator of component c (``T`` is affine in a
translation, so this is exact for any size); an offset's is the angle's times pi/180, a
compliance gain's the angle's times ``l_j pi / 180`` (the lever is taken at the nominal pose,
so it does not depend on the gains). Checked against central differences for every built-in
model (tests/test_robot_errors.py).
"""
from __future__ import annotations

import dataclasses

import numpy as np

from handeye.model.common.rotation import matrix_from_rotvec

#: The robot effects, in the order the chain applies them.
NAMES = ("joint_offsets", "link_lengths", "joint_compliance")
#: Joints whose gravity deflection ``joint_compliance`` models (indices of the chain: shoulder, elbow).
COMPLIANT = (1, 2)
#: Gravity in the robot base frame (unit vector): a floor-mounted robot, base z up.
GRAVITY = np.array([0.0, 0.0, -1.0])
#: A nominal translation component counts as a length above this (mm).
LENGTH_FLOOR = 1e-6


def length_params(model):
    """The nominal lengths of ``model`` that ``link_lengths`` errs: ``[(joint, where, axis, name)]``
    with ``where`` 'origin' (chain: ``O_j``) or 'after' (DH: ``A_j``) and ``axis`` 0, 1, 2."""
    out = []
    for j in range(6):
        for where, fixed in (("origin", model.origins[j]), ("after", model.after[j])):
            for c in range(3):
                if abs(fixed[c, 3]) > LENGTH_FLOOR:
                    dh = where == "after" and c in (0, 2)
                    name = (("a" if c == 0 else "d") + str(j + 1)) if dh else f"j{j + 1}_{'xyz'[c]}"
                    out.append((j, where, c, name))
    return out


def param_names(model, name):
    """The parameter names of robot effect ``name`` on ``model``."""
    if name == "joint_offsets":
        return tuple(f"j{j + 1}" for j in range(6))
    if name == "joint_compliance":
        return tuple(f"j{j + 1}" for j in COMPLIANT)
    if name == "link_lengths":
        return tuple(p[3] for p in length_params(model))
    raise ValueError(f"unknown robot effect {name!r}; robot effects are {', '.join(NAMES)}")


def _translation(c):
    e = np.zeros((4, 4))
    e[c, 3] = 1.0
    return e


def _hat(w):
    out = np.zeros((4, 4))
    out[:3, :3] = [[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]]
    return out


def _fixed(model, values):
    """The joint origins and after-transforms (6, 4, 4) with ``link_lengths`` errors."""
    origins, after = model.origins.copy(), model.after.copy()
    lengths = values.get("link_lengths")
    if lengths is not None:
        for (j, where, c, _), e in zip(length_params(model), np.asarray(lengths, float)):
            (origins if where == "origin" else after)[j, c, 3] += e
    return origins, after


def _chain(model, qc, origins, after):
    """Per joint ``O_j Rot_j`` and ``O_j Rot_j A_j`` (each (N, 6, 4, 4)), and the prefix products
    ``P_j`` (before ``O_j``) and suffix products ``S_j`` (after ``A_j``, the flange included), each
    (N, 7, 4, 4) and (N, 6, 4, 4): the products of every joint at once, then one running product
    each way."""
    n = len(qc)
    turns = np.zeros((n, 6, 4, 4))
    turns[:, :, 3, 3] = 1.0
    turns[:, :, :3, :3] = matrix_from_rotvec(model.axes[None, :, :] * qc[:, :, None])  # every joint at once
    turned = origins[None] @ turns
    links = turned @ after[None]
    prefix = np.empty((n, 7, 4, 4))
    prefix[:, 0] = model.base
    for j in range(6):
        prefix[:, j + 1] = prefix[:, j] @ links[:, j]
    suffix = np.empty((n, 6, 4, 4))
    suffix[:, 5] = model.flange
    for j in range(5, 0, -1):
        suffix[:, j - 1] = links[:, j] @ suffix[:, j]
    return turned, prefix, suffix


#: The last robot model, reported angles and levers :func:`levers` answered, as one tuple (read and replaced
#: whole: a thread never sees one call's key with another's levers): the levers are of the nominal pose, the
#: same for every fit of one dataset (a search asks hundreds of times).
_LAST_LEVERS = (None, None, None)


def levers(model, joints_deg):
    """The gravity levers ``l_j`` (N, 2), metres, of the flange about the shoulder and elbow at the
    nominal pose of the reported angles (module docstring)."""
    joints = np.ascontiguousarray(joints_deg, float).reshape(-1, 6)
    global _LAST_LEVERS
    last_model, last_key, last = _LAST_LEVERS
    key = joints.tobytes()
    if last_model is model and last_key == key:
        return last.copy()
    q = np.radians(joints @ model.coupling.T + model.offsets)
    _, prefix, _ = _chain(model, q, model.origins, model.after)
    flange = (prefix[:, -1] @ model.flange)[:, :3, 3]
    out = []
    for j in COMPLIANT:
        frame = prefix[:, j] @ model.origins[j]
        point, axis = frame[:, :3, 3], frame[:, :3, :3] @ model.axes[j]
        out.append(np.einsum("ni,ni->n", np.cross(flange - point, GRAVITY), axis) / 1000.0)
    result = np.stack(out, axis=1)
    _LAST_LEVERS = (model, key, result)
    return result.copy()


def perturbed(model, joints_deg, values):
    """The flange poses with robot errors and their exact derivatives.

    Parameters
    ----------
    model : handeye.model.robot.robots.RobotModel
    joints_deg : array_like, shape (N, 6)
        Reported joint angles, degrees.
    values : dict
        Robot effect name (:data:`NAMES`) -> its full parameter vector (:func:`param_names`
        order): offsets in degrees, lengths in mm, compliance gains in degrees per metre.
        Effects absent are zero.

    Returns
    -------
    fk : ndarray, shape (N, 4, 4)
        ``T*(q)`` in the robot base, mm.
    derivatives : dict
        Effect name (of ``values``) -> ``dT*/dp`` (N, k, 4, 4) per unit of each parameter.
    """
    joints = np.asarray(joints_deg, float).reshape(-1, 6)
    qc = joints @ model.coupling.T + model.offsets
    lever = None
    if "joint_offsets" in values:
        qc = qc + np.asarray(values["joint_offsets"], float)
    if "joint_compliance" in values:
        lever = levers(model, joints)
        qc[:, list(COMPLIANT)] += lever * np.asarray(values["joint_compliance"], float)
    origins, after = _fixed(model, values)
    turned, prefix, suffix = _chain(model, np.radians(qc), origins, after)
    fk = prefix[:, -1] @ model.flange
    out = {}
    if "joint_offsets" in values or "joint_compliance" in values:
        hat_after = np.stack([_hat(model.axes[j]) @ after[j] for j in range(6)])
        dq = prefix[:, :6] @ turned @ hat_after[None] @ suffix * (np.pi / 180.0)
        if "joint_offsets" in values:
            out["joint_offsets"] = dq
        if "joint_compliance" in values:
            out["joint_compliance"] = dq[:, list(COMPLIANT)] * lever[:, :, None, None]
    if "link_lengths" in values:
        cols = []
        for j, where, c, _ in length_params(model):
            if where == "origin":
                cols.append(prefix[:, j] @ _translation(c) @ (turned[:, j] @ after[j]) @ suffix[:, j])
            else:
                cols.append(prefix[:, j] @ turned[:, j] @ _translation(c) @ after[j] @ suffix[:, j])
        out["link_lengths"] = np.stack(cols, axis=1) if cols else np.zeros((len(joints), 0, 4, 4))
    return fk, {k: out[k] for k in values}


def corrected_model(model, values):
    """The nominal model with calibrated ``joint_offsets`` and ``link_lengths`` folded in (a
    :class:`~handeye.model.robot.robots.RobotModel`; ``joint_compliance`` depends on the pose and
    has no place in a kinematic model)."""
    origins, after = _fixed(model, values)
    offsets = model.offsets + np.asarray(values.get("joint_offsets", np.zeros(6)), float)
    return dataclasses.replace(model, origins=origins, after=after, offsets=offsets)


def always_absorbed(model, name, samples=24, seed=0):
    """The parameters of robot effect ``name`` that no pose set can separate from a fixed sphere's
    centre or the sensor pose: their change of the flange is a constant transform on the base side
    (``dT T^-1`` the same at every configuration: a length before the first joint's turn, a
    first-joint offset about a vertical axis...) or on the flange side (``T^-1 dT`` constant: a
    last-joint offset, a length along the last axis). Checked at ``samples`` random
    configurations; returns ``{parameter: 'base' | 'flange'}``."""
    q = np.random.default_rng(seed).uniform(-170.0, 170.0, (samples, 6))
    fk, d = perturbed(model, q, {name: np.zeros(len(param_names(model, name)))})
    inv = np.linalg.inv(fk)
    out = {}
    for k, param in enumerate(param_names(model, name)):
        left, right = d[name][:, k] @ inv, inv @ d[name][:, k]
        for side, twist in (("base", left), ("flange", right)):
            scale = max(float(np.abs(twist).max()), 1e-12)
            if np.abs(twist - twist[0]).max() <= 1e-9 * scale:
                out[param] = side
                break
    return out
