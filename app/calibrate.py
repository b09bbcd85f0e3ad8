"""One calibration run: dataset in, checked, solved, reported as plain data (described by
:mod:`handeye.app.describe`).

The pipeline is: check the request (method and parametrisation fit together, enough
measurements), check that the robot poses determine every unknown (structural
identifiability, :func:`handeye.model.identifiability.structural`), name setup and convention
slips (:mod:`handeye.app.slips`, :mod:`handeye.app.detective`), screen gross errors, solve with
the chosen method from the start and from the centre model's global minimum and keep the
lowest (:mod:`handeye.app.guarantee`), and return a
:class:`handeye.app.results.CalibrationResult`. Nothing here prints.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from handeye import solvers
from handeye.app import describe, guarantee, robust, slips
from handeye.app.choices import METHODS  # noqa: F401 - the names, defined without numpy
from handeye.app.errors import CalibrationInputError
from handeye.app.problems import calibration_problem
from handeye.app.results import Before, CalibrationResult, SampleResidual
from handeye.app.robust import ALPHA
from handeye.model import conventions, identifiability, observations
from handeye.model.calibration import ROTATIONS, UNKNOWNS, CalibrationModel
from handeye.model.closed_form import ClosedFormError, closed_form_estimate
from handeye.model.dataset import GUESS_LIMITS, LIMIT_POSITION_MM
from handeye.model.pose import pose_from_transform, transform_from_pose
from handeye.model.rotation import nearest_transform, transform_distance

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


@dataclasses.dataclass(frozen=True)
class _FinalFit:
    """How the final fit is solved: what :func:`_solve` needs besides the data and the start."""

    unknowns: str
    method: str
    rotation: str
    options: dict
    kind: str
    robot_sigma: float
    polish: bool

    def solve(self, dataset, start_pose):
        return _judge(*_solve(dataset, self.unknowns, self.method, self.rotation, start_pose, self.options, self.kind,
                              self.robot_sigma), polish=self.polish)


def _refit(final, used, sensor2flange, centre, exact=False):
    """The final fit (:class:`_FinalFit`) from a centre-model minimum; with ``exact`` the
    minimum itself when the solver ends next to it (the SVD solution of the unweighted centre
    model is exact)."""
    data = used if final.unknowns == "sensor" else dataclasses.replace(used, sphere_centre=centre)
    verdict = final.solve(data, pose_from_transform(sensor2flange))
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
    refusal = guarantee.explains_nothing(used, basin, sigma) or (  # a fit that did not converge says so itself
        guarantee.cross_check(used, fit, basin, sigma) if fit.converged else None)
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
        when every sample has a profile, else ``centre``. Screening, the plain fit and the
        centre model's global minimum (:mod:`handeye.app.guarantee`) use the reconstructed
        centres; leave-one-out refits this model.
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
    effects, unknowns, model = describe.check_effects(effects, unknowns, model)
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
    if unknowns == "sensor":  # a taught centre the pose would absorb (diagnose names it as an effect instead)
        slips.check_centre(dataset, sigma)
    before = Before(len(dataset), plain_rms, describe.rms(robust.leave_one_out(everything, plain)) if loo else None)
    excluded, mask = [], np.ones(len(dataset), bool)
    if outliers:
        screening = robust.screen(dataset, unknowns, start_t, alpha=alpha)
        mask, excluded = screening.inliers, screening.excluded
        if screening.note:
            warnings.append(screening.note)
    mask, excluded = robust.exclude_inconsistent(dataset, unknowns, mask, excluded)  # rows contradicting themselves
    used = dataset.subset(mask)
    if unknowns == "sensor":
        slips.check_centre(used, sigma)  # a taught centre the pose would absorb: named (exit 2)
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
    final = _FinalFit(unknowns, method, rotation, options, kind, robot_sigma, polish)
    fit, global_check, refusal = _global(used, unknowns, fit, kind, sigma,
                                         lambda *a, **k: _refit(final, used, *a, **k))
    refusal = refusal or guarantee.two_groups(dataset, mask, fit, sigma)
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
    common["effect_tests"] = describe.effect_tests(dataset, mask, fit, effects, unknowns, alpha, warnings)
    if effects:
        return CalibrationResult(warnings=warnings, **describe.with_effects(dataset, mask, fit, effects, sigma, warnings, common,
                                                                    centre_given=centre_note is None))
    return CalibrationResult(warnings=warnings, **common,
                             **describe.describe_fit(dataset, mask, fit, loo, outliers, warnings, sigma))
