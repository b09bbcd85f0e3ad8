"""Glue: the model's functions as :class:`handeye.solvers.Problem` objects."""
from __future__ import annotations

import numpy as np

from handeye.model.chain import testfunction
from handeye.solvers import Problem


def calibration_problem(model):
    """A :class:`handeye.solvers.Problem` of a :class:`handeye.model.fit.calibration.CalibrationModel`.

    Least-squares callables and the exact Hessian for every parametrisation; the CasADi NLP
    for ``euler`` and ``matrix``; the retraction for ``local``. The callables take stacks of
    points (``vectorised``), so :func:`handeye.solvers.solve_many` runs many starts of one
    calibration at once.
    """
    nlp = model.nlp() if model.rotation in ("euler", "matrix") else None
    smooth = model.rotation != "matrix"  # the matrix entries need the constraints (IPOPT)
    return Problem(n=model.n, residual=model.residual if smooth else None, jacobian=model.jacobian if smooth else None,
                   hessian=model.cost_hessian if smooth else None, retract=model.retract if model.rotation == "local" else None,
                   nlp=nlp, vectorised=True, normal=model.normal_equations if smooth and chunked(model) else None)


def chunked(model):
    """Whether least squares on ``model`` sums its normal equations chunk by chunk
    (:meth:`~handeye.model.fit.calibration.CalibrationModel.normal_equations`) rather than holding
    its Jacobian: more rows than one chunk."""
    from handeye.model.fit.calibration import ROW_CHUNK

    return model.n_meas > ROW_CHUNK


def testfunction_nlp():
    """The test function (6-16) as a CasADi NLP dict, generated from the same source."""
    import casadi as ca

    from handeye.model.chain import codegen, symbolic

    def build():
        s = symbolic.test_function()
        return s["x"], [s["f"]]

    gen = codegen.casadi_function(codegen.generated_source("testfunction_f", build))
    x = ca.SX.sym("x", 2)
    return {"x": x, "f": gen(x[0], x[1])[0], "g": ca.SX(0, 1), "lbg": np.zeros(0), "ubg": np.zeros(0)}


def testfunction_problem():
    """The test function with every form: f, gradient, Hessian (Newton, trust region),
    the residual with ``1/2 |r|^2 = (f + 300) / 2`` (Gauss-Newton, LM, dogleg) and the NLP.

    The callables take stacks of points (``vectorised``), so :func:`handeye.solvers.solve_many`
    evaluates all running starts at once. Note that ``objective`` is f itself, so costs reported by Newton-type and least-squares
    methods differ by the constant and the factor: compare points, not costs.
    """
    return Problem(n=2, objective=testfunction.value, gradient=testfunction.gradient, hessian=testfunction.hessian,
                   residual=testfunction.residual, jacobian=testfunction.residual_jacobian, nlp=testfunction_nlp(),
                   vectorised=True)


#: The solver-comparison studies' options: steepest descent needs more iterations
TESTFUNCTION_OPTIONS = {"sd": {"max_iter": 2000}}


def testfunction_options(method):
    """The solver options the test-function studies and bench use for ``method`` (a fresh dict)."""
    return dict(TESTFUNCTION_OPTIONS.get(method, {"max_iter": 200}))


def testfunction_starts(n, seed):
    """``n`` seeded random starts, half uniform over [-50, 50]^2 and half over [-4, 4]^2.

    The two windows of the basin study (``handeye study testfunction``).

    Returns
    -------
    ndarray, shape (n, 2)
    """
    rng = np.random.default_rng(seed)
    wide = rng.uniform(-50.0, 50.0, size=(n - n // 2, 2))
    zoom = rng.uniform(-4.0, 4.0, size=(n // 2, 2))
    return np.concatenate([wide, zoom])
