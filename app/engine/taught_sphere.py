"""What the setup says of the sphere, checked against the data: a taught centre (``[sphere] center``) or a
diameter (``[sphere] diameter``) the sensor pose would absorb is named (exit 2), never calibrated around.

Both follow the slips' rule (:mod:`handeye.app.engine.slips`): where the plain fit is worse than the stated
noise, the model with the setup's value free is the alternative, named when it fits significantly better
(F test at :data:`~handeye.app.engine.levels.P_SLIP`), fits within the stated noise (it alone explains the
misfit) and moves the sensor pose by more than :data:`~handeye.app.engine.levels.SIDE_MOVE_SD` of its own
standard deviations; an effect the user calibrates (``--effects``) or another of as many parameters that fits
clearly better is an explanation too, and then nothing is named.
"""
from __future__ import annotations

import dataclasses
import itertools

import numpy as np

from handeye.app.common.errors import CalibrationInputError
from handeye.app.engine import slips
from handeye.app.engine.levels import AMBIGUOUS, P_SLIP, P_SUSPECT, SIDE_MOVE_SD
from handeye.model import effects as catalogue
from handeye.model.common.rotation import chart_shift, pose_distance, transform_distance
from handeye.model.common.statistics import chi2_survival, f_survival
from handeye.model.datasets import observations
from handeye.model.design import robot_gate
from handeye.model.fit import extended, global_fit


def _mahalanobis(dataset, given, other):
    """Distance of the pose of ``other`` from that of ``given`` (centre-model minima) in the
    standard deviations of ``given``'s pose (:func:`handeye.app.engine.slips.pose_covariance`)."""
    a, b = given.sensor2flange, other.sensor2flange
    delta = chart_shift(b, a)
    return float(np.sqrt(delta @ np.linalg.solve(slips.pose_covariance(dataset, "sensor", given), delta)))


def _effects_keep_centre(dataset, effects, given, sigma):
    """Whether the calibrated ``effects`` (``--effects``) explain the misfit with the given centre:
    the extended model with it fits within the stated noise (chi-square at :data:`P_SUSPECT`), and
    freeing the centre beside the effects gains nothing significant (F test at :data:`P_SLIP`).
    A robot's length error or gravity sag can look like a centre offset to the centre model."""
    prob, mask = extended.Samples(dataset, sigma), np.ones(len(dataset), bool)
    held = extended.Structure(centre=False, data_effects=tuple(effects))
    robot_gate.gate_robot_effects(prob, held, mask, given.sensor2flange)
    free = dataclasses.replace(held, centre=True)
    with np.errstate(all="ignore"):
        a = prob.fit(held, mask, prob.point(held, given.sensor2flange))
        b = prob.fit(free, mask, prob.point(free, prob.transform(a.x), dataset.sphere_centre), a.params)
    if not (np.isfinite(a.ssr) and np.isfinite(b.ssr)) or a.m - a.p <= 0 or b.m - b.p <= 0:
        return False
    f = (a.ssr - b.ssr) / 3 / max(b.ssr / (b.m - b.p), 1e-300)
    return chi2_survival(a.ssr / prob.sigma**2, a.m - a.p) >= P_SUSPECT and (f <= 0 or f_survival(f, 3, b.m - b.p) >= P_SLIP)


def _robot_alternative(dataset, effects, given, sigma):
    """The robot effects not asked for (``--effects``) that explain the misfit at the given centre
    as well (:func:`_effects_keep_centre`), joined for ``--effects``; None without joint angles or
    when they do not."""
    robot = [e.NAME for e in catalogue.catalogue("robot") if e.available(dataset) and e.NAME not in effects]
    for k in range(1, len(robot) + 1):  # the fewest first
        for names in itertools.combinations(robot, k):
            if _effects_keep_centre(dataset, tuple(effects) + names, given, sigma):
                return ",".join(names)
    return None


def check_centre(dataset, sigma=None, effects=()):
    """Raise :class:`CalibrationInputError` when the given ``[sphere] center`` contradicts the
    data beyond the pose's own uncertainty.

    A sphere centre taught a millimetre off is absorbed by the sensor pose where the poses
    cut the sphere at one depth (a planned 2-inch cell: 1 mm off in z moved the pose 8 mm,
    17 sd, at an RMS of 0.13 mm, exit 0). When the fit with the given centre is worse than the
    stated noise (chi-square at :data:`P_SUSPECT`), the centre model's global minimum with the
    centre free is the alternative: it is named when it fits significantly better (F test on
    the three extra parameters, p below :data:`P_SLIP`), fits within the stated noise (the
    centre alone explains the misfit) *and* moves the sensor pose by more than
    :data:`SIDE_MOVE_SD` of its standard deviations (Mahalanobis distance). Where freeing the
    centre leaves the residuals above the stated noise, other effects are at work
    (thesis-real: 5.6 mm falls to 0.56 mm, still ten times the stated 0.05 mm), and the
    warnings point to ``handeye diagnose``, which names them. With ``effects`` (``--effects``) the
    centre is not named when the model with them explains the misfit at the given centre
    (:func:`_effects_keep_centre`).
    """
    n = len(dataset)
    sigma = dataset.noise_centre_mm if sigma is None else float(sigma)  # the stated noise (--sigma)
    if dataset.sphere_centre is None or 3 * n - 9 <= 3:
        return
    f2b, p = dataset.motions(), dataset.centre_in_sensor
    try:
        given = global_fit.centre_minima(f2b, p, dataset.sphere_centre).best
        if chi2_survival(2 * given.cost / sigma**2, 3 * n - 6) >= P_SUSPECT:
            return
        free = global_fit.centre_minima(f2b, p, None).best
    except global_fit.GlobalFitError:
        return
    dof = 3 * n - 9
    f = (given.cost - free.cost) / 3 / max(free.cost / dof, 1e-300)
    if f <= 0 or f_survival(f, 3, dof) >= P_SLIP:
        return
    if chi2_survival(2 * free.cost / sigma**2, dof) < P_SUSPECT:
        return  # the centre does not explain the misfit alone: other effects, for diagnose to name
    moved = _mahalanobis(dataset, given, free)
    if moved <= SIDE_MOVE_SD or (effects and _effects_keep_centre(dataset, effects, given, sigma)):
        return
    robot = _robot_alternative(dataset, effects, given, sigma)
    dt, dr = transform_distance(given.sensor2flange, free.sensor2flange)
    shift = free.centre - dataset.sphere_centre
    raise CalibrationInputError(
        f"{dataset.path / 'setup.toml'}, column '[sphere] center': the data put the sphere centre at "
        f"({', '.join(f'{v:.2f}' for v in free.centre)}) mm, ({', '.join(f'{v:+.2f}' for v in shift)}) mm from the "
        f"given one; with the centre free the centre model's RMS falls from {np.sqrt(2 * given.cost / n):.3g} to "
        f"{np.sqrt(2 * free.cost / n):.3g} mm, the stated noise, and the sensor pose moves {dt:.3g} mm / {dr:.3g} deg, "
        f"{moved:.3g} sd (Mahalanobis): the given centre is off and the pose would absorb it"
        + (f" -- or the robot's own errors are: with {robot} the given centre fits within the stated noise. "
           f"handeye diagnose tests both; then correct [sphere] center, or calibrate with --effects {robot}"
           if robot else ". Correct [sphere] center, or calibrate with --unknowns sensor+sphere"))


def _rival(prob, held, plain, radius, mask):
    """The catalogue's first data effect of as many parameters as ``sphere_radius`` that the samples clearly
    prefer to the radius (``radius``, the fit with it; ``plain`` without: its start), or None. Equal-size
    models: the lower SSR is the lower BIC, so "clearly" is a BIC lower by
    :data:`~handeye.app.engine.levels.AMBIGUOUS` (Kass & Raftery's "strong"; in units of the residual variance),
    its value physical. A line scanner's ``sensor_scale`` is, to first order, a ``sphere_radius`` of R s plus a
    ``centre_scale``: where its second part shows, profiles scaled by the sensor are no wrong diameter; where
    it does not (the centres seen in one spot), the two cannot be told apart, and the slip is named as before."""
    unit = radius.ssr / max(radius.m - radius.p, 1)
    size = len(catalogue.get("sphere_radius").PARAMS)
    for effect in catalogue.catalogue():
        if effect.KIND != "data" or effect.NAME == "sphere_radius" or len(effect.PARAMS) != size:
            continue
        trial = dataclasses.replace(held, data_effects=(effect.NAME,))
        with np.errstate(all="ignore"):
            other = prob.fit(trial, mask, plain.x)
        if (np.isfinite(other.ssr) and other.ssr <= radius.ssr - AMBIGUOUS * unit
                and catalogue.implausible(effect.NAME, other.params[effect.NAME], prob.radius) is None):
            return effect.NAME
    return None


def check_radius(dataset, unknowns="sensor", sigma=None, effects=()):
    """Raise :class:`CalibrationInputError` when ``[sphere] diameter`` contradicts the data beyond
    the pose's own uncertainty.

    A centre reconstructed from a profile puts it ``sqrt(R^2 - r^2)`` from the laser plane: a
    wrong R moves every centre along the sensor's y by an amount that depends on the cut, and the
    pose absorbs part of it (a 30 mm sphere given as 50.8 mm: 16.7 mm off at exit 0; given as
    30.5 mm: 0.67 mm off, two good samples excluded as gross errors). As for the centre
    (:func:`check_centre`): when the centre model is worse than the stated noise, the model with
    the radius free (the catalogue's ``sphere_radius``) is the alternative, named when it fits
    significantly better (F test on one parameter, p below :data:`P_SLIP`), fits within the
    stated noise (the radius alone explains the misfit), no other data effect of as many parameters
    fits clearly better (:func:`_rival`: a sensor's scale is no wrong diameter) and moves the pose by
    more than :data:`SIDE_MOVE_SD` of its standard deviations. Only centres reconstructed from profiles
    depend on R; with ``--effects sphere_radius`` the radius is calibrated instead. The F test and the
    pose's sd are taken in the centres' own metric (:func:`handeye.model.datasets.observations.centre_metric`:
    a centre rebuilt near the equator errs in y many times more than one near the pole, and the radius's
    column grows with the same ``r / y``): with equal weights a clean cell of 38 profile centres read its
    0.0359 mm robot noise as a diameter 0.075 mm off at F p < 1e-9 (exit 2, a false alarm); the misfit is
    still judged in mm against the stated noise.
    """
    if "sphere_radius" in effects or not any(dataset.reconstructed or ()) or unknowns not in ("sensor", "sensor+sphere"):
        return
    free_centre, n = unknowns == "sensor+sphere", len(dataset)
    sigma = dataset.noise_centre_mm if sigma is None else float(sigma)
    if not free_centre and dataset.sphere_centre is None:
        return
    try:
        given = global_fit.centre_minima(dataset.motions(), dataset.centre_in_sensor,
                                         None if free_centre else dataset.sphere_centre).best
    except global_fit.GlobalFitError:
        return
    if 3 * n - 7 - 3 * free_centre <= 0 or chi2_survival(2 * given.cost / sigma**2, 3 * n - 6 - 3 * free_centre) >= P_SUSPECT:
        return
    metric = observations.centre_metric(dataset, given.sensor2flange, given.centre, None, 6 + 3 * free_centre)
    prob, mask = extended.Samples(dataset, sigma, metric), np.ones(n, bool)
    held = extended.Structure(centre=free_centre)
    radius = dataclasses.replace(held, data_effects=("sphere_radius",))
    with np.errstate(all="ignore"):
        a = prob.fit(held, mask, prob.point(held, given.sensor2flange, given.centre))
        b = prob.fit(radius, mask, prob.point(radius, prob.transform(a.x), prob.centre(held, a.x)))
    if not (np.isfinite(a.ssr) and np.isfinite(b.ssr)) or b.m - b.p <= 0 or b.ssr <= 0:
        return
    f = (a.ssr - b.ssr) / (b.ssr / (b.m - b.p))  # in the centres' own metric: their noise is not equal
    raw = float(np.sum(prob.raw(b.e) ** 2))  # the misfit in mm, against the stated noise
    if f <= 0 or f_survival(f, 1, b.m - b.p) >= P_SLIP or chi2_survival(raw / sigma**2, b.m - b.p) < P_SUSPECT:
        return
    if _rival(prob, held, a, b, mask) is not None:
        return  # another effect of as many parameters explains the profiles clearly better: no slip to name
    jac = b.jac[mask].reshape(-1, b.p)
    cov = b.sigma2 * np.linalg.pinv(jac.T @ jac)
    moved = pose_distance(prob.transform(b.x), prob.transform(a.x), cov, b.names)
    if moved["sd"] <= SIDE_MOVE_SD:
        return
    k = b.names.index("sphere_radius.dr")
    dr, sd = float(b.params["sphere_radius"][0]), float(np.sqrt(max(cov[k, k], 0.0)))
    dt, da, moved = moved["translation_mm"], moved["rotation_deg"], moved["sd"]
    diameter, before = dataset.sphere_diameter, float(np.sum(prob.raw(a.e) ** 2))
    raise CalibrationInputError(
        f"{dataset.path / 'setup.toml'}, column '[sphere] diameter': the profiles put the sphere's diameter at "
        f"{diameter + 2 * dr:.3f} +- {2 * sd:.2g} mm, not the given {diameter:g} mm; with it the centre model's RMS falls "
        f"from {np.sqrt(before / n):.3g} to {np.sqrt(raw / n):.3g} mm, the stated noise, and the sensor pose moves "
        f"{dt:.3g} mm / {da:.3g} deg, {moved:.3g} sd (Mahalanobis): a wrong diameter (another sphere's? a radius? "
        "inches?) that the pose would absorb. Correct [sphere] diameter, or calibrate the radius with --effects "
        "sphere_radius (a sensor that sees every sphere smaller)")
