"""IPOPT through CasADi's ``nlpsol`` (Wachter & Biegler 2006; N&W 2nd ed., 19).

The problem comes as CasADi's dict ``{'x', 'f', 'g', 'p'}``: minimise ``f(x; p)`` subject to
``lbg <= g(x; p) <= ubg``. IPOPT is a primal-dual interior-point method with a filter line
search; with equality constraints only, its solution satisfies the KKT conditions

    grad f(x*) + J_g(x*)^T lam_g = 0,   g(x*) = 0,

and the multipliers ``lam_g`` are returned in ``result.extra`` so that notebooks can check
them by hand. Iterates are recorded through an iteration callback.
"""
from __future__ import annotations

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


def minimize(problem, x0, opts):
    import casadi as ca

    nlp = problem.nlp
    x_sym, g_sym, p_sym = nlp["x"], nlp["g"], nlp.get("p")
    sizes = (x_sym.shape[0], g_sym.shape[0], 0 if p_sym is None else p_sym.shape[0])
    history = []
    recorder = _recorder(sizes, history)
    options = dict(_DEFAULTS)
    options["ipopt.max_iter"] = opts.max_iter
    options.update(opts.ipopt)
    options["iteration_callback"] = recorder
    prob = {"x": x_sym, "f": nlp["f"], "g": g_sym}
    if p_sym is not None:
        prob["p"] = p_sym
    solver = ca.nlpsol("handeye_ipopt", "ipopt", prob, options)
    args = {"x0": np.asarray(x0, dtype=float), "lbg": nlp.get("lbg", []), "ubg": nlp.get("ubg", [])}
    if p_sym is not None:
        args["p"] = nlp["p_value"]
    sol = solver(**args)
    stats = solver.stats()
    x = np.array(sol["x"]).ravel()
    grad_f = ca.Function("grad_f", [x_sym] + ([p_sym] if p_sym is not None else []), [ca.gradient(nlp["f"], x_sym)])
    grad = np.array(grad_f(x, *([args["p"]] if p_sym is not None else []))).ravel()
    lam_g = np.array(sol["lam_g"]).ravel()
    if g_sym.shape[0]:
        jac_g = ca.Function("jac_g", [x_sym] + ([p_sym] if p_sym is not None else []), [ca.jacobian(g_sym, x_sym)])
        lagr_grad = grad + np.array(jac_g(x, *([args["p"]] if p_sym is not None else []))).T @ lam_g
    else:
        lagr_grad = grad
    ret = stats.get("return_status", "")
    status = 5 if ret == "Solve_Succeeded" else 6 if ret == "Solved_To_Acceptable_Level" else 7
    if status == 7 and ret == "Maximum_Iterations_Exceeded":
        status = 0
    msg = STATUS_MESSAGES[status] + (f" ({ret})" if status in (0, 7) else "")
    if not history or not np.array_equal(history[0], np.asarray(x0, float)):
        history.insert(0, np.array(x0, dtype=float))
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
