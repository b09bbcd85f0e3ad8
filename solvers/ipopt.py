"""IPOPT through CasADi's ``nlpsol`` (Wachter & Biegler 2006; N&W 2nd ed., 19).

The problem comes as CasADi's dict ``{'x', 'f', 'g', 'p'}``: minimise ``f(x; p)`` subject to
``lbg <= g(x; p) <= ubg``. IPOPT is a primal-dual interior-point method with a filter line
search; with equality constraints only, its solution satisfies the KKT conditions

    grad f(x*) + J_g(x*)^T lam_g = 0,   g(x*) = 0,

and the multipliers ``lam_g`` are returned in ``result.extra`` so that notebooks can check
them by hand. Iterates are recorded through an iteration callback.
"""
from __future__ import annotations

import collections
import threading

import numpy as np

from handeye.solvers.result import STATUS_MESSAGES, OptimizeResult

_DEFAULTS = {
    "ipopt.print_level": 0,
    "print_time": False,
    "ipopt.sb": "yes",
    "ipopt.tol": 1e-12,
    "ipopt.acceptable_tol": 1e-8,
}


def _recorder(nlp_sizes, store):
    import casadi as ca

    class Recorder(ca.Callback):
        def __init__(self):
            ca.Callback.__init__(self)
            self.construct("handeye_ipopt_recorder", {})

        def get_n_in(self):
            return ca.nlpsol_n_out()

        def get_n_out(self):
            return 1

        def get_name_in(self, i):
            return ca.nlpsol_out(i)

        def get_name_out(self, i):
            return "ret"

        def get_sparsity_in(self, i):
            name = ca.nlpsol_out(i)
            n = {"f": 1, "x": nlp_sizes[0], "lam_x": nlp_sizes[0], "g": nlp_sizes[1],
                 "lam_g": nlp_sizes[1], "p": nlp_sizes[2], "lam_p": nlp_sizes[2]}[name]
            return ca.Sparsity.dense(n, 1)

        def eval(self, arg):
            store.append(np.array(arg[0]).ravel())
            return [0]

    return Recorder()


#: Solvers kept across problems of one structure (a problem dict's ``'structure'``: the same graph, other
#: ``p_value``), least recently used dropped beyond this many. A kept solver holds its expanded graph and
#: Hessian (about 30 MB at 300 rows): a problem names a structure only where building is what costs (few rows).
SHARED_SOLVERS = 8
_shared = collections.OrderedDict()
_shared_lock = threading.Lock()


class _Solver:
    """IPOPT built once for a problem (or a problem structure); called for one start at a time."""

    def __init__(self, problem, opts, history=None):
        import casadi as ca

        nlp = problem.nlp
        self.nlp = nlp  # keeps a callback in it (e.g. a model's numpy cost) alive as long as the solver
        self.x_sym, self.g_sym, self.p_sym = nlp["x"], nlp["g"], nlp.get("p")
        p_syms = [] if self.p_sym is None else [self.p_sym]
        sizes = (self.x_sym.shape[0], self.g_sym.shape[0], 0 if self.p_sym is None else self.p_sym.shape[0])
        options = dict(_DEFAULTS)
        options["ipopt.max_iter"] = opts.max_iter
        options.update(opts.ipopt)
        self.history = history
        if history is not None:
            self._recorder = _recorder(sizes, history)  # kept alive while the solver lives
            options["iteration_callback"] = self._recorder
        prob = {"x": self.x_sym, "f": nlp["f"], "g": self.g_sym}
        if self.p_sym is not None:
            prob["p"] = self.p_sym
        self.solver = ca.nlpsol("handeye_ipopt", "ipopt", prob, options)
        self.args = {"lbg": nlp.get("lbg", []), "ubg": nlp.get("ubg", [])}
        if self.p_sym is not None:
            self.args["p"] = nlp["p_value"]
        self.p_args = [] if self.p_sym is None else [self.args["p"]]
        self.grad_f = ca.Function("grad_f", [self.x_sym] + p_syms, [ca.gradient(nlp["f"], self.x_sym)])
        self.jac_g = (ca.Function("jac_g", [self.x_sym] + p_syms, [ca.jacobian(self.g_sym, self.x_sym)])
                      if self.g_sym.shape[0] else None)

    def __call__(self, x0, nlp=None):
        """IPOPT from ``x0``, with the bounds and parameter values of ``nlp`` (a problem dict of the same
        ``x``, ``f`` and ``g``; default those of the problem it was built for)."""
        x0 = np.asarray(x0, dtype=float)
        args, p_args = self.args, self.p_args
        if nlp is not None:  # this call's own bounds and data (locals: the solver object keeps its first problem's)
            args = {"lbg": nlp.get("lbg", []), "ubg": nlp.get("ubg", [])}
            if self.p_sym is not None:
                args["p"] = nlp["p_value"]
            p_args = [] if self.p_sym is None else [args["p"]]
        if self.history is not None:
            self.history.clear()
        sol = self.solver(x0=x0, **args)
        stats = self.solver.stats()
        x = np.array(sol["x"]).ravel()
        grad = np.array(self.grad_f(x, *p_args)).ravel()
        lam_g = np.array(sol["lam_g"]).ravel()
        lagr_grad = grad if self.jac_g is None else grad + np.array(self.jac_g(x, *p_args)).T @ lam_g
        ret = stats.get("return_status", "")
        status = 5 if ret == "Solve_Succeeded" else 6 if ret == "Solved_To_Acceptable_Level" else 7
        if status == 7 and ret == "Maximum_Iterations_Exceeded":
            status = 0
        msg = STATUS_MESSAGES[status] + (f" ({ret})" if status in (0, 7) else "")
        history = list(self.history or [])
        if not history or not np.array_equal(history[0], x0):
            history.insert(0, x0.copy())
        counts = {k[len("n_call_"):]: v for k, v in stats.items() if k.startswith("n_call_")}
        return OptimizeResult(
            x=x,
            cost=float(sol["f"]),
            grad_norm=float(np.max(np.abs(lagr_grad))) if lagr_grad.size else float("nan"),
            iterations=int(stats.get("iter_count", len(history) - 1)),
            nfev=int(counts.get("nlp_f", 0)),
            njev=int(counts.get("nlp_grad_f", 0)),
            nhev=int(counts.get("nlp_hess_l", 0)),
            status=status,
            message=msg,
            converged=status in (5, 6),
            method="ipopt",
            history=history,
            extra={"lam_g": lam_g, "g": np.array(sol["g"]).ravel(), "return_status": ret},
        )


def minimize(problem, x0, opts):
    """IPOPT from one start, with its iterates recorded; the solver is built once per problem
    and options (``problem.built``) and called again for the next start (the same answer as a
    fresh one: IPOPT keeps no state between calls without warm-start options). A problem that names
    its ``'structure'`` shares the solver of every problem of that structure and options (in this
    thread), called with its own ``p_value``: ``nlpsol`` is built once per structure, not per problem."""
    return _solver_of(problem, opts, history=True)(x0, problem.nlp)


def _solver_of(problem, opts, history):
    """The solver of ``problem`` and ``opts`` (iterates recorded with ``history``), built once per problem
    (``problem.built``) from the one kept for its structure, if any (:func:`_shared_solver`)."""
    key = ("ipopt" if history else "ipopt-batch", opts.max_iter, repr(sorted(opts.ipopt.items())))
    solver = problem.built.get(key)
    if solver is None:
        solver = problem.built[key] = _shared_solver(problem, opts, key, history)
    return solver


def _shared_solver(problem, opts, key, history=True):
    """The solver of ``problem`` and ``opts`` (recording its iterates with ``history``): the one kept for its
    ``'structure'`` (:data:`SHARED_SOLVERS`) when it was built on the very same ``x``, ``f`` and ``g`` (a
    structure's graph is built once), or a new one."""
    nlp = problem.nlp
    structure = nlp.get("structure")
    if structure is None:
        return _Solver(problem, opts, history=[] if history else None)
    shared = (structure, key, history, threading.get_ident())
    with _shared_lock:
        solver = _shared.get(shared)
        if solver is None or not all(nlp[k] is solver.nlp[k] for k in ("x", "f", "g")):
            solver = _shared[shared] = _Solver(problem, opts, history=[] if history else None)
            while len(_shared) > SHARED_SOLVERS:
                _shared.popitem(last=False)
        _shared.move_to_end(shared)
    return solver


def minimize_many(problem, starts, opts):
    """IPOPT from each row of ``starts`` (N, d), one after another through one solver object."""
    from handeye.solvers.batch import BatchResult

    solver = _solver_of(problem, opts, history=False)  # no iterates recorded: a batch reports none
    results = [solver(x0, problem.nlp) for x0 in starts]
    messages = {i: r.message for i, r in enumerate(results) if r.status in (0, 7)}

    def column(name, dtype=float):
        return np.array([getattr(r, name) for r in results], dtype=dtype).reshape(len(results), *(() if name != "x" else (-1,)))

    return BatchResult(x=column("x") if results else np.zeros((0, np.shape(starts)[-1])), cost=column("cost"),
                       grad_norm=column("grad_norm"), iterations=column("iterations", int), nfev=column("nfev", int),
                       njev=column("njev", int), nhev=column("nhev", int), status=column("status", int),
                       method="ipopt", messages=messages)
