"""Trust-region methods (Nocedal & Wright, 2nd ed., chapter 4 and 7.1).

Each iteration minimises a quadratic model within a ball of radius Delta_k,

    min_p  m_k(p) = f_k + g_k^T p + 1/2 p^T B_k p    s.t.  |p| <= Delta_k,

then compares the actual with the predicted reduction,

    rho_k = (f(x_k) - f(retract(x_k, p_k))) / (m_k(0) - m_k(p_k)),

(when both reductions are at rounding level, ``100 eps |f|``, the step is taken and the gradient
test decides) and updates the radius as N&W Algorithm 4.1 (the seed's 6.1.6 prints the same rules):
``rho < 1/4`` shrinks Delta to ``|p|/4``; ``rho > 3/4`` with ``|p| = Delta`` doubles it (up to
a maximum); the step is taken when ``rho > eta``.

Models and subproblems:

* ``tr`` -- Newton model, ``B_k`` the exact Hessian. Subproblem ``exact``: More-Sorensen
  (N&W Algorithm 4.3): find lambda >= 0 with ``(B + lambda I) p = -g``, ``B + lambda I``
  positive semidefinite and ``lambda (Delta - |p|) = 0``, by Newton's method on
  ``1/|p(lambda)| - 1/Delta`` with Cholesky factors; the hard case is handled by adding a
  multiple of the eigenvector of the smallest eigenvalue. Subproblem ``cg``: Steihaug's
  truncated conjugate gradients (N&W Algorithm 7.2), which stops at the boundary or at
  negative curvature.
* ``dogleg`` -- Gauss-Newton model for least squares, ``B_k = J^T J`` (N&W 4.1, 10.3): the
  path from the Cauchy point ``-(g^T g / g^T B g) g`` to the Gauss-Newton point, cut at the
  boundary.

Scaling (N&W 4.5; More 1978): when parameters have different units (mm and radians) a
round trust region is a poor shape. With ``scaling=True`` the region is the ellipsoid
``|D p| <= Delta`` with ``D = diag(sqrt(max_k |diag B_k|))`` (non-decreasing over iterations, as in
MINPACK); the subproblem is solved in ``p~ = D p`` with ``g~ = D^-1 g``, ``B~ = D^-1 B D^-1``.

Everything runs on stacks of starts (:mod:`handeye.solvers.batch`): each row has its own
radius, scaling and Newton iteration on lambda; More-Sorensen and dogleg are vectorised over
rows, Steihaug-CG runs row by row.
"""
from __future__ import annotations

import numpy as np

from handeye.solvers.batch import Runs
from handeye.solvers.result import reduction_small, step_small
from handeye.solvers.stacks import (
    dot_rows,
    finite_rows,
    gram,
    half_squares,
    matvec,
    max_abs_rows,
    norm_rows,
    quad_rows,
    row_sum,
    solve_rows,
    transpose_times,
)


def _boundary_tau(p, d, radius):
    """tau >= 0 with |p + tau d| = radius, row by row (p, d (k, n); radius (k,))."""
    a = dot_rows(d, d)
    b = 2.0 * dot_rows(p, d)
    c = dot_rows(p, p) - radius**2
    return (-b + np.sqrt(np.maximum(b * b - 4 * a * c, 0.0))) / (2 * a)


def _rows(function):
    """Let a subproblem on stacks (k, n) also take one (n,) problem."""
    def wrapper(g, b, radius, *args, **kwargs):
        g, b = np.asarray(g, dtype=float), np.asarray(b, dtype=float)
        if g.ndim == 1:
            return function(g[None], b[None], np.atleast_1d(radius).astype(float), *args, **kwargs)[0]
        return function(g, b, np.asarray(radius, dtype=float), *args, **kwargs)

    wrapper.__name__, wrapper.__doc__ = function.__name__, function.__doc__
    return wrapper


@_rows
def subproblem_exact(g, b, radius, iters=100):
    """More-Sorensen solution of the trust-region subproblem (N&W Algorithm 4.3), row by row.

    Works in the eigenbasis of B: ``p(lam) = -sum_i (q_i^T g) / (w_i + lam) q_i``;
    ``phi(lam) = 1/|p(lam)| - 1/radius`` is increasing and nearly linear on
    ``(max(0, -w_1), inf)``, where Newton's method, safeguarded by bisection, finds its root.
    ``g`` (k, n) or (n,), ``b`` (k, n, n) or (n, n), ``radius`` (k,) or scalar.
    """
    w, v = np.linalg.eigh(b)
    gt = matvec(np.swapaxes(v, 1, 2), g)
    tiny = 1e-12 * np.maximum(1.0, max_abs_rows(w))
    p = np.zeros_like(g)
    with np.errstate(divide="ignore", invalid="ignore"):
        newton = -matvec(v, gt / w)
        done = (w[:, 0] > tiny) & (norm_rows(newton) <= radius)
        p[done] = newton[done]
        lo = np.maximum(0.0, -w[:, 0])
        lowest = np.abs(w - w[:, :1]) <= tiny[:, None]
        # hard case candidate: g has no component along the lowest eigenvectors
        hard = ~done & (norm_rows(np.where(lowest, gt, 0.0))
                        <= 1e-10 * np.maximum(1.0, norm_rows(g)))
        denom = w + lo[:, None]
        inner = -matvec(v, np.where(~lowest & (np.abs(denom) > tiny[:, None]), gt / denom, 0.0))
        hard &= norm_rows(inner) <= radius
        z = v[:, :, 0]
        p[hard] = inner[hard] + _boundary_tau(inner[hard], z[hard], radius[hard])[:, None] * z[hard]
        done |= hard
        hi = lo + norm_rows(g) / radius + tiny
        lam = lo + tiny
        going = ~done
        for _ in range(iters):
            rows = np.flatnonzero(going)
            if not rows.size:
                break
            lo_r, hi_r, lam_r, rad = lo[rows], hi[rows], lam[rows], radius[rows]
            lam_r = np.where((lo_r < lam_r) & (lam_r < hi_r), lam_r, 0.5 * (lo_r + hi_r))
            shifted = w[rows] + lam_r[:, None]
            q = gt[rows] / shifted
            pn = norm_rows(q)
            met = np.abs(pn - rad) <= 1e-10 * rad
            phi = 1.0 / pn - 1.0 / rad
            lo_r = np.where(phi < 0, lam_r, lo_r)
            hi_r = np.where(phi < 0, hi_r, lam_r)
            dphi = row_sum(q**2 / shifted) / pn**3
            step = np.where(dphi > 0, lam_r - phi / dphi, 0.5 * (lo_r + hi_r))
            lam[rows] = np.where(met, lam_r, step)
            lo[rows] = np.where(met, lo[rows], lo_r)
            hi[rows] = np.where(met, hi[rows], hi_r)
            going[rows[met]] = False
        rest = ~done
        p[rest] = -matvec(v[rest], gt[rest] / (w[rest] + lam[rest, None]))
    return p


def _steihaug(g, b, radius, tol=None, max_iter=None):
    n = len(g)
    max_iter = max_iter or 2 * n
    tol = tol if tol is not None else min(0.5, np.sqrt(np.linalg.norm(g))) * np.linalg.norm(g)
    z = np.zeros(n)
    r = g.copy()
    d = -r

    def boundary(z, d):
        return z + _boundary_tau(z[None], d[None], np.array([radius]))[0] * d

    if np.linalg.norm(r) <= tol:
        return z
    for _ in range(max_iter):
        curv = d @ b @ d
        if curv <= 0:
            return boundary(z, d)
        alpha = (r @ r) / curv
        z_next = z + alpha * d
        if np.linalg.norm(z_next) >= radius:
            return boundary(z, d)
        r_next = r + alpha * (b @ d)
        if np.linalg.norm(r_next) <= tol:
            return z_next
        beta = (r_next @ r_next) / (r @ r)
        d = -r_next + beta * d
        z, r = z_next, r_next
    return z


@_rows
def subproblem_steihaug(g, b, radius, tol=None, max_iter=None):
    """Steihaug's truncated CG on the trust-region subproblem (N&W Algorithm 7.2), row by row."""
    return np.stack([_steihaug(gi, bi, ri, tol, max_iter) for gi, bi, ri in zip(g, b, radius)])


@_rows
def subproblem_dogleg(g, b, radius):
    """Dogleg step for a positive semidefinite model (N&W 4.1), row by row."""
    full, ok = solve_rows(b, -g)
    ok &= finite_rows(full)
    with np.errstate(divide="ignore", invalid="ignore"):
        p = np.where((ok & (norm_rows(full) <= radius))[:, None], full, np.nan)
        todo = ~finite_rows(p)
        gbg = quad_rows(g, b)
        flat = todo & (gbg <= 0)
        p[flat] = -radius[flat, None] * g[flat] / norm_rows(g[flat])[:, None]
        p_u = -(dot_rows(g, g) / gbg)[:, None] * g
        u_norm = norm_rows(p_u)
        cut = todo & ~flat & ((u_norm >= radius) | ~ok)
        p[cut] = (radius[cut] / u_norm[cut])[:, None] * p_u[cut]
        leg = todo & ~flat & ~cut
        dl = full[leg] - p_u[leg]
        p[leg] = p_u[leg] + _boundary_tau(p_u[leg], dl, radius[leg])[:, None] * dl
    return p


def _cauchy_length(g, b):
    """Length of the steepest-descent minimiser of the model: the default initial radius (k,)."""
    gg = dot_rows(g, g)
    curv = quad_rows(g, b)
    with np.errstate(divide="ignore", invalid="ignore"):
        length = np.where(curv > 0, gg**1.5 / curv, np.sqrt(gg))
    return np.where(np.isfinite(length), np.maximum(length, 1e-8), 1.0)


def run(stacked, x0, opts, trace=False, model="newton"):
    """Trust-region iteration from each row of ``x0`` (N, d); ``model`` is ``'newton'`` (exact
    Hessian) or ``'gauss-newton'``. Returns the :class:`~handeye.solvers.batch.Runs`."""
    runs = Runs(stacked, x0, "dogleg" if model == "gauss-newton" else f"tr-{opts.subproblem}", trace)
    subproblem = (subproblem_dogleg if model == "gauss-newton"
                  else subproblem_steihaug if opts.subproblem == "cg" else subproblem_exact)

    rows = runs.active()
    runs.f[rows], runs.g[rows], b = _evaluate(runs, model, runs.x, rows)
    diag = _scale(b, None, opts, stacked.n)
    radius = (np.full(len(rows), float(opts.initial_radius)) if opts.initial_radius
              else _cauchy_length(runs.g / diag, b / (diag[:, :, None] * diag[:, None, :])))
    max_radius = opts.max_radius_factor * radius
    min_radius = 1e-14 * radius
    runs.note("radius", rows, radius)
    for k in range(opts.max_iter):
        rows = runs.screened(k, opts, b)
        if not rows.size:
            break
        f, g, bk, dk = runs.f[rows], runs.g[rows], b[rows], diag[rows]
        ps = subproblem(g / dk, bk / (dk[:, :, None] * dk[:, None, :]), radius[rows])
        p = ps / dk
        predicted = -(dot_rows(g, p) + 0.5 * quad_rows(p, bk))
        x_new = stacked.move(runs.x[rows], p)
        f_new = _cost(runs, model, x_new, rows)
        rho = _ratio(f, f_new, predicted)
        pnorm = norm_rows(ps)
        shrink = ~np.isfinite(f_new) | (rho < 0.25)
        grow = ~shrink & (rho > 0.75) & (pnorm >= 0.999 * radius[rows])
        radius[rows[shrink]] = 0.25 * pnorm[shrink]
        radius[rows[grow]] = np.minimum(2.0 * radius[rows[grow]], max_radius[rows[grow]])
        runs.note("radius", rows, radius[rows])
        accept = np.isfinite(f_new) & (rho > opts.eta)
        acc, x_old = rows[accept], runs.x[rows[accept]]
        if acc.size:
            runs.x[acc] = x_new[accept]
            runs.record(acc, x_new[accept])
            runs.f[acc], runs.g[acc], b[acc] = _evaluate(runs, model, x_new[accept], acc)
            diag[acc] = _scale(b[acc], diag[acc], opts, stacked.n)
        small_step = step_small(p[accept], x_old, opts)
        runs.stop(acc, small_step, 3, k + 1)
        runs.stop(acc, ~small_step & reduction_small(f[accept], runs.f[acc], opts), 2, k + 1)
        rej = rows[~accept]
        runs.stop(rej, radius[rej] < min_radius[rej], 4, k + 1)
    runs.stop(runs.active(), True, 0, opts.max_iter)
    return runs


def _evaluate(runs, model, x, rows):
    """Cost, gradient and the model's Hessian (exact, or Gauss-Newton's ``J^T J``) at ``x``."""
    if model == "gauss-newton":
        r = runs.residual(x, rows)
        j = runs.jacobian(x, rows)
        return half_squares(r), transpose_times(j, r), gram(j)
    return runs.cost(x, rows), runs.grad(x, rows), runs.hessian(x, rows)


def _cost(runs, model, x, rows):
    if model == "gauss-newton":
        return half_squares(runs.residual(x, rows))
    return runs.cost(x, rows)


def _scale(b, previous, opts, n):
    """The ellipsoidal region's scaling ``D`` from the Hessian's diagonal (never shrinking), or ones."""
    if not opts.scaling:
        return np.ones((len(b), n))
    d = np.sqrt(np.abs(np.diagonal(b, axis1=1, axis2=2)))
    if previous is not None:
        d = np.maximum(previous, d)
    return np.where(d > 0, d, 1.0)


def _ratio(f, f_new, predicted):
    """Actual over predicted reduction, ``rho``; 1 where both are at rounding level (-1 where none was predicted)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        rho = np.where(predicted > 0, (f - f_new) / predicted, -1.0)
    noise = 100 * np.finfo(float).eps * np.maximum(1.0, np.abs(f))
    # reductions at rounding level: rho is noise; let the gradient decide
    rho[(predicted >= 0) & (predicted <= noise) & np.isfinite(f_new) & (f_new <= f + noise)] = 1.0
    return rho
