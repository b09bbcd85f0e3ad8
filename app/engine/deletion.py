"""The deletion formula of leave-one-out (:func:`handeye.app.engine.robust.leave_one_out`): the
Gauss-Newton step of the fit without one sample from one evaluation at the full fit, the samples'
leverages, and Gauss-Newton refits from that point; and the screening's whitened weighted fit by
Gauss-Newton (:func:`_gauss_newton`). Pure linear algebra on a model; the choice of
which samples to refit exactly, and the fallback, stay in :mod:`handeye.app.engine.robust`.
"""
from __future__ import annotations

import dataclasses

import numpy as np

#: A leave-one-out refit is Gauss-Newton from the deletion-formula point. It stops when the
#: distance left to the refit's minimum is below LOO_XTOL (1 + |x|) (mm and rad of the step):
#: when a step is that small, or, Gauss-Newton converging linearly at the rate rho (below), when
#: LOO_RATE_SAFETY rho / (1 - rho) times the step is. It falls back to :func:`~handeye.app.engine.robust.least_squares`
#: from the full fit when it has not stopped within LOO_GN_ITER steps or a step raised the cost.
LOO_XTOL = 1e-9
LOO_GN_ITER = 8
LOO_RATE_SAFETY = 10.0
#: At a rate this high (large residuals: a gross error among the samples) Gauss-Newton is not
#: tried: the high-leverage refits above robust.LOO_EXACT_UP_TO are robust.least_squares from the full
#: fit (robust), the batched refits up to it (:func:`handeye.app.engine.loo.refits`) keep the exact Hessian.
LOO_GN_MAX_RATE = 0.5


def _gauss_newton_rate(fitted, x, info):
    """Gauss-Newton's local rate of convergence at the fit ``x`` of the model ``fitted``: the
    spectral radius of ``(J^T J)^-1 S``, ``S = sum_k r_k grad^2 r_k`` the part of the cost
    Hessian Gauss-Newton leaves out (small residuals: rho << 1, each step gains digits; the
    thesis's real data, 5.6 mm RMS: rho ~ 0.1). ``info`` is its ``J^T J``."""
    try:
        s = fitted.cost_hessian(x) - info
        inv_l = np.linalg.inv(np.linalg.cholesky(info))
        rho = float(np.max(np.abs(np.linalg.eigvalsh(inv_l @ s @ inv_l.T))))
    except np.linalg.LinAlgError:
        return np.inf
    return rho if np.isfinite(rho) else np.inf


def _gauss_newton_refit(fitted, out, z, cost=np.inf, rho=np.inf):
    """Gauss-Newton on the model ``fitted`` without its rows ``out`` (one sample's), from ``z``
    (next to the minimum); the point, or None when a step raises the sum of squares (the first
    one above ``cost``, theirs at the full fit: then the deletion formula's linearisation does
    not hold, and the caller's fallback decides) or it has not converged (see
    :data:`LOO_XTOL`). The normal equations are the whole model's minus the sample's rows
    (no copy of the other rows: the points model has thousands)."""
    left = LOO_RATE_SAFETY * rho / (1.0 - rho) if rho < LOO_GN_MAX_RATE else np.inf  # distance left per step
    for _ in range(LOO_GN_ITER):
        r, j = fitted.residual_and_jacobian(z)
        r, j = np.ascontiguousarray(r), np.ascontiguousarray(j)  # strided views make the products slow
        r_out, j_out = r[out].reshape(-1), j[out].reshape(-1, fitted.n)
        r, j = r.reshape(-1), j.reshape(-1, fitted.n)
        # einsum for the long products: OpenBLAS threads them, slow on a busy machine (points model)
        new_cost = float(np.einsum("i,i->", r, r) - r_out @ r_out)
        if not np.isfinite(new_cost) or new_cost > cost * (1 + 1e-9) + 1e-300:
            return None
        cost = new_cost
        try:
            step = -np.linalg.solve(j.T @ j - j_out.T @ j_out, np.einsum("ij,i->j", j, r) - j_out.T @ r_out)
        except np.linalg.LinAlgError:
            return None
        if not np.all(np.isfinite(step)):
            return None
        z = fitted.retract(z, step)
        size, tol = np.linalg.norm(step), LOO_XTOL * (1.0 + np.linalg.norm(z))
        if size <= tol or left * size <= tol:
            return z
    return None


def _group_normal_equations(model, x):
    """Per sample: ``J_g^T J_g`` (G, p, p), ``J_g^T r_g`` (G, p) and ``r_g^T r_g`` (G,) of the
    (whitened) rows."""
    r, j = model.residual_and_jacobian(x)
    jtj = np.einsum("rkp,rkq->rpq", j, j)
    jtr = np.einsum("rkp,rk->rp", j, r)
    rtr = np.einsum("rk,rk->r", r, r)
    if model.groups is None:
        return jtj, jtr, rtr
    g = int(model.groups.max()) + 1  # the samples (row groups): robust.n_samples
    out_jtj, out_jtr, out_rtr = np.zeros((g, model.n, model.n)), np.zeros((g, model.n)), np.zeros(g)
    np.add.at(out_jtj, model.groups, jtj)
    np.add.at(out_jtr, model.groups, jtr)
    np.add.at(out_rtr, model.groups, rtr)
    return out_jtj, out_jtr, out_rtr


def _deletion_step(info, jtj, jtr):
    """The deletion formula's steps ``(A - B_g)^-1 J_g^T r_g`` (G, p) (NaN where a sample alone
    determines a direction: then it is refitted from x)."""
    with np.errstate(all="ignore"):
        try:
            return np.linalg.solve(info - jtj, jtr[..., None])[..., 0]
        except np.linalg.LinAlgError:
            return np.full(jtr.shape, np.nan)


def _deletion_steps(model, x, mask):
    """Deletion-formula steps ``(A - B_g)^-1 J_g^T r_g`` (G, p) of the samples in ``mask``,
    their leverages (largest eigenvalue of ``A^-1 B_g``) and the sum of squares of the other
    samples at ``x`` (G,), from one evaluation at ``x``."""
    jtj, jtr, rtr = _group_normal_equations(model, x)
    jtj, jtr, rtr = jtj[mask], jtr[mask], rtr[mask]
    others = rtr.sum() - rtr
    info = jtj.sum(axis=0)
    try:
        inv_l = np.linalg.inv(np.linalg.cholesky(info))
    except np.linalg.LinAlgError:
        return np.full(jtr.shape, np.nan), np.full(len(jtr), np.nan), others, info
    leverage = np.linalg.eigvalsh(inv_l @ jtj @ inv_l.T)[:, -1]
    return _deletion_step(info, jtj, jtr), leverage, others, info


@dataclasses.dataclass(frozen=True)
class Information:
    """The normal equations of the full fit, shared by every chunk of :func:`_deletion_chunk`.

    Attributes
    ----------
    info : ndarray, shape (p, p)
        ``A = J^T J`` of the samples fitted.
    info_l : ndarray, shape (p, p)
        ``L^-1`` of its Cholesky factor (NaN when ``A`` is not positive definite).
    total : float
        The samples' sum of squares at the fit.
    """

    info: np.ndarray
    info_l: np.ndarray
    total: float


def _deletion_chunk(normal, e, jac, d, dj):
    """The deletion formula on one chunk of samples (one row each), ``normal`` an :class:`Information`:
    their steps (R, p), leverages, the other samples' sums of squares and prediction errors |d + D step| (R,)."""
    info_l, info, total = normal.info_l, normal.info, normal.total
    jtj = np.einsum("rkp,rkq->rpq", jac, jac)
    jtr = np.einsum("rkp,rk->rp", jac, e)
    if np.all(np.isfinite(info_l)):  # the eigenvalues of L^-1 B_g L^-T are those of the hat block M M^T, M = J_g L^-T
        mm = (info_l @ jac.reshape(-1, jac.shape[-1]).T).T.reshape(jac.shape)
        leverage = np.linalg.eigvalsh(mm @ np.swapaxes(mm, 1, 2))[:, -1]
    else:
        leverage = np.full(len(jtj), np.nan)
    step = _deletion_step(info, jtj, jtr)
    errors = np.linalg.norm(d + np.einsum("gkp,gp->gk", dj, step), axis=1)
    return step, leverage, total - np.einsum("rk,rk->r", e, e), errors


def whitened_norms(model, x):
    """``|W_i e_i|`` (N,) of a centre model's rows at ``x``: mm without whitening."""
    return np.linalg.norm(model.residual(x).reshape(model.n_meas, -1), axis=1)


#: A whitened weighted fit (the screening's metric) from a near start: Gauss-Newton on the normal
#: equations, at most GN_ITER steps, until a step is below GN_XTOL (1 + |x|) (mm and rad); the
#: centre residual is nearly linear near its minimum, so a few steps suffice where Levenberg-Marquardt's
#: machinery cost a calibration a third of a second. Else (a step that raised the cost) LM.
GN_ITER = 20
GN_XTOL = 1e-10


def _gauss_newton(model, x, weights):
    """Gauss-Newton of ``sum w_i |W_i e_i|^2`` from ``x``; the point, or None when a step raised the
    cost or it did not converge (the caller's LM decides)."""
    cost = np.inf
    for _ in range(GN_ITER):
        jtj, jtr, rtr = model.normal_equations(x, weights)
        if not float(rtr) <= cost * (1 + 1e-12) + 1e-300:
            return None
        cost = float(rtr)
        try:
            step = -np.linalg.solve(jtj, jtr)
        except np.linalg.LinAlgError:
            return None
        x = model.retract(x, step)
        if np.linalg.norm(step) <= GN_XTOL * (1.0 + np.linalg.norm(x)):
            return x
    return None
