"""The compiled per-start loop: the batchable solvers on the test function (6-16), in C.

:func:`handeye.solvers.solve_many` runs many starts as numpy stacks, one array operation per
step of the iteration for all running rows; on a 2-D problem each operation does little work
and the interpreter's overhead per operation dominates. Here the same methods run one start
after another in C, each row to its own end:

* no derivative is written by hand: CasADi generates C for the test function's ``f``, gradient,
  Hessian, residual and residual Jacobian (:func:`handeye.model.chain.testfunction.casadi_function`,
  from the one sympy source);
* ``fast_starts.c`` holds the iteration of each method of :mod:`handeye.solvers` (local and
  damped Newton, steepest descent, BFGS, Gauss-Newton, Levenberg-Marquardt, trust-region
  Newton with the exact subproblem), rule for rule: the same steps, acceptance, stopping tests,
  statuses, messages and evaluation counts;
* both are compiled once with the system C compiler and cached
  (:func:`handeye.model.compiled.ccompile.cached_library`), like :mod:`handeye.model.compiled.fast`.

The ends agree with the numpy batch to round-off, not bit for bit: the C solves its 2 x 2
systems by LU and Jacobi rotations where numpy calls LAPACK. A start whose iteration is
chaotic (a step onto a basin boundary) may therefore end elsewhere on the two paths; the tests
compare both on a grid and bound that share. :func:`solve_many` returns None when there is no
C compiler or when the options ask for what the C does not have (forward-difference
Jacobians, Steihaug-CG); callers then use :func:`handeye.solvers.solve_many` and say so.
"""
from __future__ import annotations

import ctypes
import functools
import pathlib

import numpy as np

from handeye.model.chain import testfunction
from handeye.model.compiled import ccompile
from handeye.solvers import BatchResult
from handeye.solvers.line_search import AT_PRECISION, NO_STEP
from handeye.solvers.problem import Options
from handeye.solvers.stacks import max_abs_rows

DRIVER = pathlib.Path(__file__).with_name("fast_starts.c")
#: the methods the C runs, in the order of its ``enum`` (fast_starts.c)
METHODS = ("newton", "newton-ls", "sd", "bfgs", "gn", "lm", "tr")
#: generated function in the C -> part of :mod:`handeye.model.chain.testfunction`
PARTS = {"he_f": "f", "he_g": "grad", "he_h": "hess", "he_r": "r", "he_j": "rjac"}
#: the message codes of fast_starts.c (beyond the status table)
MESSAGES = {1: AT_PRECISION, 2: NO_STEP}


def _generated():
    """C source of the five generated functions and the work sizes they need."""
    import casadi as ca

    gen = ca.CodeGenerator("he_generated.c", {"with_header": False})
    x = ca.SX.sym("x", 2)
    sz_w = sz_iw = 1
    for name, part in PARTS.items():
        fn = ca.Function(name, [x], [testfunction.casadi_function(part)(x)])
        gen.add(fn)
        sz_w, sz_iw = max(sz_w, fn.sz_w()), max(sz_iw, fn.sz_iw())
    return gen.dump(), sz_w, sz_iw


@functools.lru_cache(maxsize=None)
def library():
    """The compiled per-start loop (ctypes), or None when no C compiler is available."""
    generated, sz_w, sz_iw = _generated()
    flags = (*ccompile.CFLAGS, "-DHE_N=2", "-DHE_M=4", f"-DHE_SZ_W={sz_w}", f"-DHE_SZ_IW={sz_iw}")
    dll = ccompile.cached_library("fast_starts", {"fast_starts.c": DRIVER.read_text(), "he_generated.c": generated},
                                  flags, ("he_starts",))
    if dll is None:
        return None
    pointer = ctypes.c_void_p
    dll.he_starts.argtypes = [ctypes.c_int, ctypes.c_long, pointer, pointer, pointer, pointer, pointer]
    dll.he_starts.restype = ctypes.c_int
    return dll


def supports(method, options=None):
    """Whether the C has ``method`` with these options (exact Jacobian, exact trust-region subproblem)."""
    opts = options if isinstance(options, Options) else Options.from_mapping(options)
    return method in METHODS and opts.jacobian == "exact" and (method != "tr" or opts.subproblem == "exact")


def _option_vector(opts):
    return np.array([opts.max_iter, opts.gtol, opts.ftol, opts.xtol, opts.eta, opts.lm_tau, opts.max_radius_factor,
                     float(opts.initial_radius or 0.0), float(bool(opts.scaling))], dtype=float)


def solve_many(starts, method, options=None):
    """Minimise the test function from every row of ``starts`` with ``method``, in C.

    Row i ends where :func:`handeye.solvers.solve_many` on
    :func:`handeye.app.engine.problems.testfunction_problem` ends from it, to round-off (module
    docstring).

    Parameters
    ----------
    starts : array_like, shape (N, 2)
    method : str
        One of :data:`METHODS`.
    options : dict or Options, optional
        As :func:`handeye.solvers.solve_many`.

    Returns
    -------
    BatchResult or None
        None when no C compiler is available or :func:`supports` says no.
    """
    opts = options if isinstance(options, Options) else Options.from_mapping(options)
    if not supports(method, opts):
        return None
    dll = library()
    if dll is None:
        return None
    x = np.array(starts, dtype=float, order="C")
    if x.ndim != 2 or x.shape[1] != 2:
        raise ValueError(f"starts must have shape (N, 2), got {x.shape}")
    n = len(x)
    f, g, info = np.zeros(n), np.zeros((n, 2)), np.zeros((n, 7))
    if n:
        dll.he_starts(METHODS.index(method), n, _option_vector(opts).ctypes.data, x.ctypes.data, f.ctypes.data,
                      g.ctypes.data, info.ctypes.data)
    counts = info.astype(int)
    messages = {i: MESSAGES[c] for i, c in enumerate(counts[:, 5].tolist()) if c in MESSAGES}
    return BatchResult(x=x, cost=f, grad_norm=max_abs_rows(g), iterations=counts[:, 0], nfev=counts[:, 1],
                       njev=counts[:, 2], nhev=counts[:, 3], status=counts[:, 4], method=method, messages=messages)
