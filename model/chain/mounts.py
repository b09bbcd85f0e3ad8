"""Where the sensor and the sphere are mounted, and the one chain every mount reduces to.

Three cells are observable (the sensor must move relative to the sphere):

=================  ==================  ======================================================
sensor mount       sphere mount        the chain of sample i (mm)
=================  ==================  ======================================================
``flange``         ``world``           ``flange2base_i . sensor2flange . xs_i = c_base``
``world``          ``flange``          ``sensor2base . xs_i = flange2base_i . c_flange``
``flange``         ``positioner``      ``flange2base_i . sensor2flange . xs_i = table2base(th_i) . c_table``
=================  ==================  ======================================================

Each is one equation of the seed's form (4-3), ``M_i . X . xs_i = c``, with a *carrier motion*
``M_i`` known from the robot (and the positioner), ``X`` the sensor frame in its mount's frame
and ``c`` the sphere centre in its mount's frame:

* sensor on the flange, sphere in the world: ``M_i = flange2base_i`` (the seed's cell).
* sensor in the world, sphere on the flange: multiply by ``base2flange_i``:
  ``base2flange_i . sensor2base . xs_i = c_flange``, so ``M_i = inv(flange2base_i)``. The roles of
  base and flange are exchanged; the residual is the seed's rotated into the flange frame, with the
  same length, so the least-squares problem is the same (cost, minimum and covariance).
* sphere on the positioner: multiply by ``base2table(th_i)``: ``M_i = inv(table2base(th_i)) .
  flange2base_i`` and ``c = c_table``, the centre in the table frame (equal to the base frame at
  zero axis angles).

So every stage of a calibration (closed form, global check, screening, fits, leave-one-out, slips,
diagnose) works on ``M_i`` (:meth:`handeye.model.datasets.dataset.Dataset.motions`) without knowing the
mount. Only the positioner's own axes, when they are unknown, need more than this reduction: the
cell model (:mod:`handeye.model.fit.cell`) adds them to the chain.

Positioner kinematics (product of exponentials)
-----------------------------------------------
Axis ``j`` has a point ``p_j`` and a unit direction ``d_j`` in the base frame at all axis angles
zero, and turns a point by ``th_j`` (degrees, right hand about ``d_j``)::

    A_j(th) x = R(d_j, th) (x - p_j) + p_j,        table2base(th) = A_1(th_1) A_2(th_2) ...

with the axes listed base first (``axes[1]`` is carried by ``axes[0]``). Parallel or intersecting
axes need no special case (no Denavit-Hartenberg singularity).
"""
from __future__ import annotations

import dataclasses

import numpy as np

from handeye.model.chain.names import SENSOR_MOUNTS, SPHERE_MOUNTS  # noqa: F401  (named once, where nothing is imported)
from handeye.model.common.rotation import matrix_from_rotvec

#: The observable combinations, (sensor mount, sphere mount) -> a sentence for reports.
CELLS = {
    ("flange", "world"): "sensor on the flange, sphere fixed in the robot's base frame",
    ("world", "flange"): "sensor fixed in the robot's base frame, sphere carried on the flange",
    ("flange", "positioner"): "sensor on the flange, sphere on the positioner's table",
}
#: Frame names of each mount, as the results say them.
FRAME = {"flange": "flange", "world": "robot base", "positioner": "positioner table"}


@dataclasses.dataclass(frozen=True)
class Axis:
    """One revolute positioner axis at all axis angles zero, robot base frame.

    Attributes
    ----------
    name : str
        The ``measurements.csv`` column holding its angle (degrees).
    point : ndarray, shape (3,)
        A point on the axis, mm, robot base.
    direction : ndarray, shape (3,)
        Unit direction, robot base.
    """

    name: str
    point: np.ndarray
    direction: np.ndarray

    def to_dict(self):
        return {"name": self.name, "point": [float(v) for v in self.point],
                "direction": [float(v) for v in self.direction]}


@dataclasses.dataclass(frozen=True)
class Mounts:
    """Mounts of a cell (module docstring).

    Attributes
    ----------
    sensor : {'flange', 'world'}
    sphere : {'world', 'flange', 'positioner'}
    axes : tuple of Axis
        The positioner's axes, base first (nominal unless calibrated); empty without a positioner.
    """

    sensor: str = "flange"
    sphere: str = "world"
    axes: tuple = ()

    @property
    def default(self):
        """The seed's cell: sensor on the flange, sphere fixed in the base frame."""
        return self.sensor == "flange" and self.sphere == "world"

    @property
    def axis_names(self):
        return tuple(a.name for a in self.axes)

    def describe(self):
        """The cell in words."""
        return CELLS[(self.sensor, self.sphere)]

    def with_axes(self, points, directions):
        """The same mounts with other axis points (k, 3) and directions (k, 3)."""
        axes = tuple(Axis(a.name, np.asarray(p, float), unit(d)) for a, p, d in zip(self.axes, points, directions))
        return dataclasses.replace(self, axes=axes)

    def at(self, axes):
        """The same mounts at the geometry of ``axes`` (a calibration's: the same names, in order)."""
        return self.with_axes([a.point for a in axes], [a.direction for a in axes])


def unit(v):
    """``v / |v|`` for a 3-vector (scaled by its largest component first: no overflow)."""
    v = np.asarray(v, float)
    v = v / np.abs(v).max()
    return v / np.linalg.norm(v)


def table2base(axes, angles_deg):
    """The positioner table's pose in the robot base at each row of axis angles.

    Parameters
    ----------
    axes : sequence of Axis
        Base first.
    angles_deg : array_like, shape (N, k)
        Axis angles, degrees, one column per axis.

    Returns
    -------
    ndarray, shape (N, 4, 4)
        ``A_1(th_1) A_2(th_2) ...`` (module docstring), mm.
    """
    th = np.radians(np.asarray(angles_deg, float)).reshape(-1, len(axes))
    out = np.broadcast_to(np.eye(4), (len(th), 4, 4)).copy()
    for j, axis in enumerate(axes):
        a = np.broadcast_to(np.eye(4), (len(th), 4, 4)).copy()
        rot = matrix_from_rotvec(unit(axis.direction)[None, :] * th[:, j:j + 1])
        a[:, :3, :3] = rot
        a[:, :3, 3] = axis.point - rot @ axis.point
        out = out @ a
    return out


def inverse_transforms(t):
    """Inverses of rigid transforms, shape (..., 4, 4)."""
    t = np.asarray(t, float)
    out = np.zeros_like(t)
    rt = np.swapaxes(t[..., :3, :3], -1, -2)
    out[..., :3, :3] = rt
    out[..., :3, 3] = -(rt @ t[..., :3, 3, None])[..., 0]
    out[..., 3, 3] = 1.0
    return out


def motions(flange2base, mounts, axis_angles=None):
    """The carrier motions ``M_i`` of the chain ``M_i X xs_i = c`` (module docstring).

    Parameters
    ----------
    flange2base : array_like, shape (N, 4, 4)
        Flange poses in the robot base, mm.
    mounts : Mounts
    axis_angles : array_like, shape (N, k), optional
        Positioner axis angles, degrees (sphere on the positioner).

    Returns
    -------
    ndarray, shape (N, 4, 4)
        ``flange2base``, its inverse, or ``inv(table2base) flange2base``.
    """
    f2b = np.asarray(flange2base, float)
    if mounts.sensor == "world":
        return inverse_transforms(f2b)
    if mounts.sphere == "positioner":
        return inverse_transforms(table2base(mounts.axes, axis_angles)) @ f2b
    return f2b


def sphere_in_base(mounts, centre, flange2base=None, axis_angles=None):
    """The sphere centre in the robot base at each sample (N, 3), mm, from its mount's frame."""
    c = np.append(np.asarray(centre, float), 1.0)
    if mounts.sphere == "flange":
        return (np.asarray(flange2base, float) @ c)[..., :3]
    if mounts.sphere == "positioner":
        return (table2base(mounts.axes, axis_angles) @ c)[..., :3]
    return np.broadcast_to(c[:3], (1 if flange2base is None else len(flange2base), 3)).copy()
