"""The one front end: ``solve(problem, x0, method=..., options=...)``."""
from __future__ import annotations

from handeye.solvers import gauss_newton, ipopt, levenberg_marquardt, line_search, newton, trust_region
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
    return {
        "newton": newton.minimize,
        "newton-ls": line_search.damped_newton,
        "sd": line_search.steepest_descent,
        "bfgs": line_search.bfgs,
        "gn": gauss_newton.minimize,
        "lm": levenberg_marquardt.minimize,
        "tr": lambda p, x0, o: trust_region.minimize(p, x0, o, model="newton"),
        "dogleg": lambda p, x0, o: trust_region.minimize(p, x0, o, model="gauss-newton"),
        "ipopt": ipopt.minimize,
    }[method]


def supports(problem, method):
    """Whether ``problem`` provides what ``method`` needs."""
    needs = METHODS[method][0]
    if method in ("newton", "newton-ls", "tr", "sd", "bfgs") and not (
            problem.has("objective", "gradient") or problem.has("residual", "jacobian")):
        return False
    return problem.has(*needs)


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
    if method not in METHODS:
        raise UnsupportedProblem(f"unknown method {method!r}; choose one of {sorted(METHODS)}")
    if not supports(problem, method):
        raise UnsupportedProblem(f"method {method!r} needs {', '.join(METHODS[method][0])}; the problem does not provide it")
    opts = options if isinstance(options, Options) else Options.from_mapping(options)
    if opts.jacobian not in ("exact", "forward"):
        raise UnsupportedProblem(f"jacobian must be 'exact' or 'forward', got {opts.jacobian!r}")
    if opts.subproblem not in ("exact", "cg"):
        raise UnsupportedProblem(f"subproblem must be 'exact' or 'cg', got {opts.subproblem!r}")
    return _runner(method)(problem, x0, opts)
