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
"""
from __future__ import annotations

import numpy as np

from handeye.solvers.result import Tracker, gradient_small, reduction_small, step_small


def _boundary_tau(p, d, radius):
    """tau >= 0 with |p + tau d| = radius."""
    a = d @ d
    b = 2.0 * (p @ d)
    c = p @ p - radius**2
    return (-b + np.sqrt(max(b * b - 4 * a * c, 0.0))) / (2 * a)


def subproblem_exact(g, b, radius, iters=100):
    """More-Sorensen solution of the trust-region subproblem (N&W Algorithm 4.3).

    Works in the eigenbasis of B: ``p(lam) = -sum_i (q_i^T g) / (w_i + lam) q_i``;
    ``phi(lam) = 1/|p(lam)| - 1/radius`` is increasing and nearly linear on
    ``(max(0, -w_1), inf)``, where Newton's method, safeguarded by bisection, finds its root.
    """
    w, v = np.linalg.eigh(b)
    gt = v.T @ g
    tiny = 1e-12 * max(1.0, float(np.max(np.abs(w))))
    if w[0] > tiny:
        p = -(v @ (gt / w))
        if np.linalg.norm(p) <= radius:
            return p
    lo = max(0.0, -w[0])
    lowest = np.abs(w - w[0]) <= tiny
    if np.linalg.norm(gt[lowest]) <= 1e-10 * max(1.0, float(np.linalg.norm(g))):
        # hard case candidate: g has no component along the lowest eigenvectors
        rest = ~lowest
        denom = w[rest] + lo
        p = -(v[:, rest] @ (gt[rest] / np.where(np.abs(denom) > tiny, denom, np.inf)))
        if np.linalg.norm(p) <= radius:
            z = v[:, 0]
            return p + _boundary_tau(p, z, radius) * z
    hi = lo + float(np.linalg.norm(g)) / radius + tiny
    lam = lo + tiny
    for _ in range(iters):
        if not lo < lam < hi:
            lam = 0.5 * (lo + hi)
        q = gt / (w + lam)
        pn = float(np.linalg.norm(q))
        if abs(pn - radius) <= 1e-10 * radius:
            break
        phi = 1.0 / pn - 1.0 / radius
        if phi < 0:
            lo = lam
        else:
            hi = lam
        dphi = float(np.sum(q**2 / (w + lam))) / pn**3
        lam = lam - phi / dphi if dphi > 0 else 0.5 * (lo + hi)
    return -(v @ (gt / (w + lam)))


def subproblem_steihaug(g, b, radius, tol=None, max_iter=None):
    """Steihaug's truncated CG on the trust-region subproblem (N&W Algorithm 7.2)."""
    n = len(g)
    max_iter = max_iter or 2 * n
    tol = tol if tol is not None else min(0.5, np.sqrt(np.linalg.norm(g))) * np.linalg.norm(g)
    z = np.zeros(n)
    r = g.copy()
    d = -r
    if np.linalg.norm(r) <= tol:
        return z
    for _ in range(max_iter):
        curv = d @ b @ d
        if curv <= 0:
            return z + _boundary_tau(z, d, radius) * d
        alpha = (r @ r) / curv
        z_next = z + alpha * d
        if np.linalg.norm(z_next) >= radius:
            return z + _boundary_tau(z, d, radius) * d
        r_next = r + alpha * (b @ d)
        if np.linalg.norm(r_next) <= tol:
            return z_next
        beta = (r_next @ r_next) / (r @ r)
        d = -r_next + beta * d
        z, r = z_next, r_next
    return z


def _cauchy_length(g, b):
    """Length of the steepest-descent minimiser of the model: the default initial radius."""
    gg = float(g @ g)
    curv = float(g @ b @ g)
    length = gg**1.5 / curv if curv > 0 else np.sqrt(gg)
    return max(length, 1e-8) if np.isfinite(length) else 1.0


def subproblem_dogleg(g, b, radius):
    """Dogleg step for a positive semidefinite model (N&W 4.1)."""
    try:
        p_full = -np.linalg.solve(b, g)
    except np.linalg.LinAlgError:
        p_full = None
    if p_full is not None and np.all(np.isfinite(p_full)) and np.linalg.norm(p_full) <= radius:
        return p_full
    gbg = g @ b @ g
    if gbg <= 0:
        return -radius * g / np.linalg.norm(g)
    p_u = -(g @ g) / gbg * g
    if np.linalg.norm(p_u) >= radius or p_full is None or not np.all(np.isfinite(p_full)):
        return radius * p_u / np.linalg.norm(p_u)
    return p_u + _boundary_tau(p_u, p_full - p_u, radius) * (p_full - p_u)


def minimize(problem, x0, opts, model="newton"):
    """Trust-region iteration; ``model`` is ``'newton'`` (exact Hessian) or ``'gauss-newton'``."""
    name = "dogleg" if model == "gauss-newton" else f"tr-{opts.subproblem}"
    t = Tracker(problem, x0, name)
    x = np.array(x0, dtype=float)

    def evaluate(x):
        if model == "gauss-newton":
            r = t.residual(x)
            j = t.jacobian(x)
            return 0.5 * float(r @ r), j.T @ r, j.T @ j
        return t.cost(x), t.grad(x), t.hess(x)

    def cost(x):
        if model == "gauss-newton":
            r = t.residual(x)
            return 0.5 * float(r @ r)
        return t.cost(x)

    def scale(b, previous):
        if not opts.scaling:
            return np.ones(problem.n)
        d = np.sqrt(np.abs(np.diag(b)))
        if previous is not None:
            d = np.maximum(previous, d)
        return np.where(d > 0, d, 1.0)

    f, g, b = evaluate(x)
    diag = scale(b, None)
    radius = opts.initial_radius or _cauchy_length(g / diag, b / np.outer(diag, diag))
    max_radius = opts.max_radius_factor * radius
    min_radius = 1e-14 * radius
    t.extra["radius"] = [radius]
    for k in range(opts.max_iter):
        if not (np.isfinite(f) and np.all(np.isfinite(g)) and np.all(np.isfinite(b))):
            return t.finish(x, f, g, -1, k)
        if gradient_small(g, f, opts):
            return t.finish(x, f, g, 1, k)
        gs, bs = g / diag, b / np.outer(diag, diag)
        if model == "gauss-newton":
            ps = subproblem_dogleg(gs, bs, radius)
        elif opts.subproblem == "cg":
            ps = subproblem_steihaug(gs, bs, radius)
        else:
            ps = subproblem_exact(gs, bs, radius)
        p = ps / diag
        predicted = -(g @ p + 0.5 * p @ b @ p)
        x_new = problem.move(x, p)
        f_new = cost(x_new)
        rho = (f - f_new) / predicted if predicted > 0 else -1.0
        noise = 100 * np.finfo(float).eps * max(1.0, abs(f))
        if 0 <= predicted <= noise and np.isfinite(f_new) and f_new <= f + noise:
            rho = 1.0  # reductions at rounding level: rho is noise; let the gradient decide
        pnorm = float(np.linalg.norm(ps))
        if not np.isfinite(f_new) or rho < 0.25:
            radius = 0.25 * pnorm
        elif rho > 0.75 and pnorm >= 0.999 * radius:
            radius = min(2.0 * radius, max_radius)
        t.extra["radius"].append(radius)
        if np.isfinite(f_new) and rho > opts.eta:
            f_old, x_old = f, x
            x = x_new
            t.record(x)
            f, g, b = evaluate(x)
            diag = scale(b, diag)
            if step_small(p, x_old, opts):
                return t.finish(x, f, g, 3, k + 1)
            if reduction_small(f_old, f, opts):
                return t.finish(x, f, g, 2, k + 1)
        elif radius < min_radius:
            return t.finish(x, f, g, 4, k + 1)
    return t.finish(x, f, g, 0, opts.max_iter)
