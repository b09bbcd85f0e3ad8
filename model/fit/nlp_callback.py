"""The IPOPT problem of a large calibration model: cost, gradient and Hessian as CasADi callbacks.

A CasADi graph of the residual, expanded (SX) or ``map``-ped (MX), makes IPOPT differentiate
every row twice by AD: for the ``points`` model of a real scan (15 profiles, 33,000 points)
building the solver alone took 25 s and every exact Hessian about a second. Here the NLP's
objective is instead one :class:`casadi.Callback` whose value, gradient and Hessian are the
model's own numpy evaluations (:meth:`CalibrationModel.cost`, :meth:`~CalibrationModel.gradient`,
:meth:`~CalibrationModel.cost_hessian`): the same generated code from the one symbolic source
(:mod:`handeye.model.chain.symbolic`), vectorised over the rows, so the solver is built in
milliseconds and an iteration costs a few numpy passes over the data.

CasADi asks a callback for its derivatives as functions: the cost's Jacobian (the gradient, a
row) is a second callback, whose Jacobian (the Hessian) is a third. The last point's
evaluations are kept, as IPOPT asks for gradient and Hessian at the same point.

Only the objective is a callback: the constraints of the ``matrix`` parametrisation (six
entries of ``R^T R - I``) stay symbolic, so IPOPT's Lagrangian Hessian adds theirs by AD.
"""
from __future__ import annotations

import numpy as np

#: Points closer than this (relative to the largest coordinate, mm) share one Hessian. Near its
#: end IPOPT (tol 1e-12) keeps taking steps of ~1e-13 mm that no longer change the cost, until
#: its search direction is "too small": half of a scan's iterations. Over such a step the
#: Hessian of 33,000 rows changes by ~1e-15 of itself (step / sphere radius), below the
#: rounding of its own sum; the gradient, which decides convergence, is always evaluated.
SAME_POINT = 1e-15


class _Cache:
    """The model's evaluations at the last points asked for: IPOPT evaluates the cost at each
    trial point, then gradient and Hessian at the accepted one, which share the residuals
    and Jacobian."""

    def __init__(self, model):
        self.model = model
        self.last = {}  # what -> (x, value)

    def _at(self, what, x, compute):
        if what not in self.last or not np.array_equal(self.last[what][0], x):
            self.last[what] = (x.copy(), compute())
        return self.last[what][1]

    def get(self, order, x):
        """Cost, gradient or Hessian (``order`` 0, 1, 2) at the point ``x``."""
        x = np.asarray(x, dtype=float).ravel()
        model = self.model
        if order == 0:
            return np.asarray(self._at("cost", x, lambda: model.cost(x)), dtype=float)
        e, jac = self._at("rows", x, lambda: model.residual_and_jacobian(x))
        if order == 1:
            return self._at("gradient", x, lambda: model.gradient_from(e, jac))
        last = self.last.get("hessian")
        if last is not None and np.max(np.abs(x - last[0])) <= SAME_POINT * max(1.0, np.max(np.abs(x))):
            return last[1]  # the same point to rounding: the Hessian would differ in its rounding only
        return self._at("hessian", x, lambda: model.cost_hessian_from(x, e, jac))


def _callback_class():
    import casadi as ca

    class Derivative(ca.Callback):
        """Derivative ``order`` (0 cost, 1 gradient row, 2 Hessian) of the model's cost at x.

        Inputs follow CasADi's Jacobian convention: x, then the nominal outputs of every lower
        order (unused); outputs: this order's value and, for the Hessian, the (empty) block with
        respect to the nominal cost.
        """

        def __init__(self, cache, order, name):
            ca.Callback.__init__(self)
            self.cache, self.order, self.n = cache, order, cache.model.n
            self.child = None  # the next order, kept alive while this one lives
            self.construct(name, {"enable_fd": False})

        def _shapes(self):
            """Shapes of the inputs and outputs of this order (CasADi's Jacobian convention)."""
            n = self.n
            ins = [(n, 1), (1, 1), (1, n)][: self.order + 1]
            return ins, [[(1, 1)], [(1, n)], [(n, n), (n, 1)]][self.order]

        def get_n_in(self):
            return len(self._shapes()[0])

        def get_n_out(self):
            return len(self._shapes()[1])

        def get_sparsity_in(self, i):
            return ca.Sparsity.dense(*self._shapes()[0][i])

        def get_sparsity_out(self, i):
            shape = self._shapes()[1][i]
            return ca.Sparsity.dense(*shape) if i == 0 else ca.Sparsity(*shape)  # nominal inputs: no effect

        def eval(self, arg):
            value = self.cache.get(self.order, np.array(arg[0]))
            out = [ca.DM(value.reshape(self._shapes()[1][0]))]
            return out + [ca.DM(self.get_sparsity_out(i)) for i in range(1, self.get_n_out())]

        def has_jacobian(self):
            return self.order < 2

        def get_jacobian(self, name, inames, onames, opts):
            self.child = Derivative(self.cache, self.order + 1, name)
            return self.child

    return Derivative


def cost_callback(model):
    """The model's cost ``f(x)`` as a CasADi function with exact first and second derivatives.

    Parameters
    ----------
    model : handeye.model.fit.calibration.CalibrationModel
        ``euler`` or ``matrix`` rotation (the step is the point: derivatives with respect to x).

    Returns
    -------
    casadi.Callback
        Keep it referenced while any function built from it is in use (CasADi does not).
    """
    if model.rotation == "local":
        raise ValueError("the NLP callback needs the 'euler' or 'matrix' point; 'local' needs a retraction")
    return _callback_class()(_Cache(model), 0, "handeye_cost")
