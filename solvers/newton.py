"""Local Newton's method (Nocedal & Wright, *Numerical Optimization*, 2nd ed., 3.3).

A quadratic model of f about x_k,

    m_k(p) = f_k + g_k^T p + 1/2 p^T H_k p,

is stationary where ``H_k p = -g_k``. Local Newton takes that step in full, with no line
search and no safeguard, exactly as the seed's 6.2 and C8 do:

    x_{k+1} = retract(x_k, p_k),   H_k p_k = -g_k.

Near a minimiser with positive definite Hessian it converges quadratically (N&W Thm 3.5).
Because it seeks *stationary* points, from close enough it converges to a saddle or a
maximum just as happily -- the basin maps of the studies show exactly that.
"""
from __future__ import annotations

import numpy as np

from handeye.solvers.result import Tracker, gradient_small, step_small


def minimize(problem, x0, opts):
    t = Tracker(problem, x0, "newton")
    x = np.array(x0, dtype=float)
    f = t.cost(x)
    g = t.grad(x)
    for k in range(opts.max_iter):
        if not np.isfinite(f) or not np.all(np.isfinite(g)):
            return t.finish(x, f, g, -1, k)
        if gradient_small(g, f, opts):
            return t.finish(x, f, g, 1, k)
        h = t.hess(x)
        try:
            p = np.linalg.solve(h, -g)
        except np.linalg.LinAlgError:
            return t.finish(x, f, g, -1, k)
        if not np.all(np.isfinite(p)):
            return t.finish(x, f, g, -1, k)
        x_new = problem.move(x, p)
        f_new = t.cost(x_new)
        t.record(x_new)
        x_old, x, f = x, x_new, f_new
        g = t.grad(x)
        if step_small(p, x_old, opts):
            return t.finish(x, f, g, 3, k + 1)
    return t.finish(x, f, g, 0, opts.max_iter)
