"""The nominal-model gate: do the joint angles, through the nominal model, give the reported flange poses?

A controller reports ``F_i = B T(q_i) C`` for the joint angles ``q_i`` it reports, where ``T`` is
the nominal forward kinematics (:meth:`handeye.model.robot.robots.RobotModel.flange2base`) and
``B``, ``C`` are constant transforms at the base and at the flange: its own calibrated model (an
ABB's absolute-accuracy model turns the flange by a fraction of a degree about its z; a zero
offset of the first or the last joint is such a constant), or a mounting offset of the base
frame the poses are given in. handeye always takes the reported poses; the model only carries
the robot's effects (:mod:`handeye.model.robot.robot_errors`: ``F_rep T(q)^-1 T(q + delta)``),
so the constants are absorbed into the model (``base <- B base``, ``flange <- flange C``: the
effects' change is then that of the controller's frames) and said with their size.

What is left after the constants is pose-dependent, and that is what the gate judges
(:data:`AGREE_MM`, :data:`AGREE_DEG`): within it, the model is the controller's up to what a
calibrated model changes; beyond it, the gate refuses and names what makes the model agree --
angles in radians, joint columns in another order or with another sign, another built-in model --
or, when nothing does, says that a wrong model or the columns are to be checked. A constant
transform at the flange larger than a calibrated model's (:data:`ABSORB_MM`, :data:`ABSORB_DEG`)
means the poses are of another point than the flange (a TCP): refused, as before.

The constants are fitted by Gauss-Newton on ``(omega_B, t_B, t_C, omega_C)`` (12 parameters;
position rows in mm, rotation rows in rad times :data:`LEVER_MM`), linear in the translations, from
the identity.
"""
from __future__ import annotations

import dataclasses
import itertools

import numpy as np

from handeye.model.chain.conventions import LENGTH_UNITS
from handeye.model.common.rotation import matrix_from_rotvec, rotvec_from_matrix, skew, transform_distance
from handeye.model.readers.tables import DatasetError

#: The pose-dependent difference the nominal model may leave after the constant transforms (mm, deg):
#: a controller's calibrated model differs from the nominal one by its joint offsets and lengths, about
#: a millimetre and a tenth of a degree over the workspace; a wrong model or a joint order or sign error
#: leaves tens of mm and degrees.
AGREE_MM, AGREE_DEG = 5.0, 0.5
#: The largest constant transform at the flange absorbed as the controller's calibrated model (mm, deg):
#: a calibration moves the flange frame by up to a millimetre or two and turns it by a joint offset's
#: fraction of a degree; a TCP lies tens of mm or more from the flange (refused, naming it).
ABSORB_MM, ABSORB_DEG = 5.0, 2.0
#: Constants below these (mm, deg) are absorbed without a word: the rounding of a controller's printed
#: poses (0.01 mm, 0.001 deg and quaternions to 6 digits) and of the fit of the constants themselves.
SAY_MM, SAY_DEG = 0.05, 0.01
#: The lever that weighs a rotation against a translation in the constants' fit (mm): the robot's reach.
LEVER_MM = 1000.0
#: Gauss-Newton iterations of the constants' fit (from the identity; the translations are linear, the
#: rotations converge quadratically: 1e-12 of a 2 deg constant in four).
ITERATIONS = 6
#: Poses the search for a named mismatch uses (the first ones): each candidate costs a constants' fit.
SEARCH_POSES = 24


@dataclasses.dataclass(frozen=True)
class Constants:
    """The constant transforms of a model against reported poses, and what they leave.

    Attributes
    ----------
    base, flange : ndarray, shape (4, 4)
        ``B`` and ``C`` (mm): ``F_rep ~ B T(q) C``.
    left_mm, left_deg : float
        The largest pose-dependent difference left (mm, deg).
    """

    base: np.ndarray
    flange: np.ndarray
    left_mm: float
    left_deg: float

    def agrees(self):
        """Whether what is left is within :data:`AGREE_MM`, :data:`AGREE_DEG`."""
        return self.left_mm <= AGREE_MM and self.left_deg <= AGREE_DEG


def _transform(rotvec, t):
    out = np.eye(4)
    out[:3, :3], out[:3, 3] = matrix_from_rotvec(rotvec), t
    return out


def constants(fk, flange2base):
    """Fit ``B``, ``C`` with ``flange2base ~ B fk C`` (module docstring).

    Parameters
    ----------
    fk, flange2base : ndarray, shape (N, 4, 4)
        The nominal forward kinematics of the reported angles, and the reported flange poses (mm).

    Returns
    -------
    Constants
    """
    b, c = np.eye(4), np.eye(4)
    n = len(fk)
    for _ in range(ITERATIONS):
        a = b @ fk @ c
        rot, pos = a[:, :3, :3], a[:, :3, 3]
        r_pos = flange2base[:, :3, 3] - pos
        r_rot = rotvec_from_matrix(flange2base[:, :3, :3] @ np.transpose(rot, (0, 2, 1)))
        jac = np.zeros((n, 6, 12))
        jac[:, :3, 0:3] = -skew(pos)
        jac[:, :3, 3:6] = np.eye(3)
        jac[:, :3, 6:9] = rot
        jac[:, 3:, 0:3] = LEVER_MM * np.eye(3)
        jac[:, 3:, 9:12] = LEVER_MM * rot
        rhs = np.concatenate([r_pos, LEVER_MM * r_rot], axis=1).reshape(-1)
        step = np.linalg.lstsq(jac.reshape(-1, 12), rhs, rcond=1e-10)[0]
        b = _transform(step[0:3], step[3:6]) @ b
        c = c @ _transform(step[9:12], step[6:9])
    dpos, dang = transform_distance(b @ fk @ c, flange2base)
    return Constants(b, c, float(np.max(dpos)), float(np.max(dang)))


def _size(t):
    """``(mm, deg)`` of a 4x4."""
    return float(np.linalg.norm(t[:3, 3])), float(np.degrees(np.linalg.norm(rotvec_from_matrix(t[:3, :3]))))


def _describe(t, where):
    """``"0.35 deg about (0.00, 0.00, -1.00), 0.01 mm"`` of a constant at ``where``: its rotation and
    its translation, each where it reaches :data:`SAY_DEG`, :data:`SAY_MM`."""
    mm, deg = _size(t)
    w = rotvec_from_matrix(t[:3, :3])
    axis = np.round(w / max(np.linalg.norm(w), 1e-300), 2) + 0.0  # + 0.0: no '-0.00'
    parts = ([f"{deg:.3g} deg about ({', '.join(f'{v:.2f}' for v in axis)})"] if deg >= SAY_DEG else []) + (
        [f"({', '.join(f'{v:.2f}' for v in np.round(t[:3, 3], 2) + 0.0)}) mm ({mm:.3g} mm)"] if mm >= SAY_MM else [])
    return f"{' and '.join(parts) or 'nothing'} at the {where}"


def absorbed_note(model_name, found):
    """What absorbing ``found`` (a :class:`Constants`) says, or "" when it is below :data:`SAY_MM`, :data:`SAY_DEG`."""
    said = [_describe(t, where) for t, where in ((found.flange, "flange"), (found.base, "base"))
            if _size(t)[0] >= SAY_MM or _size(t)[1] >= SAY_DEG]
    if not said:
        return ""
    return (f"the reported flange poses differ from the {model_name} model's nominal kinematics by a constant "
            f"transform, {' and '.join(said)} (the controller's calibrated model, or a mounting offset), absorbed "
            f"into the model; up to {found.left_mm:.2g} mm / {found.left_deg:.2g} deg depend on the pose (the gate: "
            f"{AGREE_MM:g} mm / {AGREE_DEG:g} deg)")


def gated(model, joints_deg, flange2base, file, others=()):
    """The model with the constants absorbed (a note in its ``absorbed``), or DatasetError naming
    what is wrong (module docstring).

    Parameters
    ----------
    model : handeye.model.robot.robots.RobotModel
    joints_deg : array_like, shape (N, 6)
        Reported joint angles, degrees.
    flange2base : array_like, shape (N, 4, 4)
        Reported flange poses, mm.
    file : path
        The file the refusal names.
    others : callable or sequence, optional
        The other models a refusal tries (``others()`` gives them: loaded only on the refusal's path).

    Returns
    -------
    handeye.model.robot.robots.RobotModel
    """
    joints, f2b = np.asarray(joints_deg, float), np.asarray(flange2base, float)
    found = constants(model.flange2base(joints), f2b)
    flange_mm, flange_deg = _size(found.flange)
    if found.agrees() and flange_mm <= ABSORB_MM and flange_deg <= ABSORB_DEG:
        return dataclasses.replace(model, base=found.base @ model.base, flange=model.flange @ found.flange,
                                   absorbed=absorbed_note(model.name, found))
    dpos, dang = transform_distance(model.flange2base(joints), f2b)
    said = (f"the {model.name} model's flange is up to {float(np.max(dpos)):.1f} mm / {float(np.max(dang)):.2f} deg "
            "from the reported poses")
    if found.agrees():
        raise DatasetError(file, f"{said}, by one constant transform at the flange ({_describe(found.flange, 'flange')}), "
                                 f"more than a controller's calibrated model ({ABSORB_MM:g} mm, {ABSORB_DEG:g} deg): the "
                                 "poses are of a TCP, not the flange; record them with the TCP at zero", column="x")
    reading = _reading(model, joints, f2b)
    raise DatasetError(file, f"{said}; after a constant transform at the base and at the flange up to "
                             f"{found.left_mm:.1f} mm / {found.left_deg:.2f} deg still depend on the pose (the gate: "
                             f"{AGREE_MM:g} mm / {AGREE_DEG:g} deg): " + _named(model, joints, f2b, reading, others),
                       column="[robot] model" if reading is None else "x" if reading[0] in LENGTH_UNITS.values()
                       else "j1")


def _candidates(joints):
    """``(what, angles)`` of the readings a user's slip makes: radians, each column's sign, the
    columns in another order (fewest moved first)."""
    if np.all(np.abs(joints) <= 2 * np.pi + 1e-9):
        yield "radians", np.degrees(joints)
    for k in range(6):
        flipped = joints.copy()
        flipped[:, k] *= -1
        yield f"sign j{k + 1}", flipped
    orders = sorted(itertools.permutations(range(6)), key=lambda p: sum(a != b for a, b in enumerate(p)))
    for order in orders[1:]:
        yield "order " + ",".join(f"j{k + 1}" for k in order), joints[:, list(order)]


def _reading(model, joints, f2b):
    """The first slip under which the model agrees: the positions in another length
    (:data:`~handeye.model.chain.conventions.LENGTH_UNITS`: poses in metres with their joints once were blamed on
    the model), then the joints' (:func:`_candidates`); ``(what, Constants)`` or None."""
    joints, f2b = joints[:SEARCH_POSES], f2b[:SEARCH_POSES]
    fk = model.flange2base(joints)
    for factor, unit in LENGTH_UNITS.items():
        scaled = f2b.copy()
        scaled[:, :3, 3] *= factor
        found = constants(fk, scaled)
        if found.agrees():
            return unit, found
    for what, angles in _candidates(joints):
        found = constants(model.flange2base(angles), f2b)
        if found.agrees():
            return what, found
    return None


def _named(model, joints, f2b, reading, others):
    """What makes the model agree (``reading``, of :func:`_reading`), said; else the other built-in
    models tried, and the advice."""
    if reading is not None:
        what, fit = reading
        left = f"({fit.left_mm:.2g} mm / {fit.left_deg:.2g} deg left)"
        if what in LENGTH_UNITS.values():
            factor = next(f for f, unit in LENGTH_UNITS.items() if unit == what)
            return f"read in {what} (x {factor:g}) the positions agree {left}: write x, y, z in mm"
        if what == "radians":
            return f"read as radians the joint angles agree {left}: write j1..j6 in degrees"
        if what.startswith("sign"):
            return (f"with the sign of {what[5:]} reversed the joint angles agree {left}: the {what[5:]} column has "
                    "the other sign than the model's joint (write it as the controller's, or fix the model's axis)")
        return (f"the joint columns are in another order: with the model's j1..j6 read from the file's columns "
                f"{what[6:]} they agree {left}: write j1..j6 in the robot's order")
    for spec, other in (others() if callable(others) else others):
        if other.name != model.name and constants(other.flange2base(joints), f2b).agrees():
            return f"the built-in {spec} model ({other.name}) reproduces them: a wrong [robot] model"
    return ("a wrong [robot] model (no built-in model, no reading of the angles in radians, with one sign reversed "
            "or in another column order reproduces them), or poses that are not of the flange")
