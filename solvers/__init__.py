"""handeye's solvers: unconstrained and least-squares minimisation, written from their
definitions (Nocedal & Wright), plus IPOPT through CasADi. Knows nothing of robots.

>>> from handeye.solvers import Problem, solve
>>> res = solve(Problem(n=1, residual=lambda x: x - 3, jacobian=lambda x: [[1.0]]), [0.0], "gn")
"""
from handeye.solvers.api import METHODS, solve, solve_many, supports
from handeye.solvers.batch import BatchResult
from handeye.solvers.problem import Options, Problem, UnsupportedProblem, forward_difference_jacobian, last_point
from handeye.solvers.result import CONVERGED, STATUS_MESSAGES, OptimizeResult

__all__ = [
    "BatchResult",
    "CONVERGED",
    "METHODS",
    "STATUS_MESSAGES",
    "OptimizeResult",
    "Options",
    "Problem",
    "UnsupportedProblem",
    "forward_difference_jacobian",
    "last_point",
    "solve",
    "solve_many",
    "supports",
]
