"""The whole cell as one least-squares problem: sensor, sphere and positioner axes together.

The residual of sample i (:func:`handeye.model.chain.symbolic.cell_residual`, generated from the one
symbolic source)::

    e_i = M_i X xs_i - P(th_i) c           (mm, robot base frame for a positioner)

``M_i`` the carrier motion (:mod:`handeye.model.chain.mounts`; for a positioner the flange pose in the
base, and ``P`` the positioner's product of exponentials), ``X`` the sensor frame in its mount's
frame, ``c`` the sphere centre in its mount's frame. :class:`CellModel` lets any of the three
parts be *free* (estimated) or *held* (known): ``sphere+positioner`` with a sensor calibrated
before is the seed's outlook (chapter 8): calibrate the positioner with the calibrated sensor.

Data effects of the catalogue (:mod:`handeye.model.effects`: ``sensor_scale``, ``sphere_radius``,
``centre_scale``) may be fitted with the parts: ``xs_i`` is then the centre corrected by them, and their
columns are ``R(M_i) R_X d xs_i / d theta``, the chain's rotation times the effect's own exact derivative,
as :class:`handeye.model.fit.extended.Samples` composes them.

Points and steps
----------------
The point is ``x = (R_X row-major (9), t_X (3), c (3), per axis p (3), d (3))``; a step is a
local chart: ``dt`` (mm), ``dr`` (rad, about the sensor's axes), ``dc`` (mm), per axis ``a, b``
(rad: tilts of the direction about two normals ``e1, e2`` of ``d``) and ``u, v`` (mm: moves of
the point along those normals). A move of an axis's point *along* the axis changes no rotation,
so it is no parameter and the chart has no gauge freedom: 4 numbers per axis. The effects' parameters
follow the axes in both (a plain sum).
"""
from __future__ import annotations

import dataclasses
import functools

import numpy as np

from handeye.model import effects as catalogue
from handeye.model.chain import codegen
from handeye.model.chain.mounts import Axis, unit
from handeye.model.chain.names import PARTS  # the parts a calibration can estimate, in the order of the step
from handeye.model.common.rotation import matrix_from_rotvec


@functools.lru_cache(maxsize=None)
def _resjac(n_axes):
    def build():
        from handeye.model.chain import symbolic  # sympy only on a cache miss

        s = symbolic.cell_residual(n_axes)
        return s["theta"] + s["extra"] + s["data"], list(s["e"]) + list(s["jac"])

    return codegen.numpy_function(codegen.generated_source(f"cell_resjac_{n_axes}", build))


def _cross(a, b):
    """``a x b`` of two 3-vectors (numpy's cross costs tens of microseconds on one pair)."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def normals(direction):
    """Two unit vectors ``e1, e2`` normal to ``direction`` and to each other (a fixed choice)."""
    d = unit(direction)
    helper = np.eye(3)[np.argmin(np.abs(d))]
    e1 = unit(_cross(d, helper))
    return e1, _cross(d, e1)


def step_names(n_axes, axis_names=None, effects=()):
    """Names of the step's coordinates: ``tx .. wz, cx, cy, cz``, per axis ``<name>_tilt1, _tilt2, _shift1,
    _shift2``, per data effect ``<effect>.<parameter>``."""
    names = ["tx", "ty", "tz", "wx", "wy", "wz", "cx", "cy", "cz"]
    for j in range(n_axes):
        a = axis_names[j] if axis_names else f"e{j + 1}"
        names += [f"{a}_tilt1", f"{a}_tilt2", f"{a}_shift1", f"{a}_shift2"]
    return names + [f"{name}.{p}" for name in effects for p in catalogue.get(name).PARAMS]


def pack(sensor, centre, axes=()):
    """The point ``x`` of a sensor 4x4, a centre (3,) and axes (module docstring)."""
    parts = [np.asarray(sensor, float)[:3, :3].ravel(), np.asarray(sensor, float)[:3, 3], np.asarray(centre, float)]
    for axis in axes:
        parts += [np.asarray(axis.point, float), unit(axis.direction)]
    return np.concatenate(parts)


def unpack(x, axis_names):
    """``(sensor 4x4, centre (3,), axes)`` of a point."""
    x = np.asarray(x, float)
    sensor = np.eye(4)
    sensor[:3, :3], sensor[:3, 3] = x[:9].reshape(3, 3), x[9:12]
    axes = tuple(Axis(name, x[15 + 6 * j:18 + 6 * j].copy(), x[18 + 6 * j:21 + 6 * j].copy())
                 for j, name in enumerate(axis_names))
    return sensor, x[12:15].copy(), axes


def corrected_centres(centre_in_sensor, radius, params):
    """Measured centres (N, 3, mm, sensor frame) corrected by data effects ``params`` (name -> parameters, in
    order), and per effect their derivative (N, 3, k) with respect to its parameters (each at the centres the
    effects before it corrected); ``radius``: the sphere's, mm."""
    xs, derivatives = np.asarray(centre_in_sensor, float), []
    for name, p in params.items():
        with np.errstate(invalid="ignore", divide="ignore"):  # non-finite trial steps are rejected
            xs, dxs = catalogue.correct(name, xs, radius, p)
        derivatives.append(dxs)
    return xs, derivatives


@dataclasses.dataclass(frozen=True)
class CellModel:
    """Residual, exact Jacobian and retraction of the cell problem (module docstring).

    Parameters
    ----------
    motions : ndarray, shape (N, 4, 4)
        Carrier motions ``M_i`` (mm); for a positioner the flange poses in the robot base.
    centre_in_sensor : ndarray, shape (N, 3)
        ``xs_i``, mm, sensor frame.
    angles : ndarray, shape (N, k)
        Positioner axis angles, degrees (k = 0: no positioner).
    axis_names : tuple of str
    free : tuple of str
        Parts estimated, a subset of :data:`PARTS`; the others are held at the point's values.
    free_axes : tuple of str or None
        With ``positioner`` free: the axes estimated (None: every axis); the others are held.
    effects : tuple of str
        Data effects of the catalogue fitted with the parts (always free), their parameters at the
        point's end.
    radius : float
        The sphere's radius (mm), which the effects' corrections take.
    """

    motions: np.ndarray
    centre_in_sensor: np.ndarray
    angles: np.ndarray
    axis_names: tuple = ()
    free: tuple = PARTS
    free_axes: tuple | None = None
    effects: tuple = ()
    radius: float = 0.0

    @property
    def n_axes(self):
        return len(self.axis_names)

    @property
    def n_chain(self):
        """Coordinates of the chain's full step (sensor, centre, axes), before the effects'."""
        return 9 + 4 * self.n_axes

    @functools.cached_property
    def n_effects(self):
        return sum(len(catalogue.get(name).PARAMS) for name in self.effects)

    def effect_params(self, x):
        """The effects' parameters at the point ``x``: name -> array."""
        out, at = {}, len(x) - self.n_effects
        for name in self.effects:
            k = len(catalogue.get(name).PARAMS)
            out[name], at = np.asarray(x[at:at + k], float), at + k
        return out

    @functools.cached_property
    def columns(self):
        """Indices of the free parts' step coordinates in the full step."""
        turning = [j for j, name in enumerate(self.axis_names) if self.free_axes is None or name in self.free_axes]
        cols = {"sensor": range(0, 6), "sphere": range(6, 9),
                "positioner": [9 + 4 * j + k for j in turning for k in range(4)]}
        chain = [i for part in PARTS if part in self.free for i in cols[part]]
        return np.array(chain + list(range(self.n_chain, self.n_chain + self.n_effects)), int)

    @property
    def n(self):
        return len(self.columns)

    @property
    def names(self):
        return [step_names(self.n_axes, self.axis_names, self.effects)[i] for i in self.columns]

    def _inputs(self, x, centre_in_sensor):
        x = np.asarray(x, float)
        extra = list(x[:12])
        for j in range(self.n_axes):
            p, d = x[15 + 6 * j:18 + 6 * j], x[18 + 6 * j:21 + 6 * j]
            e1, e2 = normals(d)
            extra += [*p, *d, *e1, *e2]
        m = self.motions
        data = [m[:, 0, 0], m[:, 0, 1], m[:, 0, 2], m[:, 1, 0], m[:, 1, 1], m[:, 1, 2], m[:, 2, 0], m[:, 2, 1],
                m[:, 2, 2], m[:, 0, 3], m[:, 1, 3], m[:, 2, 3], *centre_in_sensor.T, *np.asarray(self.angles).T]
        theta = [0.0] * (9 + 4 * self.n_axes)
        theta[6:9] = x[12:15]
        return theta + extra + data

    def corrected(self, x):
        """:func:`corrected_centres` of the measured centres by the effects at ``x``."""
        return corrected_centres(self.centre_in_sensor, self.radius, self.effect_params(x))

    def evaluate(self, x):
        """Residuals (N, 3) and the full Jacobian (N, 3, 9 + 4k + the effects' parameters) at the point ``x``."""
        xs, derivatives = self.corrected(x)
        out = codegen.stack_outputs(_resjac(self.n_axes)(*self._inputs(x, xs)), (len(xs),))
        jac = out[:, 3:].reshape(-1, 3, self.n_chain)
        if derivatives:
            turn = self.motions[:, :3, :3] @ np.asarray(x, float)[:9].reshape(3, 3)  # R(M_i) R_X: d e_i / d xs_i
            jac = np.concatenate([jac] + [turn @ dxs for dxs in derivatives], axis=2)
        return out[:, :3], jac

    def residual(self, x):
        """Stacked residual (3N,), mm."""
        return self.evaluate(x)[0].ravel()

    def jacobian(self, x):
        """Jacobian of :meth:`residual` with respect to the free parts' step (3N, n)."""
        return self.evaluate(x)[1][:, :, self.columns].reshape(-1, self.n)

    def retract(self, x, delta):
        """The point reached from ``x`` by the free parts' step ``delta`` (module docstring)."""
        full = np.zeros(self.n_chain + self.n_effects)
        full[self.columns] = delta
        x = np.array(x, float)
        if self.n_effects:
            x[len(x) - self.n_effects:] += full[self.n_chain:]
        x[:9] = (x[:9].reshape(3, 3) @ matrix_from_rotvec(full[3:6])).ravel()
        x[9:12] += full[:3]
        x[12:15] += full[6:9]
        for j in range(self.n_axes):
            p, d = x[15 + 6 * j:18 + 6 * j], x[18 + 6 * j:21 + 6 * j]
            e1, e2 = normals(d)
            a, b, u, v = full[9 + 4 * j:13 + 4 * j]
            x[15 + 6 * j:18 + 6 * j] = p + u * e1 + v * e2
            x[18 + 6 * j:21 + 6 * j] = unit(d + a * e1 + b * e2)
        return x

    def subset(self, mask):
        """The model of the samples where ``mask`` is true."""
        return dataclasses.replace(self, motions=self.motions[mask], centre_in_sensor=self.centre_in_sensor[mask],
                                   angles=np.asarray(self.angles)[mask])
