"""Screening with catalogue effects (``calibrate --effects``): judge each sample against the
model *with* the effects, so that an effect the plain centre model lacks does not make clean
samples look like gross errors. A robust preliminary fit of the extended model
(:mod:`handeye.model.fit.extended`) estimates the effects; the measured centres corrected by them
are screened as usual (:func:`handeye.app.engine.robust.screen`). A robot effect (joint offsets,
lengths, sag: joint angles given) corrects the flange poses instead, ``F_rep T(q)^-1 T*(q)``
(:meth:`handeye.model.fit.extended.Samples.robot_motion`), its parameters those the identifiability
gate lets the poses separate: without it a j5 offset made the poses with the wrist flipped look
like gross errors in the screening of the very fit that names the offset.)"""
from __future__ import annotations

import dataclasses

import numpy as np

from handeye.app.engine import robust
from handeye.model import effects as catalogue
from handeye.model.common.statistics import chi_median
from handeye.model.design.robot_gate import gate_robot_effects
from handeye.model.fit import extended
from handeye.model.fit.calibration import ROW_CHUNK, CalibrationModel
from handeye.model.fit.cell import corrected_centres


def robust_effects(dataset, unknowns, start, effects, max_rounds=50, prob=None):
    """The effects' parameters from a robust fit of the extended model (the pose with ``effects``).

    Cauchy IRLS as :func:`robust_fit`, started from the robust fit of the centre model (its
    point and weights, so that a gross error cannot pull the first round), on at most
    :data:`~handeye.model.fit.calibration.ROW_CHUNK` evenly spread samples.

    Parameters
    ----------
    dataset : handeye.model.datasets.dataset.Dataset
    unknowns : {'sensor', 'sensor+sphere'}
    start : ndarray, shape (4, 4)
        Start sensor pose (sensor in flange, mm).
    effects : sequence of str
        Data effects of the catalogue (:mod:`handeye.model.effects`), and robot effects (their
        parameters gated first: ``prob.robot_free``; an effect with none is left out).
    max_rounds : int
    prob : handeye.model.fit.extended.Samples, optional
        The samples' model (default a new one): a robot effect's gate is kept in it.

    Returns
    -------
    dict
        Effect name -> parameters.
    """
    rows = np.unique(np.linspace(0, len(dataset) - 1, min(len(dataset), ROW_CHUNK)).astype(int))
    plain = CalibrationModel.from_dataset(dataset.subset(np.isin(np.arange(len(dataset)), rows)), "local", unknowns)
    x, _, weights = robust.robust_fit(plain, plain.point_from(start))
    prob = prob or extended.Samples(dataset)
    structure = extended.Structure(centre=unknowns == "sensor+sphere", data_effects=tuple(effects))
    x = prob.point(structure, plain.sensor2flange(x), plain.sphere_centre(x))  # the one chain model's point
    if any(catalogue.get(n).KIND == "robot" for n in effects):
        with np.errstate(all="ignore"):
            gate_robot_effects(prob, structure, np.ones(len(dataset), bool), prob.transform(x), prob.centre(structure, x))
        structure = dataclasses.replace(structure, data_effects=tuple(
            n for n in effects if catalogue.get(n).KIND != "robot" or prob.robot_free[n]))
    params, med3 = None, chi_median(3)
    for _ in range(max_rounds):
        with np.errstate(all="ignore"):
            x, params, e = prob.weighted_fit(structure, rows, weights, x, params)
        norms = np.linalg.norm(e, axis=1)
        sigma = max(float(np.median(norms)) / med3, 1e-12)
        new = 1.0 / (1.0 + (norms / (robust.CAUCHY_K * sigma)) ** 2)
        change, weights = np.max(np.abs(new - weights)), new
        if not change >= 1e-6:  # converged (or non-finite: stop)
            break
    return params


def corrected(dataset, params):
    """The dataset with its measured centres corrected by the effects ``params`` (name ->
    parameters, :func:`handeye.model.fit.cell.corrected_centres`), or None where a correction is not finite."""
    with np.errstate(all="ignore"):
        xs = corrected_centres(dataset.centre_in_sensor, dataset.sphere_radius_mm, params)[0]
    if not np.all(np.isfinite(xs)):
        return None
    out = dataclasses.replace(dataset, centre_in_sensor=xs)
    if "_flange2base" in dataset.__dict__:  # computed already: the same poses
        out.__dict__["_flange2base"] = dataset.__dict__["_flange2base"]
    return out


def moved(dataset, prob, params):
    """The dataset with its carrier motions corrected by the robot effects ``params`` (name ->
    estimated parameters; :meth:`handeye.model.fit.extended.Samples.robot_motion`), or None where
    that is not finite."""
    if not params:
        return dataset
    with np.errstate(all="ignore"):
        motions = np.array(prob.robot_motion(params)[0])
    if not np.all(np.isfinite(motions)):
        return None
    out = dataclasses.replace(dataset)
    flange = motions if dataset.mounts.default else np.linalg.inv(motions)
    for key, value in (("_motions", motions), ("_flange2base", flange)):
        value.setflags(write=False)
        out.__dict__[key] = value
    return out


def screen_with_effects(dataset, unknowns, start, effects, alpha=robust.ALPHA, min_keep=None):
    """:func:`handeye.app.engine.robust.screen` against the model with the data effects ``effects``.

    A sample is judged on its centre corrected by the effects of a robust preliminary fit
    (:func:`robust_effects`): an effect the plain centre model lacks would otherwise make
    clean samples look like gross errors. Without effects (or when the correction is not
    finite) this is :func:`~handeye.app.engine.robust.screen` of ``dataset``.

    Parameters
    ----------
    dataset : handeye.model.datasets.dataset.Dataset
    unknowns : {'sensor', 'sensor+sphere'}
    start : ndarray, shape (4, 4)
    effects : sequence of str
    alpha : float
    min_keep : int, optional

    Returns
    -------
    Screening
    """
    robot = [e for e in effects if catalogue.get(e).KIND == "robot" and catalogue.get(e).available(dataset)]
    effects = [e for e in effects if catalogue.get(e).KIND == "data"]  # a robot effect moves poses, not centres
    fixed, prob = None, extended.Samples(dataset)
    if effects or robot:
        params = robust_effects(dataset, unknowns, start, effects + robot, prob=prob)
        fixed = corrected(dataset, {n: params[n] for n in effects})
        fixed = None if fixed is None else moved(fixed, prob, {n: params[n] for n in robot if n in params})
    return robust.screen(dataset if fixed is None else fixed, unknowns, start, alpha=alpha, min_keep=min_keep)
