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
Everything works on stacks of starts (:mod:`handeye.solvers.batch`): each row runs its own
backtracking or its own bracketing and zooming, and stops on its own tests.
"""
from __future__ import annotations

import dataclasses
from typing import Callable

import numpy as np

from handeye.solvers.batch import Runs
from handeye.solvers.result import reduction_small, step_small
from handeye.solvers.stacks import dot_rows, finite_rows, matvec, norm_rows, solve_rows

C1, C2, RHO = 1e-4, 0.9, 0.5
#: messages of the two line-search stops that the status table does not word
AT_PRECISION = "converged to the precision of f: the possible decrease along the direction is below rounding"
NO_STEP = "line search failed: no acceptable step along the direction"


def armijo(phi, f0, slope, max_steps=60):
    """Backtracking on each row: the largest ``RHO^k`` with sufficient decrease.

    ``phi(alpha, rows)`` returns f along the rows' directions at steps ``alpha`` (k,).
    Returns ``alpha``, the value there and ``found`` (False: no acceptable step), each (N,).
    """
    alpha = np.ones(len(f0))
    value = np.full(len(f0), np.nan)
    found = np.zeros(len(f0), dtype=bool)
    for _ in range(max_steps):
        rows = np.flatnonzero(~found)
        if not rows.size:
            break
        v = phi(alpha[rows], rows)
        ok = np.isfinite(v) & (v <= f0[rows] + C1 * alpha[rows] * slope[rows])
        found[rows[ok]] = True
        value[rows[ok]] = v[ok]
        alpha[rows[~ok]] *= RHO
    return alpha, value, found


class _Wolfe:
    """Per-row state of the strong Wolfe search (N&W Algorithms 3.5 and 3.6)."""

    BRACKET, ZOOM, FOUND, FAILED = range(4)

    def __init__(self, f0, slope, alpha_max):
        n = len(f0)
        self.f0, self.slope, self.alpha_max = f0, slope, alpha_max
        self.phase = np.zeros(n, dtype=int)
        self.alpha, self.prev_alpha, self.prev_value = np.ones(n), np.zeros(n), f0.copy()
        self.lo, self.hi, self.f_lo = np.zeros(n), np.zeros(n), np.zeros(n)
        self.steps = np.zeros(n, dtype=int)  # passes in the current phase
        self.value = np.full(n, np.nan)

    def zoom(self, rows, lo, hi, f_lo):
        self.phase[rows] = self.ZOOM
        self.lo[rows], self.hi[rows], self.f_lo[rows] = lo, hi, f_lo
        self.steps[rows] = 0

    def settle(self, rows, alpha, value):
        self.phase[rows] = self.FOUND
        self.alpha[rows], self.value[rows] = alpha, value


def wolfe(phi, dphi, f0, slope, alpha_max=1e6, max_steps=60):
    """Step satisfying the strong Wolfe conditions on each row (N&W Algorithms 3.5, 3.6).

    Bracketing doubles alpha from 1 until the bracket holds a Wolfe point; zooming bisects it.
    ``phi(alpha, rows)`` and ``dphi(alpha, rows)`` give f and its slope along the rows'
    directions. Returns ``alpha``, value and ``found``, each (N,).
    """
    s = _Wolfe(f0, slope, alpha_max)
    while True:
        rows = np.flatnonzero(s.phase <= s.ZOOM)
        if not rows.size:
            break
        zoom = s.phase[rows] == s.ZOOM
        trial = np.where(zoom, 0.5 * (s.lo[rows] + s.hi[rows]), s.alpha[rows])
        v = phi(trial, rows)
        armijo_fails = ~np.isfinite(v) | (v > f0[rows] + C1 * trial * slope[rows])
        high = armijo_fails | np.where(zoom, v >= s.f_lo[rows], (s.steps[rows] > 0) & (v >= s.prev_value[rows]))
        need = ~high
        d = np.full(len(rows), np.nan)
        if need.any():
            d[need] = dphi(trial[need], rows[need])
        curvature = need & (np.abs(d) <= -C2 * slope[rows])
        s.settle(rows[curvature], trial[curvature], v[curvature])
        # bracketing: a bracket found (too high, or slope turned up), or double alpha
        br = ~zoom & ~curvature
        up = br & high
        s.zoom(rows[up], s.prev_alpha[rows[up]], trial[up], s.prev_value[rows[up]])
        turned = br & ~high & (d >= 0)
        s.zoom(rows[turned], trial[turned], s.prev_alpha[rows[turned]], v[turned])
        grow = rows[br & ~high & ~(d >= 0)]
        s.prev_alpha[grow], s.prev_value[grow] = s.alpha[grow], v[br & ~high & ~(d >= 0)]
        s.alpha[grow] = np.minimum(2.0 * s.alpha[grow], alpha_max)
        s.steps[grow] += 1
        s.phase[grow[s.steps[grow] >= max_steps]] = s.FAILED
        # zooming: shrink the bracket [lo, hi] (its ends in either order)
        zm = zoom & ~curvature
        s.hi[rows[zm & high]] = trial[zm & high]
        zl = zm & ~high
        flip = rows[zl & (d * (s.hi[rows] - s.lo[rows]) >= 0)]
        s.hi[flip] = s.lo[flip]
        s.lo[rows[zl]], s.f_lo[rows[zl]] = trial[zl], v[zl]
        zrows = rows[zm]
        s.steps[zrows] += 1
        out = zrows[s.steps[zrows] >= max_steps]
        some = out[s.lo[out] > 0]
        s.settle(some, s.lo[some], s.f_lo[some])
        s.phase[out[s.lo[out] <= 0]] = s.FAILED
    return s.alpha, s.value, s.phase == s.FOUND


@dataclasses.dataclass(frozen=True)
class Method:
    """A line-search method: its ``name``; ``direction(runs, rows) -> p`` for the running rows;
    ``search`` 'armijo' or 'wolfe'; ``update(rows, s, y)`` after each accepted step (BFGS) or None."""

    name: str
    direction: Callable
    search: str
    update: Callable | None = None


def _run(stacked, x0, opts, method, trace=False):
    """Generic line-search loop on stacks (``method``: a :class:`Method`)."""
    direction, search, update = method.direction, method.search, method.update
    runs = Runs(stacked, x0, method.name, trace)
    rows = runs.active()
    runs.f[rows] = runs.cost(runs.x, rows)
    runs.g[rows] = runs.grad(runs.x, rows)
    eps = np.finfo(float).eps
    for k in range(opts.max_iter):
        rows = runs.screened(k, opts)
        if not rows.size:
            break
        x, f, g = runs.x[rows], runs.f[rows], runs.g[rows]
        p = direction(runs, rows)
        slope = dot_rows(g, p)
        steepest = ~finite_rows(p) | (slope >= 0)  # not a descent direction: steepest descent
        p[steepest] = -g[steepest]
        slope[steepest] = -dot_rows(g[steepest], g[steepest])
        if update is not None:
            update(rows[steepest], None, None)

        def phi(a, sub):
            return runs.cost(stacked.move(x[sub], a[:, None] * p[sub]), rows[sub])

        def dphi(a, sub):
            return dot_rows(runs.grad(stacked.move(x[sub], a[:, None] * p[sub]), rows[sub]), p[sub])

        alpha, f_new, found = armijo(phi, f, slope) if search == "armijo" else wolfe(phi, dphi, f, slope)
        precision = ~found & (np.abs(slope) <= 100 * eps * np.maximum(1.0, np.abs(f)))
        runs.stop(rows, precision, 2, k, AT_PRECISION)
        runs.stop(rows, ~found & ~precision, -1, k, NO_STEP)
        rows, x, g, p, alpha, f_new, f = (a[found] for a in (rows, x, g, p, alpha, f_new, f))
        if not rows.size:
            continue
        step = alpha[:, None] * p
        x_new = stacked.move(x, step)
        g_new = runs.grad(x_new, rows)
        if update is not None:
            update(rows, step, g_new - g)
        runs.record(rows, x_new)
        runs.x[rows], runs.f[rows], runs.g[rows] = x_new, f_new, g_new
        small_step = step_small(step, x, opts)
        runs.stop(rows, small_step, 3, k + 1)
        runs.stop(rows, ~small_step & reduction_small(f, f_new, opts), 2, k + 1)
    runs.stop(runs.active(), True, 0, opts.max_iter)
    return runs


def damped_newton(stacked, x0, opts, trace=False):
    """Newton direction ``H p = -g`` with an Armijo line search (N&W 3.3); where H is singular, or
    not positive definite along p, the step falls back to steepest descent."""

    def direction(runs, rows):
        g = runs.g[rows]
        p, ok = solve_rows(runs.hessian(runs.x[rows], rows), -g)
        p[~ok] = -g[~ok]
        return p

    return _run(stacked, x0, opts, Method("newton-ls", direction, "armijo"), trace=trace)


def steepest_descent(stacked, x0, opts, trace=False):
    """``p = -g`` with an Armijo line search (N&W 3.1): linear convergence at best."""
    return _run(stacked, x0, opts, Method("sd", lambda runs, rows: -runs.g[rows], "armijo"), trace=trace)


def bfgs(stacked, x0, opts, trace=False):
    """BFGS (N&W Algorithm 6.1) with a strong Wolfe line search: the inverse Hessian
    approximation ``H <- (I - rho s y^T) H (I - rho y s^T) + rho s s^T``, ``rho = 1 / y^T s``,
    scaled at the first step by ``y^T s / y^T y`` (N&W 6.20)."""
    n = stacked.n
    h_inv = np.zeros((len(x0), n, n))
    has = np.zeros(len(x0), dtype=bool)  # whether a row has an approximation yet

    def direction(runs, rows):
        g = runs.g[rows]
        p = -g
        some = has[rows]
        p[some] = -matvec(h_inv[rows[some]], g[some])
        return p

    def update(rows, s, y):
        if s is None:  # a steepest-descent fallback discards the approximation
            has[rows] = False
            return
        sy = dot_rows(s, y)
        ok = sy > 1e-12 * norm_rows(s) * norm_rows(y)
        # the curvature condition cannot fail after a Wolfe step, but on manifolds it may: skip
        rows, s, y, sy = rows[ok], s[ok], y[ok], sy[ok]
        eye = np.eye(n)
        h0 = np.where(has[rows][:, None, None], h_inv[rows], (sy / dot_rows(y, y))[:, None, None] * eye)
        rho = (1.0 / sy)[:, None, None]
        v = eye - rho * np.einsum("ki,kj->kij", s, y)
        h_inv[rows] = v @ h0 @ np.swapaxes(v, 1, 2) + rho * np.einsum("ki,kj->kij", s, s)
        has[rows] = True

    return _run(stacked, x0, opts, Method("bfgs", direction, "wolfe", update), trace=trace)
