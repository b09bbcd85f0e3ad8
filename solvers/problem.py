"""What a solver is given: a problem as a bundle of callables, and its options.

A problem knows nothing of robots. Every field is optional; each method states what it needs
(``REQUIRES`` in :mod:`handeye.solvers.api`) and :func:`handeye.solvers.solve` refuses, with a clear message, a
problem that lacks it.

* Least squares: ``residual(x) -> r (m,)`` and ``jacobian(x) -> J (m, n)``; the cost is
  ``f = 1/2 |r|^2`` unless ``objective`` is given.
* General smooth minimisation: ``objective``, ``gradient`` and ``hessian``.
* Manifolds: ``retract(x, delta)`` moves from point ``x`` by a step ``delta`` of dimension
  ``n`` (default ``x + delta``); points may be larger than steps, as for a rotation matrix
  moved by a rotation vector. Derivatives are always with respect to the step at ``delta = 0``.
* Batches: ``vectorised=True`` says the callables also accept stacks of points, shape
  (k, d) in and (k, ...) out (``retract`` also a stack of steps (k, n)); then
  :func:`handeye.solvers.solve_many` evaluates all running starts in one call.
* Normal equations: ``normal(x) -> (J^T J (n, n), J^T r (n,), r^T r)``, optional beside
  ``residual`` and ``jacobian``: Levenberg-Marquardt then never holds J (a million rows are
  summed chunk by chunk); the cost stays ``1/2 |residual(x)|^2``.
* IPOPT: ``nlp``, a CasADi problem dict ``{'x', 'f', 'g', 'p'}`` with ``lbg``, ``ubg`` and
  ``p_value``.
"""
from __future__ import annotations

import dataclasses
from typing import Callable, Optional

import numpy as np


class UnsupportedProblem(ValueError):
    """The chosen method cannot work on this problem (it lacks what the method needs)."""


@dataclasses.dataclass(frozen=True)
class Problem:
    """A minimisation problem (see module docstring)."""

    n: int
    residual: Optional[Callable] = None
    jacobian: Optional[Callable] = None
    objective: Optional[Callable] = None
    gradient: Optional[Callable] = None
    hessian: Optional[Callable] = None
    retract: Optional[Callable] = None
    nlp: Optional[dict] = None
    vectorised: bool = False
    normal: Optional[Callable] = None
    #: Built solver objects (IPOPT's ``nlpsol``), kept for the next solve of the same problem.
    built: dict = dataclasses.field(default_factory=dict, compare=False, repr=False, init=False)

    def cost(self, x):
        if self.objective is not None:
            return float(self.objective(x))
        r = np.asarray(self.residual(x), dtype=float)
        return 0.5 * float(r @ r)

    def grad(self, x):
        if self.gradient is not None:
            return np.asarray(self.gradient(x), dtype=float)
        return np.asarray(self.jacobian(x), dtype=float).T @ np.asarray(self.residual(x), dtype=float)

    def move(self, x, delta):
        if self.retract is not None:
            return self.retract(x, delta)
        return np.asarray(x, dtype=float) + delta

    def has(self, *fields):
        return all(getattr(self, f) is not None for f in fields)


def forward_difference_jacobian(problem, x, step):
    """Forward-difference Jacobian through the retraction (the seed's C4, step ``step``).

    ``J[:, j] = (r(retract(x, h e_j)) - r(x)) / h``.
    """
    r0 = problem.residual(x)
    cols = []
    for j in range(problem.n):
        e = np.zeros(problem.n)
        e[j] = step
        cols.append((problem.residual(problem.move(x, e)) - r0) / step)
    return np.stack(cols, axis=1)


@dataclasses.dataclass(frozen=True)
class Options:
    """Options shared by the iterative solvers (each ignores what it does not use).

    Attributes
    ----------
    max_iter : int
        Iteration limit.
    gtol : float
        Stop when ``|grad f|_inf <= gtol * max(1, |f|)``.
    ftol : float
        Stop when an accepted step reduces f by at most ``ftol * max(1, |f|)``.
    xtol : float
        Stop when ``|delta| <= xtol * (xtol + |x|)``.
    jacobian : {'exact', 'forward'}
        Gauss-Newton only: exact Jacobian, or forward differences with ``fd_step``.
    fd_step : float
        Forward-difference step (the seed's C4 uses 5e-7).
    subproblem : {'exact', 'cg'}
        Trust-region Newton only: More-Sorensen or Steihaug-CG.
    initial_radius : float or None
        Trust-region radius at start (in scaled units); None: the length of the model's
        steepest-descent minimiser (the Cauchy step without a bound).
    scaling : bool
        Trust regions only: ellipsoidal region ``|D p| <= Delta`` (see :mod:`handeye.solvers.trust_region`).
    max_radius_factor : float
        Largest radius as a multiple of the initial one.
    eta : float
        Trust-region acceptance threshold on the ratio rho, in [0, 1/4).
    lm_tau : float
        Levenberg-Marquardt initial damping relative to ``max diag(J^T J)``.
    ipopt : dict
        Extra IPOPT options (merged into a copy of the defaults).
    """

    max_iter: int = 200
    gtol: float = 1e-10
    ftol: float = 1e-14
    xtol: float = 1e-12
    jacobian: str = "exact"
    fd_step: float = 5e-7
    subproblem: str = "exact"
    initial_radius: Optional[float] = None
    scaling: bool = True
    max_radius_factor: float = 1e3
    eta: float = 1e-4
    lm_tau: float = 1e-3
    ipopt: dict = dataclasses.field(default_factory=dict)

    @classmethod
    def from_mapping(cls, mapping):
        """Options from a dict; unknown keys raise ``UnsupportedProblem`` naming them."""
        mapping = dict(mapping or {})
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(mapping) - names)
        if unknown:
            raise UnsupportedProblem(f"unknown solver option(s) {unknown}; known: {sorted(names)}")
        return cls(**mapping)


def last_point(evaluate):
    """``evaluate(x)`` remembering its last point (one entry, compared by value): a least-squares
    solver asks for the Jacobian at the point whose residual it has just accepted, and where one
    evaluation gives both (``evaluate(x) -> (r, J)``) it is done once, not twice."""
    last = {}

    def at(x):
        key = np.asarray(x, float).tobytes()
        if last.get("key") != key:
            value = evaluate(x)
            for a in value if isinstance(value, tuple) else (value,):  # shared by the calls at this point:
                if isinstance(a, np.ndarray):  # read-only, so that no caller changes another's
                    a.setflags(write=False)
            last["key"], last["value"] = key, value
        return last["value"]

    return at
