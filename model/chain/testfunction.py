"""The seed's test function (6-16): values, derivatives, least-squares form, stationary points.

Everything is generated from :func:`handeye.model.chain.symbolic.test_function`. ``f + 300 = |r(x)|^2``
exactly, so Gauss-Newton and Levenberg-Marquardt can be run on ``1/2 |r|^2 = (f + 300) / 2``,
which has the same minimisers and saddle as f.

All stationary points lie on the line through ``a = (1, 1)`` and ``b = (-1, -2)``:
``grad f = 200 (x-a)/q1^2 + 400 (x-b)/q2^2 = 0`` forces ``x - a`` and ``x - b`` to be
parallel. With ``x = a + s (b - a)`` the condition becomes the quintic
``200 s q2(s)^2 + 400 (s - 1) q1(s)^2 = 0``, whose real roots are *all* the stationary points.
"""
from __future__ import annotations

import dataclasses
import functools

import numpy as np

from handeye.model.chain import codegen

A_POINT = np.array([1.0, 1.0])
B_POINT = np.array([-1.0, -2.0])


#: the generated functions, one per output group, so that a cost evaluation (a line search's
#: trial point) does not pay for the Hessian: name -> (symbolic key, shape of one output)
_PARTS = {"f": ("f", ()), "grad": ("grad", (2,)), "hess": ("hess", (2, 2)), "r": ("r", (4,)), "rjac": ("rjac", (4, 2))}


@functools.lru_cache(maxsize=None)
def _source(part):
    def build():
        from handeye.model.chain import symbolic  # sympy only on a cache miss

        s = symbolic.test_function()
        out = s[_PARTS[part][0]]
        return s["x"], [out] if part == "f" else list(out)

    return codegen.generated_source(f"testfunction_{part}", build)


@functools.lru_cache(maxsize=None)
def _functions(part):
    return codegen.numpy_function(_source(part)), codegen.math_function(_source(part))


def casadi_function(part):
    """The generated function ``part`` (a key of ``_PARTS``: f, grad, hess, r, rjac) as a CasADi
    ``Function`` of the point ``x`` (2,), its output flat (matrices row-major); for C generation."""
    import casadi as ca

    x = ca.SX.sym("x", 2)
    out = codegen.casadi_function(_source(part))(x[0], x[1])
    return ca.Function(f"testfunction_{part}", [x], [ca.vertcat(*out)])


def _eval(part, x):
    x = np.asarray(x, dtype=float)
    vectorised, scalar = _functions(part)
    shape = _PARTS[part][1]
    if x.shape == (2,):  # one point: plain floats are faster than arrays
        return np.array(scalar(float(x[0]), float(x[1]))).reshape(shape)
    return codegen.stack_outputs(vectorised(x[..., 0], x[..., 1]), x.shape[:-1]).reshape(x.shape[:-1] + shape)


def value(x):
    """f(x), shape (..., 2) -> (...)."""
    return _eval("f", x)


def gradient(x):
    """grad f(x), shape (..., 2) -> (..., 2)."""
    return _eval("grad", x)


def hessian(x):
    """Hessian of f, shape (..., 2) -> (..., 2, 2)."""
    return _eval("hess", x)


def residual(x):
    """Least-squares residual r(x), shape (..., 2) -> (..., 4); ``|r|^2 = f + 300``."""
    return _eval("r", x)


def residual_jacobian(x):
    """dr/dx, shape (..., 2) -> (..., 4, 2)."""
    return _eval("rjac", x)


@dataclasses.dataclass(frozen=True)
class StationaryPoint:
    """A stationary point of f with its classification.

    Attributes
    ----------
    x : ndarray, shape (2,)
    value : float
    eigenvalues : ndarray, shape (2,)
        Of the Hessian, ascending.
    kind : str
        ``'minimum'`` (both > 0), ``'maximum'`` (both < 0) or ``'saddle'``.
    """

    x: np.ndarray
    value: float
    eigenvalues: np.ndarray
    kind: str


def classify(eigenvalues):
    """'minimum', 'maximum' or 'saddle' from Hessian eigenvalues (second-order conditions)."""
    lo, hi = np.min(eigenvalues), np.max(eigenvalues)
    if lo > 0:
        return "minimum"
    if hi < 0:
        return "maximum"
    if lo < 0 < hi:
        return "saddle"
    return "degenerate"


@functools.lru_cache(maxsize=None)
def stationary_points(digits=30):
    """All stationary points, found as the real roots of the quintic (module docstring).

    Roots are computed with sympy to ``digits`` significant digits, then rounded to float.

    Returns
    -------
    tuple of StationaryPoint
        Sorted by function value (global minimum first).
    """
    import sympy as sp

    s = sp.symbols("s", real=True)
    d = sp.Matrix(B_POINT - A_POINT).applyfunc(sp.nsimplify)
    dd = (d.T * d)[0]
    q1 = s**2 * dd + 1
    q2 = (s - 1) ** 2 * dd + 1
    poly = sp.Poly(sp.expand(200 * s * q2**2 + 400 * (s - 1) * q1**2), s)
    points = []
    for root in poly.nroots(n=digits):
        if abs(sp.im(root)) > 10 ** (-digits // 2):
            continue
        x = A_POINT + float(sp.re(root)) * (B_POINT - A_POINT)
        w = np.linalg.eigvalsh(hessian(x))
        points.append(StationaryPoint(x=x, value=float(value(x)), eigenvalues=w, kind=classify(w)))
    return tuple(sorted(points, key=lambda p: p.value))


#: where a start can end: the stationary points in :func:`stationary_points`'s order, then none
END_KINDS = ("global", "local", "saddle", "none")


def end_kind(x, converged, tol=1e-4):
    """Where each end lies: index into :data:`END_KINDS` (the basin maps' colours).

    Parameters
    ----------
    x : ndarray, shape (N, 2)
        End points.
    converged : ndarray of bool, shape (N,)
        Whether the solver reported convergence; an end that did not converge is "none".
    tol : float
        Distance to a stationary point that counts as reaching it.

    Returns
    -------
    ndarray of int, shape (N,)
    """
    x = np.asarray(x, dtype=float)
    kind = np.full(len(x), len(END_KINDS) - 1)
    for k, point in enumerate(stationary_points()[:3]):
        kind[(np.linalg.norm(x - point.x, axis=1) < tol) & np.asarray(converged, dtype=bool)] = k
    return kind
