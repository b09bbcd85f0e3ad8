"""One result type for every solver, and the table of termination messages."""
from __future__ import annotations

import dataclasses

import numpy as np

from handeye.solvers.stacks import max_abs_rows, norm_rows

#: status -> message. Statuses 1, 2, 3 and 5, 6 count as converged.
STATUS_MESSAGES = {
    -1: "numerical failure: singular or non-finite linear system or function value",
    0: "maximum number of iterations reached",
    1: "first-order condition met: gradient norm below gtol",
    2: "relative cost reduction below ftol",
    3: "step size below xtol",
    4: "trust-region radius fell below its minimum without progress",
    -2: "normal equations singular even with large damping",
    -3: "rank-deficient at the solution: a combination of the unknowns is not constrained (scaled J^T J singular)",
    5: "IPOPT: optimal solution found",
    6: "IPOPT: solved to acceptable level",
    7: "IPOPT: did not converge",
}
CONVERGED = frozenset({1, 2, 3, 5, 6})


@dataclasses.dataclass
class OptimizeResult:
    """Outcome of :func:`handeye.solvers.solve`.

    Attributes
    ----------
    x : ndarray
        Final point.
    cost : float
        Objective at ``x`` (``1/2 |r|^2`` for least squares).
    grad_norm : float
        Infinity norm of the gradient at ``x`` (NaN where not available).
    iterations, nfev, njev, nhev : int
        Iterations and evaluations of function, Jacobian/gradient and Hessian.
    status : int
        Key of :data:`STATUS_MESSAGES`.
    message : str
    converged : bool
    method : str
    history : list of ndarray
        Iterates, starting with ``x0`` (for plots).
    extra : dict
        Method-specific data (IPOPT multipliers ``lam_g``, trust radii, damping ...).
    """

    x: np.ndarray
    cost: float
    grad_norm: float
    iterations: int
    nfev: int
    njev: int
    nhev: int
    status: int
    message: str
    converged: bool
    method: str
    history: list
    extra: dict = dataclasses.field(default_factory=dict)


# Stopping tests, on stacks: gradients and steps (k, n), points (k, d), costs (k,).
def gradient_small(grad, cost, opts):
    """``|grad f|_inf <= gtol max(1, |f|)``."""
    return max_abs_rows(grad) <= opts.gtol * np.maximum(1.0, np.abs(cost))


def step_small(delta, x, opts):
    """``|delta| <= xtol (xtol + |x|)``."""
    return norm_rows(delta) <= opts.xtol * (opts.xtol + norm_rows(x))


def reduction_small(f_old, f_new, opts):
    """``|f_old - f_new| <= ftol max(1, |f_old|)``."""
    return np.abs(f_old - f_new) <= opts.ftol * np.maximum(1.0, np.abs(f_old))
