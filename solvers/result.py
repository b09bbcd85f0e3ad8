"""One result type for every solver, and the table of termination messages."""
from __future__ import annotations

import dataclasses

import numpy as np

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


class Tracker:
    """Counts evaluations and records iterates while a solver runs."""

    def __init__(self, problem, x0, method):
        self.problem = problem
        self.method = method
        self.nfev = self.njev = self.nhev = 0
        self.history = [np.array(x0, dtype=float)]
        self.extra = {}

    def residual(self, x):
        self.nfev += 1
        return np.asarray(self.problem.residual(x), dtype=float)

    def jacobian(self, x):
        self.njev += 1
        return np.asarray(self.problem.jacobian(x), dtype=float)

    def cost(self, x):
        self.nfev += 1
        return self.problem.cost(x)

    def grad(self, x):
        self.njev += 1
        return self.problem.grad(x)

    def hess(self, x):
        self.nhev += 1
        return np.asarray(self.problem.hessian(x), dtype=float)

    def record(self, x):
        self.history.append(np.array(x, dtype=float))

    def finish(self, x, cost, grad, status, iterations, message=None):
        gnorm = float(np.max(np.abs(grad))) if grad is not None and np.size(grad) else float("nan")
        return OptimizeResult(
            x=np.array(x, dtype=float),
            cost=float(cost),
            grad_norm=gnorm,
            iterations=int(iterations),
            nfev=self.nfev,
            njev=self.njev,
            nhev=self.nhev,
            status=status,
            message=message or STATUS_MESSAGES[status],
            converged=status in CONVERGED,
            method=self.method,
            history=self.history,
            extra=self.extra,
        )


def gradient_small(grad, cost, opts):
    return float(np.max(np.abs(grad))) <= opts.gtol * max(1.0, abs(cost))


def step_small(delta, x, opts):
    return float(np.linalg.norm(delta)) <= opts.xtol * (opts.xtol + float(np.linalg.norm(x)))


def reduction_small(f_old, f_new, opts):
    return abs(f_old - f_new) <= opts.ftol * max(1.0, abs(f_old))
