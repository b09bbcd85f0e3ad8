"""The fast path: the calibration's normal equations in one CasADi call.

For the ``local`` parametrisation and the ``centre`` residual, one call returns, for all N
measurements at once,

    H = sum_i J_i^T J_i  (6 x 6),   g = sum_i J_i^T e_i  (6),   f = 1/2 sum_i |e_i|^2,

from the same generated source as every other evaluation (:mod:`model.codegen`). The
per-measurement function is mapped over the measurements (``casadi.Function.map``) and the
sums are taken inside the CasADi graph, so an iteration of Gauss-Newton or
Levenberg-Marquardt costs one call plus a 6 x 6 solve. ``compile=True`` additionally
generates C code for the function and compiles it with the system's C compiler (gcc), cached
next to the generated Python source.
"""
from __future__ import annotations

import functools
import hashlib
import math
import subprocess

import numpy as np

from model import codegen
from model.calibration import _sources


@functools.lru_cache(maxsize=None)
def _per_measurement():
    import casadi as ca

    resjac, _ = _sources("local", "centre")
    gen = codegen.casadi_function(resjac)
    t2 = ca.SX.sym("t2", 3)
    ref = ca.SX.sym("ref", 9)
    c = ca.SX.sym("c", 3)
    d = ca.SX.sym("d", 15)
    out = gen(*[t2[k] for k in range(3)], 0, 0, 0, *[c[k] for k in range(3)], *[ref[k] for k in range(9)],
              *[d[k] for k in range(15)])
    e = ca.vertcat(*out[:3])
    jac = ca.reshape(ca.vertcat(*out[3:]), 9, 3).T[:, :6]  # row-major (3 x 9) -> first 6 columns
    h = ca.mtimes(jac.T, jac)
    g = ca.mtimes(jac.T, e)
    return ca.Function("normal_one", [t2, ref, c, d], [ca.vec(h), g, 0.5 * ca.sumsqr(e)])


@functools.lru_cache(maxsize=None)
def normal_equations(n, compile=False):
    """CasADi function ``(x = (t2, Rref row-major) (12), c (3), data (15 x n)) -> [H (36), g (6), f]``."""
    import casadi as ca

    one = _per_measurement()
    x, c = ca.SX.sym("x", 12), ca.SX.sym("c", 3)
    data = ca.SX.sym("data", 15, n)
    h, g, f = one.map(n, "serial")(x[:3], x[3:], c, data)
    fun = ca.Function("normal_all", [x, c, data], [ca.vertcat(ca.sum2(h), ca.sum2(g), ca.sum2(f))])
    if not compile:
        return fun
    try:
        return _compiled(fun)
    except (OSError, subprocess.CalledProcessError):
        return fun  # no C compiler here: the CasADi virtual machine gives the same numbers


def _compiled(fun):
    import casadi as ca

    folder = codegen.cache_dir() / "c"
    folder.mkdir(parents=True, exist_ok=True)
    key = hashlib.sha256(fun.serialize().encode()).hexdigest()[:16]
    lib = folder / f"{fun.name()}_{key}.so"
    if not lib.is_file():
        src = f"{fun.name()}_{key}.c"
        gen = ca.CodeGenerator(src, {"with_header": False})
        gen.add(fun)
        gen.generate(str(folder) + "/")
        subprocess.run(["gcc", "-O3", "-fPIC", "-shared", str(folder / src), "-o", str(lib)], check=True,
                       capture_output=True)
    return ca.external(fun.name(), str(lib))


def data_matrix(flange2base, centre_in_sensor):
    """The 15 x N data of the generated functions: R1 row-major, t1, xs per column."""
    f2b = np.asarray(flange2base, float)
    return np.concatenate([f2b[:, :3, :3].reshape(-1, 9), f2b[:, :3, 3], np.asarray(centre_in_sensor, float)], axis=1).T


def calibrate_fast(flange2base, centre_in_sensor, sphere_centre, sensor2flange, max_iter=100, compile=False):
    """Levenberg-Marquardt on the normal equations, local rotation chart.

    Returns
    -------
    sensor2flange : ndarray (4, 4)
    iterations : int
    cost : float
    converged : bool
    """
    import casadi as ca

    n = len(centre_in_sensor)
    fun = normal_equations(n, compile)
    data = ca.DM(data_matrix(flange2base, centre_in_sensor))  # converted once, not per call
    c = ca.DM(np.asarray(sphere_centre, float))
    t2 = np.array(sensor2flange[:3, 3], float)
    rot = np.array(sensor2flange[:3, :3], float)

    def evaluate(t, r):
        out = fun.call([ca.DM(np.concatenate([t, r.ravel()])), c, data])[0].full().ravel()
        return out[:36].reshape(6, 6), out[36:42], float(out[42])

    h, g, f = evaluate(t2, rot)
    mu = 1e-9 * float(np.max(np.diag(h)))  # nearly Gauss-Newton; raised only when a step fails
    for k in range(max_iter):
        if np.max(np.abs(g)) <= 1e-10 * max(1.0, f):
            return _pose(t2, rot), k, f, True
        step = np.linalg.solve(h + mu * np.diag(np.diag(h)), -g)
        predicted = -float(g @ step) - 0.5 * float(step @ h @ step)
        if predicted <= 100 * np.finfo(float).eps * max(1.0, f):
            return _pose(t2, rot), k, f, True  # nothing left to gain above rounding
        t_new = t2 + step[:3]
        r_new = rot @ _rodrigues(step[3], step[4], step[5])
        h_new, g_new, f_new = evaluate(t_new, r_new)
        if f_new < f:
            done = f - f_new <= 1e-14 * max(1.0, f)
            t2, rot, h, g, f = t_new, r_new, h_new, g_new, f_new
            mu = max(mu / 3.0, 1e-12)
            if done:
                return _pose(t2, rot), k + 1, f, True
        else:
            mu *= 4.0
    return _pose(t2, rot), max_iter, f, False


def _rodrigues(wx, wy, wz):
    """exp([w]x) for one small rotation vector, in plain floats (faster than the batched form)."""
    theta = math.sqrt(wx * wx + wy * wy + wz * wz)
    if theta < 1e-8:
        a, b = 1.0 - theta * theta / 6.0, 0.5 - theta * theta / 24.0
    else:
        a, b = math.sin(theta) / theta, (1.0 - math.cos(theta)) / (theta * theta)
    k = np.array([[0.0, -wz, wy], [wz, 0.0, -wx], [-wy, wx, 0.0]])
    return np.eye(3) + a * k + b * (k @ k)


def _pose(t2, rot):
    out = np.eye(4)
    out[:3, :3] = rot
    out[:3, 3] = t2
    return out
