"""``handeye calibrate --method kim-cho|li-two-step``: the closed-form baselines on a dataset.

Gross errors are screened first, exactly as ``calibrate`` does (robust pass and deletion
tests, :func:`handeye.app.engine.robust.screen`; ``--keep-all`` skips it), then the closed-form method of
:mod:`handeye.model.fit.classics` runs on the samples kept. The estimate is reported beside what the
nonlinear least squares makes of the same samples when started from it (distance,
iterations), so a user sees at once how far the linear method is from the least-squares
optimum. No uncertainty: these are baselines, and the report says so.

A baseline's verdict is the data's own (:func:`judged`): its plain chain is the model of the default
calibration, so where that calibration refuses the data, or its search chooses another model (a sensor
scale, a wrong radius, the robot's errors) or cannot vouch for the baseline: a baseline has no sd, so it is
right only within 0.2 mm / 0.05 deg of the truth (the issue's "away from the truth" with no sd), and the
truth lies within 3 sd of the data's own calibration -- the baseline's distance from it plus 3 of its sd
must stay within that floor. Otherwise the baseline is refused (exit 1), naming why; the tool never exits 0
with an answer its own calibration of the same data cannot vouch for.
"""
from __future__ import annotations

import dataclasses
import time

import numpy as np

from handeye.app.common.choices import CLASSIC_METHODS as METHODS  # noqa: F401 - defined without numpy
from handeye.app.common.errors import CalibrationInputError
from handeye.app.engine import robust, set_aside, slips
from handeye.app.engine.levels import AWAY, AWAY_SD  # the verdict's levels, one place
from handeye.app.engine.prepare import resolve_start, with_sphere_centre
from handeye.app.engine.robust import ALPHA
from handeye.app.present.residual_table import SampleResidual
from handeye.app.present.result_parts import FitRecord, ScreeningRecord, cleaning_summary
from handeye.app.present.results import CalibrationResult, ClosedFormDetails
from handeye.model.chain import conventions
from handeye.model.chain.pose import pose_from_transform, transform_from_pose
from handeye.model.common.rotation import pose_distance, pose_sd, transform_distance
from handeye.model.fit import classics
from handeye.model.fit.calibration import CalibrationModel


def estimate(method, flange2base, centre_in_sensor, sphere_centre=None):
    """Run one closed-form method; ``sphere_centre`` None lets Li et al. estimate it."""
    if method == "kim-cho":
        return classics.kim_cho(flange2base, centre_in_sensor)
    if method == "li-two-step":
        return classics.li_two_step(flange2base, centre_in_sensor, sphere_centre)
    raise CalibrationInputError(f"unknown closed-form method {method!r}; choose one of {', '.join(METHODS)}")


def judged(result, own):
    """The closed-form ``result`` under the verdict of ``own``, the default calibration of the same data and
    unknowns (module docstring): refused where ``own`` is, where ``own`` names catalogue effects, or where the
    truth may lie beyond :data:`AWAY` of the baseline (its distance from ``own`` plus :data:`AWAY_SD` of ``own``'s
    sd); else ``result`` with a line saying where the data's own calibration lies from it."""
    if not own.converged:
        return result.refused(f"not a calibration: the data's own calibration (nonlinear least squares, searched) "
                              f"refuses these data: {own.message}")
    named = [e.name for e in own.effects or [] if e.name != "sign_flip"]
    if named:
        return result.refused(f"not a calibration: the data choose the model with {', '.join(named)} (the default "
                              "calibration's search names it); a closed-form baseline fits the plain chain, "
                              "which these data contradict")
    d = pose_distance(np.asarray(result.sensor2flange, float), np.asarray(own.sensor2flange, float), own.covariance,
                      own.parameter_names)
    far = f"{d['translation_mm']:.3g} mm / {d['rotation_deg']:.3g} deg" + (
        "" if d["sd"] is None else f", {d['sd']:.3g} of its sd (Mahalanobis)")
    reach = _reach(d, own.covariance)
    if reach is None or reach[0] > AWAY[0] or reach[1] > AWAY[1]:
        return result.refused(f"not a calibration: the data's own calibration (the default, searched: the plain chain) "
                              f"lies {far} from this baseline; with {AWAY_SD:g} of its sd the truth may lie "
                              + ("an unknown distance" if reach is None else f"{reach[0]:.3g} mm / {reach[1]:.3g} deg")
                              + f" from it, beyond the {AWAY[0]:g} mm / {AWAY[1]:g} deg a baseline with no sd of its own "
                              "may miss; calibrate without --method gives the calibration")
    return dataclasses.replace(result, warnings=[*result.warnings, (
        f"the data's own calibration (the default, searched: the plain chain) lies {far} from this baseline")])


def _reach(distance, covariance):
    """How far (mm, deg) the truth may lie from the baseline: its distance from the data's own calibration
    plus :data:`AWAY_SD` of that calibration's sd (the length of the per-axis sd vector); None without one."""
    sd = pose_sd(covariance)
    if sd is None or not all(np.all(np.isfinite(s)) for s in sd):
        return None
    return (distance["translation_mm"] + AWAY_SD * float(np.linalg.norm(sd[0])),
            distance["rotation_deg"] + AWAY_SD * float(np.linalg.norm(sd[1])))


def calibrate_classic(dataset, method, unknowns="sensor", outliers=True, alpha=ALPHA, convention=None):
    """A closed-form method on ``dataset``, as a :class:`handeye.app.present.results.CalibrationResult`.

    ``unknowns='sensor+sphere'`` does not use the dataset's sphere centre: Kim & Cho never
    need it (the centre is then the mean of the predicted centres), Li et al. estimate it in
    step 2. ``outliers`` screens gross errors first (module docstring). Raises
    CalibrationInputError naming the file when the motions the method needs are missing.
    The result has ``status`` None (no solver ran), no uncertainty and no leave-one-out
    error; ``closed_form`` holds the linear solution and where the least squares goes from it.
    """
    convention = conventions.check(convention or dataset.convention)
    dataset, centre_note = with_sphere_centre(dataset, unknowns)
    slips.check(dataset, unknowns, slips.plain_rms(dataset, unknowns) or 0.0)
    f2b_all, xs_all = dataset.motions(), dataset.centre_in_sensor
    known = None if unknowns == "sensor+sphere" else np.asarray(dataset.sphere_centre, float)
    mask, excluded = np.ones(len(xs_all), bool), []
    if outliers:
        start = transform_from_pose(resolve_start(dataset, unknowns)[0])
        screening = robust.screen(dataset, unknowns, start, alpha=alpha)
        mask, excluded = screening.inliers, screening.excluded
    mask, excluded = set_aside.exclude_inconsistent(dataset, unknowns, mask, excluded)  # as calibrate and diagnose
    excluded = set_aside.with_geometry(dataset, excluded)
    f2b, xs = f2b_all[mask], xs_all[mask]
    classics.axxb_system(np.eye(4)[None], p=np.zeros((1, 3)), q=np.zeros((1, 3)))  # load the generated code untimed
    t0 = time.perf_counter()
    try:
        est = estimate(method, f2b, xs, known)
    except classics.MissingMotions as exc:
        raise CalibrationInputError(f"{dataset.path / 'measurements.csv'}: {exc}"
                                    + (f" ({len(excluded)} sample(s) excluded as gross errors)" if excluded else "")
                                    ) from None
    elapsed = time.perf_counter() - t0
    rot, trans = est.sensor2flange[:3, :3], est.sensor2flange[:3, 3]
    predicted = np.einsum("nij,jk,nk->ni", f2b_all[:, :3, :3], rot, xs_all) + f2b_all[:, :3, :3] @ trans \
        + f2b_all[:, :3, 3]
    centre = known if known is not None else (est.sphere_centre if est.sphere_centre is not None
                                              else predicted[mask].mean(axis=0))
    e = predicted - centre
    norms = np.linalg.norm(e, axis=1)
    model = CalibrationModel(f2b, xs, centre, "local", "sensor" if known is not None else "sensor+sphere")
    refined = robust.least_squares(model, model.point_from(est.sensor2flange, centre))
    dt, dr = transform_distance(model.sensor2flange(refined.x), est.sensor2flange)
    warnings = ["closed-form baseline: no uncertainty estimate"
                + ("" if outliers else "; every sample used (--keep-all: no outlier screening)")]
    if centre_note:
        warnings.append(centre_note)
    if est.details.get("orthogonality_error", 0) > 0.01:
        warnings.append(f"the linear solution's rotation block was {est.details['orthogonality_error']:.3g} from "
                        "orthogonal (|R^T R - I|) before projection onto SO(3)")
    fit = FitRecord(
        sensor2flange=est.sensor2flange, sensor_pose_kuka=pose_from_transform(est.sensor2flange),
        sensor_pose=conventions.pose_from(convention, est.sensor2flange), sphere_centre=np.asarray(centre, float),
        converged=True, status=None, message="closed-form estimate (no iterations)",
        n_used=int(mask.sum()), rms_mm=float(np.sqrt(np.mean(norms[mask] ** 2))),
        max_residual_mm=float(norms[mask].max()), cost_mm2=float(0.5 * np.sum(norms[mask] ** 2)),
        residuals=[SampleResidual(i, int(r), v, float(n), bool(u))
                   for i, r, v, n, u in zip(dataset.ids, dataset.rows, e, norms, mask)])
    return CalibrationResult(
        dataset=dataset.name, dataset_path=str(dataset.path), dataset_sha256=dataset.content_hash(),
        method=method, unknowns=unknowns, convention=convention, columns=conventions.columns(convention),
        fit=fit, screening=ScreeningRecord(list(excluded)), warnings=warnings, cleaning=cleaning_summary(dataset),
        closed_form=ClosedFormDetails(
            linear_matrix=est.linear, details=est.details, time_ms=elapsed * 1e3,
            least_squares_from_here={"distance_mm": float(dt), "distance_deg": float(dr),
                                     "iterations": int(refined.iterations), "converged": bool(refined.converged),
                                     "rms_mm": float(np.sqrt(2 * refined.cost / len(xs)))}),
    )
