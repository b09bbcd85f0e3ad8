"""Line-search methods (Nocedal & Wright, 2nd ed., chapter 3).

Along a descent direction p (``g^T p < 0``) from x, a step length alpha is accepted when

* **Armijo** (sufficient decrease, N&W 3.4): ``f(x + alpha p) <= f(x) + c1 alpha g^T p``,
  found by backtracking ``alpha <- rho alpha`` from alpha = 1 (N&W Algorithm 3.1);
* **strong Wolfe** (N&W 3.7): Armijo and ``|g(x + alpha p)^T p| <= c2 |g^T p|``, found by
  bracketing and zooming (N&W Algorithms 3.5 and 3.6, with bisection inside the bracket).

Points move through the problem's retraction, so the same code serves manifolds. When no
step is acceptable because the possible decrease ``|g^T p|`` is below ``100 eps |f|``, the
point is as converged as f's precision allows (status 2), not a failure.

Damped Newton, steepest descent and BFGS (N&W 3.3, 6.1) are written here on top of them.
"""
from __future__ import annotations

import numpy as np

from handeye.solvers.result import Tracker, gradient_small, reduction_small, step_small

C1, C2, RHO = 1e-4, 0.9, 0.5


def armijo(phi, f0, slope, alpha=1.0, max_steps=60):
    """Backtracking: largest ``alpha * RHO^k`` with sufficient decrease; None if none found."""
    for _ in range(max_steps):
        value = phi(alpha)
        if np.isfinite(value) and value <= f0 + C1 * alpha * slope:
            return alpha, value
        alpha *= RHO
    return None, None


def wolfe(phi, dphi, f0, slope, alpha=1.0, alpha_max=1e6, max_steps=60):
    """Step satisfying the strong Wolfe conditions (N&W Algorithms 3.5, 3.6)."""
    prev_alpha, prev_value = 0.0, f0

    def zoom(lo, hi, f_lo):
        for _ in range(max_steps):
            a = 0.5 * (lo + hi)
            value = phi(a)
            if not np.isfinite(value) or value > f0 + C1 * a * slope or value >= f_lo:
                hi = a
            else:
                d = dphi(a)
                if abs(d) <= -C2 * slope:
                    return a, value
                if d * (hi - lo) >= 0:
                    hi = lo
                lo, f_lo = a, value
        return (lo, f_lo) if lo > 0 else (None, None)

    for k in range(max_steps):
        value = phi(alpha)
        if not np.isfinite(value) or value > f0 + C1 * alpha * slope or (k > 0 and value >= prev_value):
            return zoom(prev_alpha, alpha, prev_value)
        d = dphi(alpha)
        if abs(d) <= -C2 * slope:
            return alpha, value
        if d >= 0:
            return zoom(alpha, prev_alpha, value)
        prev_alpha, prev_value = alpha, value
        alpha = min(2.0 * alpha, alpha_max)
    return None, None


def _run(problem, x0, opts, name, direction, search, update=None):
    """Generic line-search loop: ``direction(x, g, state) -> p``; ``search`` 'armijo' or 'wolfe'."""
    t = Tracker(problem, x0, name)
    x = np.array(x0, dtype=float)
    f = t.cost(x)
    g = t.grad(x)
    state = {}
    for k in range(opts.max_iter):
        if not (np.isfinite(f) and np.all(np.isfinite(g))):
            return t.finish(x, f, g, -1, k)
        if gradient_small(g, f, opts):
            return t.finish(x, f, g, 1, k)
        p = direction(x, g, state)
        slope = float(g @ p)
        if not np.all(np.isfinite(p)) or slope >= 0:
            p, slope = -g, -float(g @ g)  # not a descent direction: steepest descent
            state.pop("h_inv", None)

        def phi(a):
            return t.cost(problem.move(x, a * p))

        def dphi(a):
            return float(t.grad(problem.move(x, a * p)) @ p)

        alpha, f_new = (armijo(phi, f, slope) if search == "armijo" else wolfe(phi, dphi, f, slope))
        if alpha is None:
            if abs(slope) <= 100 * np.finfo(float).eps * max(1.0, abs(f)):
                # the possible decrease is at rounding level: as converged as f's precision allows
                return t.finish(x, f, g, 2, k, "converged to the precision of f: the possible decrease along the "
                                               "direction is below rounding")
            return t.finish(x, f, g, -1, k, "line search failed: no acceptable step along the direction")
        x_new = problem.move(x, alpha * p)
        g_new = t.grad(x_new)
        if update is not None:
            update(state, alpha * p, g_new - g)
        t.record(x_new)
        x_old, f_old = x, f
        x, f, g = x_new, f_new, g_new
        if step_small(alpha * p, x_old, opts):
            return t.finish(x, f, g, 3, k + 1)
        if reduction_small(f_old, f, opts):
            return t.finish(x, f, g, 2, k + 1)
    return t.finish(x, f, g, 0, opts.max_iter)


def damped_newton(problem, x0, opts):
    """Newton direction ``H p = -g`` with an Armijo line search (N&W 3.3); where H is not
    positive definite along p the step falls back to steepest descent."""
    tracker_hess = problem.hessian

    def direction(x, g, state):
        try:
            return np.linalg.solve(np.asarray(tracker_hess(x), float), -g)
        except np.linalg.LinAlgError:
            return -g

    return _run(problem, x0, opts, "newton-ls", direction, "armijo")


def steepest_descent(problem, x0, opts):
    """``p = -g`` with an Armijo line search (N&W 3.1): linear convergence at best."""
    return _run(problem, x0, opts, "sd", lambda x, g, state: -g, "armijo")


def bfgs(problem, x0, opts):
    """BFGS (N&W Algorithm 6.1) with a strong Wolfe line search: the inverse Hessian
    approximation ``H <- (I - rho s y^T) H (I - rho y s^T) + rho s s^T``, ``rho = 1 / y^T s``,
    scaled at the first step by ``y^T s / y^T y`` (N&W 6.20)."""

    def direction(x, g, state):
        h = state.get("h_inv")
        return -(g if h is None else h @ g)

    def update(state, s, y):
        sy = float(s @ y)
        if sy <= 1e-12 * np.linalg.norm(s) * np.linalg.norm(y):
            return  # curvature condition fails (cannot after a Wolfe step, but on manifolds it may)
        n = len(s)
        h = state.get("h_inv", sy / float(y @ y) * np.eye(n))
        rho = 1.0 / sy
        v = np.eye(n) - rho * np.outer(s, y)
        state["h_inv"] = v @ h @ v.T + rho * np.outer(s, s)

    return _run(problem, x0, opts, "bfgs", direction, "wolfe", update)
