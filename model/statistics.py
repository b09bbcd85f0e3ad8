"""Statistics of a least-squares calibration: covariance, deletion tests, tail probabilities.

Noise model: the residual components are independent, zero-mean, with one common variance
sigma^2 (mm^2), estimated as ``sigma^2 = SSR / (m - p)`` (m = 3N components, p unknowns).
Then, to first order, ``Cov(theta) = sigma^2 (J^T J)^-1`` on the local chart of the solution.

Deletion (externally studentised) statistics for a measurement ``i`` with residual block e_i
(3,), Jacobian block J_i (3, p) and hat block ``H_ii = J_i (J^T J)^-1 J_i^T``:

* if ``i`` was fitted: ``q_i = e_i^T (I - H_ii)^-1 e_i`` is the squared leave-one-out residual
  in its own metric, ``s_(i)^2 = (SSR - q_i) / (m - p - 3)`` the variance without it, and
  ``T_i = q_i / (3 s_(i)^2) ~ F(3, m - p - 3)``;
* if ``i`` was left out: its prediction error has covariance ``sigma^2 (I + H_ii)``, and
  ``T_i = e_i^T (I + H_ii)^-1 e_i / (3 sigma^2) ~ F(3, m - p)``.

Tail probabilities use mpmath's regularised incomplete beta (mpmath comes with sympy).
"""
from __future__ import annotations

import dataclasses

import numpy as np


def f_survival(x, d1, d2):
    """P(F > x) for an F(d1, d2) variable; NaN for a NaN statistic (never a hang), 0 at infinity."""
    import mpmath

    if x != x or d1 != d1 or d2 != d2:  # NaN: mpmath's series would never converge
        return float("nan")
    if x <= 0:
        return 1.0
    if d2 <= 0 or d1 <= 0:
        return float("nan")
    if x == float("inf"):
        return 0.0
    z = d1 * x / (d1 * x + d2)
    return min(max(float(mpmath.betainc(d1 / 2.0, d2 / 2.0, z, 1, regularized=True)), 0.0), 1.0)


def chi2_survival(x, k):
    """P(chi^2_k > x); NaN for a NaN statistic (never a hang), 0 at infinity."""
    import mpmath

    if x != x or k != k or k <= 0:
        return float("nan")
    if x <= 0:
        return 1.0
    if x == float("inf"):
        return 0.0
    return min(max(float(mpmath.gammainc(k / 2.0, x / 2.0, mpmath.inf, regularized=True)), 0.0), 1.0)


def chi_median(k):
    """Median of the chi distribution with k degrees of freedom (norm of a k-vector of N(0,1))."""
    import mpmath

    def below_half(x):
        return mpmath.gammainc(k / 2.0, 0, x / 2.0, regularized=True) - 0.5

    return float(mpmath.sqrt(mpmath.findroot(below_half, k - 2.0 / 3.0)))


@dataclasses.dataclass(frozen=True)
class Covariance:
    """Covariance of a least-squares estimate.

    Attributes
    ----------
    sigma : float
        Estimated residual standard deviation per component, mm.
    dof : int
        Degrees of freedom ``m - p``.
    matrix : ndarray, shape (p, p)
        ``sigma^2 (J^T J)^-1`` in the step's units (mm, rad).
    std : ndarray, shape (p,)
    correlation : ndarray, shape (p, p)
    """

    sigma: float
    dof: int
    matrix: np.ndarray
    std: np.ndarray
    correlation: np.ndarray


def covariance(residual, jacobian, groups=None):
    """:class:`Covariance` from the stacked residual (m,) and Jacobian (m, p) at the solution.

    With ``groups`` (m,) -- rows that share errors, such as the points of one profile, which
    one robot pose error moves together -- the cluster-robust (sandwich) estimate
    ``G/(G-1) (J^T J)^-1 (sum_g J_g^T r_g r_g^T J_g) (J^T J)^-1`` is returned instead, which
    does not assume independent rows.
    """
    r = np.asarray(residual, float)
    j = np.asarray(jacobian, float)
    m, p = j.shape
    dof = m - p
    if dof <= 0:
        raise ValueError(f"no degrees of freedom left for a covariance ({m} residuals, {p} unknowns)")
    sigma2 = float(r @ r) / dof
    bread = np.linalg.pinv(j.T @ j)
    if groups is None:
        cov = sigma2 * bread
    else:
        groups = np.asarray(groups)
        labels = np.unique(groups)
        scores = np.array([j[groups == g].T @ r[groups == g] for g in labels])
        g = len(labels)
        cov = g / max(g - 1, 1) * bread @ (scores.T @ scores) @ bread
    std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    corr = cov / np.outer(np.where(std > 0, std, 1.0), np.where(std > 0, std, 1.0))
    return Covariance(float(np.sqrt(sigma2)), dof, cov, std, corr)


def deletion_statistics(e_all, j_all, fitted):
    """Externally studentised statistics of every measurement (module docstring).

    Parameters
    ----------
    e_all : ndarray, shape (N, 3)
        Residuals of all measurements at the fit on the ``fitted`` ones.
    j_all : ndarray, shape (N, 3, p)
        Their Jacobians there.
    fitted : ndarray of bool, shape (N,)

    Returns
    -------
    stat : ndarray, shape (N,)
        F statistics T_i.
    p_value : ndarray, shape (N,)
        Unadjusted tail probabilities.
    """
    fitted = np.asarray(fitted, bool)
    jf = j_all[fitted].reshape(-1, j_all.shape[2])
    ef = e_all[fitted].ravel()
    m, p = jf.shape
    info_inv = np.linalg.pinv(jf.T @ jf)
    ssr = float(ef @ ef)
    stat = np.empty(len(e_all))
    pval = np.empty(len(e_all))
    eye = np.eye(3)
    for i, (e, j) in enumerate(zip(e_all, j_all)):
        h = j @ info_inv @ j.T
        if fitted[i]:
            q = float(e @ np.linalg.solve(eye - h + 1e-12 * eye, e))
            d2 = m - p - 3
            s2 = max(ssr - q, 1e-300) / d2 if d2 > 0 else float("nan")
            stat[i] = q / (3.0 * s2)
        else:
            d2 = m - p
            stat[i] = float(e @ np.linalg.solve(eye + h, e)) / (3.0 * ssr / d2)
        pval[i] = f_survival(stat[i], 3, d2)
    return stat, pval
