"""The hand-eye calibration residual (seed 4-3) as a least-squares problem.

For measurement ``i`` (flange pose ``flange2base_i = (R1_i, t1_i)``, sphere centre
``centre_in_sensor_i = xs_i``)::

    e_i(theta) = R1_i (R2 xs_i + t2) + t1_i - c

``sensor2flange = (R2, t2)`` is unknown; so, with ``unknowns='sensor+sphere'``, is the sphere
centre ``c`` in the robot base. The cost is ``1/2 sum |e_i|^2`` (mm^2).

Residual, Jacobian and the second derivatives needed for Newton's exact Hessian
``H = J^T J + sum_k e_k grad^2 e_k`` are generated from :func:`handeye.model.symbolic.calibration_residual`.

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

Residual kinds
--------------
The same chain gives three residuals (:func:`handeye.model.symbolic.calibration_residual`): the
seed's ``centre`` residual (one row per measurement, 3 components, mm), the ``measurement``
residual in the sensor's own space (circle centre and radius in the laser plane; one row per
measurement) and the ``points`` residual (one row per profile point: distance from the sphere
surface). Rows can be *whitened* by matrices ``W_i`` (``W_i^T W_i`` the inverse covariance of
row i), so that the cost ``1/2 sum |W_i e_i|^2`` weights each component by its precision.
"""
from __future__ import annotations

import functools

import numpy as np

from handeye.model import codegen, rotation
from handeye.model.names import KINDS, ROTATIONS, UNKNOWNS  # noqa: F401 - the names, defined without numpy
from handeye.model.pose import kuka_from_matrix, matrix_from_kuka, transform_from_pose

#: Above this many rows the IPOPT problem is a CasADi MX graph calling the one-row residual
#: function ``map``-ped over the rows (memory O(1) per row); below, the same expressions expanded
#: to SX (faster per evaluation, as before). The two agree to rounding (tested).
NLP_MX_ABOVE = 1000


@functools.lru_cache(maxsize=None)
def _sources(rot, kind="centre"):
    def build_resjac():
        from handeye.model import symbolic  # sympy only on a cache miss

        s = symbolic.calibration_residual(rot, kind)
        return s["theta"] + s["extra"] + s["data"], list(s["e"]) + list(s["jac"])

    def build_hess():
        from handeye.model import symbolic

        s = symbolic.calibration_residual(rot, kind)
        return s["theta"] + s["extra"] + s["data"], [v for h in s["hess"] for v in h]

    return (
        codegen.generated_source(f"calib_resjac_{rot}_{kind}", build_resjac),
        codegen.generated_source(f"calib_hess_{rot}_{kind}", build_hess),
    )


@functools.lru_cache(maxsize=None)
def _numpy_functions(rot, kind="centre"):
    resjac, hess = _sources(rot, kind)
    return codegen.numpy_function(resjac), codegen.numpy_function(hess)


@functools.lru_cache(maxsize=None)
def _numpy_residual(rot, kind="centre"):
    """The residual alone, generated from the same expressions as ``calib_resjac`` (its first
    outputs; simplified on its own, so it agrees with them to rounding, not bit for bit): what
    a line search or a trial step needs, several times cheaper than with the Jacobian."""

    def build_res():
        from handeye.model import symbolic

        s = symbolic.calibration_residual(rot, kind)
        return s["theta"] + s["extra"] + s["data"], list(s["e"])

    return codegen.numpy_function(codegen.generated_source(f"calib_res_{rot}_{kind}", build_res))


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
    kind : {'centre', 'measurement', 'points'}
        Residual model; for the last two ``centre_in_sensor`` holds the rows' data instead:
        circles ``(xc, zc, r)`` (N, 3) or profile points ``(x, z)`` (N, 2), one row each, with
        ``flange2base`` given per row. See :meth:`from_circles` and :meth:`from_profiles`.
    radius : float, optional
        Sphere radius, mm (``measurement`` and ``points``).
    whiten : array_like, shape (N, m, m), optional
        Whitening matrices of the rows (module docstring).
    """

    def __init__(self, flange2base, centre_in_sensor, sphere_centre, rotation="euler", unknowns="sensor",
                 kind="centre", radius=None, whiten=None):
        if rotation not in ROTATIONS:
            raise ValueError(f"rotation must be one of {ROTATIONS}, got {rotation!r}")
        if unknowns not in UNKNOWNS:
            raise ValueError(f"unknowns must be one of {UNKNOWNS}, got {unknowns!r}")
        if kind not in KINDS:
            raise ValueError(f"kind must be one of {tuple(KINDS)}, got {kind!r}")
        if kind != "centre" and radius is None:
            raise ValueError(f"the {kind!r} residual needs the sphere radius")
        f2b = np.asarray(flange2base, dtype=float)
        xs = np.asarray(centre_in_sensor, dtype=float)
        self.rotation = rotation
        self.unknowns = unknowns
        self.kind = kind
        self.m = KINDS[kind]
        self.radius = None if radius is None else float(radius)
        self.whiten = None if whiten is None else np.asarray(whiten, dtype=float)
        self.n_meas = len(xs)
        self.fixed_centre = np.asarray(sphere_centre, dtype=float).reshape(3)
        # per-row data in the generated functions' argument order: R1 (9), t1, the kind's data
        self._data = tuple(np.concatenate([f2b[:, :3, :3].reshape(-1, 9), f2b[:, :3, 3], xs], axis=1).T)
        self.flange2base = f2b
        self.centre_in_sensor = xs
        #: rows that share one measurement (profile points); None: every row its own
        self.groups = None
        n_rot = _N_ROT[rotation]
        self._cols = slice(0, 3 + n_rot + (3 if unknowns == "sensor+sphere" else 0))
        self.n = self._cols.stop
        self.names = parameter_names(rotation, unknowns)

    @classmethod
    def from_dataset(cls, dataset, rotation="local", unknowns="sensor", sphere_centre=None):
        """The centre-residual model of every sample of a dataset.

        Parameters
        ----------
        dataset : handeye.model.dataset.Dataset
        rotation : {'euler', 'matrix', 'local'}
        unknowns : {'sensor', 'sensor+sphere'}
        sphere_centre : array_like, shape (3,), optional
            Robot base, mm; default the dataset's (known value, or start value when free).
        """
        centre = dataset.sphere_centre if sphere_centre is None else sphere_centre
        return cls(dataset.flange2base(), dataset.centre_in_sensor, centre, rotation, unknowns)

    @classmethod
    def from_circles(cls, flange2base, circles, radius, sphere_centre, rotation="local", unknowns="sensor",
                     whiten=None):
        """The ``measurement`` residual: one row per circle ``(xc, zc, r)`` (mm)."""
        return cls(flange2base, circles, sphere_centre, rotation, unknowns, "measurement", radius, whiten)

    @classmethod
    def from_profiles(cls, flange2base, profiles, radius, sphere_centre, rotation="local", unknowns="sensor"):
        """The ``points`` residual: one row per profile point; ``profiles`` is a list of (K_i, 2)."""
        f2b = np.asarray(flange2base, dtype=float)
        rows = np.concatenate([np.repeat(f2b[k : k + 1], len(p), axis=0) for k, p in enumerate(profiles)])
        model = cls(rows, np.concatenate(profiles), sphere_centre, rotation, unknowns, "points", radius)
        model.groups = np.concatenate([np.full(len(p), k) for k, p in enumerate(profiles)])
        return model

    def with_rotation(self, rotation, sphere_centre=None):
        """The same rows, kind and whitening in another parametrisation (and fixed centre)."""
        twin = CalibrationModel(self.flange2base, self.centre_in_sensor,
                                self.fixed_centre if sphere_centre is None else sphere_centre,
                                rotation, self.unknowns, self.kind, self.radius, self.whiten)
        twin.groups = self.groups
        return twin

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
        """Translation, rotation entries and sphere centre of a point (n,) or a stack (..., n)."""
        x = np.asarray(x, dtype=float)
        nr = _N_POINT_ROT[self.rotation]
        t2, q = x[..., :3], x[..., 3 : 3 + nr]
        if self.unknowns == "sensor+sphere":
            c = x[..., 3 + nr : 6 + nr]
        else:
            c = np.broadcast_to(self.fixed_centre, x.shape[:-1] + (3,))
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
        """Move from point ``x`` by step ``delta`` (table in the module docstring); both may be
        stacks (..., n) and (..., n_step)."""
        if self.rotation != "local":
            return np.asarray(x, dtype=float) + delta
        t2, q, c = self._split(x)
        delta = np.asarray(delta, dtype=float)
        rot = q.reshape(q.shape[:-1] + (3, 3)) @ rotation.matrix_from_rotvec(delta[..., 3:6])
        parts = [t2 + delta[..., :3], rot.reshape(rot.shape[:-2] + (9,))]
        if self.unknowns == "sensor+sphere":
            parts.append(c + delta[..., 6:9])
        return np.concatenate(parts, axis=-1)

    # -- residual and derivatives ---------------------------------------------------------
    # A point x (n,) or a stack of points (..., n): the batch axes lead every result, so the
    # batched solvers (handeye.solvers.solve_many) evaluate all running starts in one call.
    def _args(self, x):
        t2, q, c = self._split(x)
        batch = np.shape(x)[:-1]

        def entries(v):  # each parameter as a column (..., 1) against the rows' data (N,)
            return [v[..., j, None] if batch else v[..., j] for j in range(v.shape[-1])]

        if self.rotation == "local":
            zero = np.zeros(batch + (1,)) if batch else 0.0
            theta, extra = [*entries(t2), zero, zero, zero, *entries(c)], entries(q)
        else:
            theta, extra = [*entries(t2), *entries(q), *entries(c)], []
        if self.kind != "centre":
            extra.append(self.radius)
        return (*theta, *extra, *self._data)

    def _raw(self, x):
        resjac, _ = _numpy_functions(self.rotation, self.kind)
        batch = np.shape(x)[:-1]
        vals = codegen.stack_outputs(resjac(*self._args(x)), batch + (self.n_meas,))
        m = self.m
        e = vals[..., :m]
        n_theta = (vals.shape[-1] - m) // m
        jac = vals[..., m:].reshape(batch + (self.n_meas, m, n_theta))[..., self._cols]
        return e, jac

    def residual_and_jacobian(self, x):
        """Whitened residuals (..., N, m) and Jacobian (..., N, m, n) with respect to the step."""
        e, jac = self._raw(x)
        if self.whiten is not None:
            jac = np.einsum("ikl,...iln->...ikn", self.whiten, jac)
        return self._whitened(e), jac

    def _whitened(self, e):
        """``W_i e_i`` row by row, (..., N, m); ``e`` itself without whitening."""
        return e if self.whiten is None else np.einsum("ikl,...il->...ik", self.whiten, e)

    def residuals(self, x):
        """Residual rows (..., N, m) as the model defines them (mm), not whitened."""
        batch = np.shape(x)[:-1]
        return codegen.stack_outputs(_numpy_residual(self.rotation, self.kind)(*self._args(x)), batch + (self.n_meas,))

    def residual(self, x):
        """Stacked whitened residual (..., N m), what the solvers minimise."""
        e = self._whitened(self.residuals(x))
        return e.reshape(e.shape[:-2] + (-1,))

    def jacobian(self, x):
        """Stacked whitened Jacobian (..., N m, n)."""
        jac = self.residual_and_jacobian(x)[1]
        return jac.reshape(jac.shape[:-3] + (-1, self.n))

    def second_derivatives(self, x):
        """Second derivatives of each (unwhitened) residual component, shape (..., N, m, n, n)."""
        _, hess = _numpy_functions(self.rotation, self.kind)
        batch = np.shape(x)[:-1]
        vals = codegen.stack_outputs(hess(*self._args(x)), batch + (self.n_meas,))
        n_theta = int(round(np.sqrt(vals.shape[-1] / self.m)))
        d2 = vals.reshape(batch + (self.n_meas, self.m, n_theta, n_theta))
        return d2[..., self._cols, self._cols]

    def cost(self, x):
        """``1/2 sum |W_i e_i|^2`` (mm^2 without whitening); a float, or (...) for a stack."""
        e = self.residual(x)
        return 0.5 * float(e @ e) if e.ndim == 1 else 0.5 * np.einsum("...i,...i->...", e, e)

    def gradient(self, x):
        """Gradient of :meth:`cost` with respect to the step, (..., n)."""
        e, jac = self.residual_and_jacobian(x)
        return np.einsum("...ik,...ikn->...n", e, jac)

    def cost_hessian(self, x):
        """Exact Hessian of the cost: ``sum J_i^T W_i^T W_i J_i + sum_l (W_i^T W_i e_i)_l grad^2 e_il``, (..., n, n)."""
        e, jac = self.residual_and_jacobian(x)
        d2 = self.second_derivatives(x)
        weighted = e if self.whiten is None else np.einsum("ilk,...il->...ik", self.whiten, e)  # W^T (W e)
        flat = jac.reshape(jac.shape[:-3] + (-1, self.n))
        return np.swapaxes(flat, -1, -2) @ flat + np.einsum("...ik,...iknm->...nm", weighted, d2)

    # -- CasADi ----------------------------------------------------------------------------
    def nlp(self):
        """The problem for IPOPT as a dict ``{'x', 'f', 'g', 'p'}`` plus values.

        ``x`` is the point (``euler`` or ``matrix``; ``local`` has no meaning without a
        retraction). ``p`` holds the rows (R1 row-major, t1, the kind's data and the whitening
        matrix, row-major) and, for ``sensor``, the fixed sphere centre. With ``matrix`` the six independent entries of
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
        resjac, _ = _sources(self.rotation, self.kind)
        gen = codegen.casadi_function(resjac)
        nr = _N_ROT[self.rotation]
        m = self.m
        n_data = len(self._data)
        sym = ca.MX if self.n_meas > NLP_MX_ABOVE else ca.SX  # a graph of calls: memory O(1) per row, not O(ops)
        x = sym.sym("x", self.n)
        d = ca.SX.sym("d", n_data + m * m)
        theta = ca.SX.sym("theta", 3 + nr + 3)
        extra = [self.radius] if self.kind != "centre" else []
        e = ca.vertcat(*gen(*[theta[k] for k in range(theta.shape[0])], *extra, *[d[k] for k in range(n_data)])[:m])
        w = ca.reshape(d[n_data:], m, m).T  # row-major entries -> matrix
        one = ca.Function("e", [theta, d], [ca.mtimes(w, e)])
        whiten = self.whiten if self.whiten is not None else np.broadcast_to(np.eye(m), (self.n_meas, m, m))
        table = np.concatenate([np.stack(self._data), whiten.reshape(self.n_meas, m * m).T])
        data = sym.sym("data", table.shape[0], self.n_meas)
        p_value = table.ravel(order="F")  # ca.vec is column-major
        if self.unknowns == "sensor+sphere":
            p, full = ca.vec(data), x
        else:
            cfix = sym.sym("c", 3)
            p, full = ca.vertcat(ca.vec(data), cfix), ca.vertcat(x, cfix)
            p_value = np.concatenate([p_value, self.fixed_centre])
        e_all = one.map(self.n_meas)(full, data)
        f = 0.5 * ca.sumsqr(e_all)
        if self.rotation == "matrix":
            rt = ca.reshape(x[3:12], 3, 3).T  # row-major entries -> matrix
            m = ca.mtimes(rt.T, rt) - sym.eye(3)
            g = ca.vertcat(*[m[i, j] for i in range(3) for j in range(i, 3)])
        else:
            g = sym(0, 1)
        ng = g.shape[0]
        return {"x": x, "f": f, "g": g, "p": p, "lbg": np.zeros(ng), "ubg": np.zeros(ng), "p_value": p_value}
