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

from handeye.solvers.batch import Runs
from handeye.solvers.result import step_small
from handeye.solvers.stacks import finite_rows, solve_rows


def run(stacked, x0, opts, trace=False):
    """Local Newton from each row of ``x0`` (N, d); returns the :class:`~handeye.solvers.batch.Runs`."""
    runs = Runs(stacked, x0, "newton", trace)
    rows = runs.active()
    runs.f[rows] = runs.cost(runs.x, rows)
    runs.g[rows] = runs.grad(runs.x, rows)
    for k in range(opts.max_iter):
        rows = runs.screened(k, opts)
        if not rows.size:
            break
        p, ok = solve_rows(runs.hessian(runs.x[rows], rows), -runs.g[rows])
        ok &= finite_rows(p)
        rows = runs.stop(rows, ~ok, -1, k)
        p = p[ok]
        if not rows.size:
            continue
        x_old = runs.x[rows]
        runs.x[rows] = x_new = stacked.move(x_old, p)
        runs.f[rows] = runs.cost(x_new, rows)
        runs.record(rows, x_new)
        runs.g[rows] = runs.grad(x_new, rows)
        runs.stop(rows, step_small(p, x_old, opts), 3, k + 1)
    runs.stop(runs.active(), True, 0, opts.max_iter)
    return runs
