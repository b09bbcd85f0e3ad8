"""The front end: ``solve(problem, x0, method=..., options=...)`` for one start and
``solve_many(problem, starts, ...)`` for a stack of them, both through the same code
(:mod:`handeye.solvers.batch`: one start is the N = 1 case)."""
from __future__ import annotations

import numpy as np

from handeye.solvers import gauss_newton, ipopt, levenberg_marquardt, line_search, newton, trust_region
from handeye.solvers.batch import BatchResult, Stacked
from handeye.solvers.problem import Options, Problem, UnsupportedProblem

#: method -> (what the problem must provide, description)
METHODS = {
    "newton": (("hessian",), "local Newton, exact Hessian (N&W 3.3)"),
    "newton-ls": (("hessian",), "damped Newton, Armijo line search (N&W 3.3)"),
    "sd": ((), "steepest descent, Armijo line search (N&W 3.1)"),
    "bfgs": ((), "BFGS, strong Wolfe line search (N&W 6.1)"),
    "gn": (("residual", "jacobian"), "Gauss-Newton, full steps (N&W 10.3)"),
    "lm": (("residual", "jacobian"), "Levenberg-Marquardt (N&W 10.3)"),
    "tr": (("hessian",), "trust region, Newton model; subproblem exact or cg (N&W 4, 7.1)"),
    "dogleg": (("residual", "jacobian"), "trust region, Gauss-Newton model, dogleg (N&W 4.1)"),
    "ipopt": (("nlp",), "IPOPT interior point via CasADi nlpsol"),
}


def _runner(method):
    """The iterative method on stacks: ``(stacked, x0 (N, d), options, trace) -> Runs``."""
    return {
        "newton": newton.run,
        "newton-ls": line_search.damped_newton,
        "sd": line_search.steepest_descent,
        "bfgs": line_search.bfgs,
        "gn": gauss_newton.run,
        "lm": levenberg_marquardt.run,
        "tr": lambda s, x0, o, trace: trust_region.run(s, x0, o, trace, model="newton"),
        "dogleg": lambda s, x0, o, trace: trust_region.run(s, x0, o, trace, model="gauss-newton"),
    }[method]


def supports(problem, method):
    """Whether ``problem`` provides what ``method`` needs."""
    needs = METHODS[method][0]
    if method in ("newton", "newton-ls", "tr", "sd", "bfgs") and not (
            problem.has("objective", "gradient") or problem.has("residual", "jacobian")):
        return False
    return problem.has(*needs)


def _checked(problem, method, options):
    if method not in METHODS:
        raise UnsupportedProblem(f"unknown method {method!r}; choose one of {sorted(METHODS)}")
    if not supports(problem, method):
        raise UnsupportedProblem(f"method {method!r} needs {', '.join(METHODS[method][0])}; the problem does not provide it")
    opts = options if isinstance(options, Options) else Options.from_mapping(options)
    if opts.jacobian not in ("exact", "forward"):
        raise UnsupportedProblem(f"jacobian must be 'exact' or 'forward', got {opts.jacobian!r}")
    if opts.subproblem not in ("exact", "cg"):
        raise UnsupportedProblem(f"subproblem must be 'exact' or 'cg', got {opts.subproblem!r}")
    return opts


def solve(problem: Problem, x0, method="lm", options=None):
    """Minimise ``problem`` from ``x0`` with one of :data:`METHODS`.

    Parameters
    ----------
    problem : Problem
    x0 : array_like
        Start point (a point of the problem's space, not a step).
    method : str
        Key of :data:`METHODS`.
    options : dict or Options, optional
        See :class:`handeye.solvers.problem.Options`; a dict is copied, never mutated.

    Returns
    -------
    OptimizeResult

    Raises
    ------
    UnsupportedProblem
        Unknown method or option, or a problem lacking what the method needs.
    """
    opts = _checked(problem, method, options)
    if method == "ipopt":
        return ipopt.minimize(problem, x0, opts)
    x0 = np.asarray(x0, dtype=float)
    return _runner(method)(Stacked(problem), x0[None], opts, True).single()


def solve_many(problem: Problem, starts, method="lm", options=None):
    """Minimise ``problem`` from every row of ``starts`` at once; row i ends where
    ``solve(problem, starts[i], method, options)`` ends.

    Every running start is evaluated in one call per iteration when the problem is
    ``vectorised`` (else row by row). IPOPT has no batch form: its starts run one after
    another through one solver object built once.

    Parameters
    ----------
    problem : Problem
    starts : array_like, shape (N, d)
        Start points, one per row.
    method, options
        As :func:`solve`.

    Returns
    -------
    BatchResult
    """
    opts = _checked(problem, method, options)
    starts = np.asarray(starts, dtype=float)
    if starts.ndim != 2:
        raise UnsupportedProblem(f"starts must be a stack of points (N, d), got shape {starts.shape}")
    if not len(starts):
        return BatchResult.empty(starts.shape[1], method)
    if method == "ipopt":
        return ipopt.minimize_many(problem, starts, opts)
    return _runner(method)(Stacked(problem), starts, opts, False).result()
