"""Bad samples: a robust first pass, then a statistical test on the least-squares fit.

1. **Robust pass.** Iteratively reweighted least squares with Cauchy's loss on the residual
   norms, ``w_i = 1 / (1 + (|e_i| / k)^2)``, ``k = 2.385 sqrt(3) sigma`` (95 % efficiency per
   component), with the robust scale ``sigma = median |e_i| / median(chi_3)``. A single
   gross error (the thesis's misprint of 2 m) cannot pull this fit.
2. **Screening.** A sample whose robust residual is improbable under ``|e|^2 / sigma^2 ~
   chi^2_3`` after a Bonferroni correction over the N samples starts out excluded.
3. **Test on the fit.** Least squares on the remaining samples; externally studentised
   deletion statistics for every sample (:func:`handeye.model.statistics.deletion_statistics`),
   Bonferroni-adjusted. The worst significant fitted sample is excluded, or the most
   plausible excluded sample reinstated, one at a time, until no change is called for.

Nothing is excluded silently: every excluded sample is returned with its residual, its
statistic, its adjusted p-value and the reason. Exclusion stops before fewer than half the
samples (or fewer than the unknowns need) would remain; the result then says so.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from handeye import solvers
from handeye.app.results import ExcludedSample
from handeye.model.calibration import CalibrationModel
from handeye.model.statistics import chi2_survival_array, chi_median, deletion_statistics

#: Family-wise significance level of the outlier tests.
ALPHA = 0.01
CAUCHY_K = 2.385 * np.sqrt(3.0)


@dataclasses.dataclass
class Screening:
    """Outcome of :func:`screen`.

    Attributes
    ----------
    inliers : ndarray of bool, shape (N,)
    excluded : list of handeye.app.results.ExcludedSample
        With the prediction error from the final fit, the statistic (F), the Bonferroni
        p-value and the reason.
    robust_sigma_mm : float
        Robust scale of the robust pass, per component.
    robust_sensor2flange : ndarray, shape (4, 4)
    robust_centre : ndarray, shape (3,)
    note : str
        Empty, or why the procedure stopped early.
    """

    inliers: np.ndarray
    excluded: list
    robust_sigma_mm: float
    robust_sensor2flange: np.ndarray
    robust_centre: np.ndarray
    note: str = ""


def _weighted_problem(model, weights):
    sw = np.sqrt(np.repeat(weights, 3))
    return solvers.Problem(
        n=model.n,
        residual=lambda x: sw * model.residual(x),
        jacobian=lambda x: sw[:, None] * model.jacobian(x),
        retract=model.retract,
    )


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


def robust_fit(model, x0, max_rounds=50):
    """IRLS with Cauchy weights (module docstring); returns (x, sigma, weights)."""
    x = np.asarray(x0, float)
    weights = np.ones(model.n_meas)
    med3 = chi_median(3)
    sigma = np.nan
    for _ in range(max_rounds):
        x = solvers.solve(_weighted_problem(model, weights), x, "lm", {"max_iter": 100}).x
        norms = np.linalg.norm(model.residuals(x), axis=1)
        sigma = max(float(np.median(norms)) / med3, 1e-12)
        new = 1.0 / (1.0 + (norms / (CAUCHY_K * sigma)) ** 2)
        if np.max(np.abs(new - weights)) < 1e-6:
            weights = new
            break
        weights = new
    return x, sigma, weights


def _subset(model, mask):
    return CalibrationModel(model.flange2base[mask], model.centre_in_sensor[mask], model.fixed_centre,
                            model.rotation, model.unknowns)


def exclude_inconsistent(dataset, unknowns, mask, excluded):
    """Exclude the rows whose centre columns contradict their own profile
    (:func:`handeye.model.consistency.check_rows`); calibrate, its closed-form baselines and
    diagnose call this one function, so that they fit the same observations.

    Such a row is excluded whatever the statistical screening (and ``--keep-all``) says: its
    two halves cannot both be right, and the profile models and the centre residual would each
    believe a different one. A row the screening excluded too keeps the screening's record,
    its reason extended by the contradiction.

    Parameters
    ----------
    dataset : handeye.model.dataset.Dataset
    unknowns : {'sensor', 'sensor+sphere'}
    mask : ndarray of bool, shape (N,)
        Samples used so far.
    excluded : list of ExcludedSample
        Their records so far.

    Returns
    -------
    mask : ndarray of bool, shape (N,)
    excluded : list of ExcludedSample
        The inconsistent rows first (``statistic`` the chi-square on 3 dof of the row against
        itself, ``residual_mm`` and ``robust_residual_mm`` NaN: no fit is involved; the
        screening's numbers where it excluded the row too), then the others.

    Raises
    ------
    CalibrationInputError
        Naming the rows, when more than half of the rows contradict themselves (a systematic slip:
        a shifted ``profile`` column, another campaign's files) or too few rows would remain for
        the unknowns.
    """
    from handeye.app.calibrate import min_measurements
    from handeye.app.errors import CalibrationInputError
    from handeye.model import consistency

    check = consistency.check_rows(dataset)
    bad = check.inconsistent
    if not bad:
        return mask, excluded
    n, need = len(dataset), min_measurements(unknowns)
    keep = np.asarray(mask, bool) & check.consistent
    if len(bad) > n // 2 or keep.sum() < need:
        named = "; ".join(f"row {c.row} ({c.id!r}: {c.disagreement_mm:.3g} mm, {c.sd:.3g} sd)" for c in bad[:12])
        raise CalibrationInputError(
            f"{dataset.path / 'measurements.csv'}: {len(bad)} of the {len(check.checked)} rows that give both xs, ys, "
            f"zs and a profile contradict themselves (the profile's circle is not the cut the centre columns predict): "
            f"{named}{' ...' if len(bad) > 12 else ''}; "
            + ("so many point to a systematic slip, not a bad row. " if len(bad) > n // 2 else "")
            + (f"Only {int(keep.sum())} usable row(s) would remain; unknowns {unknowns!r} need {need}. "
               if keep.sum() < need else "")
            + "Check that each row's profile file is its own (a column shifted by one row?) and that the centres "
              "come from the same scans; or leave xs, ys, zs empty to reconstruct the centres from the profiles")
    screened = {e.row: e for e in excluded}
    records = []
    for c in bad:
        also = screened.pop(c.row, None)
        if also is not None:  # a gross error of the centre too: the screening's evidence, both reasons
            records.append(dataclasses.replace(also, reason=f"{also.reason}; and {c.reason}"))
            continue
        records.append(ExcludedSample(
            id=c.id, row=c.row, residual_mm=float("nan"), robust_residual_mm=float("nan"), statistic=c.sd**2,
            p_bonferroni=c.p_bonferroni, reason=c.reason))
    return keep, records + [e for e in excluded if e.row in screened]


def screen(dataset, unknowns, start, alpha=ALPHA, min_keep=None):
    """Find gross errors (module docstring).

    Parameters
    ----------
    dataset : handeye.model.dataset.Dataset
        Every sample (ids and rows name them in the report).
    unknowns : {'sensor', 'sensor+sphere'}
    start : ndarray, shape (4, 4)
        Start sensor pose (sensor in flange, mm).
    alpha : float
        Family-wise significance level.
    min_keep : int, optional
        Never keep fewer samples; default ``max(N // 2 + 1, 4)``.

    Returns
    -------
    Screening
    """
    ids, rows = dataset.ids, dataset.rows
    full = CalibrationModel.from_dataset(dataset, "local", unknowns)
    n = full.n_meas
    min_keep = min(min_keep or max(n // 2 + 1, 4), n)
    x_rob, sigma, _ = robust_fit(full, full.point_from(start))
    norms = np.linalg.norm(full.residuals(x_rob), axis=1)
    p_chi = chi2_survival_array((norms / sigma) ** 2, 3)
    inliers = np.minimum(p_chi * n, 1.0) >= alpha
    note = ""
    if inliers.sum() < min_keep:
        improbable = n - int(inliers.sum())
        keep = np.argsort(norms)[:min_keep]
        inliers = np.zeros(n, bool)
        inliers[keep] = True
        note = (f"the robust pass found {improbable} improbable sample(s), but at least {min_keep} of {n} must be "
                f"kept; kept the {min_keep} best")
    seen = set()
    x = x_rob
    for _ in range(2 * n):
        key = inliers.tobytes()
        if key in seen:
            note = note or "the exclusion test cycled; stopped at a set seen before"
            break
        seen.add(key)
        sub = _subset(full, inliers)
        x = least_squares(sub, x).x
        e, j = full.residual_and_jacobian(x)
        stat, pval = deletion_statistics(e, j, inliers)
        adj = np.minimum(pval * n, 1.0)
        fitted_bad = np.where(inliers & (adj < alpha))[0]
        excluded_ok = np.where(~inliers & (adj >= alpha))[0]
        if len(fitted_bad):
            if inliers.sum() <= min_keep:
                note = note or f"more samples test as outliers, but at least {min_keep} must be kept"
                break
            if n > LOO_EXACT_UP_TO:  # many samples: all significant ones at once (linear, not quadratic)
                room = max(int(inliers.sum()) - min_keep, 0)
                inliers[fitted_bad[np.argsort(-stat[fitted_bad])][:room]] = False
            else:  # one at a time: a gross error can mask another
                inliers[fitted_bad[np.argmax(stat[fitted_bad])]] = False
        elif len(excluded_ok):
            if n > LOO_EXACT_UP_TO:
                inliers[excluded_ok] = True
            else:
                inliers[excluded_ok[np.argmin(stat[excluded_ok])]] = True
        else:
            break
    e, j = full.residual_and_jacobian(x)
    stat, pval = deletion_statistics(e, j, inliers)
    adj = np.minimum(pval * n, 1.0)
    excluded = []
    for k in np.where(~inliers)[0]:
        excluded.append(ExcludedSample(
            id=ids[k],
            row=int(rows[k]),
            residual_mm=float(np.linalg.norm(e[k])),
            robust_residual_mm=float(norms[k]),
            statistic=float(stat[k]),
            p_bonferroni=float(adj[k]),
            reason=(f"prediction error {np.linalg.norm(e[k]):.2f} mm is improbable under the fit of the other "
                    f"samples (F = {stat[k]:.1f}, Bonferroni p = {adj[k]:.2g} < {alpha:g})"),
        ))
    return Screening(
        inliers=inliers,
        excluded=excluded,
        robust_sigma_mm=float(sigma),
        robust_sensor2flange=full.sensor2flange(x_rob),
        robust_centre=full.sphere_centre(x_rob),
        note=note,
    )


#: Up to this many samples leave-one-out refits every sample exactly; above, the deletion formula
#: (the exact update of the linearised problem) gives every sample at once, and only samples of
#: high leverage (largest eigenvalue of the hat block above LOO_LEVERAGE) are refitted.
LOO_EXACT_UP_TO = 2000
LOO_LEVERAGE = 0.5


def _refit_error(model, x, keep, i):
    xi = least_squares(_subset(model, keep), x).x
    t2 = model.sensor2flange(xi)
    pred = model.flange2base[i] @ t2 @ np.append(model.centre_in_sensor[i], 1.0)
    return float(np.linalg.norm(pred[:3] - model.sphere_centre(xi)))


def leave_one_out(model, x, mask=None):
    """Leave-one-out prediction errors of the sphere centre, mm.

    For each sample i in ``mask`` the calibration is refitted without it and i's centre is
    predicted: ``|T1_i T2_(-i) xs_i - c_(-i)|``. An accuracy figure that the fit's own
    residual cannot flatter. Up to :data:`LOO_EXACT_UP_TO` samples every refit is exact; above,
    the deletion formula ``e_(i) = (I - H_ii)^-1 e_i`` (H_ii = J_i (J^T J)^-1 J_i^T, the 3x3 hat
    block) gives all of them in time linear in the samples, and the samples whose leverage
    makes the linearisation doubtful are refitted exactly.

    Parameters
    ----------
    model : CalibrationModel
        ``local`` rotation; all samples.
    x : ndarray
        The fit on the samples of ``mask`` (start of every refit).
    mask : ndarray of bool, optional
        Samples to use (default all).

    Returns
    -------
    ndarray, shape (N,)
        NaN where the sample is not in ``mask``.
    """
    mask = np.ones(model.n_meas, bool) if mask is None else np.asarray(mask, bool)
    out = np.full(model.n_meas, np.nan)
    used = np.where(mask)[0]
    if len(used) <= LOO_EXACT_UP_TO:
        for i in used:
            keep = mask.copy()
            keep[i] = False
            out[i] = _refit_error(model, x, keep, i)
        return out
    e, j = model.residual_and_jacobian(x)
    e, j = e.reshape(model.n_meas, 3), j.reshape(model.n_meas, 3, -1)
    info_inv = np.linalg.inv(np.einsum("nip,niq->pq", j[mask], j[mask]))
    h = np.einsum("nip,pq,njq->nij", j[mask], info_inv, j[mask])
    deleted = np.linalg.solve(np.eye(3) - h, e[mask][..., None])[..., 0]
    out[mask] = np.linalg.norm(deleted, axis=1)
    for k in np.where(np.linalg.eigvalsh(h)[:, -1] > LOO_LEVERAGE)[0]:
        i = used[k]
        keep = mask.copy()
        keep[i] = False
        out[i] = _refit_error(model, x, keep, i)
    return out
