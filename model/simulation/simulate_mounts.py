"""Simulated cells of every mount (:mod:`handeye.model.chain.mounts`): where the robot goes so that the
sensor sees the sphere, for a sensor fixed in the cell or a sphere on the flange or a positioner.

:mod:`handeye.model.simulation.simulate` measures (profiles, circle fits, noise, effects) the same way for
every mount; this module only places the robot (and the positioner) and writes the mount's keys.

Cells and their default truths
------------------------------
``flange``/``world`` (the seed's cell)
    :mod:`handeye.model.simulation.simulate`'s thesis strategy, unchanged.
``world``/``flange``: sensor fixed in the cell, sphere on the flange
    Truth: the sensor 1.75 m in front of the robot, 1 m high, looking back at the robot and 20
    degrees down (:data:`WORLD_SENSOR`, robot base); the sphere on a 150 mm stick along the
    flange's z axis (:data:`FLANGE_SPHERE`, flange frame). Each pose puts the sphere at a random
    point of the sensor's view (the simulator's ``VIEW``) with the flange turned by one of the
    thesis orientations (tilts about four horizontal axes). Occlusion by the stick or the robot is
    not modelled.
``flange``/``positioner``: sensor on the flange, sphere on a positioner's table
    Nominal positioner (:data:`POSITIONER_AXES`, KUKA KP1-V-like, robot base at zero angles):
    ``e1`` a horizontal tilt axis 1.5 m in front of the robot, 600 mm high, along the base's y;
    ``e2`` the table's rotation axis, vertical at zero angles, through the table centre. The
    sphere stands 150 mm off ``e2`` and 300 mm above ``e1`` (:data:`TABLE_SPHERE`, table frame =
    robot base at zero angles). Each pose draws the axis angles (:func:`draw_axis_angles`) and
    places the sensor with a thesis orientation so that it sees the sphere where the table puts it.
    The TRUE axes differ from the nominal ones (written in ``[positioner]``) by ``error`` (mm, deg:
    each point moved normal to its axis, each direction tilted, in random directions; written in
    ``[truth] axes``). The axis angles are recorded exactly (no positioner noise).
"""
from __future__ import annotations

import dataclasses

import numpy as np

from handeye.model.chain.mounts import Axis, Mounts, table2base, unit
from handeye.model.chain.pose import transform_from_pose
from handeye.model.common.rotation import matrix_from_rotvec
from handeye.model.simulation.simulate import VIEW, flanges_for_views, random_view, thesis_orientations, toml_vector

#: Default true sensor pose in the robot base for a sensor fixed in the cell (KUKA: mm, degrees):
#: laser line along the base's y, looking back at the robot (-x) and 20 degrees down.
WORLD_SENSOR = (1750.0, -50.0, 1000.0, 90.0, 0.0, -110.0)
#: Default sphere centre in the flange frame for a sphere carried by the robot (mm): a 150 mm stick.
FLANGE_SPHERE = (0.0, 0.0, 150.0)
#: Default nominal positioner axes (robot base at zero angles, mm), KUKA KP1-V-like.
POSITIONER_AXES = (Axis("e1", np.array([1500.0, 0.0, 600.0]), np.array([0.0, 1.0, 0.0])),
                   Axis("e2", np.array([1500.0, 0.0, 800.0]), np.array([0.0, 0.0, 1.0])))
#: Default sphere centre in the positioner's table frame (mm): 150 mm off e2, 300 mm above e1.
TABLE_SPHERE = (1650.0, 0.0, 900.0)
#: Default difference between the true and the nominal axes: mm (points), degrees (directions).
POSITIONER_ERROR = (1.0, 0.2)
#: Angles of a tilt axis (every axis but the last), degrees; the last (the table) turns over the
#: full circle.
TILT_LEVELS = (-45.0, -22.5, 0.0, 22.5, 45.0)


@dataclasses.dataclass(frozen=True)
class Cell:
    """The mounts of a simulated cell, with the positioner's nominal and true axes.

    Attributes
    ----------
    sensor : {'flange', 'world'}
    sphere : {'world', 'flange', 'positioner'}
    nominal_axes, true_axes : tuple of Axis
        Robot base at zero angles; empty without a positioner.
    """

    sensor: str = "flange"
    sphere: str = "world"
    nominal_axes: tuple = ()
    true_axes: tuple = ()

    @property
    def default(self):
        """The seed's cell (sensor on the flange, sphere in the world)."""
        return (self.sensor, self.sphere) == ("flange", "world")

    @property
    def mounts(self):
        """The true cell's :class:`Mounts` (the true axes)."""
        return Mounts(self.sensor, self.sphere, tuple(self.true_axes))

    @property
    def axis_names(self):
        return tuple(a.name for a in self.nominal_axes)

    def poses(self, setup, rng, centre, n_poses):
        """The default strategy for a cell other than the seed's (what
        :func:`handeye.model.simulation.simulate.simulate_rig` calls): ids, true flanges (N, 4, 4) and axis angles
        (N, k) or None (module docstring)."""
        ids, rots = zip(*thesis_orientations(n_poses, setup.max_tilt_deg))
        seen_at = np.array([random_view(setup, rng) for _ in rots])
        angles = draw_axis_angles(len(ids), len(self.true_axes), rng) if self.sphere == "positioner" else None
        return list(ids), flanges_for_cell(self.mounts, setup, np.array(rots), seen_at, centre, angles), angles

    def toml_parts(self):
        """(``[sensor]`` lines, ``[sphere]`` lines, ``[positioner]`` section, ``[truth]`` lines) to add
        to a simulated ``setup.toml`` for this cell; empty strings for the seed's cell."""
        if self.default:
            return "", "", "", ""
        sensor = f'mount = "{self.sensor}"\n' if self.sensor != "flange" else ""
        sphere = f'mount = "{self.sphere}"\n'
        if self.sphere != "positioner":
            return sensor, sphere, "", ""
        return sensor, sphere, f"[positioner]\naxes = {_axes_toml(self.nominal_axes)}\n\n", \
            f"axes = {_axes_toml(self.true_axes)}\n"

    def describe(self):
        """The cell for ``simulation.json``: mounts and (positioner) nominal and true axes."""
        return {"sensor_mount": self.sensor, "sphere_mount": self.sphere,
                "nominal_axes": [a.to_dict() for a in self.nominal_axes],
                "true_axes": [a.to_dict() for a in self.true_axes]}


def perturb_axes(axes, error_mm, error_deg, rng):
    """True axes: each point moved ``error_mm`` normal to its axis, each direction tilted by
    ``error_deg``, both in random directions (robot base, mm, degrees)."""
    out = []
    for axis in axes:
        d = unit(axis.direction)
        normals = [unit(np.cross(d, v)) for v in rng.normal(size=(2, 3))]
        tilt = matrix_from_rotvec(np.radians(error_deg) * normals[1])
        out.append(Axis(axis.name, axis.point + error_mm * normals[0], unit(tilt @ d)))
    return tuple(out)


def make_cell(sensor="flange", sphere="world", axes=None, error=POSITIONER_ERROR, seed=0):
    """A :class:`Cell` of an observable pair of mounts (:data:`handeye.model.chain.mounts.CELLS`); the true
    axes drawn from ``seed`` (their own stream: the poses do not depend on ``error``). ``axes`` (nominal,
    default :data:`POSITIONER_AXES`) and ``error`` (mm, deg) apply to a positioner only."""
    if sphere != "positioner":
        return Cell(sensor, sphere)
    nominal = POSITIONER_AXES if axes is None else tuple(axes)
    error_mm, error_deg = (float(v) for v in error)
    return Cell(sensor, sphere, nominal, perturb_axes(nominal, error_mm, error_deg, np.random.default_rng([seed, 7])))


def default_truth(cell):
    """(sensor pose KUKA in its mount's frame or None, sphere centre in its mount's frame or None):
    this mount's defaults, None where the seed's default applies."""
    pose = WORLD_SENSOR if cell.sensor == "world" else None
    return pose, {"flange": FLANGE_SPHERE, "positioner": TABLE_SPHERE}.get(cell.sphere)


def placed_at(cell, sensor_pose, sphere_centre, target, side=-1):
    """The cell moved so that its sphere works at ``target`` (robot base, mm; a robot's reachable point):
    ``(cell, sensor_pose, sphere_centre)``. A sensor fixed in the cell keeps its orientation and moves so
    that the middle of its view (the simulator's ``VIEW``) lies at ``target``; a positioner's axes (nominal
    and true) and its table's sphere move together by the table sphere's offset from ``target``; the seed's
    cell takes ``target`` as its sphere centre. ``sensor_pose`` (KUKA) and ``sphere_centre``: the cell's
    defaults (:func:`default_truth`)."""
    target = np.asarray(target, float)
    if cell.sensor == "world":
        view = np.array([np.mean(VIEW[0]), side * np.mean(VIEW[1]), np.mean(VIEW[2])])
        pose = transform_from_pose(sensor_pose)
        return cell, (*(target - pose[:3, :3] @ view), *sensor_pose[3:]), sphere_centre
    if cell.sphere == "positioner":
        shift = target - np.asarray(sphere_centre, float)
        moved = [tuple(Axis(a.name, a.point + shift, a.direction) for a in axes) for axes in (cell.nominal_axes, cell.true_axes)]
        return dataclasses.replace(cell, nominal_axes=moved[0], true_axes=moved[1]), sensor_pose, tuple(target)
    return cell, sensor_pose, tuple(target)


def draw_axis_angles(n, k, rng):
    """Axis angles (n, k), degrees: every axis but the last at :data:`TILT_LEVELS` (cycled, then
    shuffled: each level about equally often), the last uniform over [-180, 180)."""
    out = np.empty((n, k))
    for j in range(k - 1):
        out[:, j] = rng.permutation(np.resize(TILT_LEVELS, n))
    out[:, k - 1] = rng.uniform(-180.0, 180.0, n)
    return out


def flanges_for_cell(mounts, setup, rotations, seen_at, centre, angles=None):
    """Flange poses (N, 4, 4) that show the sphere at ``seen_at`` (N, 3; sensor frame, mm).

    Parameters
    ----------
    mounts : Mounts
        With the true axes for a positioner.
    setup : handeye.model.simulation.simulate.Setup
        Its ``sensor_pose`` is the true sensor pose in its mount's frame.
    rotations : ndarray, shape (N, 3, 3)
        The sensor's rotation in the robot base (sensor on the flange), or the flange's (sensor
        fixed in the cell).
    centre : array_like, shape (3,)
        The true sphere centre in its mount's frame, mm.
    angles : ndarray, shape (N, k), optional
        Positioner axis angles, degrees.
    """
    rotations, seen_at = np.asarray(rotations, float), np.asarray(seen_at, float)
    centre = np.asarray(centre, float)
    if mounts.sensor == "world":  # the sphere where the fixed sensor sees it; the flange turned about it
        at = (transform_from_pose(setup.sensor_pose) @ np.c_[seen_at, np.ones(len(seen_at))].T).T[:, :3]
        out = np.tile(np.eye(4), (len(at), 1, 1))
        out[:, :3, :3] = rotations
        out[:, :3, 3] = at - rotations @ centre
        return out
    if mounts.sphere == "positioner":
        centre = (table2base(mounts.axes, angles) @ np.append(centre, 1.0))[:, :3]
    return flanges_for_views(setup, rotations, seen_at, centre)


def _axes_toml(axes):
    rows = [f'  {{ name = "{a.name}", point = {toml_vector(a.point)}, direction = {toml_vector(a.direction)} }}'
            for a in axes]
    return "[\n" + ",\n".join(rows) + ",\n]"
