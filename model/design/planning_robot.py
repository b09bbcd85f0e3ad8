"""Which poses, in which joint configurations, make the robot's own errors identifiable, and how many.

``handeye plan --robot MODEL --effects joint_offsets[,link_lengths,joint_compliance]``. The cell
is the seed's (sensor on the flange, sphere fixed in the robot base, centre ``c``); the robot's
errors (:mod:`handeye.model.robot.robot_errors`) move the flange from the reported ``F_i = T(q_i)`` to
``T*(q_i)``, so that the centre residual of the extended model (:mod:`handeye.model.fit.extended`) is

    e_i = T*(q_i) X xs_i - c,        xs_i = (T(q_i) X)^-1 c   (the nominal cell),

``X`` the sensor pose on the flange. Its Jacobian at zero errors has the calibration's local
chart (sensor translation mm, rotation rad about the sensor's axes, centre mm:
:class:`~handeye.model.fit.calibration.CalibrationModel`) and one column per robot parameter (per
degree of a joint offset, mm of a length, degree per metre of a compliance:
:func:`handeye.model.robot.robot_errors.perturbed`, exact). With a stated isotropic noise ``sigma`` (mm
per component of a sphere centre through the chain) a candidate's Fisher information is
``J_i^T J_i / sigma^2``.

Candidates in joint space
-------------------------
Each candidate flange pose is reached by the nominal inverse kinematics
(:func:`handeye.model.simulation.simulate_robot.inverse_kinematics`; a pose it cannot reach is dropped and
named). Where the other wrist reaches the same flange pose -- started from ``j4 + 180, -j5,
j6 + 180`` (exact for a spherical wrist, refined by the same damped least squares otherwise) and
converged within the IK's tolerance to other joint angles -- it is a candidate of its own, id
``<id>~flip``: a robot parameter's effect on the flange depends on the configuration.

Identifiability and how many
----------------------------
A robot parameter that the WHOLE candidate set cannot separate from the sensor pose, the sphere
centre and the parameters before it is dropped and named with what absorbs it -- the gate of
:func:`handeye.model.design.robot_gate.robot_free` (:func:`handeye.model.fit.extended.gate`,
:data:`~handeye.model.fit.extended.JOINT_GATE`, and its 1 sd beside them at the stated noise within
:data:`~handeye.model.design.robot_gate.WEAKEST`), on every candidate: a first-joint offset turns the
base (the centre absorbs it), a last-joint offset turns the flange (the sensor's rotation), a
length along the last axis moves the flange (the sensor's translation). The same gate on the
chosen poses alone says what ``calibrate --effects`` would not estimate on them (a warning).
The D-optimal choice (:func:`handeye.model.design.planning.select`) runs on the rest.

The number of poses it takes is the smallest ``n`` whose D-optimal plan predicts every kept robot
parameter's 1-sd (Cramer-Rao, ``(sum F_i)^-1``) at or below its target (:data:`DEFAULT_TARGETS`),
and that keeps as many residual degrees of freedom as parameters (:data:`DOF_PER_PARAMETER`):
bracketed on the greedy chain (nested, so its sds only fall) from the least ``n`` with full-rank
information, then confirmed with the exchanges of the D-optimal plan. The sum over all
candidates bounds what any subset can reach: when even it misses a target, no ``n`` does, and
the plan says so. The sphere centre is estimated with the rest (``calibrate --unknowns
sensor+sphere --effects ...``): a centre known independently makes the sds smaller (a
shoulder offset trades with it). The predicted sds agree with Monte Carlo
fits at the stated isotropic noise within about 15 % (tests/test_plan_robot.py).
"""
from __future__ import annotations

import dataclasses

import numpy as np

from handeye.model.chain.pose import pose_from_transform, transform_from_pose
from handeye.model.design import planning, robot_gate
from handeye.model.design.planning import PlanningError
from handeye.model.fit import extended
from handeye.model.fit.calibration import CalibrationModel
from handeye.model.robot import robot_errors
from handeye.model.simulation import simulate, simulate_robot

#: 1-sd a plan aims at per robot effect: degrees, mm, degrees per metre.
DEFAULT_TARGETS = {"joint_offsets": 0.01, "link_lengths": 0.05, "joint_compliance": 0.005}
UNITS = robot_gate.UNITS
#: The calibration's parameters besides the robot's (local chart: mm, rad, mm).
BASE_NAMES = ("tx", "ty", "tz", "wx", "wy", "wz", "cx", "cy", "cz")
#: Id suffix of a candidate in the other wrist configuration.
FLIP = "~flip"
#: Smallest eigenvalue of the correlation form of the information that counts as full rank.
FULL_RANK = 1e-10
#: Residual degrees of freedom a plan keeps per parameter (``3 n - p >= p``): enough to estimate
#: the noise and test the fit; on the UR10e's 5 poses that reach the default target (13
#: parameters) handeye diagnose names no effect, on 9 it names the hidden joint offsets.
DOF_PER_PARAMETER = 1.0


@dataclasses.dataclass(frozen=True)
class Reached:
    """Candidates in joint space: flange poses (N, 4, 4), joint angles (N, 6, degrees), ids, and the
    poses the robot cannot reach ``[(id, reason)]``; ``flips`` of them are the other wrist."""

    ids: list
    flanges: np.ndarray
    joints: np.ndarray
    unreachable: list
    flips: int


def other_wrist(joints):
    """The other wrist's seed (N, 6): ``j4 + 180, -j5, j6 + 180`` (degrees, wrapped)."""
    out = np.array(joints, float)
    out[:, 3] += 180.0
    out[:, 4] *= -1.0
    out[:, 5] += 180.0
    return simulate_robot._wrap(out)


def reach(model, model_name, ids, flanges, wrists=True, joints=None):
    """Joint angles of the candidate flange poses (``flanges`` (N, 4, 4), mm) by the nominal inverse
    kinematics (or the ``joints`` given, degrees), and with ``wrists`` the other wrist as candidates
    of their own (module docstring)."""
    if joints is None:
        joints, ok = simulate_robot.inverse_kinematics(model, flanges, model_name)
    else:  # the configurations given: their nominal flange poses
        joints, ok, flanges = np.asarray(joints, float), np.ones(len(ids), bool), model.flange2base(joints)
    unreachable = [(i, f"the {model.name} cannot reach this flange pose (no inverse kinematics solution within "
                       f"{simulate_robot.TOL_MM:g} mm / {simulate_robot.TOL_DEG:g} deg)") for i, k in zip(ids, ok) if not k]
    ids, flanges, joints = [i for i, k in zip(ids, ok) if k], flanges[ok], joints[ok]
    if not wrists or not len(ids):
        return Reached(ids, flanges, joints, unreachable, 0)
    q = simulate_robot._wrap(simulate_robot._levenberg_marquardt(model, flanges, other_wrist(joints))[0])
    err = simulate_robot.pose_error(flanges, model.flange2base(q))
    apart = np.abs(simulate_robot._wrap(q[:, None] - joints[None])).max(axis=2).min(axis=1) > 1e-3  # a new one
    good = (np.linalg.norm(err[:, :3], axis=1) < simulate_robot.TOL_MM) & \
           (np.linalg.norm(err[:, 3:], axis=1) < simulate_robot.TOL_DEG) & apart
    return Reached(ids + [f"{i}{FLIP}" for i, g in zip(ids, good) if g], np.concatenate([flanges, flanges[good]]),
                   np.concatenate([joints, q[good]]), unreachable, int(good.sum()))


def jacobian(model, joints, flanges, sensor2flange, centre, effects):
    """The centre residual's Jacobian at the nominal cell (module docstring).

    Parameters
    ----------
    model : handeye.model.robot.robots.RobotModel
    joints : ndarray, shape (N, 6)
        Reported joint angles, degrees.
    flanges : ndarray, shape (N, 4, 4)
        ``T(q)``, robot base, mm.
    sensor2flange : ndarray, shape (4, 4)
        Nominal sensor pose on the flange, mm.
    centre : array_like, shape (3,)
        Nominal sphere centre in the robot base, mm.
    effects : sequence of str
        Robot effects (:data:`~handeye.model.robot.robot_errors.NAMES`).

    Returns
    -------
    jac : ndarray, shape (N, 3, 9 + k)
        Per mm and rad of the sensor (local chart), mm of the centre, unit of each robot parameter.
    names : list of str
        :data:`BASE_NAMES`, then ``effect.parameter``.
    """
    centre = np.asarray(centre, float)
    home = np.append(centre, 1.0)
    xs = np.einsum("nij,j->ni", np.linalg.inv(flanges @ sensor2flange), home)[:, :3]
    calib = CalibrationModel(flanges, xs, centre, "local", "sensor+sphere")
    _, jac = calib.residual_and_jacobian(calib.point_from(sensor2flange, centre))
    _, derivatives = robot_errors.perturbed(model, joints, {e: np.zeros(len(robot_errors.param_names(model, e)))
                                                            for e in effects})
    in_flange = np.einsum("nij,j->ni", np.linalg.inv(flanges), home)[:, :3]
    cols = [extended._moved_centre(derivatives[e], in_flange) for e in effects]
    names = list(BASE_NAMES) + [f"{e}.{p}" for e in effects for p in robot_errors.param_names(model, e)]
    return np.concatenate([jac] + cols, axis=2), names


def identifiable(jac, names, sigma=None):
    """The columns the poses of ``jac`` (N, 3, p) separate: the sensor and the centre, and each
    robot parameter gated (:func:`handeye.model.fit.extended.gate`) against them and the robot
    parameters kept before it, and with ``sigma`` (mm) its 1 sd beside them held to
    :data:`~handeye.model.design.robot_gate.WEAKEST`, as :func:`handeye.model.design.robot_gate.robot_free` does.

    Returns
    -------
    keep : list of int
        Column indices kept.
    dropped : dict
        ``effect.parameter`` -> the names that absorb it (strongest first), or ``['1 sd <value>
        <unit>']`` for one too weakly seen.
    """
    flat = jac.reshape(-1, jac.shape[2])
    base = len(BASE_NAMES)
    keep, kept_names, dropped = list(range(base)), list(names[:base]), {}
    for k in range(base, len(names)):
        col, effect = flat[:, k:k + 1], names[k].split(".")[0]
        frac, who = extended.gate(flat[:, keep], col, kept_names)
        if not np.all(np.isfinite(col)) or frac < extended.JOINT_GATE:
            dropped[names[k]] = who
            continue
        sd = np.inf if sigma is None else robot_gate._alone_sd(flat[:, keep], col, sigma)
        if sigma is not None and sd > robot_gate.WEAKEST[effect]:
            dropped[names[k]] = [f"1 sd {sd:.3g} {UNITS[effect]}"]
            continue
        keep.append(k)
        kept_names.append(names[k])
    return keep, dropped


def full_rank(info):
    """Whether ``info`` (p, p) is positive definite after scaling to unit diagonal."""
    d = np.sqrt(np.diag(info))
    if not np.all(d > 0):
        return False
    return bool(np.linalg.eigvalsh(info / np.outer(d, d))[0] > FULL_RANK)


def report_sd(info):
    """1-sd (p,) of the information ``info`` (p, p) in report units: the sensor's rotation in
    degrees, everything else as the chart's (mm, and the robot parameters' own units)."""
    sd = np.sqrt(np.diag(np.linalg.inv(info)))
    sd[3:6] = np.degrees(sd[3:6])
    return sd


def _meets(info, chosen, robot, limits):
    """Whether the poses ``chosen`` give full rank and every robot sd at or below its limit."""
    total = info[chosen].sum(axis=0)
    return full_rank(total) and bool(np.all(report_sd(total)[robot] <= limits))


def _first(low, high, good):
    """The least n in [low, high] with ``good(n)`` for a ``good`` that never turns False again
    above (galloping up from ``low``, then bisection); None when ``good(high)`` is False."""
    top, step = low, 1
    while not good(top):
        if top >= high:
            return None
        low, top, step = top + 1, min(high, top + step), 2 * step
    while low < top:
        mid = (low + top) // 2
        low, top = (low, mid) if good(mid) else (mid + 1, top)
    return top


def how_many(info, robot, limits, floor=0):
    """How many poses it takes: ``(least, targets, needed)``.

    ``least`` is the least number of poses whose plan has full rank; ``targets`` the least whose
    D-optimal plan meets the ``limits`` (report units) of the columns ``robot``; ``needed`` the
    least at or above ``floor`` that does (both None when even all candidates miss). Bracketed on
    the greedy chain (:func:`handeye.model.design.planning.select` without exchanges: nested sets,
    information only growing), then confirmed on the D-optimal plans with exchanges, stepping down
    while a smaller one still meets the limits and up until one does."""
    total, p = len(info), info.shape[1]

    def chain(n):
        return planning.select(info, n, exchange=False)[0]

    def meets(n):
        return _meets(info, planning.select(info, n)[0], robot, limits)

    least = _first(-(-p // 3), total, lambda n: full_rank(info[chain(n)].sum(axis=0)))
    if least is None:
        raise PlanningError("the candidates do not determine the sensor pose and the sphere centre (identical or "
                            "only translated poses?)")
    n = _first(least, total, lambda n: _meets(info, chain(n), robot, limits))
    if n is None:
        return least, None, None
    while n > least and meets(n - 1):
        n -= 1
    while n < total and not meets(n):
        n += 1
    needed = max(n, min(floor, total))
    while needed < total and not meets(needed):
        needed += 1
    return least, n, needed


def visible(ids, flanges, setup, centre):
    """Which candidates' laser plane cuts the sphere with enough of the profile in range (as the
    simulator sees it, :func:`handeye.model.simulation.simulate.profile_points`): ``(mask (N,), [(id, reason)])``."""
    quiet = dataclasses.replace(setup, sigma_point=0.0, linearity=0.0)
    sensor = flanges @ transform_from_pose(setup.sensor_pose)
    in_sensor = np.einsum("nij,j->ni", np.linalg.inv(sensor), np.append(np.asarray(centre, float), 1.0))[:, :3]
    mask, skipped = np.ones(len(ids), bool), []
    for k, (ident, xs) in enumerate(zip(ids, in_sensor)):
        try:
            simulate.profile_points(xs, setup.diameter / 2, quiet, np.random.default_rng(0))
        except simulate.SimulationError as exc:
            mask[k] = False
            skipped.append((ident, str(exc)))
    return mask, skipped


def absorbed_why(absorbers):
    """Why a parameter is left out, in words: ``['cy', 'cx']`` -> 'absorbed by cy, cx: the sphere
    centre'; a weak one's ``['1 sd 0.2 deg']`` -> 'too weakly seen: 1 sd 0.2 deg ...'."""
    if len(absorbers) == 1 and absorbers[0].startswith("1 sd "):
        return f"too weakly seen: {absorbers[0]} beside the others at the stated noise"
    groups = [("the sphere centre", "c"), ("the sensor's rotation", "w"), ("the sensor's translation", "t")]
    words = [text for text, first in groups if any(len(a) == 2 and a[0] == first for a in absorbers)]
    words += [a for a in absorbers if "." in a]
    return f"absorbed by {', '.join(absorbers)}: " + (" and ".join(words) if words else "the other parameters")


@dataclasses.dataclass(frozen=True)
class RobotPlan:
    """A plan for the robot's effects (:func:`identify`, then :func:`choose`).

    Attributes
    ----------
    model : str
        ``[robot] model`` (a built-in name or a model file).
    effects : tuple of str
    sigma_mm : float
        Stated noise per component of a sphere centre, mm.
    targets : dict
        Effect -> 1-sd aimed at (:data:`UNITS`).
    ids : list of str
    poses : ndarray, shape (n, 6)
        Flange poses, KUKA (mm, degrees).
    joints : ndarray, shape (n, 6)
        Their joint angles j1..j6, degrees.
    logdet : float
    names : list of str
        The parameters estimated: :data:`BASE_NAMES`, then ``effect.parameter`` of the kept ones.
    sd : ndarray
        Their predicted 1-sd (report units: :func:`report_sd`) with these poses.
    best_sd : ndarray
        The same with every usable candidate: the least any plan of them can reach.
    dropped : dict
        ``effect.parameter`` not identifiable on the candidates -> what absorbs it.
    n_min : int
        Least number of poses with full-rank information.
    n_targets : int or None
        Least number of poses whose plan meets the targets; None when no plan of these candidates does.
    n_needed : int or None
        The same at or above ``ceil(2 p / 3)`` (:data:`DOF_PER_PARAMETER`): the poses it takes.
    skipped : list of (str, str)
        Candidates that cannot see the sphere or cannot be reached, with the reason.
    unreachable, flips, usable : int
        Candidates the robot cannot reach; candidates in the other wrist; usable candidates in all.
    warnings : tuple of str
    """

    model: str
    effects: tuple
    sigma_mm: float
    targets: dict
    ids: list
    poses: np.ndarray
    joints: np.ndarray
    logdet: float
    names: list
    sd: np.ndarray
    best_sd: np.ndarray
    dropped: dict
    n_min: int
    n_targets: int | None
    n_needed: int | None
    skipped: list
    unreachable: int
    flips: int
    usable: int
    warnings: tuple = ()

    @property
    def reached(self):
        """Whether these poses meet every target."""
        return bool(all(self.sd[k] <= self.targets[n.split(".")[0]] for k, n in self._robot()))

    def _robot(self):
        return [(k, n) for k, n in enumerate(self.names) if "." in n]

    def robot_sd(self, sd=None):
        """Effect -> {parameter: 1-sd} (:data:`UNITS`) of ``sd`` (default :attr:`sd`)."""
        sd = self.sd if sd is None else sd
        out = {e: {} for e in self.effects}
        for k, name in self._robot():
            effect, param = name.split(".", 1)
            out[effect][param] = float(sd[k])
        return out

    def to_dict(self):
        """The ``robot`` object of ``handeye plan --json``."""
        return {"model": self.model, "effects": list(self.effects), "sigma_mm": self.sigma_mm,
                "targets": dict(self.targets), "units": {e: UNITS[e] for e in self.effects},
                "predicted_sd": {"sensor_translation_mm": self.sd[:3].tolist(),
                                 "sensor_rotation_deg": self.sd[3:6].tolist(), "sphere_centre_mm": self.sd[6:9].tolist(),
                                 **self.robot_sd()},
                "best_sd": self.robot_sd(self.best_sd),
                "not_identifiable": [{"parameter": name, "absorbed_by": list(who), "why": absorbed_why(who)}
                                     for name, who in self.dropped.items()],
                "n_min": self.n_min, "n_targets": self.n_targets, "n_needed": self.n_needed, "target_reached": self.reached,
                "targets_reachable": self.n_needed is not None,
                "candidates": {"usable": self.usable, "other_wrist": self.flips, "unreachable": self.unreachable}}


def _worst(sd, names, targets, robot):
    """``'joint_offsets.j2 0.0123 deg > 0.01'`` for each robot parameter of ``sd`` above its target."""
    out = []
    for k in robot:
        effect = names[k].split(".")[0]
        if sd[k] > targets[effect]:
            out.append(f"{names[k]} {sd[k]:.3g} {UNITS[effect]} > {targets[effect]:g}")
    return "; ".join(out)


def _warnings(made, jac, chosen, floor, score=False):
    """What the plan ``made`` (a :class:`RobotPlan`) misses: targets out of reach, a given n too small (for the
    targets, or for a residual that can test the fit: ``floor``), parameters calibrate would not estimate on
    the chosen poses alone (``jac`` of every usable candidate, ``chosen`` their indices)."""
    names, sd, best, targets, needed, sigma = made.names, made.sd, made.best_sd, made.targets, made.n_needed, made.sigma_mm
    robot = [k for k, n in enumerate(names) if "." in n]
    out = []
    if needed is None and score:
        out.append(f"these {len(chosen)} poses miss the targets ({_worst(sd, names, targets, robot)})")
    elif needed is None:
        out.append(f"the targets are not reached even with all {len(jac)} usable candidates "
                   f"({_worst(best, names, targets, robot)}): relax --target, state a smaller --sigma, or give "
                   "candidates that move these joints more (--candidates); without --n every usable one is planned")
    elif _worst(sd, names, targets, robot):
        out.append(f"these {len(chosen)} poses miss the targets ({_worst(sd, names, targets, robot)}): "
                   f"{needed} poses reach them")
    if len(chosen) < floor:
        out.append(f"{len(chosen)} poses leave {3 * len(chosen) - len(names)} degrees of freedom for the residual of "
                   f"{len(names)} parameters: too few to estimate the noise and test the fit (handeye diagnose); "
                   f"plan at least {floor}")
    _, dropped = identifiable(jac[chosen], names, sigma)
    if dropped:
        out.append("on these poses alone calibrate --effects would not estimate "
                   + "; ".join(f"{p} ({absorbed_why(w)})" for p, w in dropped.items()))
    return tuple(out)


@dataclasses.dataclass(frozen=True)
class PlanAsk:
    """What a robot plan is asked.

    Attributes
    ----------
    setup : handeye.model.simulation.simulate.Setup
        Nominal sensor pose on the flange, sphere diameter and laser side.
    centre : array_like, shape (3,)
        Nominal sphere centre, robot base, mm.
    robot : handeye.model.simulation.simulate_robot.Robot
        The nominal model and its ``[robot] model`` name.
    effects : sequence of str
        Robot effects, :data:`~handeye.model.robot.robot_errors.NAMES` order.
    sigma : float
        Stated noise per component of a sphere centre, mm.
    targets : dict, optional
        Effect -> 1-sd aimed at (default :data:`DEFAULT_TARGETS`).
    score : bool
        Take every usable pose as given (no other wrist, no choice): ``handeye plan --score``.
    """

    setup: object
    centre: object
    robot: object
    effects: tuple
    sigma: float = 0.05
    targets: dict | None = None
    score: bool = False


@dataclasses.dataclass(frozen=True)
class Identified:
    """What the candidates identify (:func:`identify`), for :func:`choose`.

    Attributes
    ----------
    ask : PlanAsk
        As asked, its ``targets`` with the defaults filled in.
    reached : Reached
        The candidates that see the sphere, in joint space.
    skipped : list of (str, str)
        Candidates that cannot see the sphere, with the reason.
    jac : ndarray, shape (N, 3, p)
        Each reached candidate's Jacobian of the parameters kept (:func:`identifiable`).
    names, dropped
        The parameters kept (:data:`BASE_NAMES` first) and those left out (-> what absorbs them).
    info : ndarray, shape (N, p, p)
        Each candidate's information at the stated noise.
    least, by_targets, needed : int or None
        :func:`how_many`.
    floor : int
        Poses that leave a residual able to test the fit (:data:`DOF_PER_PARAMETER`).
    """

    ask: PlanAsk
    reached: Reached
    skipped: list
    jac: np.ndarray
    names: list
    dropped: dict
    info: np.ndarray
    least: int
    by_targets: int | None
    needed: int | None
    floor: int


def identify(candidates, ask):
    """What the :class:`~handeye.model.design.planning.Candidates` (KUKA flange poses, optionally their
    joints) can identify of the robot effects ``ask`` (:class:`PlanAsk`) names (module docstring): an
    :class:`Identified`, from which :func:`choose` chooses."""
    setup, centre, robot, effects = ask.setup, ask.centre, ask.robot, ask.effects
    ask = dataclasses.replace(ask, targets={e: DEFAULT_TARGETS[e] for e in effects} | dict(ask.targets or {}))
    flanges = transform_from_pose(np.asarray(candidates.flange_poses, float))
    seen, skipped = visible(candidates.ids, flanges, setup, centre)
    key = robot.model_key if robot.model_key in simulate_robot.SEEDS else None
    cand = reach(robot.model, key, [i for i, s in zip(candidates.ids, seen) if s], flanges[seen], not ask.score,
                 None if candidates.joints is None else np.asarray(candidates.joints, float)[seen])
    if not cand.ids:
        raise PlanningError(f"the {robot.model.name} reaches none of the {int(seen.sum())} candidate poses that see "
                            "the sphere: put the sphere (its centre) inside its workspace")
    jac, names = jacobian(robot.model, cand.joints, cand.flanges, transform_from_pose(setup.sensor_pose), centre, effects)
    keep, dropped = identifiable(jac, names, ask.sigma)
    jac, names = jac[:, :, keep], [names[k] for k in keep]
    info = np.einsum("nki,nkj->nij", jac, jac) / ask.sigma**2
    limits = np.array([ask.targets[name.split(".")[0]] for name in names[len(BASE_NAMES):]])
    floor = int(np.ceil((1.0 + DOF_PER_PARAMETER) * len(names) / 3))
    counts = how_many(info, np.arange(len(BASE_NAMES), len(names)), limits, floor)
    return Identified(ask, cand, skipped, jac, names, dropped, info, *counts, floor)


def choose(found, n):
    """The D-optimal ``n`` of the candidates :func:`identify` found (``n`` at least ``found.least``, at most
    every usable candidate): a :class:`RobotPlan`."""
    ask, cand, info = found.ask, found.reached, found.info
    chosen, value = planning.select(info, n)
    sd, best = report_sd(info[chosen].sum(axis=0)), report_sd(info.sum(axis=0))
    made = RobotPlan(ask.robot.model_key, tuple(ask.effects), float(ask.sigma), ask.targets,
                     [cand.ids[k] for k in chosen], pose_from_transform(cand.flanges[chosen]), cand.joints[chosen], value,
                     found.names, sd, best, found.dropped, found.least, found.by_targets, found.needed,
                     found.skipped + cand.unreachable, len(cand.unreachable), cand.flips, len(info), ())
    return dataclasses.replace(made, warnings=_warnings(made, found.jac, chosen, found.floor, ask.score))
