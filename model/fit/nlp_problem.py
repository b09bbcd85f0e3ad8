"""The IPOPT problem of a calibration model as a CasADi dict (``x``, ``f``, ``g``, ``p``), the
form ``nlpsol`` takes: for the centre model in ``matrix`` (linear in the point) its cost as one quadratic form
of the point, whatever the rows (:func:`_quadratic`); else one SX graph of every row up to
:data:`handeye.model.fit.calibration.NLP_CALLBACK_ABOVE` rows, a callback to the model's own numpy
cost, gradient and Hessian above (:mod:`handeye.model.fit.nlp_callback`); the orthogonality
constraints of the ``matrix`` parametrisation as ``g``.

The graph depends on the data only through ``p``: it is built once per problem structure (the
rows' residual, its parametrisation and kind, the number of rows, what is free, the sphere radius of
a profile model) and kept (:func:`_template`); its dict's ``'structure'`` names that structure, so
that :mod:`handeye.solvers.ipopt` builds ``nlpsol`` once per structure too and solves every
calibration of that shape with its own ``p_value``.
"""
from __future__ import annotations

import functools

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
        Above this many rows the cost is a callback, not a graph (not for the centre model in ``matrix``,
        whose cost is a quadratic form at any size: :func:`_quadratic`).
    """
    import casadi as ca

    if model.rotation == "local":
        raise ValueError("IPOPT works on 'euler' or 'matrix'; 'local' needs a retraction")
    if model.kind == "centre" and model.rotation == "matrix":
        out = _quadratic(model)
    elif model.n_meas > callback_above:
        from handeye.model.fit import nlp_callback

        cb = nlp_callback.cost_callback(model)
        x = ca.MX.sym("x", model.n)
        out = {"x": x, "f": cb(x), "callback": cb, "g": _constraints(x, model.rotation)}
    else:
        out = _graph(model, resjac, n_rot)
    ng = out["g"].shape[0]
    return {**out, "lbg": np.zeros(ng), "ubg": np.zeros(ng)}


def _constraints(x, rotation):
    """``g``: the six independent entries of ``R^T R - I`` of the ``matrix`` parametrisation (none for Euler)."""
    import casadi as ca

    if rotation != "matrix":
        return type(x)(0, 1)
    rt = ca.reshape(x[3:12], 3, 3).T  # row-major entries -> matrix
    m = ca.mtimes(rt.T, rt) - type(x).eye(3)
    return ca.vertcat(*[m[i, j] for i in range(3) for j in range(i, 3)])


def _graph(model, resjac, n_rot):
    """``x``, ``f``, ``p``, ``p_value`` and ``structure`` of :func:`nlp`: one SX graph of every row (the
    structure's, kept), the model's data as the parameter values."""
    m = model.m
    radius = float(model.radius) if model.kind != "centre" else None
    structure = ("calibration-graph", resjac, n_rot, m, len(model._data), model.n, model.n_meas,
                 model.unknowns == "sensor+sphere", radius)
    whiten = model.whiten if model.whiten is not None else np.broadcast_to(np.eye(m), (model.n_meas, m, m))
    table = np.concatenate([np.stack(model._data), whiten.reshape(model.n_meas, m * m).T])
    p_value = table.ravel(order="F")  # ca.vec is column-major
    if model.unknowns != "sensor+sphere":
        p_value = np.concatenate([p_value, model.fixed_centre])
    return {**_template(structure), "p_value": p_value, "structure": structure}


def _quadratic(model):
    """``x``, ``f``, ``g``, ``p``, ``p_value`` and ``structure`` of :func:`nlp` for the centre model in ``matrix``:
    its residual is linear in the point (the sensor's translation and rotation entries, the sphere centre), so
    the cost is ``1/2 |R d|^2 + (J^T r)^T d + 1/2 r^T r`` in ``d = x - x_r``, with ``J = Q R`` and ``r`` the
    (whitened) Jacobian and residuals at a reference point ``x_r`` (R by QR chunk by chunk,
    :meth:`~handeye.model.fit.calibration.CalibrationModel.jacobian_r`): the same function of ``x`` as the rows'
    sum, with a graph of 12 (15) variables whatever the rows (IPOPT's fit of 300 rows took 27 ms through the
    callback, 3,000 rows 35 ms). ``|R d|^2``, not ``d^T J^T J d``: never negative where ``J`` is rank-deficient
    (``J^T J`` rounded to eigenvalues of -1e-11 and IPOPT's iterates diverged on 3-8 poses with the centre free).
    ``x_r`` is the unconstrained minimum (the rotation entries free): about it the form's terms are as small as
    the cost itself, so its rounding is the cost's (about ``x = 0`` the terms are ``|J|^2 |x|^2``, 10^7 times a
    3,000-row cost, and IPOPT's line search stalled in that noise)."""
    n = model.n
    jtj, jtr, _ = model.normal_equations(np.zeros(n))
    ref = -np.linalg.lstsq(jtj, jtr, rcond=None)[0]
    _, jtr, rtr = model.normal_equations(ref)
    factor = np.zeros((n, n))
    r = model.jacobian_r(ref)
    factor[: len(r)] = r  # fewer rows than unknowns: the rest zero
    structure = ("calibration-quadratic", n)
    return {**_quadratic_template(structure), "p_value": np.concatenate([factor.ravel(), ref, jtr, [rtr]]),
            "structure": structure}


@functools.lru_cache(maxsize=4)
def _quadratic_template(structure):
    """``x``, ``f``, ``g`` and ``p`` of :func:`_quadratic`'s graph, built once per number of unknowns."""
    import casadi as ca

    n = structure[1]
    x, p = ca.SX.sym("x", n), ca.SX.sym("p", n * n + 2 * n + 1)
    factor = ca.reshape(p[: n * n], n, n).T  # R, row-major entries
    d = x - p[n * n : n * n + n]
    f = 0.5 * ca.sumsqr(ca.mtimes(factor, d)) + ca.dot(p[n * n + n : n * n + 2 * n], d) + 0.5 * p[n * n + 2 * n]
    return {"x": x, "f": f, "p": p, "g": _constraints(x, "matrix")}


@functools.lru_cache(maxsize=8)
def _template(structure):
    """``x``, ``f``, ``g`` and ``p`` of the graph of a ``structure`` (:func:`_graph`), built once."""
    import casadi as ca

    _, resjac, n_rot, m, n_data, n_x, n_meas, centre_free, radius = structure
    gen = codegen.casadi_function(resjac)
    x = ca.SX.sym("x", n_x)
    d = ca.SX.sym("d", n_data + m * m)
    theta = ca.SX.sym("theta", 3 + n_rot + 3)
    extra = [radius] if radius is not None else []
    e = ca.vertcat(*gen(*[theta[k] for k in range(theta.shape[0])], *extra, *[d[k] for k in range(n_data)])[:m])
    w = ca.reshape(d[n_data:], m, m).T  # row-major entries -> matrix
    one = ca.Function("e", [theta, d], [ca.mtimes(w, e)])
    data = ca.SX.sym("data", n_data + m * m, n_meas)
    if centre_free:
        p, full = ca.vec(data), x
    else:
        cfix = ca.SX.sym("c", 3)
        p, full = ca.vertcat(ca.vec(data), cfix), ca.vertcat(x, cfix)
    return {"x": x, "f": 0.5 * ca.sumsqr(one.map(n_meas)(full, data)), "p": p,
            "g": _constraints(x, "matrix" if n_rot == 9 else "euler")}
