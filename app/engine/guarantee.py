"""The global guarantee: the pose calibrate reports is the lowest minimum of its objective.

A local solver ends in the basin it starts in. From a CAD start 5 mm / 1 deg off, the
measurement model of a planned 12-pose set has a second minimum 16 mm / 35 deg from the
truth (RMS 11 mm against 0.04 mm) that IPOPT reaches and reports as optimal. The centre
model's global minimum is known in closed form (:mod:`handeye.model.fit.global_fit`: one SVD
with the sphere centre known; a quadratic form in vec R, searched over a cover of SO(3),
with it free), and every residual model's minimum lies next to it on good data (they differ
by the noise). So:

1. the final fit is solved from the user's start *and* from each centre-model minimum the
   search found (the global one first), and the lowest cost of the final objective is kept
   (:func:`lowest`); the count of starts that reached it and the cost of the next distinct
   minimum are reported (:class:`GlobalCheck`, the JSON's ``global``);
2. with the centre known and the unweighted centre model, the SVD solution *is* the minimum:
   the reported pose is it, exactly (the solver's tolerance stops ~1e-7 mm short);
3. the reported pose is cross-checked against the centre model's global minimum on the same
   samples: a final fit whose centres scatter far more than at that minimum is a fit in
   the wrong basin -- reported as not converged, never as a result (:func:`cross_check`);
4. a fit that explains nothing -- the centre model's global minimum has an RMS above
   :data:`EXPLAINS_NOTHING` of the motion the sensor sees (:func:`motion_seen`, below) -- is
   not a calibration (:func:`explains_nothing`): the data, their pairing or their conventions
   are wrong, whatever the solver says; nor is one whose RMS exceeds the spread of the centres
   the sensor measured (the pose then predicts them no better than their mean). Both only
   when the residuals are also above the stated noise: a cell whose large noise is stated in
   ``[noise] centre_mm`` is noisy, not wrong.

The motion the sensor sees
--------------------------
Every mount is one chain ``M_i X xs_i = c`` (:mod:`handeye.model.chain.mounts`), and its residual
``e_i = M_i X xs_i - c`` has the length of ``xs_i - T_i^-1 c`` with ``T_i = M_i X``, the sensor
in the frame of the sphere's mount: the residual is a distance *in the sensor's view*, whatever
the mount. What a model has to explain is therefore how the robot moves the sensor's view
relative to the sphere, ``T_i``, and not the carrier motions' own translations: for a sensor
fixed in the cell ``M_i`` is the inverted flange pose, whose translation ``-R_i^T t_i`` swings
by the robot's whole reach as the flange turns (an independent tester's tour: 398 mm RMS where
the flange moved 48.7 mm; simulated tours: 250-360 mm where the sphere crossed the sensor's view
by 10-23 mm), and for the seed's cell the flange's position
says nothing of a sensor that turns about it. A rigid motion moves different points by
different amounts; the points that matter are those the sensor looks along, its line of sight
from its origin (``s = 0``) to the mean observed centre ``p`` (``s = 1``, in the sensor frame).
With ``u_i`` the deviation of ``T_i 0`` (the sensor's origin in the mount's frame) from its mean
and ``v_i`` that of ``T_i p``, the point ``s p`` deviates by ``(1 - s) u_i + s v_i`` and

    motion^2 = mean_i of the integral over s in [0, 1] of |(1 - s) u_i + s v_i|^2
             = mean_i (|u_i|^2 + u_i . v_i + |v_i|^2) / 3.

At ``s = 1`` it is the observed point's own motion relative to the sensor: with ``q_i = T_i^-1 c``
the centre the model puts in the sensor's view, ``T_i p = c + R_i (p - q_i)``, so ``|v_i|`` is of
the order of the spread of the centres the sensor sees (the sphere crossing its view). At
``s = 0`` it is the sensor turning about what it sees: rotations about the sphere (``handeye
simulate --motions about-sphere``, the sphere at one sensor point) move the observed point by
nothing, and a rule on that point alone would call any residual above the noise "nothing
explained" (``--translations 3 --robot kr60ha --effect joint_offsets=j3:0.05``: RMS 0.71 mm
against 5.3 mm of observed motion, 0.13, refused at 0.1 -- good data with a robot error the
search names); along the line of sight they move the view by the turn times the standoff (there
120 mm: 0.006). The measure is the same for every mount (``M_i`` is the mount's),
independent of the frames' origins (deviations from the mean), and needs no special case
where the flange only turns.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from handeye.app.engine.levels import (  # the verdict's levels, one place
    CROSS_CHECK_RATIO,
    CROSS_CHECK_SIGMAS,
    EXPLAINS_NOTHING,
    EXPLAINS_NOTHING_SENSOR,
    GROUP_AGREE,
    GROUP_APART_DEG,
    GROUP_APART_MM,
    NOISE_P,
)
from handeye.app.present.result_parts import AsDict
from handeye.model.chain import own_frame
from handeye.model.chain.pose import pose_from_transform
from handeye.model.common.rotation import transform_distance
from handeye.model.common.statistics import chi2_survival
from handeye.model.fit import global_fit

#: Two ends within this distance (mm, deg) or relative cost are the same minimum.
SAME_MM, SAME_DEG, SAME_COST = 1e-3, 1e-3, 1e-9
#: Centre-model minima (lowest first) that the final fit is also started from.
FINAL_STARTS = 2


@dataclasses.dataclass(frozen=True)
class GlobalCheck(AsDict):
    """How the reported minimum was established (the JSON's ``global``).

    Attributes
    ----------
    method : str
        How the centre model's global minimum was found, and that the final fit started there.
    starts : int
        Starts of the final fit (the user's or the closed-form start, and the centre model's
        minima).
    reached : int
        Starts that ended at the reported minimum.
    next_best_cost : float or None
        ``1/2 sum r^2`` of the final objective at the next distinct local minimum a start
        reached, or None when every start reached the reported one. In that objective's units:
        mm^2 for the unweighted centre model, dimensionless where the rows are whitened (the
        profile models; ``cost_mm2`` is always the centre residual's).
    centre_minima : int
        Distinct local minima of the centre model the search found (1 with the centre known:
        the SVD solution is the unique one).
    """

    method: str
    starts: int
    reached: int
    next_best_cost: float | None
    centre_minima: int = 1


def centre_basin(dataset, unknowns):
    """The centre model's local minima on ``dataset`` (known centre unless 'sensor+sphere'),
    or None when the data do not determine them (the caller's other checks name why)."""
    centre = None if unknowns == "sensor+sphere" else dataset.sphere_centre
    try:
        return global_fit.centre_minima(dataset.motions(), dataset.centre_in_sensor, centre)
    except global_fit.GlobalFitError:
        return None


def _cost(verdict):
    local = verdict.local
    return float(local.cost(local.point_from(verdict.sensor, verdict.centre)))


def _same(a, b):
    dt, dr = transform_distance(a.sensor, b.sensor)
    ca, cb = _cost(a), _cost(b)
    return (dt <= SAME_MM and dr <= SAME_DEG) or abs(ca - cb) <= SAME_COST * max(1.0, abs(ca))


def lowest(fit, basin, solve, exact_centre_model=False):
    """The lowest of the final fits from the user's start and the centre model's minima.

    Parameters
    ----------
    fit : handeye.app.engine.fitting.Verdict
        The final fit from the user's (or the closed-form) start.
    basin : handeye.model.fit.global_fit.CentreMinima or None
    solve : callable
        ``solve(sensor2flange, centre, exact=...) -> Verdict``: the final fit from a start
        (``exact``: ``exact_centre_model``).
    exact_centre_model : bool
        The final objective is the unweighted centre model with the centre known: the SVD
        solution is its minimum, reported exactly.

    Returns
    -------
    (verdict, note, GlobalCheck)
        The lowest fit, a sentence when it is not the one from the start (else None), and
        how the minimum was established.
    """
    if basin is None:
        return fit, None, GlobalCheck("none: the centre model's minimum is not determined by these data", 1, 1, None, 0)
    ends = [fit, *(solve(m.sensor2flange, m.centre, exact=exact_centre_model) for m in basin.minima[:FINAL_STARTS])]
    good = [e for e in ends if e.local is not None and e.converged]
    if not good:
        return fit, None, GlobalCheck(f"{basin.method}; no start of the final fit converged", len(ends), 0, None,
                                      len(basin.minima))
    best = min(good, key=_cost)
    if any(e is fit for e in good) and _same(fit, best):  # identity: verdicts hold arrays
        best = fit  # the run from the user's start, its iterations and history, reached it
    if exact_centre_model and any(e is ends[1] for e in good) and _same(best, ends[1]):
        best = dataclasses.replace(best, sensor=ends[1].sensor)  # the SVD minimum itself, exactly
    reached = [e for e in good if _same(e, best)]
    others = [_cost(e) for e in good if not _same(e, best)]
    note = None
    if fit.local is not None and not _same(fit, best):
        dt, dr = transform_distance(fit.sensor, best.sensor)
        note = (f"the fit from the start ended {dt:.3g} mm / {dr:.3g} deg from the reported pose, at cost {_cost(fit):.6g} "
                f"({'a local minimum' if fit.converged else 'not converged'}); the fit started from the centre model's "
                f"global minimum reaches cost {_cost(best):.6g} and is reported")
    k = min(FINAL_STARTS, len(basin.minima))
    return best, note, GlobalCheck(f"{basin.method}; the final fit started from the given (or closed-form) start and from "
                                   f"{k} centre-model minim{'um' if k == 1 else 'a'}, lowest cost kept",
                                   len(ends), len(reached), min(others) if others else None, len(basin.minima))


def cross_check(dataset, verdict, basin, sigma):
    """A message when the final fit's centres scatter far more than at the centre model's
    global minimum on the same samples (a wrong basin, never a result), else None."""
    if basin is None or verdict.local is None:
        return None
    cost = global_fit.centre_cost(dataset.motions(), dataset.centre_in_sensor, verdict.sensor, verdict.centre)
    rms_fit = float(np.sqrt(2 * cost / len(dataset)))
    rms_best = float(np.sqrt(2 * basin.best.cost / len(dataset)))
    if rms_fit <= CROSS_CHECK_RATIO * rms_best + CROSS_CHECK_SIGMAS * sigma:
        return None
    dt, dr = transform_distance(verdict.sensor, basin.best.sensor2flange)
    return (f"the final fit's sphere centres scatter with RMS {rms_fit:.4g} mm, the centre model's global minimum's "
            f"with {rms_best:.4g} mm on the same samples ({dt:.3g} mm / {dr:.3g} deg away): the fit ended in a wrong "
            "basin; not a calibration")


def motion_seen(dataset, sensor2flange, centre):
    """The motion the sensor sees (mm, module docstring): the RMS displacement, relative to the
    sphere's mount, of the sensor's line of sight from its origin to the mean observed centre.

    Parameters
    ----------
    dataset : handeye.model.datasets.dataset.Dataset
        Its carrier motions ``M_i`` (:meth:`~handeye.model.datasets.dataset.Dataset.motions`).
    sensor2flange : array_like, shape (4, 4)
        ``X``, the sensor in its mount's frame (mm).
    centre : array_like, shape (3,)
        ``c``, the sphere centre in its mount's frame (mm).
    """
    sight = np.asarray(dataset.motions()) @ np.asarray(sensor2flange, float)  # T_i: sensor in the sphere mount's frame
    rot, origin = sight[:, :3, :3], sight[:, :3, 3]
    seen = np.einsum("nba,nb->na", rot, np.asarray(centre, float) - origin)  # T_i^-1 c, sensor frame
    point = np.einsum("nab,b->na", rot, seen.mean(axis=0)) + origin
    u, v = origin - origin.mean(axis=0), point - point.mean(axis=0)
    return float(np.sqrt(np.mean(np.sum(u * u + u * v + v * v, axis=1)) / 3.0))


def explains_nothing(dataset, basin, sigma):
    """A message when even the centre model's global minimum leaves residuals above
    :data:`EXPLAINS_NOTHING` of the motion the sensor sees (:func:`motion_seen`; or above the spread of the sensor's
    centres) *and* above the stated noise ``sigma`` (mm per component; chi-square at
    :data:`NOISE_P`: a cell whose large noise is stated is not refused), else None."""
    if basin is None:
        return None
    rms = float(np.sqrt(2 * basin.best.cost / len(dataset)))
    dof = 3 * len(dataset) - 6
    if dof <= 0 or chi2_survival(2 * basin.best.cost / sigma**2, dof) >= NOISE_P:
        return None
    motion = motion_seen(dataset, basin.best.sensor2flange, basin.best.centre)
    p = dataset.centre_in_sensor
    spread = float(np.sqrt(np.mean(np.sum((p - p.mean(axis=0)) ** 2, axis=1))))
    if rms > EXPLAINS_NOTHING * motion:
        than = (f"more than {EXPLAINS_NOTHING:g} x the motion the sensor sees ({motion:.4g} mm RMS: its line of sight, "
                "from its origin to the sphere, moved relative to the sphere's mount)")
    elif rms > EXPLAINS_NOTHING_SENSOR * spread:
        than = (f"more than the spread of the centres the sensor measured ({spread:.4g} mm RMS about their mean): the "
                "pose predicts them no better than their mean does")
    else:
        return None
    pose = pose_from_transform(own_frame.to_own(basin.best.sensor2flange, getattr(dataset, "own_axes", None)))
    return (f"the fit explains nothing: even the best sensor pose of the centre model ({', '.join(f'{v:.1f}' for v in pose)}, "
            f"KUKA) leaves an RMS residual of {rms:.4g} mm, {than}: the poses, their convention or their pairing with "
            "the sensor's centres, or the sphere centre are wrong; not a calibration")


def two_groups(dataset, mask, verdict, sigma):
    """A message when the rows the screening excluded (at least four) agree with each other on
    a sensor pose far from the reported one, else None.

    Gross errors scatter; rows that share a slip the others do not (a convention or sign slip
    in some rows, another setup's rows) agree with each other. When such rows are many enough,
    the robust screening may keep the wrong group -- a negated C angle, for instance, leaves
    the rows with C = 0 as they were and turns the others by 180 deg, and the screening kept
    the turned ones, 320 mm off, with exit 0. The excluded rows are fitted alone (centre model,
    the reported sphere centre, its exact global minimum): if they fit as well as the used rows
    (or the stated noise) at a pose far from the reported one, the data hold two calibrations
    and neither is reported.
    """
    used = np.asarray(mask, bool)
    excluded = ~used
    if verdict.local is None or excluded.sum() < 4:
        return None
    f2b, p = dataset.motions(), dataset.centre_in_sensor
    try:
        other = global_fit.centre_minima(f2b[excluded], p[excluded], verdict.centre).best
    except global_fit.GlobalFitError:
        return None
    rms_used = float(np.sqrt(2 * global_fit.centre_cost(f2b[used], p[used], verdict.sensor, verdict.centre) / used.sum()))
    rms_other = float(np.sqrt(2 * other.cost / excluded.sum()))
    dt, dr = transform_distance(other.sensor2flange, verdict.sensor)
    if rms_other > GROUP_AGREE * max(rms_used, np.sqrt(3) * sigma) or (dt <= GROUP_APART_MM and dr <= GROUP_APART_DEG):
        return None
    rows = [r for r, e in zip(dataset.rows, excluded) if e]
    return (f"the {len(rows)} rows the screening excluded (rows {', '.join(map(str, rows[:12]))}"
            f"{' ...' if len(rows) > 12 else ''}) are no gross errors: alone they fit each other with RMS {rms_other:.3g} mm "
            f"(the used rows {rms_used:.3g} mm) at a sensor pose {dt:.3g} mm / {dr:.3g} deg from the reported one. The data "
            "hold two calibrations -- a slip in some rows (a sign, a convention, another setup's rows?); not a calibration")

