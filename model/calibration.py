"""The hand-eye calibration residual (seed 4-3) as a least-squares problem.

For measurement ``i`` (flange pose ``flange2base_i = (R1_i, t1_i)``, sphere centre
``centre_in_sensor_i = xs_i``)::

    e_i(theta) = R1_i (R2 xs_i + t2) + t1_i - c

``sensor2flange = (R2, t2)`` is unknown; so, with ``unknowns='sensor+sphere'``, is the sphere
centre ``c`` in the robot base. The cost is ``1/2 sum |e_i|^2`` (mm^2).

Residual, Jacobian and the second derivatives needed for Newton's exact Hessian
``H = J^T J + sum_k e_k grad^2 e_k`` are generated from :func:`model.symbolic.calibration_residual`.

Points and steps
----------------
The solver's point ``x`` and its step ``delta`` may live in different spaces:

=========  ===========================  ==========================  ============================
rotation   point x                      step delta                  retraction
=========  ===========================  ==========================  ============================
euler      t2 (mm), A, B, C (deg)       same (6)                    x + delta
matrix     t2, R2 row-major (12)        same (12); RᵀR = I is a     x + delta (IPOPT only)
                                        constraint
local      t2, R2 row-major (12)        dt (mm), dr (rad) (6)       t2 + dt, R2 exp([dr]x)
=========  ===========================  ==========================  ============================

With ``sensor+sphere`` the three coordinates of ``c`` (mm) follow in point and step.
"""
from __future__ import annotations

import functools

import numpy as np

from model import codegen, rotation
from model.pose import kuka_from_matrix, matrix_from_kuka, transform_from_pose

UNKNOWNS = ("sensor", "sensor+sphere")
ROTATIONS = ("euler", "matrix", "local")  # as model.symbolic.ROTATIONS (tested)


@functools.lru_cache(maxsize=None)
def _sources(rot):
    def build_resjac():
        from model import symbolic  # sympy only on a cache miss

        s = symbolic.calibration_residual(rot)
        return s["theta"] + s["extra"] + s["data"], list(s["e"]) + list(s["jac"])

    def build_hess():
        from model import symbolic

        s = symbolic.calibration_residual(rot)
        return s["theta"] + s["extra"] + s["data"], [v for h in s["hess"] for v in h]

    return (
        codegen.generated_source(f"calib_resjac_{rot}", build_resjac),
        codegen.generated_source(f"calib_hess_{rot}", build_hess),
    )


@functools.lru_cache(maxsize=None)
def _numpy_functions(rot):
    resjac, hess = _sources(rot)
    return codegen.numpy_function(resjac), codegen.numpy_function(hess)


_N_ROT = {"euler": 3, "matrix": 9, "local": 3}
_N_POINT_ROT = {"euler": 3, "matrix": 9, "local": 9}


def parameter_names(rotation_name, unknowns):
    """Names of the step coordinates, e.g. ``['tx', 'ty', 'tz', 'A', 'B', 'C']``."""
    rot = {
        "euler": ["A", "B", "C"],
        "matrix": [f"r{i}{j}" for i in range(1, 4) for j in range(1, 4)],
        "local": ["wx", "wy", "wz"],
    }[rotation_name]
    names = ["tx", "ty", "tz"] + rot
    if unknowns == "sensor+sphere":
        names += ["cx", "cy", "cz"]
    return names


class CalibrationModel:
    """Residual, derivatives and retraction of one dataset's calibration problem.

    Parameters
    ----------
    flange2base : array_like, shape (N, 4, 4)
        Flange poses in the robot base (homogeneous, mm).
    centre_in_sensor : array_like, shape (N, 3)
        Sphere centre measured in the sensor frame, mm.
    sphere_centre : array_like, shape (3,)
        Sphere centre in the robot base, mm: the known value (``unknowns='sensor'``) or the
        start value (``'sensor+sphere'``).
    rotation : {'euler', 'matrix', 'local'}
    unknowns : {'sensor', 'sensor+sphere'}
    """

    def __init__(self, flange2base, centre_in_sensor, sphere_centre, rotation="euler", unknowns="sensor"):
        if rotation not in ROTATIONS:
            raise ValueError(f"rotation must be one of {ROTATIONS}, got {rotation!r}")
        if unknowns not in UNKNOWNS:
            raise ValueError(f"unknowns must be one of {UNKNOWNS}, got {unknowns!r}")
        f2b = np.asarray(flange2base, dtype=float)
        xs = np.asarray(centre_in_sensor, dtype=float)
        self.rotation = rotation
        self.unknowns = unknowns
        self.n_meas = len(xs)
        self.fixed_centre = np.asarray(sphere_centre, dtype=float).reshape(3)
        # per-measurement data in the generated functions' argument order: R1 (9), t1, xs
        self._data = tuple(np.concatenate([f2b[:, :3, :3].reshape(-1, 9), f2b[:, :3, 3], xs], axis=1).T)
        self.flange2base = f2b
        self.centre_in_sensor = xs
        n_rot = _N_ROT[rotation]
        self._cols = slice(0, 3 + n_rot + (3 if unknowns == "sensor+sphere" else 0))
        self.n = self._cols.stop
        self.names = parameter_names(rotation, unknowns)

    # -- points ----------------------------------------------------------------------------
    def point_from(self, sensor2flange, sphere_centre=None):
        """Solver point of a sensor pose (4x4) and, for ``sensor+sphere``, a sphere centre."""
        t = np.asarray(sensor2flange, dtype=float)
        rot = kuka_from_matrix(t[:3, :3]) if self.rotation == "euler" else t[:3, :3].ravel()
        parts = [t[:3, 3], rot]
        if self.unknowns == "sensor+sphere":
            parts.append(self.fixed_centre if sphere_centre is None else np.asarray(sphere_centre, float))
        return np.concatenate(parts)

    def point_from_pose(self, pose, sphere_centre=None):
        """Solver point of a KUKA pose (mm, deg); ``euler`` keeps the angles exactly as given
        (B = -90.1 stays -90.1 rather than becoming its equivalent with B = -89.9)."""
        pose = np.asarray(pose, dtype=float)
        x = self.point_from(transform_from_pose(pose), sphere_centre)
        if self.rotation == "euler":
            x[3:6] = pose[3:6]
        return x

    def _split(self, x):
        x = np.asarray(x, dtype=float)
        nr = _N_POINT_ROT[self.rotation]
        t2, q = x[:3], x[3 : 3 + nr]
        c = x[3 + nr : 6 + nr] if self.unknowns == "sensor+sphere" else self.fixed_centre
        return t2, q, c

    def sensor_rotation(self, x):
        """R2 of a point (3x3; for ``matrix`` the raw, possibly non-orthogonal entries)."""
        _, q, _ = self._split(x)
        return matrix_from_kuka(q) if self.rotation == "euler" else q.reshape(3, 3)

    def sensor2flange(self, x):
        """4x4 sensor pose on the flange of a point."""
        t2, _, _ = self._split(x)
        out = np.eye(4)
        out[:3, :3] = self.sensor_rotation(x)
        out[:3, 3] = t2
        return out

    def sphere_centre(self, x):
        """Sphere centre in the robot base (mm) of a point."""
        return self._split(x)[2].copy()

    def retract(self, x, delta):
        """Move from point ``x`` by step ``delta`` (table in the module docstring)."""
        if self.rotation != "local":
            return np.asarray(x, dtype=float) + delta
        t2, q, c = self._split(x)
        rot = q.reshape(3, 3) @ rotation.matrix_from_rotvec(delta[3:6])
        parts = [t2 + delta[:3], rot.ravel()]
        if self.unknowns == "sensor+sphere":
            parts.append(c + delta[6:9])
        return np.concatenate(parts)

    # -- residual and derivatives ---------------------------------------------------------
    def _args(self, x):
        t2, q, c = self._split(x)
        if self.rotation == "local":
            theta, extra = [*t2, 0.0, 0.0, 0.0, *c], list(q)
        else:
            theta, extra = [*t2, *q, *c], []
        return (*theta, *extra, *self._data)

    def residual_and_jacobian(self, x):
        """Residuals (N, 3) in mm and Jacobian (N, 3, n) with respect to the step."""
        resjac, _ = _numpy_functions(self.rotation)
        vals = codegen.stack_outputs(resjac(*self._args(x)), (self.n_meas,))
        e = vals[:, :3]
        n_theta = (vals.shape[1] - 3) // 3
        jac = vals[:, 3:].reshape(self.n_meas, 3, n_theta)[:, :, self._cols]
        return e, jac

    def residuals(self, x):
        """Residual vectors (N, 3), mm."""
        return self.residual_and_jacobian(x)[0]

    def residual(self, x):
        """Stacked residual (3N,), mm."""
        return self.residuals(x).ravel()

    def jacobian(self, x):
        """Stacked Jacobian (3N, n)."""
        return self.residual_and_jacobian(x)[1].reshape(-1, self.n)

    def second_derivatives(self, x):
        """Second derivatives of each residual component, shape (N, 3, n, n)."""
        _, hess = _numpy_functions(self.rotation)
        vals = codegen.stack_outputs(hess(*self._args(x)), (self.n_meas,))
        n_theta = int(round(np.sqrt(vals.shape[1] / 3)))
        d2 = vals.reshape(self.n_meas, 3, n_theta, n_theta)
        return d2[:, :, self._cols, self._cols]

    def cost(self, x):
        """``1/2 sum |e_i|^2`` in mm^2."""
        e = self.residual(x)
        return 0.5 * float(e @ e)

    def gradient(self, x):
        e, jac = self.residual_and_jacobian(x)
        return np.einsum("ik,ikn->n", e, jac)

    def cost_hessian(self, x):
        """Exact Hessian of the cost: ``J^T J + sum_k e_k grad^2 e_k`` (n, n)."""
        e, jac = self.residual_and_jacobian(x)
        d2 = self.second_derivatives(x)
        return np.einsum("ikn,ikm->nm", jac, jac) + np.einsum("ik,iknm->nm", e, d2)

    # -- CasADi ----------------------------------------------------------------------------
    def nlp(self):
        """The problem for IPOPT as a dict ``{'x', 'f', 'g', 'p'}`` plus values.

        ``x`` is the point (``euler`` or ``matrix``; ``local`` has no meaning without a
        retraction). ``p`` holds the measurements (15 x N: R1 row-major, t1, xs) and, for
        ``sensor``, the fixed sphere centre. With ``matrix`` the six independent entries of
        ``R^T R - I`` are equality constraints ``g = 0``.

        Returns
        -------
        dict
            ``{'x', 'f', 'g', 'p'}`` (CasADi SX), ``'lbg'``, ``'ubg'`` (arrays) and
            ``'p_value'`` (the numeric parameter vector).
        """
        import casadi as ca

        if self.rotation == "local":
            raise ValueError("IPOPT works on 'euler' or 'matrix'; 'local' needs a retraction")
        resjac, _ = _sources(self.rotation)
        gen = codegen.casadi_function(resjac)
        nr = _N_ROT[self.rotation]
        x = ca.SX.sym("x", self.n)
        d = ca.SX.sym("d", 15)
        theta = ca.SX.sym("theta", 3 + nr + 3)
        e = ca.vertcat(*gen(*[theta[k] for k in range(theta.shape[0])], *[d[k] for k in range(15)])[:3])
        one = ca.Function("e", [theta, d], [e])
        data = ca.SX.sym("data", 15, self.n_meas)
        p_value = np.stack(self._data).ravel(order="F")  # ca.vec is column-major
        if self.unknowns == "sensor+sphere":
            p, full = ca.vec(data), x
        else:
            cfix = ca.SX.sym("c", 3)
            p, full = ca.vertcat(ca.vec(data), cfix), ca.vertcat(x, cfix)
            p_value = np.concatenate([p_value, self.fixed_centre])
        e_all = one.map(self.n_meas)(full, data)
        f = 0.5 * ca.sumsqr(e_all)
        if self.rotation == "matrix":
            rt = ca.reshape(x[3:12], 3, 3).T  # row-major entries -> matrix
            m = ca.mtimes(rt.T, rt) - ca.SX.eye(3)
            g = ca.vertcat(*[m[i, j] for i in range(3) for j in range(i, 3)])
        else:
            g = ca.SX(0, 1)
        ng = g.shape[0]
        return {"x": x, "f": f, "g": g, "p": p, "lbg": np.zeros(ng), "ubg": np.zeros(ng), "p_value": p_value}
