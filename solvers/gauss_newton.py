"""Gauss-Newton for nonlinear least squares (Nocedal & Wright, 2nd ed., 10.3).

For ``f(x) = 1/2 |r(x)|^2`` the gradient is ``J^T r`` and the Hessian
``J^T J + sum_i r_i grad^2 r_i``. Gauss-Newton drops the second term -- small where the
residuals are small or nearly linear -- and takes the full step of the resulting model:

    J_k^T J_k p_k = -J_k^T r_k   (solved as the linear least-squares problem  min |J_k p + r_k|),
    x_{k+1} = retract(x_k, p_k).

This is the seed's 6.1.5 / C5. With ``jacobian='forward'`` J is replaced by forward
differences with the seed's step (C4, 5e-7), for comparison with the exact Jacobian.
Where ``J`` is rank-deficient (at the Euler singularity B = +-90 deg, for instance) the
minimum-norm solution of the linear least-squares problem is taken and counted in
``result.extra['rank_deficient_steps']``. No line search: like the seed, the method is local; Levenberg-Marquardt and the dogleg
trust region are its globalised relatives.
"""
from __future__ import annotations

from handeye.solvers.batch import Runs
from handeye.solvers.result import gradient_small, reduction_small, step_small
from handeye.solvers.stacks import finite_rows, half_squares, lstsq_rows, transpose_times


def run(stacked, x0, opts, trace=False):
    """Gauss-Newton from each row of ``x0`` (N, d); returns the :class:`~handeye.solvers.batch.Runs`."""
    runs = Runs(stacked, x0, "gn" if opts.jacobian == "exact" else "gn-fd", trace)

    def jac(x, rows):
        if opts.jacobian == "forward":
            runs.nfev[rows] += stacked.n + 1
            return stacked.forward_jacobian(x, opts.fd_step)
        return runs.jacobian(x, rows)

    def settle(rows):  # the gradient reported at a stop after a step (not counted)
        runs.g[rows] = stacked.grad(runs.x[rows])

    rows = runs.active()
    r = runs.residual(runs.x, rows)
    runs.f[rows] = half_squares(r)
    for k in range(opts.max_iter):
        rows = runs.active()
        if not rows.size:
            break
        j = jac(runs.x[rows], rows)
        runs.g[rows] = g = transpose_times(j, r[rows])
        bad = ~finite_rows(runs.f[rows], j)
        small = ~bad & gradient_small(g, runs.f[rows], opts)
        runs.stop(rows, bad, -1, k)
        runs.stop(rows, small, 1, k)
        go = ~bad & ~small
        rows, j = rows[go], j[go]
        if not rows.size:
            break
        p, rank = lstsq_rows(j, -r[rows])
        # J^T J singular: the minimum-norm Gauss-Newton step is taken and counted
        runs.count("rank_deficient_steps", rows[rank < stacked.n])
        ok = finite_rows(p)
        rows = runs.stop(rows, ~ok, -1, k)
        p = p[ok]
        if not rows.size:
            continue
        x_old, f_old = runs.x[rows], runs.f[rows]
        runs.x[rows] = x_new = stacked.move(x_old, p)
        r[rows] = runs.residual(x_new, rows)
        runs.f[rows] = f_new = half_squares(r[rows])
        runs.record(rows, x_new)
        small_step = step_small(p, x_old, opts)
        reduced = ~small_step & (f_new <= f_old) & reduction_small(f_old, f_new, opts)
        settle(rows[small_step | reduced])
        runs.stop(rows, small_step, 3, k + 1)
        runs.stop(rows, reduced, 2, k + 1)
    rows = runs.active()
    settle(rows)  # no rows: the gradient of none (Stacked.grad returns (0, n) at once)
    runs.stop(rows, True, 0, opts.max_iter)
    return runs
