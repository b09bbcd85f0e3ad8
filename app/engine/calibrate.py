"""One calibration run as explicit stages: dataset in, checked, solved, verified, described.

Stage map (each stage a function of its typed input record; nothing here prints)::

    CalibrationRequest.checked    (request.py)   every option validated once, defaults resolved
      -> prepare                  (prepare.py)   Prepared: dataset with a sphere centre, the final
                                                 model of every sample and the plain centre model
                                                 (each built once), the start, the centre
                                                 model's global minima, structural identifiability
      -> screen                                  Screened: the plain fit of every sample (Before),
                                                 setup and convention slips (slips.py,
                                                 detective.py: exit 2), gross errors and rows
                                                 that contradict their own profile excluded
                                                 (robust.py; with --effects judged on the
                                                 centres corrected by a robust fit of the
                                                 effects), a taught centre the pose would
                                                 absorb (exit 2)
      -> fit                      (fitting.py)   Verdict: the final fit from the start, judged on
                                                 the local chart; the closed form restarts a start
                                                 that does not converge
      -> verify                   (guarantee.py) Verified: the lowest of the final fits from the
                                                 start and the centre model's minima; a wrong
                                                 basin, a fit that explains nothing, two groups
                                                 of samples: refused (exit 1 with the evidence)
      -> describe                 (describe.py)  CalibrationResult: residuals, uncertainty,
                                                 identifiability, leave-one-out, effect tests

The stages hand over frozen records, so each can be run and tested on its own:
``calibrate(dataset, **keywords)`` is ``run(CalibrationRequest(**keywords).checked(dataset),
dataset)``, and :func:`run` is the five calls above.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from handeye.app.engine import (
    bend,
    cell_stage,
    configuration_group,
    describe,
    effect_screen,
    guarantee,
    positioner_effect,
    robust,
    search,
    set_aside,
    slips,
    taught_sphere,
)
from handeye.app.engine.fitting import FinalFit, closed_form_pose
from handeye.app.engine.prepare import prepare
from handeye.app.engine.request import METHODS, SUPPORTED, CalibrationRequest  # noqa: F401  (METHODS, SUPPORTED: public here too)
from handeye.app.present.result_parts import cleaning_summary
from handeye.app.present.results import Before
from handeye.model.chain import own_frame
from handeye.model.chain.pose import transform_from_pose
from handeye.model.fit.closed_form import ClosedFormError

#: Within this many degrees of B = +-90 the Euler angles A and C are nearly one rotation.
GIMBAL_WARN_DEG = 1.0


@dataclasses.dataclass(frozen=True)
class Screened:
    """The samples the final fit uses.

    Attributes
    ----------
    before : handeye.app.present.results.Before
        The plain fit of every sample.
    mask : ndarray of bool, shape (N,)
        Samples kept.
    excluded : list of handeye.app.present.results.ExcludedSample
    used : handeye.model.datasets.dataset.Dataset
        The samples kept.
    warnings : tuple of str
    """

    before: Before
    mask: np.ndarray
    excluded: list
    used: object
    warnings: tuple


@dataclasses.dataclass(frozen=True)
class Verified:
    """The reported fit and how it was established.

    Attributes
    ----------
    fit : handeye.app.engine.fitting.Verdict
    start_used : str
    global_check : handeye.app.engine.guarantee.GlobalCheck
    refusal : str or None
        Why the fit is not a calibration (exit 1), or None.
    warnings : tuple of str
    """

    fit: object
    start_used: str
    global_check: object
    refusal: str | None
    warnings: tuple


def _plain(prep):
    """The plain fit of every sample: its RMS (mm) and leave-one-out RMS (None without ``loo``), after
    the setup slips it would show are named (exit 2)."""
    everything, basin = prep.everything, prep.basin
    plain_start = (everything.point_from(transform_from_pose(prep.start_pose)) if basin is None
                   else everything.point_from(basin.best.sensor2flange, basin.best.centre))
    plain = robust.least_squares(everything, plain_start).x
    plain_rms = float(np.sqrt(np.mean(np.sum(everything.residuals(plain) ** 2, axis=1))))
    slips.check(prep.dataset, prep.request.unknowns, plain_rms)  # side, units: named (exit 2), never calibrated
    return plain_rms, describe.rms(robust.leave_one_out(everything, plain)) if prep.request.loo else None


def screen(prep):
    """The plain fit of every sample, slips named (exit 2) and gross errors excluded."""
    request, dataset, unknowns = prep.request, prep.dataset, prep.request.unknowns
    key = ("plain", unknowns, prep.kind, tuple(prep.start_pose), request.sigma, request.robot_sigma, request.loo)
    plain_rms, loo = dataset.once(key, lambda: _plain(prep))  # the search's refit asks again: the same answer
    taught_sphere.check_radius(dataset, unknowns, request.sigma, request.effects)  # a wrong diameter the pose would absorb
    if unknowns == "sensor":  # a taught centre the pose would absorb (diagnose names it as an effect instead)
        taught_sphere.check_centre(dataset, request.sigma, request.effects)
    before = Before(len(dataset), plain_rms, loo)
    excluded, mask, warnings = [], np.ones(len(dataset), bool), []
    if request.outliers:
        start = transform_from_pose(prep.start_pose)
        screening = (effect_screen.screen_with_effects(dataset, unknowns, start, request.effects, alpha=request.alpha)
                     if request.effects else robust.screen(dataset, unknowns, start, alpha=request.alpha))
        mask, excluded = screening.inliers, screening.excluded
        warnings += [screening.note] if screening.note else []
    mask, excluded = set_aside.exclude_inconsistent(dataset, unknowns, mask, excluded)  # rows contradicting themselves
    excluded = set_aside.with_geometry(dataset, excluded)  # a profile's arc that explains its poor centre, named
    used = dataset.subset(mask)
    if unknowns == "sensor" and used is not dataset:  # (every sample kept: checked above already)
        taught_sphere.check_centre(used, request.sigma, request.effects)  # a taught centre the pose would absorb: named (exit 2)
    return Screened(before, mask, list(excluded), used, tuple(warnings))


def fit(prep, screened):
    """The final fit from the start (the closed form when that does not converge):
    (:class:`FinalFit`, verdict, where the start came from, warnings)."""
    final = FinalFit(screened.used, prep.observed.samples(screened.mask), prep.request, prep.kind)
    verdict, start_used, warnings = final.solve(prep.start_pose), prep.start_used, []
    if verdict.converged or start_used.startswith("closed-form"):
        return final, verdict, start_used, warnings
    try:
        retry = final.solve(closed_form_pose(screened.used, prep.request.unknowns))
    except ClosedFormError as exc:
        warnings.append(f"the start did not converge and no closed-form restart is possible: {exc}")
        return final, verdict, start_used, warnings
    if retry.converged:
        warnings.append(f"the start ({start_used}) did not converge ({verdict.message}); restarted from the "
                        "closed-form estimate")
        return final, retry, "closed-form estimate (after the given start failed)", warnings
    return final, verdict, start_used, warnings


def verify(prep, screened, final, verdict, start_used):
    """The lowest final fit over the start and the centre model's minima, and a refusal (a
    wrong basin, a fit that explains nothing, two groups of samples) or None
    (:mod:`handeye.app.engine.guarantee`)."""
    used, request = screened.used, prep.request
    basin = prep.basin if used is prep.dataset else guarantee.centre_basin(used, request.unknowns)  # every sample kept: known
    exact = prep.kind == "centre" and request.unknowns == "sensor" and verdict.local is not None \
        and verdict.local.whiten is None
    best, note, check = guarantee.lowest(verdict, basin, final.from_minimum, exact_centre_model=exact)
    if note:
        best = dataclasses.replace(best, notes=[*best.notes, note])
    refusal = guarantee.explains_nothing(used, basin, request.sigma) or (  # a fit that did not converge says so itself
        guarantee.cross_check(used, best, basin, request.sigma) if best.converged else None)
    group = configuration_group.deferred(prep.dataset, screened.mask, request)  # the search judges it
    refusal = refusal or (None if group else guarantee.two_groups(prep.dataset, screened.mask, best, request.sigma))
    warnings = list(best.notes)
    pose = describe.kuka_pose(own_frame.to_own(best.sensor, getattr(prep.dataset, "own_axes", None)))  # as reported
    if abs(abs(pose[4]) - 90.0) < GIMBAL_WARN_DEG:
        warnings.append(f"B = {pose[4]:.4f} deg is within {GIMBAL_WARN_DEG:g} deg of the Euler singularity: A and C "
                        "are nearly one rotation and are not separately meaningful; compare transforms, not angles")
    return Verified(best, start_used, check, refusal, tuple(warnings))


def run(request, dataset):
    """The stages (module docstring) of a checked request on a dataset.

    Parameters
    ----------
    request : handeye.app.engine.request.CalibrationRequest
        Checked (:meth:`~handeye.app.engine.request.CalibrationRequest.checked`).
    dataset : handeye.model.datasets.dataset.Dataset

    Returns
    -------
    handeye.app.present.results.CalibrationResult
    """
    if request.resolved is None:
        raise ValueError("run() takes a checked request: CalibrationRequest(...).checked(dataset)")
    request.checked(dataset)  # a request checked against other data is refused (ValueError)
    result = cell_stage.extend(request, dataset, stages) if request.cell else stages(request, dataset)
    result = search.chosen(request, dataset, result, _refit)
    result = positioner_effect.with_positioner_hint(result, dataset, request.parts, request.alpha)
    result = search.unexplained(result, dataset, request)  # residuals beyond a stated noise: structure, exit 1
    result = bend.with_bend(result, dataset)  # a corrected depth bend's uncertainty in the pose's sd
    result = dataclasses.replace(result, cleaning=cleaning_summary(dataset))  # what the profiles lost, reported
    return cell_stage.with_mount_plausibility(result, dataset)


def _refit(asked, dataset):
    """The requested model's fit of another (unchecked) request: the stages, and the cell stage where its parts
    need it (the search's model with the positioner's axes: fitted together)."""
    checked = asked.checked(dataset)
    return cell_stage.extend(checked, dataset, stages) if checked.cell else stages(checked, dataset)


def stages(request, dataset):
    """prepare -> screen -> fit -> verify -> describe on a checked request's (conditional)
    unknowns: the requested model's fit, before the search (:mod:`handeye.app.engine.search`)
    checks it or chooses another -- for studies of the fit itself."""
    prep = prepare(request, dataset)
    screened = screen(prep)
    final, verdict, start_used, warnings = fit(prep, screened)
    verified = verify(prep, screened, final, verdict, start_used)
    return describe.result(prep, screened, verified, warnings)


def calibrate(dataset, **keywords):
    """Calibrate the sensor pose on the flange from a dataset.

    The engine of :func:`handeye.calibrate` (which takes the CLI's option names); this
    function takes the checked values of :class:`~handeye.app.engine.request.CalibrationRequest`'s
    fields as keywords (``unknowns``, ``method``, ``rotation``, ``start`` (KUKA pose),
    ``options``, ``outliers``, ``alpha``, ``loo``, ``model``, ``robot_sigma``, ``convention``,
    ``sigma``, ``effects``).

    Parameters
    ----------
    dataset : handeye.model.datasets.dataset.Dataset
    **keywords
        Fields of :class:`~handeye.app.engine.request.CalibrationRequest`.

    Returns
    -------
    handeye.app.present.results.CalibrationResult
        Complete on every path: after a numerical failure the fields that need a finite
        solution (residual statistics, covariance, identifiability, leave-one-out) are None
        and the poses NaN.
    """
    return run(CalibrationRequest(**keywords).checked(dataset), dataset)
