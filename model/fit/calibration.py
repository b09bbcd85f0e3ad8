"""The hand-eye calibration residual (seed 4-3) as a least-squares problem.

For measurement ``i`` (flange pose ``flange2base_i = (R1_i, t1_i)``, sphere centre
``centre_in_sensor_i = xs_i``)::

    e_i(theta) = R1_i (R2 xs_i + t2) + t1_i - c

``sensor2flange = (R2, t2)`` is unknown; so, with ``unknowns='sensor+sphere'``, is the sphere
centre ``c`` in the robot base. The cost is ``1/2 sum |e_i|^2`` (mm^2).

Residual, Jacobian and the second derivatives needed for Newton's exact Hessian
``H = J^T J + sum_k e_k grad^2 e_k`` are generated from :func:`handeye.model.chain.symbolic.calibration_residual`.

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
The same chain gives three residuals (:func:`handeye.model.chain.symbolic.calibration_residual`): the
seed's ``centre`` residual (one row per measurement, 3 components, mm), the ``measurement``
residual in the sensor's own space (circle centre and radius in the laser plane; one row per
measurement) and the ``points`` residual (one row per profile point: distance from the sphere
surface). Rows can be *whitened* by matrices ``W_i`` (``W_i^T W_i`` the inverse covariance of
row i), so that the cost ``1/2 sum |W_i e_i|^2`` weights each component by its precision.
"""
from __future__ import annotations

import copy
import functools

import numpy as np

from handeye.model.chain import codegen
from handeye.model.chain.names import KINDS, ROTATIONS, UNKNOWNS  # noqa: F401  (re-exported: the names, defined without numpy)
from handeye.model.chain.pose import kuka_from_matrix, matrix_from_kuka, transform_from_pose
from handeye.model.common import rotation

#: Above this many rows IPOPT's cost is a callback to the model's numpy cost, gradient and exact Hessian
#: (:mod:`handeye.model.fit.nlp_callback`); up to it one CasADi SX graph of every row, built once per problem
#: structure and kept with its solver, where building costs more than solving (a graph built for one problem never
#: pays: at 300 rows 200 ms of a 220 ms solve, 48 ms through the callback). The two agree to rounding (tested).
NLP_CALLBACK_ABOVE = 120


def _derived(rot, kind, outputs):
    """The ``build`` of a generated function of the residual ``kind`` in ``rot``: the inputs of
    :func:`handeye.model.chain.symbolic.calibration_residual` (theta, extra, data) and, as outputs,
    ``outputs`` of its expressions."""

    def build():
        from handeye.model.chain import symbolic  # sympy only on a cache miss

        s = symbolic.calibration_residual(rot, kind)
        return s["theta"] + s["extra"] + s["data"], outputs(s)

    return build


@functools.lru_cache(maxsize=None)
def _sources(rot, kind="centre"):
    return (
        codegen.generated_source(f"calib_resjac_{rot}_{kind}", _derived(rot, kind, lambda s: list(s["e"]) + list(s["jac"]))),
        codegen.generated_source(f"calib_hess_{rot}_{kind}", _derived(rot, kind, lambda s: [v for h in s["hess"] for v in h])),
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
    source = codegen.generated_source(f"calib_res_{rot}_{kind}", _derived(rot, kind, lambda s: list(s["e"])))
    return codegen.numpy_function(source)


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


#: Rows per chunk of a generated function's evaluation (:meth:`CalibrationModel._evaluate`).
ROW_CHUNK = 16384
#: Numbers of the second derivatives' table held at once (:meth:`CalibrationModel._second_order`: 32 MB).
_SECOND_ORDER_BLOCK = 1 << 22


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
        self.unknowns = unknowns
        self._set_rotation(rotation)
        if unknowns not in UNKNOWNS:
            raise ValueError(f"unknowns must be one of {UNKNOWNS}, got {unknowns!r}")
        if kind not in KINDS:
            raise ValueError(f"kind must be one of {tuple(KINDS)}, got {kind!r}")
        if kind != "centre" and radius is None:
            raise ValueError(f"the {kind!r} residual needs the sphere radius")
        f2b = np.asarray(flange2base, dtype=float)
        xs = np.asarray(centre_in_sensor, dtype=float)
        self.kind = kind
        self.m = KINDS[kind]
        self.radius = None if radius is None else float(radius)
        self.whiten = None if whiten is None else np.asarray(whiten, dtype=float)
        self.n_meas = len(xs)
        self.fixed_centre = np.asarray(sphere_centre, dtype=float).reshape(3)
        # per-row data in the generated functions' argument order: R1 (9), t1, the kind's data
        data = np.empty((12 + xs.shape[1], len(xs)))  # one contiguous row per argument: chunks read it in order
        data[:9], data[9:12], data[12:] = f2b[:, :3, :3].reshape(-1, 9).T, f2b[:, :3, 3].T, xs.T
        self._data = tuple(data)
        self.flange2base = f2b
        self.centre_in_sensor = xs
        #: rows that share one measurement (profile points); None: every row its own
        self.groups = None

    def _set_rotation(self, rotation):
        """The parametrisation: its name, the step's columns of the generated Jacobian, their number and names."""
        if rotation not in ROTATIONS:
            raise ValueError(f"rotation must be one of {ROTATIONS}, got {rotation!r}")
        self.rotation = rotation
        self._cols = slice(0, 3 + _N_ROT[rotation] + (3 if self.unknowns == "sensor+sphere" else 0))
        self.n = self._cols.stop
        self.names = parameter_names(rotation, self.unknowns)

    @classmethod
    def from_dataset(cls, dataset, rotation="local", unknowns="sensor", sphere_centre=None):
        """The centre-residual model of every sample of a dataset.

        Parameters
        ----------
        dataset : handeye.model.datasets.dataset.Dataset
        rotation : {'euler', 'matrix', 'local'}
        unknowns : {'sensor', 'sensor+sphere'}
        sphere_centre : array_like, shape (3,), optional
            Robot base, mm; default the dataset's (known value, or start value when free).
        """
        centre = dataset.sphere_centre if sphere_centre is None else sphere_centre
        return cls(dataset.motions(), dataset.centre_in_sensor, centre, rotation, unknowns)

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

    def samples(self, keep):
        """The model of the samples ``keep`` (bool per sample: per row, or per profile for
        ``points``): the same kind, whitening, parametrisation and centre, samples renumbered."""
        keep = np.asarray(keep, bool)
        if self.groups is None and len(keep) == self.n_meas and keep.all():
            return copy.copy(self)  # every sample: the rows' arrays shared (read-only), not copied
        rows = keep if self.groups is None else keep[self.groups]
        sub = CalibrationModel(self.flange2base[rows], self.centre_in_sensor[rows], self.fixed_centre, self.rotation,
                               self.unknowns, self.kind, self.radius, None if self.whiten is None else self.whiten[rows])
        if self.groups is not None:
            sub.groups = np.unique(self.groups[rows], return_inverse=True)[1].reshape(-1)
        return sub

    def with_rotation(self, rotation, sphere_centre=None):
        """The same rows, kind and whitening in another parametrisation (and fixed centre)."""
        twin = copy.copy(self)  # the rows' arrays shared (read-only), not rebuilt: a million rows take a while
        twin._set_rotation(rotation)
        twin.fixed_centre = np.asarray(self.fixed_centre if sphere_centre is None else sphere_centre, float).reshape(3)
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
    def _head(self, x):
        """The generated functions' arguments before the rows' data: the parameters of ``x`` (and the radius)."""
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
        return (*theta, *extra)

    def _rows(self, function, head, rows):
        """A generated ``function`` at the parameters ``head`` (:meth:`_head`) for the row slice ``rows``."""
        return function(*head, *(d[rows] for d in self._data))

    def _evaluate(self, function, x, rows=None):
        """Outputs (..., R, K) of a generated ``function`` at the point(s) ``x`` for the rows
        ``rows`` (a slice; default all), computed ROW_CHUNK rows at a time: the generated code's
        temporaries stay in cache, and a million rows need a few MB of them, not gigabytes; a
        point of the ``points`` model is evaluated per profile (:meth:`_profile_layout`) and its
        real rows taken back in order."""
        batch, head = np.shape(x)[:-1], self._head(x)
        start, stop, _ = (rows or slice(None)).indices(self.n_meas)
        layout = None if batch or rows is not None else self._profile_layout()
        if layout is not None:  # a scan's points per profile: the flange pose's terms once per profile
            return codegen.stack_outputs(function(*head, *layout[2]), layout[1].shape)[layout[1]]
        if stop - start <= ROW_CHUNK and rows is None:
            return codegen.stack_outputs(function(*head, *self._data), batch + (self.n_meas,))
        out = None
        for a in range(start, stop, ROW_CHUNK):
            b = min(a + ROW_CHUNK, stop)
            values = self._rows(function, head, slice(a, b))
            if out is None:
                out = np.empty((len(values),) + batch + (stop - start,))
            for k, v in enumerate(values):
                out[k, ..., a - start:b - start] = v
        return np.moveaxis(out, 0, -1)

    def _raw(self, x):
        return self._residual_jacobian(self._evaluate(_numpy_functions(self.rotation, self.kind)[0], x))

    def _residual_jacobian(self, vals):
        """Residuals (..., R, m) and Jacobian (..., R, m, n) of ``calib_resjac``'s outputs (..., R, K)."""
        m = self.m
        n_theta = (vals.shape[-1] - m) // m
        return vals[..., :m], vals[..., m:].reshape(vals.shape[:-1] + (m, n_theta))[..., self._cols]

    def _chunk(self, function, x, rows):
        """The outputs (..., R, K) of a generated ``function`` at ``x`` for the row slice ``rows``
        (one chunk: the temporaries stay in cache)."""
        values = self._rows(function, self._head(x), rows)
        return codegen.stack_outputs(values, np.shape(x)[:-1] + (rows.stop - rows.start,))

    def chunks(self, x, chunk=None):
        """Residuals and Jacobians chunk by chunk: yields ``(rows, e, jac)``, ``rows`` a slice of
        at most ``chunk`` (default :data:`ROW_CHUNK`) rows, ``e`` (..., R, m) and ``jac``
        (..., R, m, n) as :meth:`residual_and_jacobian` gives for those rows (whitened). What
        only needs sums over the rows (:meth:`normal_equations`) never holds all of them."""
        resjac, _ = _numpy_functions(self.rotation, self.kind)
        step = chunk or ROW_CHUNK
        for a in range(0, self.n_meas, step):
            rows = slice(a, min(a + step, self.n_meas))
            e, jac = self._residual_jacobian(self._chunk(resjac, x, rows))
            if self.whiten is not None:
                w = self.whiten[rows]
                e, jac = np.einsum("ikl,...il->...ik", w, e), np.einsum("ikl,...iln->...ikn", w, jac)
            yield rows, e, jac

    def normal_equations(self, x, weights=None, chunk=None):
        """``(J^T J, J^T r, r^T r)`` of the whitened rows, (..., n, n), (..., n), (...), summed
        chunk by chunk (:meth:`chunks`); ``weights`` (N,) weight each row's contribution."""
        batch, n = np.shape(x)[:-1], self.n
        jtj, jtr, rtr = np.zeros(batch + (n, n)), np.zeros(batch + (n,)), np.zeros(batch)
        for rows, e, jac in self.chunks(x, chunk):
            if weights is not None:
                sw = np.sqrt(weights[rows])[:, None]
                e, jac = sw * e, sw[..., None] * jac
            flat = jac.reshape(batch + (-1, n))
            r = e.reshape(batch + (-1,))
            jtj += np.swapaxes(flat, -1, -2) @ flat
            jtr += np.einsum("...kn,...k->...n", flat, r)
            rtr += np.einsum("...k,...k->...", r, r)
        return jtj, jtr, rtr

    def jacobian_r(self, x, chunk=None):
        """The triangular factor R (n, n) of the whitened Jacobian at one point, ``J = Q R``,
        by QR of the chunks' factors stacked (TSQR): the singular values and right singular
        vectors of J without J."""
        factors = [np.linalg.qr(jac.reshape(-1, self.n), mode="r") for _, _, jac in self.chunks(x, chunk)]
        return np.linalg.qr(np.concatenate(factors), mode="r") if len(factors) > 1 else factors[0]

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
        return self._evaluate(_numpy_residual(self.rotation, self.kind), x)

    def residual(self, x):
        """Stacked whitened residual (..., N m), what the solvers minimise."""
        e = self._whitened(self.residuals(x))
        return e.reshape(e.shape[:-2] + (-1,))

    def jacobian(self, x):
        """Stacked whitened Jacobian (..., N m, n)."""
        jac = self.residual_and_jacobian(x)[1]
        return jac.reshape(jac.shape[:-3] + (-1, self.n))

    def second_derivatives(self, x, rows=None):
        """Second derivatives of each (unwhitened) residual component, shape (..., N, m, n, n)
        (the rows of the slice ``rows`` only: (..., R, m, n, n))."""
        _, hess = _numpy_functions(self.rotation, self.kind)
        batch = np.shape(x)[:-1]
        vals = self._evaluate(hess, x, rows)
        n_theta = int(round(np.sqrt(vals.shape[-1] / self.m)))
        return vals.reshape(batch + (vals.shape[-2], self.m, n_theta, n_theta))[..., self._cols, self._cols]

    def cost(self, x):
        """``1/2 sum |W_i e_i|^2`` (mm^2 without whitening); a float, or (...) for a stack."""
        e = self.residual(x)
        # einsum, not e @ e: OpenBLAS threads a long dot product, and on a busy machine its
        # threads' hand-over costs milliseconds (measured: 15 ms instead of 4 us for 33,000 rows)
        return 0.5 * float(np.einsum("i,i->", e, e)) if e.ndim == 1 else 0.5 * np.einsum("...i,...i->...", e, e)

    def gradient(self, x):
        """Gradient of :meth:`cost` with respect to the step, (..., n)."""
        if self.n_meas > ROW_CHUNK:  # summed chunk by chunk: no Jacobian of every row at once
            return self.normal_equations(x)[1]
        return self.gradient_from(*self.residual_and_jacobian(x))

    @staticmethod
    def gradient_from(e, jac):
        """:meth:`gradient` given :meth:`residual_and_jacobian` ``(e, jac)`` at the point."""
        return np.einsum("...ik,...ikn->...n", e, jac)

    def cost_hessian(self, x):
        """Exact Hessian of the cost: ``sum J_i^T W_i^T W_i J_i + sum_l (W_i^T W_i e_i)_l grad^2 e_il``, (..., n, n);
        above ROW_CHUNK rows summed chunk by chunk (a million rows' Jacobian is not held at once)."""
        if self.n_meas <= ROW_CHUNK or self._profile_layout() is not None:
            return self.cost_derivatives(x)[2]
        out = 0.0
        for rows, e, jac in self.chunks(x):
            back = e if self.whiten is None else np.einsum("ilk,...il->...ik", self.whiten[rows], e)  # W^T (W e)
            flat = jac.reshape(jac.shape[:-3] + (-1, self.n))
            out = out + np.swapaxes(flat, -1, -2) @ flat
            out = out + np.einsum("...ik,...iknm->...nm", back, self.second_derivatives(x, rows))
        return out

    def cost_hessian_from(self, x, e, jac):
        """:meth:`cost_hessian` at ``x`` given its :meth:`residual_and_jacobian` ``(e, jac)``."""
        back = e if self.whiten is None else np.einsum("ilk,...il->...ik", self.whiten, e)  # W^T (W e)
        flat = jac.reshape(jac.shape[:-3] + (-1, self.n))
        return np.swapaxes(flat, -1, -2) @ flat + self._second_order(x, back)

    def cost_derivatives(self, x, weights=None, second_order=True):
        """Cost, gradient and exact Hessian of the row-weighted cost ``1/2 sum_i w_i |W_i e_i|^2``.

        One evaluation of the rows serves many weightings: the leave-one-out problems
        (:mod:`handeye.app.engine.loo`) are this cost with one sample's rows weighted zero.

        Parameters
        ----------
        x : ndarray, shape (n_point,) or (..., n_point)
            A point or a stack of points.
        weights : ndarray, shape (..., N), optional
            Row weights, broadcast against the batch axes of ``x`` (a single point ``x`` with
            weights (G, N) gives G weighted costs at ``x``); default one.
        second_order : bool
            False: Gauss-Newton's ``sum_i w_i J_i^T J_i`` for the Hessian (no second derivatives).

        Returns
        -------
        cost : float or ndarray, shape (...)
        gradient : ndarray, shape (..., n)
        hessian : ndarray, shape (..., n, n)
            ``sum_i w_i (J_i^T J_i + sum_l (W_i^T W_i e_i)_l grad^2 e_il)`` (:meth:`cost_hessian`).
        """
        e, jac = self.residual_and_jacobian(x)
        back = e if self.whiten is None else np.einsum("ilk,...il->...ik", self.whiten, e)  # W^T (W e)
        e_w, back_w, jac_w = e, back, jac
        if weights is not None:
            w = np.asarray(weights, dtype=float)[..., None]
            e_w, back_w, jac_w = w * e, w * back, w[..., None] * jac
        rows = self.n_meas * self.m
        jac_f = jac.reshape(jac.shape[:-3] + (rows, self.n))
        cost = 0.5 * np.sum(e_w * e, axis=(-2, -1))
        grad = (e_w.reshape(e_w.shape[:-2] + (1, rows)) @ jac_f)[..., 0, :]
        gram = np.swapaxes(jac_w.reshape(jac_w.shape[:-3] + (rows, self.n)), -1, -2) @ jac_f
        hess = gram + self._second_order(x, back_w) if second_order else gram
        return (float(cost) if np.ndim(cost) == 0 else cost), grad, hess

    def _second_order(self, x, back):
        """``sum_il back_il grad^2 e_il`` (..., n, n) for ``back`` (..., N, m): the generated second derivatives
        contracted in blocks of rows (:data:`_SECOND_ORDER_BLOCK` numbers), never their (..., N, m, n, n) array,
        the entries zero everywhere skipped (all of ``matrix``'s: its residual is linear; 216 of 243 in ``euler``
        and ``local``); a point of the ``points`` model per profile (:meth:`_weighted_second_derivatives`)."""
        if not np.shape(x)[:-1] and back.ndim == 2 and self._profile_layout() is not None:
            return self._weighted_second_derivatives(x, back)
        _, hess = _numpy_functions(self.rotation, self.kind)
        head, batch = self._head(x), np.broadcast_shapes(back.shape[:-2], np.shape(x)[:-1])
        out = np.zeros(batch + (self.m * self.n * self.n,))  # entry (output, p, q), flat
        step = max(1, min(ROW_CHUNK, _SECOND_ORDER_BLOCK // (out.size or 1)))
        for a in range(0, self.n_meas, step):
            b = min(a + step, self.n_meas)
            vals = self._rows(hess, head, slice(a, b))
            n_theta = int(round(np.sqrt(len(vals) / self.m)))
            free = np.arange(self.n)
            index = ((np.arange(self.m)[:, None, None] * n_theta + free[:, None]) * n_theta + free).ravel()
            live = [i for i, k in enumerate(index) if np.ndim(vals[k]) or vals[k] != 0]
            if not live:
                continue
            table = np.empty((len(live),) + np.shape(x)[:-1] + (b - a,))  # constants and per-row values alike
            for j, i in enumerate(live):
                table[j] = vals[index[i]]
            table = table.reshape(table.shape[:1] + (1,) * (len(batch) - np.ndim(x) + 1) + table.shape[1:])
            outputs = back[..., a:b, :][..., np.asarray(live) // (self.n * self.n)]  # (..., rows, live)
            out[..., live] += np.einsum("k...r,...rk->...k", table, outputs)
        return out.reshape(batch + (self.m, self.n, self.n)).sum(axis=-3)

    def _weighted_second_derivatives(self, x, weighted):
        """``sum_i sum_l weighted_il grad^2 e_il`` (..., n, n), contracted output by output: the
        rows' second derivatives (N m n^2 numbers, 60 MB for a scan's 33,000 points) are never
        stacked into one array. Profile points of one point (not a stack) are evaluated per
        profile (:meth:`_profile_layout`)."""
        _, hess = _numpy_functions(self.rotation, self.kind)
        batch = np.shape(x)[:-1]
        layout = None if batch else self._profile_layout()
        if layout is None:
            vals = hess(*self._head(x), *self._data)
        else:
            vals = hess(*self._head(x), *layout[2])  # the rows as a (profiles, points) table
            weighted = np.where(layout[1][..., None], weighted[layout[0]], 0.0)  # (G, K, m): padding weighs nothing
        per = len(vals) // self.m  # entries of one component's Hessian
        comps = [np.ascontiguousarray(weighted[..., c]) for c in range(self.m)]
        rows = [w.sum(axis=-1) for w in comps]  # per profile in the layout, else the total (for constant entries)
        out = np.empty(batch + (len(vals),))
        for k, v in enumerate(vals):
            c = k // per
            if not np.ndim(v):
                out[..., k] = v * (rows[c] if batch else rows[c].sum())
            elif batch:
                out[..., k] = np.einsum("...i,...i->...", comps[c], v)
            else:  # a profile's constant (G, 1) against its summed weights, else row by row
                out[k] = rows[c] @ v[:, 0] if v.shape[-1] == 1 and v.ndim == 2 else np.einsum(
                    "i,i->", comps[c].ravel(), np.ravel(v))  # einsum, not a BLAS dot (see cost)
        n_theta = int(round(np.sqrt(per)))
        return out.reshape(batch + (self.m, n_theta, n_theta)).sum(axis=-3)[..., self._cols, self._cols]

    def _profile_layout(self):
        """Rows of the ``points`` model as a (profiles, longest profile) table: the row indices,
        each profile padded with its last row, which entries are real rows, and the rows' data
        in that layout (the flange pose once per profile); None for other models, or when a
        profile's rows are not contiguous or not from one flange pose.

        Evaluated in this layout the generated functions compute the terms of the flange pose
        and the unknowns once per profile (broadcast), not once per point: about half the
        work of the second derivatives. The numbers are the same, row by row."""
        if self.kind != "points" or self.groups is None or self.n_meas == 0:
            return None
        cached = getattr(self, "_layout", None)
        if cached is not None and cached[0] is self.groups:
            return cached[1]
        starts = np.flatnonzero(np.r_[True, self.groups[1:] != self.groups[:-1]])
        lengths = np.diff(np.r_[starts, self.n_meas])
        pose_rows = np.stack(self._data[:-2], axis=1)
        same_pose = np.array_equal(pose_rows, np.repeat(pose_rows[starts], lengths, axis=0))
        layout = None
        if same_pose and len(np.unique(self.groups[starts])) == len(starts):
            k = np.arange(lengths.max())
            index = starts[:, None] + np.minimum(k[None, :], lengths[:, None] - 1)
            data = (*[d[index[:, :1]] for d in self._data[:-2]], *[d[index] for d in self._data[-2:]])
            layout = (index, k[None, :] < lengths[:, None], data)
        self._layout = (self.groups, layout)
        return layout

    # -- CasADi ----------------------------------------------------------------------------
    def nlp(self):
        """The problem for IPOPT as a dict ``{'x', 'f', 'g', 'p'}`` plus values.

        ``x`` is the point (``euler`` or ``matrix``; ``local`` has no meaning without a
        retraction). With ``matrix`` the six independent entries of ``R^T R - I`` are equality
        constraints ``g = 0``. The centre model in ``matrix`` is linear in ``x``: ``f`` is its quadratic
        form, ``p`` its factor, reference point and gradient there (:mod:`handeye.model.fit.nlp_problem`).
        Else up to :data:`NLP_CALLBACK_ABOVE` rows ``f`` is an SX graph of every row, ``p`` the rows (R1
        row-major, t1, the kind's data, the whitening row-major; for ``sensor`` the sphere centre); above,
        ``f`` is a callback to this model's numpy cost, gradient and Hessian, there is no ``p``, and
        ``'callback'`` holds the callback object, which must outlive the solver.

        Returns
        -------
        dict
            ``{'x', 'f', 'g'}`` (CasADi SX or MX), ``'lbg'``, ``'ubg'`` (arrays), and ``'p'`` with
            ``'p_value'`` (the numeric parameter vector) or ``'callback'``.
        """
        from handeye.model.fit import nlp_problem

        return nlp_problem.nlp(self, _sources(self.rotation, self.kind)[0], _N_ROT[self.rotation], NLP_CALLBACK_ABOVE)
