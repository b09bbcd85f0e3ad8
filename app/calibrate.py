"""One calibration run: dataset in, checked, solved, reported as plain data.

The pipeline is: check the request (method and parametrisation fit together, enough
measurements), check that the robot poses determine every unknown (structural
identifiability, :func:`handeye.model.identifiability.structural`), solve with the chosen method,
and return a :class:`handeye.app.results.CalibrationResult`. Nothing here prints.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from handeye import solvers
from handeye.app import guarantee, robust, slips
from handeye.app.errors import CalibrationInputError
from handeye.app.problems import calibration_problem
from handeye.app.results import RMS_PER_CENTRE, Before, CalibrationResult, SampleResidual, Uncertainty
from handeye.app.robust import ALPHA
from handeye.model import conventions, identifiability, observations
from handeye.model.calibration import ROTATIONS, UNKNOWNS, CalibrationModel
from handeye.model.closed_form import ClosedFormError, closed_form_estimate
from handeye.model.dataset import GUESS_LIMITS, LIMIT_POSITION_MM
from handeye.model.pose import pose_from_transform, transform_from_pose
from handeye.model.rotation import nearest_transform, transform_distance
from handeye.model.statistics import covariance

METHODS = ("ipopt", "gn", "lm", "tr", "dogleg", "newton")

#: Which rotation parametrisations each method can use.
SUPPORTED = {
    "ipopt": ("matrix", "euler"),
    "gn": ("local", "euler"),
    "lm": ("local", "euler"),
    "tr": ("local", "euler"),
    "dogleg": ("local", "euler"),
    "newton": ("local", "euler"),
}
#: Parametrisation used when none is asked for.
DEFAULT_ROTATION = {"ipopt": "matrix"}

#: A converged point must be stationary on the local chart too: |grad| <= LOCAL_GTOL max(1, f).
LOCAL_GTOL = 1e-4
#: Iterations of the trust-region Newton polish of a solver that stopped early, and how far
#: (mm, deg) the polish may move its point: farther, the solver did not stop next to a minimum,
#: and the closed-form restart decides instead.
POLISH_ITER = 50
POLISH_MAX_MM = 1.0
POLISH_MAX_DEG = 1.0

#: Within this many degrees of B = +-90 the Euler angles A and C are nearly one rotation.
GIMBAL_WARN_DEG = 1.0


def parse_pose(text, what="--start", convention="kuka"):
    """Parse a pose written in a robot convention (``'X,Y,Z,A,B,C'`` for KUKA: mm, degrees)
    into a KUKA pose; raises CalibrationInputError."""
    pose = _parse_pose(text, what, convention)
    if np.any(np.abs(pose[:3]) > LIMIT_POSITION_MM):
        raise CalibrationInputError(f"{what}: a position beyond +-{LIMIT_POSITION_MM:g} mm in {text!r}: a unit or a "
                                    "misprint?")
    return pose


def _parse_pose(text, what, convention):
    cols = conventions.columns(convention)
    parts = [p.strip() for p in str(text).split(",")]
    if convention != "kuka":
        try:
            values = [float(p) for p in parts]
        except ValueError:
            raise CalibrationInputError(f"{what}: not a number in {text!r}") from None
        if not all(np.isfinite(values)):
            raise CalibrationInputError(f"{what}: values must be finite, got {text!r}")
        if len(values) != len(cols):
            raise CalibrationInputError(f"{what}: needs {len(cols)} numbers {','.join(cols)} ({convention}), got {text!r}")
        try:
            return conventions.convert(values, convention, "kuka")
        except conventions.ConventionError as exc:
            raise CalibrationInputError(f"{what}: {exc}") from None
    if len(parts) != 6:
        raise CalibrationInputError(f"{what}: needs six comma-separated numbers X,Y,Z,A,B,C, got {text!r}")
    try:
        pose = np.array([float(p) for p in parts])
    except ValueError:
        raise CalibrationInputError(f"{what}: not a number in {text!r}") from None
    if not np.all(np.isfinite(pose)):
        raise CalibrationInputError(f"{what}: values must be finite, got {text!r}")
    for name, v, lim in zip("ABC", pose[3:], GUESS_LIMITS):
        if abs(v) > lim:
            raise CalibrationInputError(f"{what}: angle {name} = {v} out of range [-{lim:g}, {lim:g}] degrees")
    return pose


def min_measurements(unknowns):
    """Fewest measurements with more equations (3 each) than unknowns (6 or 9)."""
    n = 6 if unknowns == "sensor" else 9
    return n // 3 + 1


def check_request(dataset, unknowns, method, rotation):
    """Validate the combination; returns the rotation parametrisation to use."""
    if method not in METHODS:
        raise CalibrationInputError(f"--method: unknown {method!r}; choose one of {', '.join(METHODS)}")
    if unknowns not in UNKNOWNS:
        raise CalibrationInputError(f"--unknowns: unknown {unknowns!r}; choose one of {', '.join(UNKNOWNS)}")
    rotation = rotation or DEFAULT_ROTATION.get(method, "local")
    if rotation not in ROTATIONS:
        raise CalibrationInputError(f"--rotation: unknown {rotation!r}; choose one of {', '.join(ROTATIONS)}")
    if rotation not in SUPPORTED[method]:
        raise CalibrationInputError(
            f"--rotation {rotation} does not work with --method {method} (it supports {', '.join(SUPPORTED[method])}):"
            + (" the matrix entries need the orthogonality constraints only IPOPT handles" if rotation == "matrix" else "")
            + (" IPOPT has no retraction for the local parametrisation" if rotation == "local" else "")
        )
    need = min_measurements(unknowns)
    if len(dataset) < need:
        raise CalibrationInputError(
            f"{dataset.path / 'measurements.csv'}: {len(dataset)} measurement(s); unknowns {unknowns!r} "
            f"need at least {need} (3 equations each for {3 * need - 3} unknowns, plus redundancy)"
        )
    return rotation


def gate(dataset, unknowns, start=None):
    """The checks every command that fits the data runs first (calibrate, diagnose): enough
    measurements for the unknowns, and poses that determine every unknown at the start.

    Returns the start pose (KUKA) and where it came from; raises CalibrationInputError.
    """
    need = min_measurements(unknowns)
    if len(dataset) < need:
        raise CalibrationInputError(
            f"{dataset.path / 'measurements.csv'}: {len(dataset)} measurement(s); unknowns {unknowns!r} "
            f"need at least {need} (3 equations each for {3 * need - 3} unknowns, plus redundancy)")
    start_pose, start_used = resolve_start(dataset, unknowns, start)
    check_identifiable(dataset, unknowns, transform_from_pose(start_pose))
    return start_pose, start_used


def with_sphere_centre(dataset, unknowns):
    """The dataset with a sphere centre to start from, and a note when it was estimated.

    A setup without ``[sphere] center`` can be calibrated only with the centre free
    (``unknowns='sensor+sphere'``): its start value is then the closed-form estimate.
    """
    if dataset.sphere_centre is not None:
        return dataset, None
    setup = dataset.path / "setup.toml"
    if unknowns != "sensor+sphere":
        raise CalibrationInputError(f"{setup}, column '[sphere] center': the setup gives no sphere centre (nor base_pose "
                                    "with center_in_plate): give it, or estimate it with --unknowns sensor+sphere")
    try:
        _, centre = closed_form_estimate(dataset.flange2base(), dataset.centre_in_sensor, None)
    except ClosedFormError as exc:
        raise CalibrationInputError(f"{setup}: no sphere centre given, and the poses do not determine the closed-form "
                                    f"estimate of it: {exc}") from None
    return dataclasses.replace(dataset, sphere_centre=centre), (
        "the setup gives no sphere centre: it is estimated with the sensor pose, starting from the closed-form "
        f"estimate ({', '.join(f'{v:.2f}' for v in centre)}) mm")


def check_identifiable(dataset, unknowns, start_transform):
    """Raise CalibrationInputError when the robot poses leave an unknown undetermined."""
    probe = CalibrationModel.from_dataset(dataset, "local", unknowns)
    ident = identifiability.structural(probe, probe.point_from(start_transform))
    if not ident.full_rank:
        raise CalibrationInputError(
            f"{dataset.path / 'measurements.csv'}: the robot poses do not determine every unknown "
            f"(rank {ident.rank} of {ident.n}); undetermined direction(s): {ident.describe_null()}. "
            "Measure from poses with rotations about at least two different axes"
            + (", and not only translations (they cannot separate the sensor offset from the sphere centre)"
               if unknowns == "sensor+sphere" else "")
        )
    if ident.observability["O2"] < identifiability.NEARLY_SINGULAR:
        raise CalibrationInputError(
            f"{dataset.path / 'measurements.csv'}: the robot poses nearly leave a direction undetermined "
            f"(inverse condition number {ident.observability['O2']:.1e} < {identifiability.NEARLY_SINGULAR:g}): "
            f"{ident.describe_weakest()}. This happens when the sphere is always seen at one sensor point "
            "(pure rotations about it): "
            "add poses that see it elsewhere in the laser plane, or pure translations")
    return ident


#: A residual this many robust standard deviations above the median is flagged.
GROSS_ERROR_Z = 10.0


def _gross_error_warnings(ids, norms):
    """Flag residuals far above the rest (median + GROSS_ERROR_Z * 1.4826 MAD); never excludes."""
    med = float(np.median(norms))
    spread = 1.4826 * float(np.median(np.abs(norms - med)))
    limit = med + GROSS_ERROR_Z * max(spread, 1e-9)
    out = []
    for i, n in zip(ids, norms):
        if n > limit:
            out.append(
                f"measurement {i!r} has residual {n:.2f} mm, above {limit:.2f} mm (median {med:.2f} mm + "
                f"{GROSS_ERROR_Z:g} robust sd): a gross error is likely (misprint, wrong side, bad profile); "
                "the whole calibration is pulled by it -- check or remove that sample"
            )
    return out


def _orthogonality(rot):
    return float(np.linalg.norm(rot.T @ rot - np.eye(3))), float(np.linalg.det(rot))


def resolve_start(dataset, unknowns, start=None):
    """The start pose and where it came from: ``--start``, the setup, or the closed form."""
    if start is not None:
        return np.asarray(start, dtype=float), "given (--start)"
    if dataset.start_pose is not None:
        return np.asarray(dataset.start_pose, dtype=float), "setup.toml start_pose"
    return _closed_form_pose(dataset, unknowns), "closed-form estimate (no start pose given)"


def _closed_form_pose(dataset, unknowns):
    centre = None if unknowns == "sensor+sphere" else dataset.sphere_centre
    try:
        t, _ = closed_form_estimate(dataset.flange2base(), dataset.centre_in_sensor, centre)
    except ClosedFormError:
        if centre is not None:
            raise
        t, _ = closed_form_estimate(dataset.flange2base(), dataset.centre_in_sensor, dataset.sphere_centre)
    return pose_from_transform(t)


def _solve(dataset, unknowns, method, rotation, start_pose, options, kind, robot_sigma):
    """(model, solver result) of one solve from ``start_pose``."""
    model = observations.build(dataset, kind, rotation, unknowns, robot_sigma)
    result = solvers.solve(calibration_problem(model), model.point_from_pose(start_pose), method=method, options=options)
    return model, result


@dataclasses.dataclass
class _Verdict:
    """A solver result judged: final transform and centre, convergence, local-chart diagnostics."""

    model: object
    result: object
    sensor: np.ndarray
    centre: np.ndarray
    converged: bool
    message: str
    notes: list
    local: object = None
    hess_eig: np.ndarray | None = None


def _polish(local, point):
    """Trust-region Newton (exact Hessian) on the local chart from ``point``: the minimum to
    machine precision when ``point`` is in its basin; None when it does not converge."""
    res = solvers.solve(calibration_problem(local), point, "tr", {"max_iter": POLISH_ITER})
    return res if res.converged and np.all(np.isfinite(res.x)) else None


def _judge(model, result, polish=True):
    """Final transform, convergence verdict and local-chart diagnostics of a solver result.

    The verdict is the first-order conditions at the returned point on the local chart (and a
    positive definite Hessian), not the solver's return string alone: a solver that stops
    early (IPOPT's ``Search_Direction_Becomes_Too_Small`` next to the minimum) is polished by
    trust-region Newton when ``polish``, and the message says so.
    """
    converged, message, notes = bool(result.converged), result.message, []
    if model.rotation == "matrix":
        orth, det = _orthogonality(model.sensor_rotation(result.x))
        if det <= 0:
            converged, message = False, f"{message}; but det R = {det:.3g} <= 0: a reflection, not a rotation"
        if orth > 1e-6:
            notes.append(f"R^T R - I has norm {orth:.2e}; R is reported projected onto SO(3)")
    sensor = nearest_transform(model.sensor2flange(result.x))  # a no-op but for 'matrix'
    centre = model.sphere_centre(result.x)
    if not (np.all(np.isfinite(sensor)) and np.all(np.isfinite(centre))):
        return _Verdict(model, result, sensor, centre, False, "numerical failure: non-finite result", notes)
    # judged in the local chart, free of the Euler singularity and of the matrix constraints
    local = model.with_rotation("local", centre)
    final = local.point_from(sensor, centre)
    if not converged and polish:
        polished = _polish(local, final)
        dt, dr = (np.inf, np.inf) if polished is None else transform_distance(local.sensor2flange(polished.x), sensor)
        if dt <= POLISH_MAX_MM and dr <= POLISH_MAX_DEG:
            notes.append(f"{result.method} stopped before its convergence test ({result.message}) {dt:.2g} mm and "
                         f"{dr:.2g} deg from the minimum; polished by trust-region Newton on the local chart "
                         f"({polished.iterations} iterations), where the first-order conditions hold")
            message = (f"first-order conditions met on the local chart after a trust-region Newton polish "
                       f"({result.method} had stopped early: {result.message})")
            converged, final = True, polished.x
            sensor, centre = local.sensor2flange(final), local.sphere_centre(final)
    hess_eig = np.linalg.eigvalsh(local.cost_hessian(final))
    grad_local = float(np.max(np.abs(local.gradient(final))))
    if converged and grad_local > LOCAL_GTOL * max(1.0, local.cost(final)):
        converged = False
        message = (f"{message}; but the gradient on the local chart is {grad_local:.3g}: stationary only in the "
                   f"{model.rotation} chart, which is singular here (gimbal lock), not a minimum")
    elif converged and hess_eig[0] < -1e-9 * max(1.0, abs(hess_eig[-1])):
        converged = False
        message = (f"{message}; but the cost Hessian has a negative eigenvalue ({hess_eig[0]:.3g}): a saddle "
                   "point, not a minimum (local Newton converges to any stationary point)")
    return _Verdict(model, result, sensor, centre, converged, message, notes, local, hess_eig)


def _refit(used, unknowns, method, rotation, options, kind, robot_sigma, polish, sensor2flange, centre, exact=False):
    """The final fit from a centre-model minimum; with ``exact`` the minimum itself when the
    solver ends next to it (the SVD solution of the unweighted centre model is exact)."""
    data = used if unknowns == "sensor" else dataclasses.replace(used, sphere_centre=centre)
    verdict = _judge(*_solve(data, unknowns, method, rotation, pose_from_transform(sensor2flange), options, kind,
                             robot_sigma), polish=polish)
    if exact and verdict.local is not None and verdict.converged:
        dt, dr = transform_distance(verdict.sensor, sensor2flange)
        if dt <= guarantee.SAME_MM and dr <= guarantee.SAME_DEG:
            verdict = dataclasses.replace(verdict, sensor=np.array(sensor2flange, float))
    return verdict


def _global(used, unknowns, fit, kind, sigma, refit):
    """The lowest final fit over the user's start and the centre model's minima, how it was
    established, and a refusal (a wrong basin, a fit that explains nothing) or None
    (:mod:`handeye.app.guarantee`)."""
    basin = guarantee.centre_basin(used, unknowns)
    exact = kind == "centre" and unknowns == "sensor" and fit.local is not None and fit.local.whiten is None
    fit, note, check = guarantee.lowest(fit, basin, refit, exact_centre_model=exact)
    if note:
        fit = dataclasses.replace(fit, notes=[*fit.notes, note])
    refusal = guarantee.explains_nothing(used, basin) or guarantee.cross_check(used, fit, basin, sigma)
    return fit, check, refusal


def _limits_iterations(options):
    """True when the options set an iteration limit anywhere (``max_iter``, nested dicts too)."""
    return any(k == "max_iter" or (isinstance(v, dict) and _limits_iterations(v)) for k, v in options.items())


def _solver_options(options):
    """Solver options checked up front: an unknown key is bad input, not a crash."""
    options = dict(options or {})
    try:
        solvers.Options.from_mapping(options)
    except solvers.UnsupportedProblem as exc:
        raise CalibrationInputError(f"options: {exc}") from None
    return options


#: Above this many measurements the default method is Levenberg-Marquardt on the local chart
#: (numpy, time and memory linear in the data) instead of IPOPT (whose problem graph costs far
#: more per measurement), and leave-one-out uses the deletion formula (robust.LOO_EXACT_UP_TO).
LARGE = 5000


def calibrate(dataset, unknowns="sensor", method=None, rotation=None, start=None, options=None,
              outliers=True, alpha=ALPHA, loo=True, model=None, robot_sigma=None, convention=None, sigma=None,
              effects=()):
    """Calibrate the sensor pose on the flange from a dataset.

    The engine of :func:`handeye.calibrate` (which takes the CLI's option names); this
    function takes the checked values.

    Parameters
    ----------
    dataset : handeye.model.dataset.Dataset
    unknowns : {'sensor', 'sensor+sphere'}
    method : {'ipopt', 'gn', 'lm', 'tr', 'dogleg', 'newton'} or None
        None: ``ipopt``, or ``lm`` above :data:`LARGE` measurements (said in the warnings).
    rotation : {'matrix', 'local', 'euler'} or None
        None: ``matrix`` for IPOPT, ``local`` otherwise.
    start : array_like, shape (6,), optional
        Start sensor pose (KUKA, mm and degrees); default the dataset's ``start_pose``, else
        the closed-form estimate. When the given start does not converge, the closed-form
        estimate is tried, and the result says so.
    options : dict, optional
        Solver options (:class:`handeye.solvers.Options`).
    outliers : bool
        Detect and exclude gross errors (:mod:`handeye.app.robust`); False fits every sample.
    alpha : float
        Family-wise level of the outlier tests.
    loo : bool
        Compute the leave-one-out prediction error (one refit per sample).
    model : {'centre', 'measurement', 'points'} or None
        Residual of the final fit (:mod:`handeye.model.observations`); None: ``measurement``
        when every sample has a profile, else ``centre``. Screening and leave-one-out always
        use the reconstructed centres.
    robot_sigma : float, optional
        Robot repeatability (mm, 1 sd per axis) for the weights of profile models; default the
        dataset's ``[noise] robot_mm`` (0.025).
    convention : str, optional
        Robot convention of the reported ``sensor_pose``; default the dataset's.
    sigma : float, optional
        Stated noise of a sphere centre through the chain (mm, per component) that the fit is
        tested against (``noise_test``); default the dataset's ``[noise] centre_mm`` (0.05).
    effects : sequence of str
        Catalogue effects (:data:`EFFECTS`) to calibrate with the sensor pose, on the
        ``centre`` residual; their parameters and 1-sd are reported in ``effects``.

    Returns
    -------
    handeye.app.results.CalibrationResult
        Complete on every path: after a numerical failure the fields that need a finite
        solution (residual statistics, covariance, identifiability, leave-one-out) are None
        and the poses NaN.
    """
    default_note = None
    if method is None:
        method = "ipopt" if len(dataset) <= LARGE or rotation in ("matrix", "euler") else "lm"
        if method != "ipopt":
            default_note = (f"{len(dataset)} measurements: the default method is lm (Levenberg-Marquardt on the local "
                            f"chart, linear in the data) above {LARGE}; ask for --method ipopt to use IPOPT")
    rotation = check_request(dataset, unknowns, method, rotation)
    effects, unknowns, model = _check_effects(effects, unknowns, model)
    dataset, centre_note = with_sphere_centre(dataset, unknowns)
    sigma = dataset.noise_centre_mm if sigma is None else float(sigma)
    robot_sigma = dataset.noise_robot_mm if robot_sigma is None else float(robot_sigma)
    options = _solver_options(options)
    convention = conventions.check(convention or dataset.convention)
    kind = model or observations.default_kind(dataset)
    observations.build(dataset, kind, "local", unknowns)  # refuses early what the data cannot give
    start_pose, start_used = resolve_start(dataset, unknowns, start)
    start_t = transform_from_pose(start_pose)
    check_identifiable(dataset, unknowns, start_t)
    warnings = [note for note in (default_note, centre_note) if note is not None]
    everything = CalibrationModel.from_dataset(dataset, "local", unknowns)
    basin_all = guarantee.centre_basin(dataset, unknowns)  # the plain fit's global minimum
    plain_start = (everything.point_from(start_t) if basin_all is None
                   else everything.point_from(basin_all.best.sensor2flange, basin_all.best.centre))
    plain = robust.least_squares(everything, plain_start).x
    plain_norms = np.linalg.norm(everything.residuals(plain), axis=1)
    plain_rms = float(np.sqrt(np.mean(plain_norms**2)))
    slips.check(dataset, unknowns, plain_rms)  # side, units: named (exit 2), never calibrated
    before = Before(len(dataset), plain_rms, _rms(robust.leave_one_out(everything, plain)) if loo else None)
    excluded, mask = [], np.ones(len(dataset), bool)
    if outliers:
        screening = robust.screen(dataset, unknowns, start_t, alpha=alpha)
        mask, excluded = screening.inliers, screening.excluded
        if screening.note:
            warnings.append(screening.note)
    mask, excluded = robust.exclude_inconsistent(dataset, unknowns, mask, excluded)  # rows contradicting themselves
    used = dataset.subset(mask)
    polish = not _limits_iterations(options)  # a limit the user set is respected, not polished past
    fit = _judge(*_solve(used, unknowns, method, rotation, start_pose, options, kind, robot_sigma), polish=polish)
    if not fit.converged and not start_used.startswith("closed-form"):
        try:
            retry_pose = _closed_form_pose(used, unknowns)
        except ClosedFormError as exc:
            warnings.append(f"the start did not converge and no closed-form restart is possible: {exc}")
        else:
            retry = _judge(*_solve(used, unknowns, method, rotation, retry_pose, options, kind, robot_sigma),
                           polish=polish)
            if retry.converged:
                warnings.append(f"the start ({start_used}) did not converge ({fit.message}); restarted from the "
                                "closed-form estimate")
                start_used = "closed-form estimate (after the given start failed)"
                fit = retry
    fit, global_check, refusal = _global(used, unknowns, fit, kind, sigma,
                                         lambda *a, **k: _refit(used, unknowns, method, rotation, options, kind,
                                                                robot_sigma, polish, *a, **k))
    warnings += fit.notes
    pose = pose_from_transform(fit.sensor)
    if abs(abs(pose[4]) - 90.0) < GIMBAL_WARN_DEG:
        warnings.append(
            f"B = {pose[4]:.4f} deg is within {GIMBAL_WARN_DEG:g} deg of the Euler singularity: A and C are "
            "nearly one rotation and are not separately meaningful; compare transforms, not angles"
        )
    result = fit.result
    common = dict(
        dataset=dataset.name,
        dataset_path=str(dataset.path),
        dataset_sha256=dataset.content_hash(),
        method=method,
        rotation=rotation,
        unknowns=unknowns,
        model=kind,
        robot_sigma_mm=robot_sigma if kind != "centre" or dataset.profiles is not None else None,
        start_pose=conventions.convert(start_pose, "kuka", convention) if convention != "kuka" else start_pose,
        start_pose_kuka=start_pose,
        start_used=start_used,
        sensor2flange=fit.sensor,
        sensor_pose_kuka=pose,
        sensor_pose=(conventions.pose_from(convention, fit.sensor) if np.all(np.isfinite(fit.sensor))
                     else np.full(len(conventions.columns(convention)), np.nan)),
        convention=convention,
        columns=conventions.columns(convention),
        sphere_centre=fit.centre,
        iterations=int(result.iterations),
        evaluations={"f": result.nfev, "jacobian": result.njev, "hessian": result.nhev},
        converged=fit.converged and refusal is None,
        status=int(result.status),
        message=fit.message if refusal is None else f"{refusal} (the solver: {fit.message})",
        global_check=global_check,
        excluded=list(excluded),
        before=before,
        history=np.array([pose_from_transform(nearest_transform(fit.model.sensor2flange(x)))
                          for x in result.history]).reshape(-1, 6),
        solver_point=np.asarray(result.x, float),
        solver_extra={k: v for k, v in result.extra.items() if k in ("rank_deficient_steps", "return_status")},
    )
    if fit.local is None:  # numerical failure: nothing to describe, but the same complete type
        residuals = [SampleResidual(i, int(r), np.full(3, np.nan), float("nan"), bool(u))
                     for i, r, u in zip(dataset.ids, dataset.rows, mask)]
        return CalibrationResult(residuals=residuals, warnings=warnings, n_used=int(mask.sum()), **common)
    common["effect_tests"] = _effect_tests(dataset, mask, fit, effects, unknowns, alpha, warnings)
    if effects:
        return CalibrationResult(warnings=warnings, **_with_effects(dataset, mask, fit, effects, sigma, warnings, common,
                                                                    centre_given=centre_note is None))
    return CalibrationResult(warnings=warnings, **common,
                             **_describe_fit(dataset, mask, fit, loo, outliers, warnings, sigma))


def _rms(values):
    values = np.asarray(values, float)
    values = values[np.isfinite(values)]
    return float(np.sqrt(np.mean(values**2))) if values.size else None


def _noise_model_text(local):
    rows = {"centre": "reconstructed centres", "measurement": "measured circles", "points": "profile points"}[local.kind]
    if local.kind == "points":
        weights = ("equal weights; covariance cluster-robust over the profiles (a robot pose error moves a whole "
                   "profile), sigma = sqrt(SSR/(m - p)) is the point scatter")
        return f"residual: {rows}; {weights}"
    if local.whiten is None:
        weights = "independent components with one common variance sigma^2, estimated as SSR/(m - p)"
    else:
        weights = ("each row whitened by its covariance (circle fit + robot repeatability); sigma_scale, estimated as "
                   "sqrt(SSR/(m - p)), should be near 1 and scales the covariance")
    return (f"residual: {rows}; {weights}; covariance sigma^2 (J^T J)^-1 on the local chart "
            "(rotation about the sensor's axes)")


#: Catalogue effects that ``--effects`` can calibrate (continuous, identifiable from the poses).
EFFECTS = ("sensor_scale", "sphere_radius", "sphere_center")
#: Level of the test of the fit against the stated noise (a warning; strict, so that clean data
#: of a slightly miscalibrated noise model are not flagged: 2 of 120 clean runs at 0.01).
NOISE_ALPHA = 0.001


def _check_effects(effects, unknowns, model):
    """Validated effect names; ``sphere_center`` is the free centre (``unknowns='sensor+sphere'``)."""
    names = [effects] if isinstance(effects, str) else list(effects or ())
    names = [n.strip() for name in names for n in str(name).split(",") if n.strip()]
    for name in names:
        if name not in EFFECTS:
            raise CalibrationInputError(f"--effects: unknown {name!r}; calibrate can add {', '.join(EFFECTS)} "
                                        "(handeye diagnose names the effect a dataset needs)")
    if not names:
        return (), unknowns, model
    if model not in (None, "centre"):
        raise CalibrationInputError(f"--effects works on the centre residual, not --model {model}")
    if "sphere_center" in names:
        unknowns = "sensor+sphere"
    return tuple(dict.fromkeys(n for n in names if n != "sphere_center")), unknowns, "centre"


def _noise_test(ssr, dof, sigma, whitened, warnings, dataset):
    """The fit against the stated noise (chi-square); a warning naming diagnose when it fails."""
    from handeye.app.results import NoiseTest
    from handeye.model.statistics import chi2_survival

    if dof <= 0:
        return None
    statistic = float(ssr if whitened else ssr / sigma**2)
    ratio = float(np.sqrt(statistic / dof))
    p_value = float(chi2_survival(statistic, dof))
    nominal = ("each row whitened by its stated covariance (sd 1)" if whitened
               else f"{sigma:g} mm per component of a sphere centre")
    passed = not (p_value < NOISE_ALPHA and ratio > 1)
    if not passed:
        warnings.append(
            f"the residuals are larger than the stated noise: sd {ratio:.1f} x the stated {nominal} (chi2 = "
            f"{statistic:.4g} on {dof} dof, p = {p_value:.2g}): the model may lack an effect (or the noise is larger "
            f"than [noise] in setup.toml says); run `handeye diagnose {dataset.path}` to find and name it, then "
            "`handeye calibrate --effects NAME`")
    return NoiseTest(statistic, int(dof), p_value, ratio, nominal, passed)


def _effect_tests(dataset, mask, fit, effects, unknowns, alpha, warnings):
    """Score tests of the catalogue's effects at the fit; a warning naming diagnose for a
    significant one (the test uses the fit's own scale, not the stated noise)."""
    from handeye.app import diagnose

    tests = diagnose.score_effects(dataset, mask, fit.sensor, fit.centre, unknowns, skip=effects)
    significant = [t for t in tests if t.p_bonferroni < alpha]
    if significant:
        names = ", ".join(f"{t.name} (score {t.score:.3g}, Bonferroni p = {t.p_bonferroni:.2g})" for t in significant)
        warnings.append(f"the residuals show structure the model lacks: {names}; run `handeye diagnose "
                        f"{dataset.path}` to confirm and name it, then `handeye calibrate --effects "
                        f"{significant[0].name}`")
    return tests


def _with_effects(dataset, mask, fit, names, sigma, warnings, common, centre_given=True):
    """The final fit with catalogue effects (:mod:`handeye.app.diagnose`'s extended model):
    fields of :class:`CalibrationResult`."""
    from handeye.app import diagnose
    from handeye.app.results import NamedEffect

    prob = diagnose.Samples(dataset)
    structure = diagnose.Structure(centre=fit.local.unknowns == "sensor+sphere", data_effects=names)
    with np.errstate(all="ignore"):
        extended = prob.fit(structure, mask, prob.point(structure, fit.sensor, fit.centre))
    jac = extended.jac[mask].reshape(-1, extended.p)
    on_plane = np.any(dataset.centre_in_sensor[mask, 1] == 0)
    if not np.all(np.isfinite(extended.x)) or (on_plane and not np.all(np.isfinite(jac))):
        raise CalibrationInputError(
            f"{dataset.path / 'measurements.csv'}: --effects {','.join(names)} cannot be fitted on these data: the "
            "effect has no derivative where a measured centre lies on the laser plane (ys = 0)")
    from handeye.model import effects as catalogue

    stuck = _not_a_minimum(dataset, mask, extended, names, prob.radius)
    if stuck is None:
        std, corr = extended.uncertainty(mask)
    else:  # the fit stopped against a bound, where the linearised sd means nothing
        std, corr = np.full(extended.p, np.nan), np.full((extended.p, extended.p), np.nan)
        jac = np.where(np.isfinite(jac), jac, 0.0)
    index = {n: k for k, n in enumerate(extended.names)}
    named = [NamedEffect(n, dict(zip(_effect_params(n), extended.params[n].tolist())),
                         {p: _finite_or_none(std[index[f"{n}.{p}"]]) for p in _effect_params(n)},
                         _effect_sd_note(dataset, mask, extended, n, prob.radius, stuck)) for n in names]
    if structure.centre and centre_given:
        delta = extended.x[12:15] - dataset.sphere_centre
        named.insert(0, NamedEffect("sphere_center", dict(zip(("dx", "dy", "dz"), delta.tolist())),
                                    dict(zip(("dx", "dy", "dz"), std[6:9].tolist()))))
    sensor, centre = prob.transform(extended.x), np.asarray(prob.centre(structure, extended.x), float)
    circles = _circles_shown(dataset, mask) if "sphere_radius" in names else None
    implausible = [why for n in names if (why := catalogue.implausible(n, extended.params[n], prob.radius, circles))]
    if stuck is not None:
        implausible.append(stuck)
    if implausible:  # an official-looking calibration it is not
        common = dict(common, converged=False, message="; ".join(implausible))
        warnings.extend(implausible)
    elif not extended.converged:
        common = dict(common, converged=False,
                      message=f"the fit with the effects did not converge: {extended.message}")
    norms = np.linalg.norm(extended.e, axis=1)
    ident = identifiability.analyse(jac, extended.names)
    pose = pose_from_transform(sensor)
    convention = common["convention"]
    warnings.append(f"calibrated with the effects {', '.join(names) or 'sphere_center'} on the centre residual; no "
                    "leave-one-out error (the effects are fitted to every sample used)")
    out = dict(common, sensor2flange=sensor, sphere_centre=centre, sensor_pose_kuka=pose,
               sensor_pose=conventions.pose_from(convention, sensor), model="centre", unknowns=(
                   "sensor+sphere" if structure.centre else "sensor"))
    out.update(
        n_used=int(mask.sum()), rms_mm=float(np.sqrt(np.mean(norms[mask] ** 2))),
        max_residual_mm=float(norms[mask].max()), cost_mm2=float(0.5 * np.sum(norms[mask] ** 2)),
        residuals=[SampleResidual(i, int(r), v, float(n), bool(u))
                   for i, r, v, n, u in zip(dataset.ids, dataset.rows, extended.e, norms, mask)],
        sigma_mm=float(np.sqrt(extended.sigma2)),
        std=Uncertainty(std[:3], np.degrees(std[3:6]), std[6:9] if structure.centre else None),
        parameter_names=tuple(extended.names), correlation=corr, covariance=corr * np.outer(std, std),
        identifiability=ident, effects=named,
        noise_model=("residual: reconstructed centres corrected by the effects; independent components with one common "
                     "variance sigma^2 = SSR/(m - p); covariance sigma^2 (J^T J)^-1 on the local chart"),
        rms_what=("RMS over the samples used of |e_i|, the distance (mm) of sample i's sphere centre, corrected by the "
                  "effects and carried through the calibrated chain, from the sphere centre: per sphere centre, "
                  "unweighted; this is what the fit with the effects minimises"),
        objective={"model": "centre", "residual": "sphere centres corrected by the effects, through the chain (3 "
                   "components, mm)", "weighted": False, "rows": int(mask.sum()), "cost": float(0.5 * extended.ssr),
                   "rms": float(np.sqrt(np.mean(norms[mask] ** 2))), "unit": "mm",
                   "rms_unweighted_mm": float(np.sqrt(np.mean(norms[mask] ** 2))),
                   "what": "sphere centres corrected by the effects, unweighted: RMS of |e_i| per sphere centre, mm",
                   "short": "the unweighted RMS per sphere centre of the centres corrected by the effects"},
        noise_test=_noise_test(extended.ssr, extended.m - extended.p, sigma, False, warnings, dataset))
    return out


#: The fit with effects is a minimum when every column of its Jacobian is orthogonal to the
#: residual: |J_k^T e| <= EFFECT_COS |J_k| |e| (a regular fit: below 1e-7; one stopped against
#: the sphere_radius bound: 1e-4 to 1e-2, or an infinite derivative).
EFFECT_COS = 1e-5


def _finite_or_none(value):
    return float(value) if np.isfinite(value) else None


def _circles_shown(dataset, mask):
    """What the data show of the sphere: per sample its id, the radius of the circle its laser
    plane cut (a profile's geometric circle fit with its 1 sd; for a used sample given as a
    centre without a profile ``sqrt(R^2 - ys^2)``, sd 0) -- ``(ids, r, sd)`` for
    :func:`handeye.model.effects.implausible`. Every profile counts, excluded or not (a gross
    error of the robot pose leaves its circle a circle of the sphere)."""
    from handeye.model import circle

    radius = dataset.sphere_diameter / 2
    ids, r, sd = [], [], []
    profiles = dataset.profiles or (None,) * len(dataset)
    for k, (ident, pts) in enumerate(zip(dataset.ids, profiles)):
        if pts is not None:
            try:
                c = circle.fit_circle(pts[:, 0], pts[:, 1], observations.CIRCLE_FIT)
                cov = circle.circle_covariance(pts[:, 0], pts[:, 1], c)
            except circle.CircleFitError:
                continue
            ids.append(ident), r.append(c.r), sd.append(float(np.sqrt(max(cov[2, 2], 0.0))))
        elif mask[k]:
            ids.append(ident), r.append(float(np.sqrt(max(radius**2 - dataset.centre_in_sensor[k, 1] ** 2, 0.0)))),
            sd.append(0.0)
    return ids, np.array(r), np.array(sd)


def _corrected_y(dataset, mask, extended, radius):
    """|y| of each used sample's centre corrected by the fitted data effects, and their ids."""
    from handeye.model import effects as catalogue

    xs = dataset.centre_in_sensor[mask]
    with np.errstate(all="ignore"):
        for name, params in extended.params.items():
            xs, _ = catalogue.correct(name, xs, radius, params)
    return np.abs(xs[:, 1]), [i for i, u in zip(dataset.ids, mask) if u]


def _not_a_minimum(dataset, mask, extended, names, radius):
    """Why the fit with effects is not a minimum (text), or None: a Jacobian column not
    orthogonal to the residual (:data:`EFFECT_COS`) or not finite. For ``sphere_radius`` this
    is the fit stopped against the bound ``R + dr >= r_i`` (a corrected y of 0): the data ask
    for a sphere smaller than a circle measured on it."""
    e = extended.e[mask].ravel()
    jac = extended.jac[mask].reshape(-1, extended.p)
    with np.errstate(all="ignore"):
        cos = np.abs(jac.T @ e) / (np.linalg.norm(jac, axis=0) * np.linalg.norm(e))
    worst = float(np.max(np.where(np.isfinite(cos), cos, np.inf)))
    if worst <= EFFECT_COS or not np.linalg.norm(e) > 0:
        return None
    if "sphere_radius" in names:
        y, ids = _corrected_y(dataset, mask, extended, radius)
        k = int(np.nanargmin(y))
        r = float(np.sqrt(max(radius**2 - dataset.centre_in_sensor[mask][k, 1] ** 2, 0.0)))
        dr = float(extended.params["sphere_radius"][0])
        return (f"sphere_radius: the fit stops at dr = {dr:.4g} mm, a sphere radius of {radius + dr:.4f} mm, against "
                f"the {r:.4f} mm circle of sample {ids[k]!r} (its corrected y is {y[k]:.2g} mm): the data ask for a "
                "sphere smaller than a circle measured on it, which cannot be; not a minimum (the gradient does not "
                f"vanish: cosine {worst:.2g}), so no sd either: the radius absorbs something else (a sphere centre "
                "offset, a wrong [profile] side or a gross error?); it is not named")
    return (f"the fit with the effects {', '.join(names)} is not a minimum (a Jacobian column is not orthogonal to "
            f"the residual: cosine {worst:.2g} > {EFFECT_COS:g}); its sd would mean nothing")


def _effect_sd_note(dataset, mask, extended, name, radius, stuck):
    """What the 1 sd of effect ``name`` is and why it is the size it is (text), or None."""
    if name != "sphere_radius":
        return None
    if stuck is not None:
        return "no sd: the fit is not a minimum (see the message)"
    y, ids = _corrected_y(dataset, mask, extended, radius)
    k = int(np.nanargmin(y))
    dr = float(extended.params["sphere_radius"][0])
    gain = (radius + dr) / y[k]
    return (f"1 sd of the linearised fit, sigma (J^T J)^-1 with sigma = {np.sqrt(extended.sigma2):.4g} mm per "
            f"component: small against the residual because a radius change dr moves each reconstructed centre's y by "
            f"(R + dr)/|y| dr, up to {gain:.3g} x for sample {ids[k]!r} (|y| = {y[k]:.3g} mm, its laser plane "
            "near the sphere's equator); within about 10 % of a Monte Carlo on simulated data while the planes stay "
            "about 1 mm or more from the equator (tests/test_effect_sd.py); nearer, y's own noise grows like r/|y| "
            "and the sd is optimistic (the Monte Carlo's is 1.4 x at 0.5 mm on a 25.4 mm sphere)")


def _effect_params(name):
    from handeye.model import effects as catalogue

    return catalogue.get(name).PARAMS


def _describe_fit(dataset, mask, fit, loo, outliers_on, warnings, sigma):
    """Residuals, uncertainty, identifiability and leave-one-out error of the final fit
    (fields of :class:`CalibrationResult`); appends to ``warnings``."""
    local, sensor, centre = fit.local, fit.sensor, fit.centre
    allm = CalibrationModel.from_dataset(dataset, "local", local.unknowns, sphere_centre=centre)
    x_all = allm.point_from(sensor, centre)
    e = allm.residuals(x_all)
    norms = np.linalg.norm(e, axis=1)
    final = local.point_from(sensor, centre)
    r_used, j_used = local.residual(final), local.jacobian(final)
    ident = identifiability.analyse(j_used, local.names)
    if not ident.full_rank:
        warnings.append(f"at the solution the data do not determine: {ident.describe_null()}")
    elif ident.observability["O2"] < identifiability.WEAK:
        warnings.append(
            f"the poses constrain one direction badly (inverse condition number {ident.observability['O2']:.2g} < "
            f"{identifiability.WEAK:g}): {ident.describe_weakest()}; add poses that move it (handeye plan)")
    groups = None if local.groups is None else np.repeat(local.groups, local.m)
    cov = covariance(r_used, j_used, groups)
    loo_errors = _final_loo(dataset, mask, local, final, centre) if loo else np.full(len(mask), np.nan)
    if not outliers_on:
        warnings += _gross_error_warnings(dataset.ids, norms)
    return dict(
        n_used=int(mask.sum()),
        rms_mm=float(np.sqrt(np.mean(norms[mask] ** 2))),
        max_residual_mm=float(norms[mask].max()),
        cost_mm2=float(0.5 * np.sum(norms[mask] ** 2)),
        residuals=[SampleResidual(i, int(r), v, float(n), bool(u), None if not np.isfinite(lo) else float(lo))
                   for i, r, v, n, u, lo in zip(dataset.ids, dataset.rows, e, norms, mask, loo_errors)],
        sigma_mm=cov.sigma if local.whiten is None else None,
        sigma_scale=cov.sigma if local.whiten is not None else None,
        std=Uncertainty(cov.std[:3], np.degrees(cov.std[3:6]),
                        cov.std[6:9] if local.unknowns == "sensor+sphere" else None),
        parameter_names=tuple(local.names),
        correlation=np.asarray(cov.correlation),
        covariance=np.asarray(cov.matrix),
        loo_error_mm=_rms(loo_errors) if loo else None,
        loo=_loo_description(local, int(mask.sum())) if loo else None,
        rms_what=RMS_PER_CENTRE,
        objective=_objective(local, final),
        identifiability=ident,
        hessian_eigenvalues=fit.hess_eig,
        noise_model=_noise_model_text(local),
        noise_test=None if local.kind == "points" else _noise_test(float(r_used @ r_used), r_used.size - local.n, sigma,
                                                                   local.whiten is not None, warnings, dataset),
    )


def _final_loo(dataset, mask, local, final, centre):
    """Leave-one-out errors (N,) of the final fit: ``local`` (the final model of the samples in
    ``mask``: its residual kind, weights and unknowns) refitted without each sample, from
    ``final``; the error is sample i's sphere centre through the refitted chain
    (:func:`handeye.app.robust.leave_one_out`). NaN for the samples not used."""
    predictor = CalibrationModel.from_dataset(dataset.subset(mask), "local", local.unknowns, sphere_centre=centre)
    out = np.full(len(mask), np.nan)
    out[mask] = robust.leave_one_out(local, final, None, predictor)
    return out


#: The rows of each residual model, in words (one row: m components).
_ROWS = {"centre": ("sphere centre", "sphere centres through the chain (3 components, mm)"),
         "measurement": ("circle", "circles (xc, zc, r) measured in the laser plane (3 components, mm)"),
         "points": ("profile point", "profile points' distances from the sphere surface (1 component, mm)")}


def _objective(local, final):
    """What the final fit minimised and its RMS (:attr:`CalibrationResult.objective`) at the
    point ``final`` of ``local`` (the final model, local chart)."""
    per, rows = _ROWS[local.kind]
    weighted = local.whiten is not None
    raw = local.residuals(final).reshape(local.n_meas, -1)
    unweighted = float(np.sqrt(np.mean(np.sum(raw**2, axis=1))))
    residual = local.residual(final)
    ssr = float(residual @ residual)
    if weighted:
        what = (f"{rows}, each whitened by its covariance (circle fit + robot repeatability): RMS of |W_i e_i| per "
                f"{per}, in units of its stated sd (about sqrt({local.m}) = {np.sqrt(local.m):.2f} when the noise is as "
                "stated)")
        short = f"the weighted RMS per {per} (whitened {rows.split(' (')[0]})"
    else:
        what = f"{rows}, unweighted: RMS of |e_i| per {per}, mm"
        short = f"the unweighted RMS per {per} ({rows.split(' (')[0]})"
    return {"model": local.kind, "residual": rows, "weighted": weighted, "rows": int(local.n_meas), "cost": 0.5 * ssr,
            "rms": float(np.sqrt(ssr / local.n_meas)), "unit": "sd" if weighted else "mm",
            "rms_unweighted_mm": unweighted, "what": what, "short": short}


def _loo_description(local, n_used):
    """How the final fit's leave-one-out error was made (:attr:`CalibrationResult.loo`)."""
    per = _ROWS[local.kind][0]
    weights = "weighted as the fit" if local.whiten is not None else "unweighted"
    method = ("exact refit per sample (Gauss-Newton from the deletion-formula point, started at the full fit)"
              if n_used <= robust.LOO_EXACT_UP_TO else
              "deletion formula (the exact update of the linearised fit); samples of high leverage refitted exactly")
    return {"model": local.kind, "weighted": local.whiten is not None, "unknowns": local.unknowns, "method": method,
            "what": (f"the final model (--model {local.kind}: {per} rows, {weights}, unknowns {local.unknowns}) refitted "
                     "without each used sample; the error is that sample's sphere centre carried through the refitted "
                     "chain against the refitted sphere centre, |T1_i T2_(-i) xs_i - c_(-i)| (mm): comparable across "
                     "models; loo_error_mm is its RMS over the samples used")}
