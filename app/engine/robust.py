"""Bad samples: a robust first pass, then a statistical test on the least-squares fit.

Every step judges a sample's centre residual ``e_i`` (mm, robot base) in the model's own metric,
whitened by its covariance ``C_i`` (:func:`handeye.model.datasets.observations.centre_whitening`):
``W_i e_i`` with ``W_i^T W_i = C_i^-1``, where ``C_i`` is the circle fit's covariance of a centre
reconstructed from its profile plus the robot's repeatability, and the stated isotropic noise of a
centre the sensor reported. Centres rebuilt from profiles are neither equal nor isotropic (near
the sphere's equator y's sd is many times x's and z's); a test that took them as equal called the
centres with a large sd gross errors (27 of 51 clean profile-only cells of an independent tester
lost 1-5 good samples at ``--alpha 0.01``; 12 of 50 of tests/indep_arcs.py, 0 of 50 in this metric,
every 3 mm gross error still caught: tests/test_arcs.py). The chain's part of ``C_i`` is estimated
from the robust fit's probable samples (:func:`~handeye.model.datasets.observations.chain_sd`, which
says why). Where no centre was rebuilt every ``C_i`` is the same multiple of I and the metric is
the plain one.

1. **Robust pass.** Iteratively reweighted least squares with Cauchy's loss on the whitened
   residual norms, ``w_i = 1 / (1 + (|W_i e_i| / k)^2)``, ``k = 2.385 sqrt(3) sigma`` (95 %
   efficiency per component), with the robust scale ``sigma = median |W_i e_i| / median(chi_3)``.
   A single gross error (the thesis's misprint of 2 m) cannot pull this fit.
2. **Screening.** A sample whose robust residual is improbable under ``|W_i e_i|^2 / sigma^2 ~
   chi^2_3`` after a Bonferroni correction over the N samples starts out excluded.
3. **Test on the fit.** Least squares on the remaining samples; externally studentised
   deletion statistics for every sample (:func:`handeye.model.common.statistics.deletion_statistics`
   on the whitened residuals and Jacobians: the generalised least-squares F, its scale estimated
   from the fit), Bonferroni-adjusted. The worst significant fitted sample is excluded, or the most
   plausible excluded sample reinstated, one at a time, until no change is called for.

Nothing is excluded silently: every excluded sample is returned with its residual (mm), its
statistic, its adjusted p-value and the reason (with its profile file when it has one).
Exclusion stops before fewer than half the samples (or fewer than the unknowns need) would
remain; the result then says so.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from handeye import solvers
from handeye.app.common.choices import ALPHA  # noqa: F401 - the level, defined without numpy
from handeye.app.engine import loo
from handeye.app.engine.deletion import (  # noqa: F401 - LOO_* and the helpers are robust's names too
    LOO_GN_MAX_RATE,
    LOO_RATE_SAFETY,
    LOO_XTOL,
    Information,
    _deletion_chunk,
    _deletion_steps,
    _gauss_newton,
    _gauss_newton_rate,
    _gauss_newton_refit,
    whitened_norms,
)
from handeye.app.engine.problems import chunked
from handeye.app.present.results import ExcludedSample
from handeye.model.common.statistics import bonferroni_survival, chi_median, deletion_statistics, deletion_statistics_chunked
from handeye.model.datasets import observations
from handeye.model.datasets.dataset import relative_name
from handeye.model.fit import global_fit
from handeye.model.fit.calibration import CalibrationModel

CAUCHY_K = 2.385 * np.sqrt(3.0)


@dataclasses.dataclass
class Screening:
    """Outcome of :func:`screen`.

    Attributes
    ----------
    inliers : ndarray of bool, shape (N,)
    excluded : list of handeye.app.present.results.ExcludedSample
        With the prediction error from the final fit, the statistic (F), the Bonferroni
        p-value and the reason.
    robust_sensor2flange : ndarray, shape (4, 4)
        The sensor pose of the robust pass.
    note : str
        Empty, or why the procedure stopped early.
    """

    inliers: np.ndarray
    excluded: list
    robust_sensor2flange: np.ndarray
    note: str = ""


def _weighted_problem(model, weights):
    sw = np.sqrt(np.repeat(weights, model.m))  # one weight per row, over the row's m components
    return solvers.Problem(n=model.n, residual=lambda x: sw * model.residual(x),
                           jacobian=lambda x: sw[:, None] * model.jacobian(x), retract=model.retract,
                           normal=(lambda x: model.normal_equations(x, weights)) if chunked(model) else None)


def least_squares(model, x0, max_iter=200, lm_iter=50):
    """Plain least-squares fit on the local chart (the workhorse of screening and leave-one-out).

    Levenberg-Marquardt first; when it has not converged after ``lm_iter`` iterations, the
    residuals are large enough that the Gauss-Newton model's missing second-order term
    (sum e_il grad^2 e_il) makes it creep (on thesis-real with its 2000 mm misprint: 2,256
    iterations), and trust-region Newton with the exact cost Hessian takes over (20).
    """
    problem = _weighted_problem(model, np.ones(model.n_meas))
    res = solvers.solve(problem, x0, "lm", {"max_iter": min(lm_iter, max_iter)})
    if res.status != 0 or max_iter <= lm_iter:
        return res
    newton = solvers.Problem(n=model.n, residual=model.residual, jacobian=model.jacobian,
                             hessian=model.cost_hessian, retract=model.retract)
    return solvers.solve(newton, res.x, "tr", {"max_iter": max_iter - lm_iter})


def _procrustes(model):
    """True when ``model``'s weighted fit is an absolute orientation, solved exactly by one SVD
    (:func:`handeye.model.fit.global_fit.absolute_orientation`): the unweighted centre residual with
    the sphere centre known (``|R_i (X p_i) + t_i - c| = |X p_i - q_i|``), on a chart of SO(3)
    (not ``matrix``: its free entries, not held to a rotation, have another minimum)."""
    return (model.kind == "centre" and model.whiten is None and model.unknowns == "sensor" and model.groups is None
            and model.rotation != "matrix")


def weighted_fit(model, x0, weights, max_iter=100):
    """The minimum of ``sum w_i |W_i e_i|^2`` near ``x0``: exact (one SVD) where :func:`_procrustes`,
    Gauss-Newton from ``x0`` for a whitened model (:func:`_gauss_newton`), else (or where that fails)
    Levenberg-Marquardt from ``x0``."""
    if _procrustes(model):
        q = global_fit.centre_targets(model.flange2base, model.fixed_centre)
        keep = weights > 0
        with np.errstate(all="ignore"):
            x, s = global_fit.absolute_orientation(model.centre_in_sensor[keep], q[keep], weights[keep])
        if s[1] > 1e-12 * max(s[0], 1e-300) and np.all(np.isfinite(x)):
            return model.point_from(x)
    if model.whiten is not None:
        x = _gauss_newton(model, x0, weights)
        if x is not None:
            return x
    return solvers.solve(_weighted_problem(model, weights), x0, "lm", {"max_iter": max_iter}).x


def robust_fit(model, x0, max_rounds=50, warm=False):
    """IRLS with Cauchy weights (module docstring); returns (x, sigma, weights). ``warm``: ``x0`` is
    a robust fit already (in another metric): the first weights are those at ``x0``, not all ones."""
    x = np.asarray(x0, float)
    weights = np.ones(model.n_meas)
    med3 = chi_median(3)
    sigma = np.nan
    norms_at = _norms(model)
    if warm:
        norms = norms_at(x)
        weights = 1.0 / (1.0 + (norms / (CAUCHY_K * max(_median(norms) / med3, 1e-12))) ** 2)
    for _ in range(max_rounds):
        x = weighted_fit(model, x, weights)
        norms = norms_at(x)
        sigma = max(_median(norms) / med3, 1e-12)
        new = 1.0 / (1.0 + (norms / (CAUCHY_K * sigma)) ** 2)
        change, weights = np.max(np.abs(new - weights)), new
        if change < 1e-6:
            break
    return x, sigma, weights


def _norms(model):
    """``x -> |W_i e_i|`` (N,) of ``model``: for an absolute orientation (:func:`_procrustes`) ``|X p_i - q_i|``, the
    same lengths (``R_i`` keeps them) without the generated residual (a sixth of its time)."""
    if not _procrustes(model):
        return lambda x: whitened_norms(model, x)
    p, q = model.centre_in_sensor, global_fit.centre_targets(model.flange2base, model.fixed_centre)
    return lambda x: np.linalg.norm(p @ model.sensor_rotation(x).T + model.sensor2flange(x)[:3, 3] - q, axis=1)


def _median(values):
    """The median of a 1-D array, as ``np.median`` (the mean of the two middle values) at a tenth of its overhead."""
    s = np.sort(values)
    return float((s[(len(s) - 1) // 2] + s[len(s) // 2]) / 2)


def n_samples(model):
    """Samples of a model: its rows, or for ``points`` its profiles (row groups)."""
    return model.n_meas if model.groups is None else int(model.groups.max()) + 1


def _subset(model, mask):
    """The model of the samples in ``mask`` (one entry per sample): the same residual kind,
    whitening and unknowns."""
    mask = np.asarray(mask, bool)
    return _subset_rows(model, mask if model.groups is None else mask[model.groups])


def _subset_rows(model, rows):
    """The model of the rows ``rows`` (bool per row)."""
    sub = CalibrationModel(model.flange2base[rows], model.centre_in_sensor[rows], model.fixed_centre,
                           model.rotation, model.unknowns, model.kind, model.radius,
                           None if model.whiten is None else model.whiten[rows])
    if model.groups is not None:
        sub.groups = model.groups[rows]
    return sub


def _deletion(model, x, fitted, chunk=None):
    """Deletion statistics of every sample at ``x`` (Bonferroni over the samples) and the residuals
    (N, 3); above one chunk (or with ``chunk``) in two passes, no Jacobian of every sample held."""
    if chunk is None and not chunked(model):
        e, j = model.residual_and_jacobian(x)
        return (*deletion_statistics(e, j, fitted, n_tests=model.n_meas), e)
    return deletion_statistics_chunked(lambda: model.chunks(x, chunk), fitted, n_tests=model.n_meas)


def screen(dataset, unknowns, start, alpha=ALPHA, min_keep=None, robot_sigma=None):
    """Find gross errors (module docstring).

    Parameters
    ----------
    dataset : handeye.model.datasets.dataset.Dataset
        Every sample (ids and rows name them in the report).
    unknowns : {'sensor', 'sensor+sphere'}
    start : ndarray, shape (4, 4)
        Start sensor pose (sensor in flange, mm).
    alpha : float
        Family-wise significance level.
    min_keep : int, optional
        Never keep fewer samples; default ``max(N // 2 + 1, 4)``.
    robot_sigma : float, optional
        The robot's repeatability per axis (mm) in the covariance of a centre rebuilt from its
        profile; default the dataset's ``[noise] robot_mm``.

    Returns
    -------
    Screening
    """
    n = len(dataset)
    min_keep = min(min_keep or max(n // 2 + 1, 4), n)
    full, x_rob, sigma = _robust_metric_fit(dataset, unknowns, start, robot_sigma, (alpha, min_keep))
    norms = whitened_norms(full, x_rob)
    inliers, note = _robust_inliers(norms, sigma, alpha, min_keep)
    x, stopped = _test_on_the_fit(full, x_rob, inliers, alpha, min_keep)
    robust_mm = np.linalg.norm(full.residuals(x_rob), axis=1)
    return Screening(inliers=inliers, excluded=_screened_out(dataset, full, x, inliers, robust_mm, alpha),
                     robust_sensor2flange=full.sensor2flange(x_rob), note=note or stopped)


def _robust_metric_fit(dataset, unknowns, start, robot_sigma, level):
    """The robust pass (step 1 of the module docstring) in the samples' metric; the model, the
    robust fit and its scale. Where centres were rebuilt from profiles the chain's part of their
    covariance is the one the plain robust fit's probable samples show
    (:func:`~handeye.model.datasets.observations.chain_sd`; ``level``
    is ``(alpha, min_keep)`` of :func:`_robust_inliers`); the stated ``robot_sigma`` (mm, default the
    dataset's ``[noise] robot_mm``) when those samples are too few to say."""
    cov = observations.profile_covariance(dataset)
    plain = observations.screening_model(dataset, unknowns, start, 0.0)
    x_rob, sigma, _ = robust_fit(plain, plain.point_from(start))  # exact and fast (one SVD per round)
    if cov is None:
        return plain, x_rob, sigma
    ok, _ = _robust_inliers(whitened_norms(plain, x_rob), sigma, *level)
    pose = plain.sensor2flange(x_rob)
    turn = dataset.motions()[:, :3, :3] @ pose[:3, :3]
    e_sensor = np.einsum("nji,nj->ni", turn, plain.residuals(x_rob))  # R_i^T e_i
    chain = (observations.chain_sd(e_sensor[ok], cov[ok], plain.n) if ok.sum() * 3 > 2 * plain.n else
             getattr(dataset, "noise_robot_mm", observations.ROBOT_SIGMA) if robot_sigma is None else float(robot_sigma))
    full = observations.screening_model(dataset, unknowns, pose, chain, cov)
    x_rob, sigma, _ = robust_fit(full, x_rob, warm=True)
    return full, x_rob, sigma


def _robust_inliers(norms, sigma, alpha, min_keep):
    """Step 2 of the module docstring: the samples whose robust residual ``norms`` (N,) is probable
    at the robust scale ``sigma``, at least the ``min_keep`` best; (inliers, note)."""
    n = len(norms)
    inliers = bonferroni_survival((norms / sigma) ** 2, n, 3) >= alpha
    if inliers.sum() >= min_keep:
        return inliers, ""
    improbable = n - int(inliers.sum())
    inliers = np.zeros(n, bool)
    inliers[np.argsort(norms)[:min_keep]] = True
    return inliers, (f"the robust pass found {improbable} improbable sample(s), but at least {min_keep} of {n} must be "
                     f"kept; kept the {min_keep} best")


def _test_on_the_fit(full, x, inliers, alpha, min_keep):
    """Step 3 of the module docstring, from the robust fit ``x``: changes ``inliers`` in place until
    no change is called for; (the last fit, a note: empty, or why it stopped early)."""
    seen = set()
    for _ in range(2 * full.n_meas):
        key = inliers.tobytes()
        if key in seen:
            return x, "the exclusion test cycled; stopped at a set seen before"
        seen.add(key)
        direct = _procrustes(full) or full.whiten is not None  # one SVD, or Gauss-Newton with LM behind it
        x = weighted_fit(full, x, inliers.astype(float)) if direct else least_squares(_subset(full, inliers), x).x
        stat, adj, _ = _deletion(full, x, inliers)
        stop = _exclude_or_reinstate(inliers, stat, adj, alpha, min_keep)
        if stop is not None:
            return x, stop
    return x, ""


def _exclude_or_reinstate(inliers, stat, adj, alpha, min_keep):
    """One change of ``inliers`` (in place) by the deletion statistics ``stat`` and adjusted p-values
    ``adj``: exclude the worst significant fitted sample, else reinstate the most plausible excluded
    one (above LOO_EXACT_UP_TO samples all of them at once); None after a change, else the note
    (empty: no change called for)."""
    fitted_bad = np.where(inliers & (adj < alpha))[0]
    excluded_ok = np.where(~inliers & (adj >= alpha))[0]
    many = len(inliers) > LOO_EXACT_UP_TO  # many samples: all significant ones at once (linear, not quadratic)
    if len(fitted_bad):
        if inliers.sum() <= min_keep:
            return f"more samples test as outliers, but at least {min_keep} must be kept"
        if many:
            room = max(int(inliers.sum()) - min_keep, 0)
            inliers[fitted_bad[np.argsort(-stat[fitted_bad])][:room]] = False
        else:  # one at a time: a gross error can mask another
            inliers[fitted_bad[np.argmax(stat[fitted_bad])]] = False
    elif len(excluded_ok):
        inliers[excluded_ok if many else excluded_ok[np.argmin(stat[excluded_ok])]] = True
    else:
        return ""
    return None


def _screened_out(dataset, full, x, inliers, norms, alpha):
    """The records of the samples not in ``inliers``, by the deletion test at the final fit ``x``
    (``norms`` their robust residuals, mm)."""
    stat, adj, _ = _deletion(full, x, inliers)
    e = np.linalg.norm(full.residuals(x), axis=1)  # mm (the test's residuals are whitened)
    metric = "" if full.whiten is None else ", each centre weighted by its covariance"
    return [ExcludedSample(
        id=dataset.ids[k], row=int(dataset.rows[k]), residual_mm=float(e[k]),
        robust_residual_mm=float(norms[k]), statistic=float(stat[k]), p_bonferroni=float(adj[k]),
        reason=(f"prediction error {e[k]:.2f} mm{profile_named(dataset, k)} is improbable under the fit of the other "
                f"samples (F = {stat[k]:.1f}{metric}, Bonferroni p = {adj[k]:.2g} < {alpha:g})"))
        for k in np.where(~inliers)[0]]


def profile_named(dataset, k):
    """`` (its profile FILE)`` for sample ``k`` of ``dataset`` when it names a profile file (the
    path relative to the dataset's folder where it lies inside), else empty."""
    files = getattr(dataset, "profile_of", None)
    if files is None or len(files) != len(dataset) or files[k] is None:
        return ""
    return f" (its profile {relative_name(files[k], dataset.path)})"


#: Up to this many samples leave-one-out refits every sample exactly; above, the deletion formula
#: (the exact update of the linearised problem) gives every sample at once, and only samples of
#: high leverage (largest eigenvalue of the hat block above LOO_LEVERAGE) are refitted.
LOO_EXACT_UP_TO = 2000
LOO_LEVERAGE = 0.5


def centre_predictor(model):
    """The unweighted ``centre`` model of ``model``'s samples (same point layout): what a
    leave-one-out prediction is measured in. ``model`` itself when it is one already; for the
    ``measurement`` and ``points`` kinds pass the dataset's (:func:`leave_one_out`)."""
    if model.kind != "centre":
        raise ValueError(f"a {model.kind!r} model has no sphere centres of its own: pass predictor= "
                         "(the centre model of the same samples)")
    if model.whiten is None:
        return model
    return CalibrationModel(model.flange2base, model.centre_in_sensor, model.fixed_centre, model.rotation,
                            model.unknowns)


def loo_in_closed_form(model, predictor):
    """Whether every leave-one-out refit is an absolute orientation: the unweighted centre model of every row with
    the sphere centre known, predicting its own centres."""
    return (model.kind == "centre" and model.whiten is None and model.unknowns == "sensor" and model.groups is None
            and predictor is model)


def _prediction_error(predictor, x, i):
    """|T1_i T2(x) xs_i - c(x)| of sample i, mm."""
    pred = predictor.flange2base[i] @ predictor.sensor2flange(x) @ np.append(predictor.centre_in_sensor[i], 1.0)
    return float(np.linalg.norm(pred[:3] - predictor.sphere_centre(x)))


@dataclasses.dataclass(frozen=True)
class DeletionStart:
    """Where a leave-one-out refit starts (:func:`_refit_without`): the full fit moved by the
    deletion formula.

    Attributes
    ----------
    fitted : CalibrationModel
        The model of the samples fitted at the full fit.
    out : slice or ndarray
        The left-out sample's rows of ``fitted``.
    step : ndarray, shape (p,)
        The deletion formula's step.
    cost : float
        The other samples' sum of squares at the full fit.
    rho : float
        Gauss-Newton's rate there (:func:`_gauss_newton_rate`); at or above
        :data:`LOO_GN_MAX_RATE` (the default) Gauss-Newton is not tried.
    """

    fitted: CalibrationModel
    out: object
    step: np.ndarray
    cost: float = np.inf
    rho: float = np.inf


def _refit_without(model, x, mask, i, start=None):
    """The fit of ``model`` on the samples in ``mask`` but sample ``i``, from the full fit ``x``:
    Gauss-Newton from ``start`` (a :class:`DeletionStart`, when given), or :func:`least_squares`
    from ``x`` when that does not converge."""
    if start is not None and np.all(np.isfinite(start.step)) and not start.rho >= LOO_GN_MAX_RATE:
        z = _gauss_newton_refit(start.fitted, start.out, start.fitted.retract(x, start.step), start.cost, start.rho)
        if z is not None:
            return z
    keep = mask.copy()
    keep[i] = False
    return least_squares(_subset(model, keep), x).x


def _sample_rows(fitted, used):
    """Rows of ``fitted`` (the model of the samples ``used``, in order) per sample: slices."""
    if fitted.groups is None:
        return {i: slice(k, k + 1) for k, i in enumerate(used)}
    starts = np.flatnonzero(np.r_[True, fitted.groups[1:] != fitted.groups[:-1]])
    ends = np.r_[starts[1:], len(fitted.groups)]
    rows = {int(fitted.groups[a]): slice(int(a), int(b)) for a, b in zip(starts, ends)}
    if len(rows) != len(used):  # a sample's rows not contiguous: index arrays instead
        return {i: np.flatnonzero(fitted.groups == i) for i in used}
    return rows


def _deletion_errors(model, x, mask, predictor, chunk=None):
    """Leave-one-out errors (G,) of the samples in ``mask`` by the deletion formula
    (:func:`leave_one_out` above :data:`LOO_EXACT_UP_TO`; one row per sample), summed and
    applied chunk by chunk: two evaluations at ``x``, no per-sample matrices of all samples.
    Samples of high leverage are refitted exactly."""
    info, _, total = model.normal_equations(x, mask.astype(float), chunk)
    try:
        normal = Information(info, np.linalg.inv(np.linalg.cholesky(info)), total)
    except np.linalg.LinAlgError:
        normal = Information(info, np.full(info.shape, np.nan), total)
    parts = []
    own = predictor.chunks(x, chunk) if predictor is not model else None
    for rows, e, jac in model.chunks(x, chunk):
        _, d, dj = (rows, e, jac) if own is None else next(own)
        keep = mask[rows]
        parts.append(_deletion_chunk(normal, e[keep], jac[keep], d[keep], dj[keep]))
    step, leverage, others, errors = (np.concatenate(p) for p in zip(*parts))
    used, fitted = np.flatnonzero(mask), None
    for k in np.flatnonzero(~(leverage <= LOO_LEVERAGE) | ~np.isfinite(errors)):
        fitted = _subset(model, mask) if fitted is None else fitted
        z = _refit_without(model, x, mask, used[k], DeletionStart(fitted, slice(k, k + 1), step[k], others[k]))
        errors[k] = _prediction_error(predictor, z, used[k])
    return errors


def _exact_refits(model, x, mask, fitted, rows):
    """The exact refits of ``model`` without each sample of ``mask`` (G, d): all at once by
    :func:`handeye.app.engine.loo.refits` (damped Newton from the full fit ``x`` of ``fitted``, whose
    rows ``rows[k]`` are sample k's: the exact Hessian's step first, Gauss-Newton's after it
    where Gauss-Newton's rate at ``x`` is below :data:`LOO_GN_MAX_RATE`, else the exact Hessian
    throughout), and :func:`least_squares` from ``x`` on the subset for a refit that does not
    converge there."""
    jac = fitted.jacobian(x)
    rho = _gauss_newton_rate(fitted, x, jac.T @ jac)
    z, converged = loo.refits(fitted, x, rows, LOO_XTOL, LOO_RATE_SAFETY, rho if rho < LOO_GN_MAX_RATE else None)
    used = np.flatnonzero(mask)
    for k in np.flatnonzero(~converged):
        z[k] = _refit_without(model, x, mask, used[k])
    return z


def leave_one_out(model, x, mask=None, predictor=None):
    """Leave-one-out prediction errors of the sphere centre, mm.

    For each sample i in ``mask`` the calibration ``model`` -- whatever its residual kind
    (centre, measurement or points), weights and unknowns -- is refitted without it, starting
    at ``x``, and i's sphere centre is predicted through the refitted chain:
    ``|T1_i T2_(-i) xs_i - c_(-i)|``, where ``xs_i`` is i's measured centre in the sensor frame
    (``predictor``'s row i). The figure is in mm of a sphere centre for every model, so the
    models compare; only the refit differs. An accuracy figure that the fit's own residual
    cannot flatter.

    For the unweighted centre model with the centre known each refit is an absolute orientation, solved in
    closed form at any size (:func:`handeye.app.engine.loo.closed_form_errors`: one batched SVD, linear).
    The deletion formula gives the Gauss-Newton step of the fit without sample g from one
    evaluation at ``x``: ``dx_g = (A - B_g)^-1 J_g^T r_g`` (``A = J^T J`` of the fit,
    ``B_g = J_g^T J_g`` and ``r_g`` sample g's whitened rows), exact for the linearised problem.
    Up to :data:`LOO_EXACT_UP_TO` samples every refit is exact, and all are made at once
    (:func:`handeye.app.engine.loo.refits`): damped Gauss-Newton from ``x`` on the stack of deleted
    problems, whose first step is ``dx_g``, when the residuals are small (a step's error shrinks
    by Gauss-Newton's rate, estimated once at ``x``; see :data:`LOO_XTOL`), damped Newton with
    the exact Hessian where Gauss-Newton is not reliable (large residuals, as the unscreened
    thesis data with their 2 m misprint); :func:`least_squares` from ``x`` for a refit that does
    not converge within a few iterations. Above, the deletion formula stands for the
    refits, in time linear in the samples: i's error is ``|d_i + D_i dx_i|`` with ``d_i, D_i``
    the predictor's residual and Jacobian (for the unweighted centre model the classical
    ``(I - H_ii)^-1 e_i``); samples whose leverage (largest eigenvalue of ``A^-1 B_g``, the hat
    block's) exceeds :data:`LOO_LEVERAGE` make the linearisation doubtful and are refitted
    exactly.

    Parameters
    ----------
    model : CalibrationModel
        ``local`` rotation; all samples (rows, or for ``points`` the row groups of profiles).
    x : ndarray
        The fit on the samples of ``mask`` (start of every refit).
    mask : ndarray of bool, optional
        Samples to use (default all).
    predictor : CalibrationModel, optional
        The unweighted ``centre`` model of the same samples, in the same point layout; default
        ``model``'s own centres (``model`` must then be a centre model).

    Returns
    -------
    ndarray, shape (N,)
        NaN where the sample is not in ``mask``.
    """
    predictor = centre_predictor(model) if predictor is None else predictor
    n = n_samples(model)
    if predictor.n_meas != n:
        raise ValueError(f"the predictor has {predictor.n_meas} samples, the model {n}")
    mask = np.ones(n, bool) if mask is None else np.asarray(mask, bool)
    out = np.full(n, np.nan)
    if mask.any():
        out[mask] = _loo_errors(model, x, mask, predictor)
    return out


def _loo_errors(model, x, mask, predictor):
    """:func:`leave_one_out`'s errors (G,) of the samples in ``mask`` (at least one): in closed form where each
    refit is an absolute orientation, else the exact refits up to :data:`LOO_EXACT_UP_TO` samples, the deletion
    formula above."""
    used = np.flatnonzero(mask)
    if loo_in_closed_form(model, predictor) and (errors := loo.closed_form_errors(
            model.flange2base, model.centre_in_sensor, model.fixed_centre, mask)) is not None:
        return errors  # the unweighted centre model, centre known: every refit an absolute orientation
    if len(used) > LOO_EXACT_UP_TO and model.groups is None:
        return _deletion_errors(model, x, mask, predictor)
    fitted = model if mask.all() else _subset(model, mask)
    rows = _sample_rows(fitted, used)
    if len(used) <= LOO_EXACT_UP_TO:
        z = _exact_refits(model, x, mask, fitted, [rows[i] for i in used])
        return [_prediction_error(predictor, z[k], i) for k, i in enumerate(used)]
    step, leverage, others, _ = _deletion_steps(model, x, mask)
    d, dj = predictor.residual_and_jacobian(x)
    errors = np.linalg.norm(d[mask] + np.einsum("gkp,gp->gk", dj[mask], step), axis=1)
    for k in np.flatnonzero(~(leverage <= LOO_LEVERAGE) | ~np.isfinite(errors)):  # the row groups of points
        z = _refit_without(model, x, mask, used[k], DeletionStart(fitted, rows[used[k]], step[k], others[k]))
        errors[k] = _prediction_error(predictor, z, used[k])
    return errors
