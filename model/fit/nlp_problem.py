"""The IPOPT problem of a calibration model as a CasADi dict (``x``, ``f``, ``g``, ``p``), the
form ``nlpsol`` takes: one SX graph of every row up to
:data:`handeye.model.fit.calibration.NLP_CALLBACK_ABOVE` rows, a callback to the model's own numpy
cost, gradient and Hessian above (:mod:`handeye.model.fit.nlp_callback`); the orthogonality
constraints of the ``matrix`` parametrisation as ``g``."""
from __future__ import annotations

import numpy as np

from handeye.model.chain import codegen


def nlp(model, resjac, n_rot, callback_above):
    """The IPOPT problem of ``model`` (:meth:`handeye.model.fit.calibration.CalibrationModel.nlp`).

    Parameters
    ----------
    model : handeye.model.fit.calibration.CalibrationModel
    resjac : str
        Generated source of the one-row residual and Jacobian (the model's rotation and kind).
    n_rot : int
        Rotation parameters of the model's parametrisation (3 Euler angles, 9 matrix entries).
    callback_above : int
        Above this many rows the cost is a callback, not a graph.
    """
    import casadi as ca

    if model.rotation == "local":
        raise ValueError("IPOPT works on 'euler' or 'matrix'; 'local' needs a retraction")
    if model.n_meas > callback_above:
        from handeye.model.fit import nlp_callback

        cb = nlp_callback.cost_callback(model)
        x = ca.MX.sym("x", model.n)
        out = {"x": x, "f": cb(x), "callback": cb}
    else:
        out = _graph(model, resjac, n_rot)
    x = out["x"]
    if model.rotation == "matrix":
        rt = ca.reshape(x[3:12], 3, 3).T  # row-major entries -> matrix
        m = ca.mtimes(rt.T, rt) - type(x).eye(3)
        g = ca.vertcat(*[m[i, j] for i in range(3) for j in range(i, 3)])
    else:
        g = type(x)(0, 1)
    ng = g.shape[0]
    return {**out, "g": g, "lbg": np.zeros(ng), "ubg": np.zeros(ng)}


def _graph(model, resjac, n_rot):
    """``x``, ``f``, ``p`` and ``p_value`` of :func:`nlp` as one SX graph of every row."""
    import casadi as ca

    gen = codegen.casadi_function(resjac)
    nr = n_rot
    m = model.m
    n_data = len(model._data)
    x = ca.SX.sym("x", model.n)
    d = ca.SX.sym("d", n_data + m * m)
    theta = ca.SX.sym("theta", 3 + nr + 3)
    extra = [model.radius] if model.kind != "centre" else []
    e = ca.vertcat(*gen(*[theta[k] for k in range(theta.shape[0])], *extra, *[d[k] for k in range(n_data)])[:m])
    w = ca.reshape(d[n_data:], m, m).T  # row-major entries -> matrix
    one = ca.Function("e", [theta, d], [ca.mtimes(w, e)])
    whiten = model.whiten if model.whiten is not None else np.broadcast_to(np.eye(m), (model.n_meas, m, m))
    table = np.concatenate([np.stack(model._data), whiten.reshape(model.n_meas, m * m).T])
    data = ca.SX.sym("data", table.shape[0], model.n_meas)
    p_value = table.ravel(order="F")  # ca.vec is column-major
    if model.unknowns == "sensor+sphere":
        p, full = ca.vec(data), x
    else:
        cfix = ca.SX.sym("c", 3)
        p, full = ca.vertcat(ca.vec(data), cfix), ca.vertcat(x, cfix)
        p_value = np.concatenate([p_value, model.fixed_centre])
    return {"x": x, "f": 0.5 * ca.sumsqr(one.map(model.n_meas)(full, data)), "p": p, "p_value": p_value}
