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

from handeye.solvers.result import Tracker, gradient_small, reduction_small, step_small


def minimize(problem, x0, opts):
    t = Tracker(problem, x0, "lm")
    x = np.array(x0, dtype=float)
    r = t.residual(x)
    f = 0.5 * float(r @ r)
    j = t.jacobian(x)
    a = j.T @ j
    g = j.T @ r
    d = np.maximum(np.diag(a), 1e-12 * max(1.0, np.max(np.diag(a))))
    mu = opts.lm_tau * float(np.max(np.diag(a))) / float(np.max(d)) if np.max(d) > 0 else opts.lm_tau
    nu = 2.0
    t.extra["damping"] = [mu]
    for k in range(opts.max_iter):
        if not (np.isfinite(f) and np.all(np.isfinite(j))):
            return t.finish(x, f, g, -1, k)
        if gradient_small(g, f, opts):
            return t.finish(x, f, g, 1, k)
        try:
            p = np.linalg.solve(a + mu * np.diag(d), -g)
        except np.linalg.LinAlgError:
            return t.finish(x, f, g, -1, k)
        if step_small(p, x, opts):
            return t.finish(x, f, g, 3, k)
        x_new = problem.move(x, p)
        r_new = t.residual(x_new)
        f_new = 0.5 * float(r_new @ r_new)
        predicted = -(g @ p) - 0.5 * float(p @ a @ p)
        rho = (f - f_new) / predicted if predicted > 0 else -1.0
        if np.isfinite(f_new) and rho > 0:
            f_old = f
            x, r, f = x_new, r_new, f_new
            t.record(x)
            j = t.jacobian(x)
            a = j.T @ j
            g = j.T @ r
            d = np.maximum(d, np.diag(a))
            mu *= max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
            nu = 2.0
            if reduction_small(f_old, f, opts):
                return t.finish(x, f, g, 2, k + 1)
        else:
            mu *= nu
            nu *= 2.0
            if mu > 1e30:
                return t.finish(x, f, g, -1, k + 1)
        t.extra["damping"].append(mu)
    return t.finish(x, f, g, 0, opts.max_iter)
