"""Which of a robot effect's parameters these samples can estimate (the identifiability gate of
the robot effects, :mod:`handeye.model.robot.robot_errors`).

Each parameter's Jacobian column (of the sphere centres through the chain, at a fit) is gated
one at a time, in the model's order, against the sensor pose, the sphere centre (free or not: a
first-joint offset is a turn of the base, which a centre given wrong looks like), the effects
already in the model and the parameters chosen before it: it must keep
:data:`~handeye.model.fit.extended.JOINT_GATE` of its size outside their span
(:func:`handeye.model.fit.extended.gate`), and its 1 sd at the stated noise must stay below
:data:`WEAKEST`. What is left out is reported with what absorbs it; what no pose set can separate
(:func:`handeye.model.robot.robot_errors.always_absorbed`) is recorded in ``Samples.robot_always``.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from handeye.model import effects
from handeye.model.datasets import observations
from handeye.model.fit import extended
from handeye.model.fit.extended import (
    GATE,
    JOINT_GATE,
    candidate_columns,
    candidate_rows,
    gate,
    score_test_robust,
)
from handeye.model.robot import robot_errors

#: A robot parameter whose 1 sd on these samples (at the stated noise, given the sensor pose, the
#: centre and the parameters chosen before it) exceeds this is too weakly seen to estimate: a
#: column that passes the gate in direction may still be tiny (a last-joint offset with the sphere
#: held on the flange axis). Units: degrees, mm, degrees per metre.
WEAKEST = {"joint_offsets": 0.1, "link_lengths": 1.0, "joint_compliance": 0.05}
#: How a robot effect's parameters are measured (for the messages).
UNITS = {"joint_offsets": "deg", "link_lengths": "mm", "joint_compliance": "deg/m"}


def _alone_sd(current, col, sigma):
    """1 sd of one more parameter of column ``col`` (m, 1) beside the columns ``current`` (m, p)."""
    coef, *_ = np.linalg.lstsq(current, col, rcond=None)
    perp = float(np.linalg.norm(col - current @ coef))
    return sigma / perp if perp > 0 else np.inf


def robot_free(prob, structure, fit, mask, name="joint_offsets"):
    """Choose the parameters robot effect ``name`` estimates on these samples: each parameter's
    column gated against the sensor pose, the sphere centre (free or not: a first-joint offset is a
    turn of the base, which a centre given wrong looks like), the effects in ``structure`` and the
    parameters chosen before it, and its 1 sd at the stated noise against :data:`WEAKEST`. Sets
    ``prob.robot_free[name]``; returns ``{parameter: absorbers}`` of the parameters left out (a
    weak one: ``['1 sd <value> <unit>']``)."""
    prob.robot_free.pop(name, None)
    all_names = effects.get(name).params(prob.d.robot_model)
    cols = candidate_rows(prob, structure, fit, None, name)[mask]  # (m, 3, k)
    current = fit.jac[mask].reshape(-1, fit.p)
    names = list(fit.names)
    if not structure.centre:
        current = np.concatenate([current, -np.tile(np.eye(3), (int(mask.sum()), 1))], axis=1)
        names += ["cx", "cy", "cz"]
    free, absorbed = [], {}
    always = robot_errors.always_absorbed(prob.d.robot_model, name)
    prob.robot_always |= {f"{name}.{param}" for param in always}
    for k, param in enumerate(all_names):
        col = cols[:, :, k].reshape(-1, 1)
        frac, who = gate(current, col, names)
        if not np.all(np.isfinite(col)) or frac < JOINT_GATE:
            absorbed[param] = who
            continue
        sd = _alone_sd(current, col, prob.sigma)
        if sd > WEAKEST[name]:
            absorbed[param] = [f"1 sd {sd:.3g} {UNITS[name]}"]
            continue
        free.append(k)
        current = np.concatenate([current, col], axis=1)
        names.append(f"{name}.{param}")
    prob.robot_free[name] = tuple(free)
    return absorbed


def gate_robot_effects(prob, structure, mask, sensor2flange, centre=None):
    """Choose the parameters of every robot effect in ``structure`` (:func:`robot_free`), each
    against the sensor pose, the centre and the effects before it, from a fit at
    ``sensor2flange`` (and ``centre``) without it. Returns ``{effect: {parameter: absorbers}}``
    of the parameters left out; an effect with none estimable has ``prob.robot_free[name] == ()``."""
    robot = [n for n in structure.data_effects if effects.get(n).KIND == "robot"]
    left_out = {}
    for k, name in enumerate(robot):
        base = dataclasses.replace(structure, data_effects=tuple(n for n in structure.data_effects if n not in robot[k:]))
        with np.errstate(all="ignore"):
            fit = prob.fit(base, mask, prob.point(base, sensor2flange, centre))
        left_out[name] = robot_free(prob, base, fit, mask, name)
    return left_out


def robot_scores(prob, structure, fit, mask):
    """The robust score tests (:func:`handeye.model.fit.extended.score_test_robust`) of the robot
    effects the dataset can show and ``structure`` lacks, each with its parameters gated first:
    ``[(p, name, statistic, gate)]`` for :func:`handeye.model.fit.extended.score_effects`'s ``robot``."""
    out = []
    if fit.jac is None:
        return out
    jac_cur = fit.jac[mask].reshape(-1, fit.p)
    for effect in effects.catalogue("robot"):
        name = effect.NAME
        if not effect.available(prob.d) or name in structure.data_effects:
            continue
        robot_free(prob, structure, fit, mask, name)
        if not prob.robot_free[name]:
            continue
        cols = candidate_columns(prob, structure, fit, mask, name)
        if not np.all(np.isfinite(cols)):
            continue
        frac, _ = gate(jac_cur, cols, fit.names, absorbers=False)
        if frac >= GATE:
            stat, p = score_test_robust(fit, mask, cols)
            out.append((p, name, stat, frac))
    return out


def score_effects(dataset, mask, sensor2flange, centre, unknowns="sensor", skip=()):
    """:func:`handeye.model.fit.extended.score_effects` with the robot effects: those among ``skip``
    (``--effects``) fitted with only the parameters the samples separate, the others tested."""
    mask = np.asarray(mask, bool)
    held = extended.Structure(centre=unknowns == "sensor+sphere", data_effects=tuple(skip))
    prob = extended.Samples(dataset, metric=observations.centre_metric(dataset, sensor2flange, centre, mask,
                                                                       9 if held.centre else 6))
    if any(effects.get(n).KIND == "robot" for n in skip):
        gate_robot_effects(prob, held, mask, sensor2flange, centre if held.centre else None)
    return extended.score_effects(dataset, extended.Calibrated(mask, sensor2flange, centre, unknowns), skip,
                                  robot=robot_scores, prob=prob)
