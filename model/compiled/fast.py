"""The fast path: Levenberg-Marquardt on the calibration's normal equations, compiled.

For the ``local`` parametrisation and the ``centre`` residual, one measurement i contributes

    H_i = J_i^T J_i  (6 x 6),   g_i = J_i^T e_i  (6),   f_i = 1/2 |e_i|^2

to the Gauss-Newton normal equations. ``normal_one`` is that CasADi function, built from the
same generated source as every other evaluation (:mod:`handeye.model.chain.codegen`, one sympy derivation),
never written by hand. Two ways to run the iteration (Marquardt's scaled damping, Nocedal &
Wright 2006, section 10.3):

* compiled (default when a C compiler is present): CasADi generates C for ``normal_one``, which
  is compiled together with a small C driver (``fast_lm.c``: sum over the measurements, 6 x 6
  Cholesky, Rodrigues update, the same acceptance and stopping rules) into a shared library,
  cached in the generated-code cache and called through ctypes. A calibration is one call;
  ``calibrate_many`` runs many in one call (Monte Carlo).
* otherwise the same iteration in Python, with the sums evaluated by ``normal_one`` mapped over
  the measurements in the CasADi virtual machine (same numbers, about 50x slower).

The result is the least-squares solution of the unweighted ``centre`` residual, the same
solution as :class:`handeye.model.fit.calibration.CalibrationModel` with any solver (tests check this).
Data that leave a combination of the six unknowns unconstrained end with status -3, never
with a "converged" pose. This is the engine for Monte Carlo studies and benchmarks; a
calibration of real data wants the full pipeline of ``handeye calibrate`` (screening,
weights, uncertainty).
"""
from __future__ import annotations

import ctypes
import functools
import pathlib
from typing import NamedTuple

import numpy as np

from handeye.model.chain import codegen
from handeye.model.common.rotation import matrix_from_rotvec
from handeye.model.compiled import ccompile
from handeye.model.fit.calibration import _sources
from handeye.solvers import CONVERGED

DRIVER = pathlib.Path(__file__).with_name("fast_lm.c")
CFLAGS = ("-O3", "-fPIC", "-shared")
#: kept here too: the tests and the cache's users read it from this module
STALE_BUILD_S = ccompile.STALE_BUILD_S

#: ``status`` codes of the iteration (fast_lm.c): the keys of the solvers' table
#: (:data:`handeye.solvers.STATUS_MESSAGES`, same meaning, same ``converged``), with the
#: fast path's own thresholds.
STATUS = {
    0: "iteration limit reached",
    1: "gradient below 1e-10 max(1, cost)",
    2: "no measurable progress: decrease below rounding and the gradient no longer falls",
    3: "step below 1e-12 (relative to the translation in mm; rad)",
    -1: "non-finite cost or gradient",
    -2: "normal equations singular even with large damping (degenerate data)",
    -3: "a combination of the unknowns is not constrained by the data (scaled J^T J singular)",
}


class FastResult(NamedTuple):
    """Result of the fast path.

    Attributes
    ----------
    sensor2flange : ndarray, shape (4, 4)
        Sensor frame in the flange frame (mm).
    iterations, evaluations : int
        LM iterations and evaluations of the normal equations.
    cost : float
        1/2 sum |e_i|^2 at the result (mm^2).
    status : int
        Key of :data:`STATUS` (and of :data:`handeye.solvers.STATUS_MESSAGES`); ``converged``
        is ``status in handeye.solvers.CONVERGED``.
    """

    sensor2flange: np.ndarray
    iterations: int
    evaluations: int
    cost: float
    status: int

    @property
    def converged(self):
        return self.status in CONVERGED

    @property
    def message(self):
        return STATUS[self.status]


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
    return ca.Function("normal_one", [t2, ref, c, d], [ca.vec(h), ca.mtimes(jac.T, e), 0.5 * ca.sumsqr(e)])


@functools.lru_cache(maxsize=None)
def normal_equations(n):
    """CasADi function ``(x = (t2, R2 row-major) (12), c (3), data (15 x n)) -> [H (36), g (6), f]``."""
    import casadi as ca

    one = _per_measurement()
    x, c = ca.SX.sym("x", 12), ca.SX.sym("c", 3)
    data = ca.SX.sym("data", 15, n)
    h, g, f = one.map(n, "serial")(x[:3], x[3:], c, data)
    return ca.Function("normal_all", [x, c, data], [ca.vertcat(ca.sum2(h), ca.sum2(g), ca.sum2(f))])


@functools.lru_cache(maxsize=None)
def library():
    """The compiled driver (ctypes), or None when no C compiler is available."""
    import casadi as ca

    one = _per_measurement()
    gen = ca.CodeGenerator("normal_one.c", {"with_header": False})
    gen.add(one)
    flags = (*CFLAGS, f"-DHE_SZ_W={max(one.sz_w(), 1)}")
    dll = ccompile.cached_library("fast_lm", {"fast_lm.c": DRIVER.read_text(), "normal_one.c": gen.dump()}, flags,
                                  ("he_lm", "he_lm_batch"))
    if dll is None:
        return None
    pointer = ctypes.c_void_p  # addresses (ndarray.ctypes.data) of C-contiguous float64 arrays
    dll.he_lm.argtypes = [ctypes.c_int, pointer, pointer, pointer, pointer, ctypes.c_int, pointer]
    dll.he_lm_batch.argtypes = [ctypes.c_int, ctypes.c_int, pointer, pointer, pointer, pointer, ctypes.c_int, pointer]
    dll.he_lm.restype = dll.he_lm_batch.restype = ctypes.c_int
    return dll


def data_rows(flange2base, centre_in_sensor):
    """Data of the generated functions, one row per measurement: R1 row-major, t1, xs.

    Parameters
    ----------
    flange2base : ndarray, shape (..., n, 4, 4)
        Flange frame in the robot base frame (mm).
    centre_in_sensor : ndarray, shape (..., n, 3)
        Sphere centre measured in the sensor frame (mm).

    Returns
    -------
    ndarray, shape (..., n, 15), C-contiguous float64
    """
    f2b = np.asarray(flange2base, float)
    xs = np.asarray(centre_in_sensor, float)
    lead = f2b.shape[:-2]
    return np.ascontiguousarray(np.concatenate([f2b[..., :3, :3].reshape(*lead, 9), f2b[..., :3, 3], xs], axis=-1))


def _state(sensor2flange):
    s = np.asarray(sensor2flange, float)
    return np.ascontiguousarray(np.concatenate([s[..., :3, 3], s[..., :3, :3].reshape(*s.shape[:-2], 9)], axis=-1))


def _pose(x):
    out = np.eye(4)
    out[:3, :3] = x[3:].reshape(3, 3)
    out[:3, 3] = x[:3]
    return out


def _array(a):
    """C-contiguous float64 view (no copy when it already is one) for the compiled driver."""
    return np.ascontiguousarray(a, dtype=np.float64)


def calibrate_fast(flange2base, centre_in_sensor, sphere_centre, sensor2flange, max_iter=100, compiled=True):
    """Least-squares sensor pose from the ``centre`` residual, Levenberg-Marquardt on the local chart.

    Parameters
    ----------
    flange2base : ndarray, shape (n, 4, 4)
        Flange frames in the robot base frame (mm).
    centre_in_sensor : ndarray, shape (n, 3)
        Sphere centre measured in the sensor frame (mm).
    sphere_centre : ndarray, shape (3,)
        Sphere centre in the base frame (mm).
    sensor2flange : ndarray, shape (4, 4)
        Start: sensor frame in the flange frame (mm).
    max_iter : int
    compiled : bool
        Use the compiled driver when a C compiler is available (else the Python loop).

    Returns
    -------
    FastResult
    """
    dll = library() if compiled else None
    if dll is None:
        return _calibrate_python(data_rows(flange2base, centre_in_sensor), np.asarray(sphere_centre, float),
                                 _state(sensor2flange), max_iter)
    f2b, xs, c = _array(flange2base), _array(centre_in_sensor), _array(sphere_centre)
    pose, info = np.array(sensor2flange, float, order="C"), np.zeros(5)  # a fresh copy: written in place
    n = len(xs)
    if f2b.shape != (n, 4, 4) or xs.shape != (n, 3) or c.shape != (3,) or pose.shape != (4, 4):
        raise ValueError(f"calibrate_fast: shapes {f2b.shape}, {xs.shape}, {c.shape}, {pose.shape}; expected "
                         f"(n, 4, 4), (n, 3), (3,), (4, 4)")
    dll.he_lm(len(xs), f2b.ctypes.data, xs.ctypes.data, c.ctypes.data, pose.ctypes.data, int(max_iter),
              info.ctypes.data)
    return FastResult(pose, int(info[0]), int(info[1]), float(info[2]), int(info[3]))


def calibrate_many(flange2base, centre_in_sensor, sphere_centre, sensor2flange, max_iter=100):
    """m independent calibrations of n measurements each, in one call of the compiled driver.

    Parameters
    ----------
    flange2base : ndarray, shape (m, n, 4, 4)
    centre_in_sensor : ndarray, shape (m, n, 3)
    sphere_centre : ndarray, shape (m, 3)
    sensor2flange : ndarray, shape (m, 4, 4)
        Starts.

    Returns
    -------
    sensor2flange : ndarray, shape (m, 4, 4)
    info : ndarray, shape (m, 5)
        iterations, evaluations, cost, status, max |gradient| per calibration.
    """
    f2b, xs = _array(flange2base), _array(centre_in_sensor)
    m, n = xs.shape[:2]
    c = np.ascontiguousarray(np.broadcast_to(np.asarray(sphere_centre, float), (m, 3)))
    poses, info = np.array(np.broadcast_to(sensor2flange, (m, 4, 4)), float, order="C"), np.zeros((m, 5))
    if f2b.shape != (m, n, 4, 4) or xs.shape != (m, n, 3):
        raise ValueError(f"calibrate_many: shapes {f2b.shape}, {xs.shape}; expected (m, n, 4, 4), (m, n, 3)")
    dll = library()
    if dll is None:
        for j in range(m):
            res = _calibrate_python(data_rows(f2b[j], xs[j]), c[j], _state(poses[j]), max_iter)
            poses[j] = res.sensor2flange
            info[j] = res.iterations, res.evaluations, res.cost, res.status, np.nan
    else:
        dll.he_lm_batch(m, n, f2b.ctypes.data, xs.ctypes.data, c.ctypes.data, poses.ctypes.data, int(max_iter),
                        info.ctypes.data)
    return poses, info


def _calibrate_python(data, c, x, max_iter):
    """fast_lm.c's iteration, line for line, with the sums from the CasADi virtual machine."""
    import casadi as ca

    fun = normal_equations(len(data))
    cdm, ddm = ca.DM(c), ca.DM(data.T)

    def evaluate(state):
        out = fun.call([ca.DM(state), cdm, ddm])[0].full().ravel()
        return out[:36].reshape(6, 6), out[36:42], float(out[42])

    eps = np.finfo(float).eps
    x = np.array(x, float)
    h, g, f = evaluate(x)
    mu, k, evals, status = 1e-6, 0, 1, 0
    while True:
        gmax = np.max(np.abs(g))
        if not (np.isfinite(f) and np.isfinite(gmax)):
            status = -1
            break
        if gmax <= 1e-10 * max(1.0, f):
            status = 1
            break
        if k >= max_iter:
            break
        k += 1
        try:
            a = h + mu * np.diag(np.diag(h))
            np.linalg.cholesky(a)
            p = np.linalg.solve(a, -g)
        except np.linalg.LinAlgError:
            if mu > 1e12:
                status = -2
                break
            mu = max(mu * 4.0, 1e-12)
            continue
        if np.max(np.abs(p[:3])) <= 1e-12 * (1.0 + np.max(np.abs(x[:3]))) and np.max(np.abs(p[3:])) <= 1e-12:
            status = 3
            break
        predicted = -float(g @ p) - 0.5 * float(p @ h @ p)
        xn = np.concatenate([x[:3] + p[:3], (x[3:].reshape(3, 3) @ matrix_from_rotvec(p[3:])).ravel()])
        hn, gn, fn = evaluate(xn)
        evals += 1
        if predicted <= 100 * eps * max(1.0, f):  # the cost cannot judge the step: the gradient does
            accept = np.max(np.abs(gn)) < gmax
            if not accept:
                status = 2
                break
        else:
            accept = fn < f
        if accept:
            x, h, g, f = xn, hn, gn, fn
            mu = max(mu / 3.0, 1e-12)
        else:
            mu *= 4.0
    if status > 0 and _rank_deficient(h):
        status = -3
    return FastResult(_pose(x), k, evals, f, status)


def _rank_deficient(h):
    """fast_lm.c's test: the column-scaled J^T J minus 1e-12 I is not positive definite."""
    d = np.diag(h)
    if np.any(~(d > 0)):
        return True
    s = h / np.sqrt(np.outer(d, d)) - 1e-12 * np.eye(6)
    try:
        np.linalg.cholesky(s)
    except np.linalg.LinAlgError:
        return True
    return False
