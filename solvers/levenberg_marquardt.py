"""Levenberg-Marquardt (Nocedal & Wright, 2nd ed., 10.3; Madsen, Nielsen & Tingleff 2004).

The Gauss-Newton model is trusted only near x_k: the step solves

    (J^T J + mu D) p = -J^T r,     D = diag(J^T J)  (Marquardt's scaling),

which interpolates between Gauss-Newton (mu -> 0) and a short scaled steepest-descent step
(mu -> inf); it is the trust-region subproblem of N&W (10.34) for some radius. The gain ratio

    rho = (f(x) - f(x + p)) / (L(0) - L(p)),   L(p) = 1/2 |r + J p|^2,

decides: rho > 0 accepts the step and lowers mu by ``max(1/3, 1 - (2 rho - 1)^3)``;
otherwise mu grows by nu and nu doubles (Nielsen's update).
"""
from __future__ import annotations

import numpy as np

from handeye.solvers.batch import RUNNING, Runs
from handeye.solvers.result import reduction_small, step_small
from handeye.solvers.stacks import dot_rows, gram, half_squares, quad_rows, solve_rows, transpose_times


def _diag(a):
    return np.diagonal(a, axis1=1, axis2=2)


def _model(runs, x, rows, r):
    """``(J^T J, J^T r)`` at the points ``x`` of ``rows`` (residuals ``r``): from the problem's
    normal equations when it gives them (J never held), else from its Jacobian."""
    if runs.stacked.problem.normal is not None:
        return runs.normal(x, rows)
    j = runs.jacobian(x, rows)
    return gram(j), transpose_times(j, r)


def run(stacked, x0, opts, trace=False):
    """Levenberg-Marquardt from each row of ``x0`` (N, d); returns the :class:`~handeye.solvers.batch.Runs`."""
    runs = Runs(stacked, x0, "lm", trace)
    rows = runs.active()
    r = runs.residual(runs.x, rows)
    runs.f[rows] = half_squares(r)
    a, runs.g[rows] = _model(runs, runs.x, rows, r)
    biggest = np.max(_diag(a), axis=1)
    d = np.maximum(_diag(a), 1e-12 * np.maximum(1.0, biggest)[:, None])
    with np.errstate(divide="ignore", invalid="ignore"):
        mu = np.where(np.max(d, axis=1) > 0, opts.lm_tau * biggest / np.max(d, axis=1), opts.lm_tau)
    nu = np.full(len(rows), 2.0)
    diag = np.arange(stacked.n)
    runs.note("damping", rows, mu)
    for k in range(opts.max_iter):
        rows = runs.screened(k, opts, a)
        if not rows.size:
            break
        g = runs.g[rows]
        damped = a[rows]
        damped[:, diag, diag] += mu[rows, None] * d[rows]  # A + mu D, D = diag(d)
        p, ok = solve_rows(damped, -g)
        rows = runs.stop(rows, ~ok, -1, k)
        p, g = p[ok], g[ok]
        small = step_small(p, runs.x[rows], opts)
        rows = runs.stop(rows, small, 3, k)
        p, g = p[~small], g[~small]
        if not rows.size:
            continue
        x_new = stacked.move(runs.x[rows], p)
        r_new = runs.residual(x_new, rows)
        f, f_new = runs.f[rows], half_squares(r_new)
        predicted = -dot_rows(g, p) - 0.5 * quad_rows(p, a[rows])
        with np.errstate(divide="ignore", invalid="ignore"):
            rho = np.where(predicted > 0, (f - f_new) / predicted, -1.0)
        accept = np.isfinite(f_new) & (rho > 0)
        # accepted: move, new model, less damping (Nielsen)
        acc = rows[accept]
        runs.x[acc], r[acc], runs.f[acc] = x_new[accept], r_new[accept], f_new[accept]
        runs.record(acc, x_new[accept])
        if acc.size:
            a[acc], runs.g[acc] = _model(runs, runs.x[acc], acc, r[acc])
            d[acc] = np.maximum(d[acc], _diag(a[acc]))
        mu[acc] *= np.maximum(1.0 / 3.0, 1.0 - (2.0 * rho[accept] - 1.0) ** 3)
        nu[acc] = 2.0
        runs.stop(acc, reduction_small(f[accept], f_new[accept], opts), 2, k + 1)
        # rejected: more damping
        rej = rows[~accept]
        mu[rej] *= nu[rej]
        nu[rej] *= 2.0
        runs.stop(rej, mu[rej] > 1e30, -1, k + 1)
        left = rows[runs.status[rows] == RUNNING]
        runs.note("damping", left, mu[left])
    runs.stop(runs.active(), True, 0, opts.max_iter)
    return runs
