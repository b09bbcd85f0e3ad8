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

import numpy as np

from handeye.solvers.problem import forward_difference_jacobian
from handeye.solvers.result import Tracker, gradient_small, reduction_small, step_small


def minimize(problem, x0, opts):
    t = Tracker(problem, x0, "gn" if opts.jacobian == "exact" else "gn-fd")

    def jac(x):
        if opts.jacobian == "forward":
            t.nfev += problem.n + 1
            return forward_difference_jacobian(problem, x, opts.fd_step)
        return t.jacobian(x)

    x = np.array(x0, dtype=float)
    r = t.residual(x)
    f = 0.5 * float(r @ r)
    for k in range(opts.max_iter):
        j = jac(x)
        g = j.T @ r
        if not (np.isfinite(f) and np.all(np.isfinite(j))):
            return t.finish(x, f, g, -1, k)
        if gradient_small(g, f, opts):
            return t.finish(x, f, g, 1, k)
        p, _, rank, _ = np.linalg.lstsq(j, -r, rcond=None)
        if rank < problem.n:
            # J^T J singular: take the minimum-norm Gauss-Newton step and say so
            t.extra["rank_deficient_steps"] = t.extra.get("rank_deficient_steps", 0) + 1
        if not np.all(np.isfinite(p)):
            return t.finish(x, f, g, -1, k)
        x_old, f_old = x, f
        x = problem.move(x, p)
        r = t.residual(x)
        f = 0.5 * float(r @ r)
        t.record(x)
        if step_small(p, x_old, opts):
            return t.finish(x, f, problem.grad(x), 3, k + 1)
        if f <= f_old and reduction_small(f_old, f, opts):
            return t.finish(x, f, problem.grad(x), 2, k + 1)
    return t.finish(x, f, problem.grad(x), 0, opts.max_iter)
