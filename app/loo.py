"""Exact leave-one-out refits, every sample at once: damped Newton on the stack of deleted problems.

Problem k is the fit without sample k,

    min_z  f_k(z) = 1/2 sum_i w_ki |W_i e_i(z)|^2,    w_ki = 0 on sample k's rows, else 1,

on the local chart (a point moves by ``retract(z, delta)``). The G problems are iterated
together: their points are a stack Z (G, d), and one call of
:meth:`handeye.model.calibration.CalibrationModel.cost_derivatives` evaluates every row at every
point with the problems' row weights (whitened as the model whitens them), giving ``f_k``, the
gradient ``g_k`` and the exact cost Hessian

    H_k = sum_i w_ki (J_i^T J_i + sum_l (W_i^T W_i e_i)_l grad^2 e_il)

(Nocedal & Wright, *Numerical Optimization*, 2nd ed., eq. 10.5: Gauss-Newton's ``J^T J`` plus the
second-order term it leaves out, which is large when a gross error is among the samples).

**Step.** Newton's step with Levenberg-Marquardt damping (N&W 3.4, 10.3; Marquardt's scaling
``D = diag |H_k|`` for the mixed units, mm and rad):

    (H_k + lambda_k D_k) delta_k = -g_k.

``lambda_k`` is zero (pure Newton: quadratic convergence, N&W Theorem 3.5) while ``H_k`` is
positive definite and steps lower ``f_k``; it is raised, per problem, to twice the distance of
the scaled Hessian's smallest eigenvalue below zero where ``H_k`` is not, ten-fold at every
rejected step, and lowered ten-fold (down to zero) at every accepted one. A step is accepted only
when it does not raise its problem's cost (beyond rounding, ``100 eps |f_k|``).

**First step.** Every problem starts at the full fit x, where the full gradient vanishes, so
``g_k(x) = -g_(k)``, sample k's own part, and the first (undamped) step is

    delta_k = (H - H_(k))^-1 g_(k),

the deletion formula with the full cost Hessian (Cook & Weisberg, *Residuals and Influence in
Regression*, 1982, ch. 5: the one-step approximation of a deleted nonlinear fit). It needs one
evaluation of the rows at x for all problems; the further steps make it exact.

**Convergence**, per problem, as the Gauss-Newton refit it replaces (:data:`handeye.app.robust.LOO_XTOL`):
an undamped step no longer than ``xtol (1 + |z|)``; or, Newton converging quadratically (the
error after a step ``~ kappa |delta_t|^2``, ``kappa ~ |delta_t| / |delta_(t-1)|^2``), when
``safety |delta_t|^3 / |delta_(t-1)|^2`` is; the step is then taken without a further
evaluation. A problem whose gradient is at rounding level, ``|g_k|_inf <= GTOL max(1, f_k)``,
stops where it is. A problem that has not stopped within :data:`NEWTON_ITER` iterations, or
whose numbers are not finite, is reported as not converged: the caller refits it another way.

**Memory.** The problems run in chunks whose second derivatives (G_chunk x rows x m x n^2
floats, the largest array) stay below :data:`CHUNK_BYTES`.
"""
from __future__ import annotations

import numpy as np

#: Iterations of the batched Newton before a problem is handed back as not converged.
NEWTON_ITER = 30
#: Bytes of second derivatives per chunk of problems.
CHUNK_BYTES = 50e6
#: A gradient this small relative to max(1, cost) is rounding: the problem stops.
GTOL = 1e-14
#: The damping a rejected undamped step starts with (scaled Hessian: unit diagonal).
LAMBDA_START = 1e-3


def refits(fitted, x, rows, xtol, safety):
    """The minimum of each deleted problem (module docstring), all problems at once.

    Parameters
    ----------
    fitted : handeye.model.calibration.CalibrationModel
        The model of the samples fitted at ``x`` (``local`` rotation).
    x : ndarray, shape (d,)
        Its fit: the start of every problem.
    rows : sequence of slice or ndarray
        Per problem, the rows of ``fitted`` it leaves out (one sample's).
    xtol, safety : float
        Step tolerance (relative to ``1 + |z|``) and the safety factor of the quadratic
        estimate of the distance left.

    Returns
    -------
    z : ndarray, shape (G, d)
        The refitted points.
    converged : ndarray of bool, shape (G,)
        False where the iteration did not converge (``z`` is then its last point).
    """
    count = len(rows)
    z, done = np.empty((count, len(x))), np.zeros(count, bool)
    n_theta = max(fitted.n, 9)  # the generated second derivatives are over all nine chart entries
    per_problem = 8.0 * fitted.n_meas * fitted.m * n_theta**2
    size = max(1, int(CHUNK_BYTES // per_problem))
    for start in range(0, count, size):
        part = range(start, min(start + size, count))
        weights = np.ones((len(part), fitted.n_meas))
        for j, k in enumerate(part):
            weights[j, rows[k]] = 0.0
        z[part.start:part.stop], done[part.start:part.stop] = _newton(fitted, x, weights, xtol, safety)
    return z, done


def _newton(fitted, x, weights, xtol, safety):
    """Damped Newton on the problems of one chunk (row weights ``weights`` (G, N)) from ``x``;
    returns the points (G, d) and which converged (module docstring)."""
    count = len(weights)
    z = np.tile(np.asarray(x, float), (count, 1))
    f, g, h = fitted.cost_derivatives(x, weights)  # one evaluation of the rows serves every problem
    lam, last = np.zeros(count), np.full(count, np.nan)  # damping; the previous undamped step's length
    done, failed = np.zeros(count, bool), ~_finite(f, g, h)
    for _ in range(NEWTON_ITER):
        act = np.flatnonzero(~done & ~failed)
        flat = np.max(np.abs(g[act]), axis=1) <= GTOL * np.maximum(1.0, np.abs(f[act]))
        done[act[flat]] = True
        act = act[~flat]
        if not act.size:
            break
        step, lam[act] = _damped_steps(h[act], g[act], lam[act])
        size, newton = np.linalg.norm(step, axis=1), lam[act] == 0
        with np.errstate(divide="ignore", invalid="ignore"):
            left = np.where(newton & (last[act] > 0), safety * size**3 / last[act] ** 2, np.inf)
        tol = xtol * (1.0 + np.linalg.norm(z[act], axis=1))
        trial = fitted.retract(z[act], step)
        small = newton & ((size <= tol) | (left <= tol))
        z[act[small]], done[act[small]] = trial[small], True
        act, trial, size, newton = act[~small], trial[~small], size[~small], newton[~small]
        if not act.size:
            break
        f_t, g_t, h_t = fitted.cost_derivatives(trial, weights[act])
        ok = _finite(f_t, g_t, h_t)
        accept = ok & (f_t <= f[act] + 100 * np.finfo(float).eps * np.maximum(1.0, np.abs(f[act])))
        acc, rej = act[accept], act[~accept]
        z[acc], f[acc], g[acc], h[acc] = trial[accept], f_t[accept], g_t[accept], h_t[accept]
        last[acc] = np.where(newton[accept], size[accept], np.nan)
        lam[acc] = np.where(lam[acc] > 10 * LAMBDA_START * 1e-3, lam[acc] / 10, 0.0)
        last[rej] = np.nan
        lam[rej] = np.maximum(10 * lam[rej], LAMBDA_START)
        failed[rej] = lam[rej] > 1e30
    return z, done


def _finite(f, g, h):
    """Problems whose cost, gradient and Hessian are finite."""
    return np.isfinite(f) & np.all(np.isfinite(g), axis=1) & np.all(np.isfinite(h), axis=(1, 2))


def _damped_steps(h, g, lam):
    """Solve ``(H + lambda D) delta = -g`` per problem, ``D = diag |H|`` (Marquardt's scaling),
    through the eigenvectors of the scaled Hessian ``D^-1/2 H D^-1/2``; ``lambda`` is raised
    where it would not make the matrix positive definite (twice the smallest eigenvalue's
    distance below zero, at least :data:`LAMBDA_START`). Returns the steps (G, n) and the
    dampings used (G,)."""
    d = np.abs(np.diagonal(h, axis1=1, axis2=2))
    d = np.maximum(d, 1e-12 * np.maximum(np.max(d, axis=1, keepdims=True), 1e-300))
    s = 1.0 / np.sqrt(d)
    vals, vecs = np.linalg.eigh(h * s[:, :, None] * s[:, None, :])
    lowest, highest = vals[:, 0], vals[:, -1]
    indefinite = lowest <= 1e-12 * np.maximum(highest, 0.0)
    lam = np.where(indefinite, np.maximum(lam, 2.0 * np.maximum(-lowest, 0.0) + LAMBDA_START), lam)
    rotated = np.einsum("gji,gj->gi", vecs, s * g) / (vals + lam[:, None])
    return -s * np.einsum("gij,gj->gi", vecs, rotated), lam
