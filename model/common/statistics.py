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
_LGAMMA_ONE = np.vectorize(lambda v: math.lgamma(v) if v > 0 else math.nan, otypes=[float])


def _lgamma(a):
    """log Gamma of an array (any shape), evaluated once per distinct value (the degrees of
    freedom of a whole array of statistics are usually one or two numbers)."""
    a = np.asarray(a, float)
    values, inverse = np.unique(a, return_inverse=True)
    return _LGAMMA_ONE(values)[inverse].reshape(a.shape) if a.size else np.empty(a.shape)


#: Above this ``a`` the factor ``x^a e^-x / Gamma(a)`` is formed from Stirling's series (no
#: cancellation between ``a log x`` and ``log Gamma(a)``, both ~1e7 for a million measurements).
_STIRLING_ABOVE = 10.0


def _log_front(a, x):
    """``log(x^a e^-x / Gamma(a))``, (n,) for (n,) ``a > 0``, ``x > 0``; relative accuracy kept
    for large ``a`` (``a (log1p(u) - u) + log(a / 2 pi) / 2 - stirling(a)``, ``u = (x - a) / a``)."""
    out = np.empty(a.shape)
    small = a <= _STIRLING_ABOVE
    out[small] = -x[small] + a[small] * np.log(x[small]) - _lgamma(a[small])
    b, y = a[~small], x[~small]
    u = (y - b) / b
    inv = 1.0 / b
    stirling = inv * (1 / 12 - inv**2 * (1 / 360 - inv**2 * (1 / 1260 - inv**2 / 1680)))
    out[~small] = b * (np.log1p(u) - u) + 0.5 * np.log(b / (2 * np.pi)) - stirling
    return out


def _compact(done, out, value, index, *state):
    """Store the converged elements' ``value`` in ``out`` and drop them from the iteration's
    state (index and arrays alike) once at least a quarter converged: fancy indexing costs more
    than a few idle elements. Returns ``(index, *state)``."""
    count = np.count_nonzero(done)
    if count * 4 < done.size and count < done.size:
        return (index, *state)
    out[index[done]] = value[done]
    keep = ~done
    return (index[keep], *(s[keep] for s in state))


def _series_p(a, x, tol=3e-16, max_terms=1_000_000, budget=1 << 20):
    """Lower regularised gamma P(a, x) = front * sum_n x^n / (a (a+1) ... (a+n)), (n,) arrays
    with ``x < a + 1`` (terms decrease). Only unconverged elements iterate, in blocks of terms
    (a cumulative product over ``budget / active`` terms at once: one term per pass over a
    million statistics, thousands per pass for the few with a large ``a``)."""
    total = np.zeros(a.shape)
    index, aa, xx, term, tot = np.arange(a.size), a, x, np.ones(a.shape), np.zeros(a.shape)
    n = 0
    while index.size and n < max_terms:
        block = int(min(max(budget // index.size, 1), 4096))
        if block == 1:  # term n, then the running sum: no (active, block) temporaries
            term = term * (xx / (aa + n)) if n else term
            tot = tot + term
            last = term
        else:
            ratios = xx[:, None] / (aa[:, None] + (n + np.arange(block, dtype=float))[None, :])
            if n == 0:
                ratios[:, 0] = 1.0
            terms = term[:, None] * np.cumprod(ratios, axis=1)
            tot = tot + terms.sum(axis=1)
            term = last = terms[:, -1]
        n += block
        done = (last <= tot * tol) | ~np.isfinite(tot)
        index, aa, xx, term, tot = _compact(done, total, tot, index, aa, xx, term, tot)
    total[index] = tot  # beyond max_terms: what the sum reached
    return np.exp(_log_front(a, x)) * total / a


def _continued_fraction_q(a, x, tol=3e-16, iterations=100_000):
    """Upper regularised gamma Q(a, x) by its continued fraction (modified Lentz, Numerical
    Recipes 6.2.7), (n,) arrays with ``x >= a + 1``; only unconverged elements iterate (a few
    dozen steps for a small ``a``, about a thousand for ``a`` ~ 1e6 at ``x`` ~ ``a``)."""
    tiny = 1e-300
    b = x + 1.0 - a
    d = 1.0 / np.where(b == 0, tiny, b)
    h = d.copy()
    index, aa, bb, c, dd, hh = np.arange(a.size), a, b, np.full(a.shape, 1.0 / tiny), d, d.copy()
    for i in range(1, iterations):
        if not index.size:
            break
        an = -i * (i - aa)
        bb = bb + 2.0
        dd = an * dd + bb
        dd = 1.0 / np.where(np.abs(dd) < tiny, tiny, dd)
        c = bb + an / c
        c = np.where(np.abs(c) < tiny, tiny, c)
        delta = dd * c
        hh = hh * delta
        done = (np.abs(delta - 1.0) <= tol) | ~np.isfinite(delta)
        index, aa, bb, c, dd, hh = _compact(done, h, hh, index, aa, bb, c, dd, hh)
    h[index] = hh
    return np.exp(_log_front(a, x)) * h


def _gammainc_upper(a, x):
    """Regularised upper incomplete gamma Q(a, x), vectorised over any shape: the series for
    P below ``a + 1`` (Q = 1 - P is not small there), the continued fraction above, each on the
    elements that need it and iterated only until they converge. Agrees with
    ``scipy.special.gammaincc`` to ~1e-13 relative, far tails and ``a`` ~ 1e6 included (tested)."""
    a, x = np.broadcast_arrays(np.asarray(a, float), np.asarray(x, float))
    shape = a.shape
    a, x = a.ravel(), x.ravel()
    out = np.full(a.shape, np.nan)
    ok = np.isfinite(a) & (a > 0) & ~np.isnan(x)
    out[ok & (x <= 0)] = 1.0
    out[ok & np.isposinf(x)] = 0.0
    inner = ok & (x > 0) & np.isfinite(x)
    low = inner & (x < a + 1.0)
    high = inner & ~low
    with np.errstate(all="ignore"):
        if np.any(low):
            out[low] = 1.0 - _series_p(a[low], x[low])
        if np.any(high):
            out[high] = _continued_fraction_q(a[high], x[high])
    return np.clip(out, 0.0, 1.0).reshape(shape)


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
        lbeta = (_lgamma(a + b) - _lgamma(a) - _lgamma(b))
        front = np.exp(lbeta + a * np.log(x) + b * np.log1p(-x))
        direct = x < (a + 1.0) / (a + b + 2.0)
        a1, b1, x1, f1, d1 = (np.ravel(v) for v in (a, b, x, front, direct))
        out = np.empty(x1.shape)
        # each element's continued fraction on its own side only (the other side's is not needed)
        out[d1] = f1[d1] * _betacf(a1[d1], b1[d1], x1[d1]) / a1[d1]
        out[~d1] = 1.0 - f1[~d1] * _betacf(b1[~d1], a1[~d1], 1.0 - x1[~d1]) / b1[~d1]
        out = out.reshape(x.shape)
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
    return np.where(np.isnan(x) | np.isnan(d1) | np.isnan(d2) | (d1 <= 0) | (d2 <= 0), np.nan, out)


def chi2_survival_array(x, k):
    """P(chi^2_k > x), vectorised; NaN in, NaN out; agrees with :func:`chi2_survival` (tested)."""
    x, k = np.broadcast_arrays(np.asarray(x, float), np.asarray(k, float))
    return np.where(np.isnan(x) | np.isnan(k) | (k <= 0), np.nan, _gammainc_upper(k / 2.0, x / 2.0))


def threshold(survival, p, lo=0.0, hi=1.0, rtol=1e-12):
    """The statistic ``x`` where the decreasing tail ``survival(x)`` (a scalar function) falls
    to ``p``, to ``rtol`` relative; ``inf`` when it never does.

    The bracket is doubled until it holds the crossing, then narrowed by false position with the
    Illinois modification (the end that stays has its value halved, so both ends converge, superlinearly:
    Dahlquist & Bjoerck, *Numerical Methods*, 6.2), each trial kept a quarter of the tolerance inside the
    bracket, and a bisection step after three steps that did not halve it: at worst four evaluations per
    halving, and on the tails here 11-22 where bisection takes ~45 to 1e-12 (the power statement's
    noncentral tails cost a sum of continued fractions each). Returns the low end of the final bracket,
    where ``survival > p``."""
    g_lo = None  # survival(lo) - p, where known
    g_hi = survival(hi) - p
    while g_hi > 0:
        lo, hi, g_lo = hi, 2.0 * hi, g_hi
        if hi > 1e300:
            return math.inf
        g_hi = survival(hi) - p
    g_lo, side = (survival(lo) - p if g_lo is None else g_lo), 0
    if not g_lo > 0:
        return lo  # at or below p already (or not a number)
    tries, reference = 0, hi - lo  # false-position steps since the bracket last halved; its width then
    while hi - lo > rtol * hi:
        bisect = tries >= 3 or not g_lo > 0 >= g_hi
        margin = 0.25 * rtol * hi
        c = 0.5 * (lo + hi) if bisect else min(max(hi - g_hi * (hi - lo) / (g_hi - g_lo), lo + margin), hi - margin)
        g_c = survival(c) - p
        if g_c > 0:
            lo, g_lo = c, g_c
            g_hi, side = (0.5 * g_hi if side == 1 else g_hi), 1
        else:
            hi, g_hi = c, g_c
            g_lo, side = (0.5 * g_lo if side == -1 else g_lo), -1
        tries, reference = (0, hi - lo) if bisect or hi - lo <= 0.5 * reference else (tries + 1, reference)
    return lo


#: Up to this many statistics of one distribution every tail is evaluated; above, only those
#: beyond the threshold (:func:`threshold`) where the adjusted value can fall below 1.
BONFERRONI_ALL_UP_TO = 10_000


def bonferroni_survival(stat, n_tests, d1, d2=None):
    """Bonferroni-adjusted tails ``min(n_tests P(T > stat), 1)`` of F(d1, d2) statistics (of
    chi^2_d1 ones when ``d2`` is None), evaluating the tail only where it can fall below
    ``1 / n_tests``: elsewhere the adjusted value is 1 whatever the tail (the bulk of a million
    statistics needs no continued fraction).

    Parameters
    ----------
    stat : ndarray, shape (N,)
        Statistics; NaN in, NaN out.
    n_tests : int
        Number of tests of the family.
    d1 : float
        Degrees of freedom (numerator).
    d2 : float or ndarray, shape (N,), optional
        Denominator degrees of freedom (a few distinct values at most); None for chi-square.

    Returns
    -------
    ndarray, shape (N,)
        Adjusted p-values in [0, 1].
    """
    stat = np.asarray(stat, float)
    d2 = np.full(stat.shape, np.nan) if d2 is None else np.broadcast_to(np.asarray(d2, float), stat.shape)
    out = np.where(np.isnan(stat), np.nan, 1.0)
    for dof in np.unique(d2):  # NaN d2: chi-square (np.unique keeps one NaN per NaN)
        same = np.isnan(d2) if np.isnan(dof) else d2 == dof
        if np.isnan(dof):
            tail = functools.partial(chi2_survival_array, k=d1)
        elif dof <= 0:
            out[same] = np.nan
            continue
        else:
            tail = functools.partial(f_survival_array, d1=d1, d2=dof)
        if same.sum() <= BONFERRONI_ALL_UP_TO:  # few: every tail (the threshold's search would cost more)
            need = same & ~np.isnan(stat)
        else:
            bound = threshold(lambda x: float(tail(x)), 1.0 / max(n_tests, 1))
            need = same & (stat >= bound * (1.0 - 1e-9))  # margin: the threshold's tolerance and the tail's rounding
        out[need] = np.minimum(tail(stat[need]) * n_tests, 1.0)
    return out


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


def covariance_normal(jtj, rtr, m):
    """:class:`Covariance` (independent rows) from the normal equations at the solution:
    ``J^T J`` (p, p), ``r^T r`` and the number of residuals m, as :func:`covariance` from r and J."""
    p = len(jtj)
    dof = m - p
    if dof <= 0:
        raise ValueError(f"no degrees of freedom left for a covariance ({m} residuals, {p} unknowns)")
    sigma2 = float(rtr) / dof
    cov = sigma2 * np.linalg.pinv(np.asarray(jtj, float))
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
        stat = float(e @ np.linalg.solve(np.eye(3) + j @ info_inv @ j.T, e)) / scale
        return stat, f_survival(stat, 3, m - p)

    return test


def deletion_statistics(e_all, j_all, fitted, n_tests=None):
    """Externally studentised statistics of every measurement (module docstring).

    Parameters
    ----------
    e_all : ndarray, shape (N, 3)
        Residuals of all measurements at the fit on the ``fitted`` ones.
    j_all : ndarray, shape (N, 3, p)
        Their Jacobians there.
    fitted : ndarray of bool, shape (N,)
    n_tests : int, optional
        When given, the p-values are Bonferroni-adjusted over ``n_tests`` tests
        (:func:`bonferroni_survival`: the tail is evaluated only where it can matter).

    Returns
    -------
    stat : ndarray, shape (N,)
        F statistics T_i.
    p_value : ndarray, shape (N,)
        Unadjusted tail probabilities (adjusted with ``n_tests``).
    """
    fitted = np.asarray(fitted, bool)
    jf = j_all[fitted].reshape(-1, j_all.shape[2])
    ef = e_all[fitted].ravel()
    m, p = jf.shape
    info_inv = np.linalg.pinv(jf.T @ jf)
    ssr = float(ef @ ef)
    q = _deletion_quadratic(np.asarray(e_all, float), np.asarray(j_all, float), fitted, info_inv)
    return _deletion_tail(q, fitted, ssr, m, p, n_tests)


def deletion_statistics_chunked(chunks, fitted, n_tests=None):
    """:func:`deletion_statistics` in two passes over chunks of the samples, never holding the
    Jacobian of all of them: the first sums the fit's information matrix and sum of squares,
    the second gives each chunk's statistics.

    Parameters
    ----------
    chunks : callable
        ``chunks()`` yields ``(rows, e, jac)``: a slice of the samples, their residuals (R, 3)
        and Jacobians (R, 3, p) (as :meth:`handeye.model.fit.calibration.CalibrationModel.chunks`);
        called twice.
    fitted : ndarray of bool, shape (N,)
    n_tests : int, optional

    Returns
    -------
    stat, p_value : ndarray, shape (N,)
        As :func:`deletion_statistics`.
    e_all : ndarray, shape (N, 3)
        The residuals, gathered in the second pass.
    """
    fitted = np.asarray(fitted, bool)
    info, ssr, m, p = 0.0, 0.0, 0, 0
    for rows, e, jac in chunks():
        keep = fitted[rows]
        jf, ef = jac[keep].reshape(-1, jac.shape[2]), e[keep].ravel()
        info, ssr, m, p = info + jf.T @ jf, ssr + float(ef @ ef), m + len(ef), jac.shape[2]
    info_inv = np.linalg.pinv(info)
    q, e_all = np.empty(len(fitted)), np.empty((len(fitted), 3))
    for rows, e, jac in chunks():
        q[rows], e_all[rows] = _deletion_quadratic(e, jac, fitted[rows], info_inv), e
    stat, p_value = _deletion_tail(q, fitted, ssr, m, p, n_tests)
    return stat, p_value, e_all


def _deletion_quadratic(e_all, j_all, fitted, info_inv):
    """``e_i^T (I -+ H_ii)^-1 e_i`` (N,) of each sample (minus for a fitted one)."""
    eye = np.eye(3)
    h = np.einsum("nip,pq,njq->nij", j_all, info_inv, j_all)  # hat blocks, all samples at once
    sign = np.where(fitted, -1.0, 1.0)[:, None, None]
    metric = eye + sign * h + np.where(fitted, 1e-12, 0.0)[:, None, None] * eye
    return np.einsum("ni,ni->n", e_all, np.linalg.solve(metric, e_all[..., None])[..., 0])


def _deletion_tail(q, fitted, ssr, m, p, n_tests):
    """The F statistics and their tail probabilities from the quadratic forms ``q``."""
    d2 = np.where(fitted, m - p - 3, m - p).astype(float)
    with np.errstate(all="ignore"):
        s2 = np.where(fitted, np.maximum(ssr - q, 1e-300) / d2, ssr / d2)
        s2 = np.where(d2 > 0, s2, np.nan)
        stat = q / (3.0 * s2)
    if n_tests is not None:
        return stat, bonferroni_survival(stat, n_tests, 3, d2)
    return stat, f_survival_array(stat, 3, d2)
