"""The score tests of the extended model's candidate effects, and the identifiability gate.

Linear algebra on a fit (:class:`handeye.model.fit.extended.Fit`: residuals ``e``, Jacobian
``jac``, ``p`` parameters) and a candidate effect's Jacobian columns: the gate (the fraction of
the candidate's columns outside the span of the fit's Jacobian, and which parameters absorb
the rest), the score (Lagrange multiplier) test, with the plain or the cluster-robust variance,
and the orthonormal basis of the span they share (:func:`projection`; CholeskyQR2 for tall
Jacobians). :mod:`handeye.model.fit.extended` computes the columns and runs the tests.
"""
from __future__ import annotations

import numpy as np

from handeye.model.common.statistics import chi2_survival

#: Above this many rows the orthonormal basis of the Jacobian's columns is CholeskyQR2 (two
#: Cholesky passes of the normal equations: matrix products, several times faster than
#: Householder QR on (3 million, p), and as orthogonal for a condition number below ~1e7).
CHOLESKY_QR_ABOVE = 30_000


def _times(tall, small):
    """``tall @ small`` for a tall (m, p) and a small (p, k) matrix, as ``(small^T tall^T)^T``:
    the same products, several times faster (numpy's matmul of a tall matrix by a small one
    does not reach BLAS's speed; the transposed product does)."""
    return (small.T @ tall.T).T


def cholesky(gram):
    """The lower Cholesky factor of ``gram``, or None where it fails or is ill-conditioned (a
    diagonal entry below 1e-7 of the largest)."""
    try:
        chol = np.linalg.cholesky(gram)
    except np.linalg.LinAlgError:
        return None
    d = np.abs(np.diag(chol))
    return chol if np.all(np.isfinite(chol)) and d.min() > 1e-7 * d.max() else None


def projection(jac_cur):
    """Orthonormal basis (m, p) of the columns of ``jac_cur`` (m, p)."""
    if len(jac_cur) <= CHOLESKY_QR_ABOVE:
        return np.linalg.qr(jac_cur)[0]
    q = jac_cur
    for _ in range(2):
        chol = cholesky(q.T @ q)
        if chol is None:  # ill-conditioned: Householder
            return np.linalg.qr(jac_cur)[0]
        q = _times(q, np.linalg.inv(chol.T))
    return q


def gate(jac_cur, cand, names, q=None, absorbers=True):
    """Fraction of the candidate's columns outside the current span, and who absorbs it
    (``q``: :func:`projection` of ``jac_cur`` when already computed; without ``absorbers``
    the list is empty and its least-squares solve skipped)."""
    norms = np.linalg.norm(cand, axis=0)
    scaled = cand / np.where(norms > 0, norms, 1.0)
    q = projection(jac_cur) if q is None else q
    perp = scaled - _times(q, q.T @ scaled)
    s_perp = np.linalg.svd(perp, compute_uv=False)
    s_full = np.linalg.svd(scaled, compute_uv=False)
    frac = float(s_perp[-1] / max(s_full[-1], 1e-300))
    if not absorbers:
        return frac, []
    coef, *_ = np.linalg.lstsq(jac_cur, scaled, rcond=None)
    weight = np.abs(coef) * np.linalg.norm(jac_cur, axis=0)[:, None]
    # strongest first; weights equal to 6 digits (a frame shift absorbed by cx, cy, cz alike)
    # keep the parameters' order, so the list does not follow the last bits of the solve
    strength = np.round(weight.max(axis=1) / max(weight.max(), 1e-300), 6)
    absorbers = [names[k] for k in np.argsort(-strength, kind="stable") if strength[k] > 0.1][:6]
    return frac, absorbers


def _score(fit, mask, cand, q=None):
    """The residual ``r`` of the samples in ``mask``, the candidate's columns ``a`` less their part
    in the span of the fit's Jacobian (``q``: its :func:`projection` when already computed), and
    the score ``a^T r``."""
    r = fit.e[mask].ravel()
    q = projection(fit.jac[mask].reshape(-1, fit.p)) if q is None else q
    a = cand - _times(q, q.T @ cand)
    return r, a, a.T @ r


def score_test(fit, mask, cand):
    """The score test with the variance of equal noise, ``g^T (a^T a)^-1 g / sigma^2`` (``g = a^T r``,
    :func:`_score`): the statistic and its chi-square p-value."""
    _, a, g = _score(fit, mask, cand)
    stat = float(g @ np.linalg.lstsq(a.T @ a, g, rcond=None)[0]) / fit.sigma2
    return stat, chi2_survival(stat, cand.shape[1])


def score_test_robust(fit, mask, cand, q=None):
    """The score test with a variance robust to unequal noise between samples (a reconstructed
    centre's y is noisier where the laser plane passes near the sphere's centre): the score's
    variance is summed over the samples (cluster-robust), with the small-sample factor m / (m - p).
    ``q``: :func:`projection` of the fit's Jacobian on ``mask`` when already computed."""
    r, a, g = _score(fit, mask, cand, q)
    per_sample = np.einsum("nik,ni->nk", a.reshape(-1, 3, a.shape[1]), r.reshape(-1, 3))
    m = len(r)
    v = per_sample.T @ per_sample * m / max(m - fit.p, 1)
    stat = float(g @ np.linalg.lstsq(v, g, rcond=None)[0])
    return stat, chi2_survival(stat, cand.shape[1])


def gate_from_sums(chol, cj, cc):
    """:func:`gate`'s fraction from sums: the candidate's scaled columns' Gram matrix less its
    part in the span of J (``chol``: the lower Cholesky factor of ``J^T J``)."""
    norms = np.sqrt(np.diag(cc))
    norms = np.where(norms > 0, norms, 1.0)
    full = cc / np.outer(norms, norms)
    w = np.linalg.solve(chol, (cj / norms[:, None]).T)
    perp = full - w.T @ w
    s_perp = np.sqrt(max(float(np.linalg.eigvalsh(perp)[0]), 0.0))
    s_full = np.sqrt(max(float(np.linalg.eigvalsh(full)[0]), 0.0))
    return float(s_perp / max(s_full, 1e-300))

