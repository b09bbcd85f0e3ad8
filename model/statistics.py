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

Tail probabilities are the regularised incomplete beta and gamma functions, vectorised in numpy
(continued fractions; checked against mpmath in the tests, which also showed mpmath's upper-tail
form underflowing to 0 far in the tail and failing to converge for 60,000 degrees of freedom).
"""
from __future__ import annotations

import dataclasses
import functools
import math

import numpy as np


def f_survival(x, d1, d2):
    """P(F > x) for an F(d1, d2) variable; NaN for a NaN statistic (never a hang), 0 at infinity."""
    return float(f_survival_array(x, d1, d2))


def chi2_survival(x, k):
    """P(chi^2_k > x); NaN for a NaN statistic (never a hang), 0 at infinity."""
    return float(chi2_survival_array(x, k))


#: log Gamma, vectorised; NaN outside its domain (a degenerate number of degrees of freedom).
_LGAMMA = np.vectorize(lambda v: math.lgamma(v) if v > 0 else math.nan, otypes=[float])


def _gammainc_upper(a, x, iterations=500):
    """Regularised upper incomplete gamma Q(a, x), vectorised (series below a + 1, Lentz's
    continued fraction above; Numerical Recipes 6.2), accurate to ~1e-14 relative."""
    a, x = np.broadcast_arrays(np.asarray(a, float), np.asarray(x, float))
    out = np.full(a.shape, np.nan)
    lg = _LGAMMA(a)
    with np.errstate(all="ignore"):
        log_front = -x + a * np.log(x) - lg
        low = x < a + 1.0
        # series: P = exp(front) sum x^n / (a (a+1) ... (a+n))
        ap, term = a.copy(), 1.0 / a
        total = term.copy()
        for _ in range(iterations):
            ap = ap + 1.0
            term = term * x / ap
            total = total + term
            if np.all(np.abs(term[low]) <= np.abs(total[low]) * 1e-16):
                break
        p_low = np.exp(log_front) * total
        # continued fraction for Q (modified Lentz)
        tiny = 1e-300
        b = x + 1.0 - a
        c = np.full(a.shape, 1.0 / tiny)
        d = 1.0 / np.where(b == 0, tiny, b)
        h = d.copy()
        for i in range(1, iterations):
            an = -i * (i - a)
            b = b + 2.0
            d = an * d + b
            d = 1.0 / np.where(np.abs(d) < tiny, tiny, d)
            c = b + an / c
            c = np.where(np.abs(c) < tiny, tiny, c)
            delta = d * c
            h = h * delta
            if np.all(np.abs(delta[~low] - 1.0) <= 1e-16):
                break
        q_high = np.exp(log_front) * h
    out = np.where(low, 1.0 - p_low, q_high)
    out = np.where(x <= 0, 1.0, out)
    out = np.where(np.isposinf(x), 0.0, out)
    return np.clip(np.where(np.isnan(x) | np.isnan(a), np.nan, out), 0.0, 1.0)


def _betacf(a, b, x, iterations=500, tol=3e-16):
    """Continued fraction of the incomplete beta (modified Lentz), iterating only on the elements
    that have not converged yet (``tol`` relative, about the rounding of one step)."""
    tiny = 1e-300
    a, b, x = (np.ravel(np.asarray(v, float)).copy() for v in np.broadcast_arrays(a, b, x))
    shape = np.broadcast(*np.broadcast_arrays(a, b, x)).shape
    qab, qap, qam = a + b, a + 1.0, a - 1.0
    c = np.ones_like(x)
    d = 1.0 - qab * x / qap
    d = 1.0 / np.where(np.abs(d) < tiny, tiny, d)
    h = d.copy()
    active = np.arange(len(x))
    for m in range(1, iterations):
        if not len(active):
            break
        aa_, bb, xx, qa, qp, qm = a[active], b[active], x[active], qab[active], qap[active], qam[active]
        cc, dd = c[active], d[active]
        m2 = 2 * m
        aa = m * (bb - m) * xx / ((qm + m2) * (aa_ + m2))
        dd = 1.0 + aa * dd
        dd = 1.0 / np.where(np.abs(dd) < tiny, tiny, dd)
        cc = 1.0 + aa / cc
        cc = np.where(np.abs(cc) < tiny, tiny, cc)
        factor = dd * cc
        aa = -(aa_ + m) * (qa + m) * xx / ((aa_ + m2) * (qp + m2))
        dd = 1.0 + aa * dd
        dd = 1.0 / np.where(np.abs(dd) < tiny, tiny, dd)
        cc = 1.0 + aa / cc
        cc = np.where(np.abs(cc) < tiny, tiny, cc)
        delta = dd * cc
        h[active] *= factor * delta
        c[active], d[active] = cc, dd
        active = active[~(np.abs(delta - 1.0) <= tol) & np.isfinite(delta)]
    return h.reshape(shape)


def _betainc(a, b, x):
    """Regularised incomplete beta I_x(a, b), vectorised (continued fraction, Numerical Recipes
    6.4, with the symmetry I_x(a, b) = 1 - I_(1-x)(b, a) where it converges faster)."""
    a, b, x = np.broadcast_arrays(np.asarray(a, float), np.asarray(b, float), np.asarray(x, float))
    with np.errstate(all="ignore"):
        lbeta = (_LGAMMA(a + b) - _LGAMMA(a)
                 - _LGAMMA(b))
        front = np.exp(lbeta + a * np.log(x) + b * np.log1p(-x))
        direct = x < (a + 1.0) / (a + b + 2.0)
        out = np.where(direct, front * _betacf(a, b, x) / a, 1.0 - front * _betacf(b, a, 1.0 - x) / b)
    out = np.where(x <= 0, 0.0, np.where(x >= 1, 1.0, out))
    return np.clip(out, 0.0, 1.0)


#: Above this many denominator degrees of freedom P(F > x) is taken as P(chi^2_d1 > d1 x): the
#: relative error is O(1/d2) (< 1e-4), far below what a test at a level alpha can see.
F_AS_CHI2_ABOVE = 10_000


def f_survival_array(x, d1, d2):
    """P(F > x) for F(d1, d2), vectorised over x (and the degrees of freedom); NaN in, NaN out.

    ``P(F > x) = I_{d2 / (d2 + d1 x)}(d2 / 2, d1 / 2)``; agrees with :func:`f_survival`
    (mpmath) to ~1e-12 (tested), at a fraction of the cost for many samples.
    """
    x, d1, d2 = np.broadcast_arrays(np.asarray(x, float), np.asarray(d1, float), np.asarray(d2, float))
    large = d2 > F_AS_CHI2_ABOVE  # the continued fraction needs ~sqrt(d2) terms; d1 F -> chi^2_d1 there
    out = np.empty(x.shape)
    with np.errstate(all="ignore"):
        z = np.where(np.isposinf(x), 0.0, d2 / (d2 + d1 * x))
        if np.any(~large):
            out[~large] = _betainc(d2[~large] / 2.0, d1[~large] / 2.0, z[~large])
        if np.any(large):
            out[large] = _gammainc_upper(d1[large] / 2.0, d1[large] * x[large] / 2.0)
    out = np.where(x <= 0, 1.0, out)
    bad = np.isnan(x) | np.isnan(d1) | np.isnan(d2) | (d1 <= 0) | (d2 <= 0)
    return np.where(bad, np.nan, out)


def chi2_survival_array(x, k):
    """P(chi^2_k > x), vectorised; NaN in, NaN out; agrees with :func:`chi2_survival` (tested)."""
    x, k = np.broadcast_arrays(np.asarray(x, float), np.asarray(k, float))
    out = _gammainc_upper(k / 2.0, x / 2.0)
    return np.where(np.isnan(x) | np.isnan(k) | (k <= 0), np.nan, out)


def chi_median(k):
    """Median of the chi distribution with k degrees of freedom (norm of a k-vector of N(0,1)).

    Newton's method on ``P(chi_k <= r) = 1/2`` (:func:`chi2_survival_array` and the chi
    density), from ``sqrt(k - 2/3)``, to the last bits of a float; no mpmath (and so no sympy)
    for one scalar. Checked against mpmath in the tests.
    """
    return _chi_median(float(k))


@functools.lru_cache(maxsize=None)
def _chi_median(k):
    log_norm = (k / 2.0 - 1.0) * math.log(2.0) + math.lgamma(k / 2.0)
    r = math.sqrt(max(k - 2.0 / 3.0, 0.25))
    for _ in range(100):
        below = 1.0 - float(chi2_survival_array(r * r, k))
        density = math.exp((k - 1.0) * math.log(r) - r * r / 2.0 - log_norm)
        new = r - (below - 0.5) / density
        new = new if new > 0 else r / 2.0
        if abs(new - r) <= 1e-15 * r:
            return new
        r = new
    return r


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


def prediction_test(e_all, j_all, fitted):
    """A function ``(e_i (3,), J_i (3, p)) -> (T_i, p-value)``: the statistic of a sample left out
    of the fit on ``fitted`` (module docstring), for one sample at a time without re-deriving the
    fit's information each time (as :func:`deletion_statistics` does for all of them)."""
    fitted = np.asarray(fitted, bool)
    jf = np.asarray(j_all, float)[fitted].reshape(-1, np.shape(j_all)[2])
    ef = np.asarray(e_all, float)[fitted].ravel()
    m, p = jf.shape
    info_inv = np.linalg.pinv(jf.T @ jf)
    scale = 3.0 * float(ef @ ef) / (m - p) if m > p else float("nan")

    def test(e, j):
        h = j @ info_inv @ j.T
        stat = float(e @ np.linalg.solve(np.eye(3) + h, e)) / scale
        return stat, f_survival(stat, 3, m - p)

    return test


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
    eye = np.eye(3)
    e_all, j_all = np.asarray(e_all, float), np.asarray(j_all, float)
    h = np.einsum("nip,pq,njq->nij", j_all, info_inv, j_all)  # hat blocks, all samples at once
    sign = np.where(fitted, -1.0, 1.0)[:, None, None]
    metric = eye + sign * h + np.where(fitted, 1e-12, 0.0)[:, None, None] * eye
    q = np.einsum("ni,ni->n", e_all, np.linalg.solve(metric, e_all[..., None])[..., 0])
    d2 = np.where(fitted, m - p - 3, m - p).astype(float)
    with np.errstate(all="ignore"):
        s2 = np.where(fitted, np.maximum(ssr - q, 1e-300) / d2, ssr / d2)
        s2 = np.where(d2 > 0, s2, np.nan)
        stat = q / (3.0 * s2)
    return stat, f_survival_array(stat, 3, d2)
