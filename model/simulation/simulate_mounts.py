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

from handeye.model.chain.mounts import CELLS, Axis, Mounts, table2base, unit
from handeye.model.chain.pose import transform_from_pose
from handeye.model.common.rotation import matrix_from_rotvec
from handeye.model.readers.mount_setup import _AXIS_NAME, MAX_AXES, RESERVED
from handeye.model.simulation.simulate import SimulationError, flanges_for_views, random_view, thesis_orientations

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


def _error(message):
    return SimulationError(message)


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
        """:func:`cell_poses` of this cell (what :func:`handeye.model.simulation.simulate.simulate` calls)."""
        return cell_poses(self, setup, rng, centre, n_poses)

    def toml_parts(self):
        """:func:`toml_parts` of this cell."""
        return toml_parts(self)

    def describe(self):
        """:func:`describe` of this cell."""
        return describe(self)


def check_pair(sensor, sphere):
    """Raise SimulationError (one line naming the options) unless the pair is an observable cell."""
    if (sensor, sphere) not in CELLS:
        pairs = ", ".join(f"{a}/{b}" for a, b in CELLS)
        raise _error(f"--sensor-mount {sensor} with --sphere-mount {sphere} is no observable cell "
                     f"(nothing moves the sensor against the sphere); use one of {pairs}")


def parse_axes(text):
    """``'NAME:px,py,pz:dx,dy,dz;NAME:...'`` (robot base at zero angles, mm) -> tuple of Axis."""
    out = []
    for part in [p.strip() for p in str(text).split(";") if p.strip()]:
        fields = part.split(":")
        if len(fields) != 3:
            raise _error(f"--positioner-axes {part!r}: expected NAME:px,py,pz:dx,dy,dz")
        name = fields[0].strip()
        if not _AXIS_NAME.match(name) or name.lower() in RESERVED or name in [a.name for a in out]:
            raise _error(f"--positioner-axes: {name!r} is no usable column name (letters, digits, _; unique; "
                         "not a pose or centre column)")
        try:
            point, direction = (np.array([float(v) for v in f.split(",")]) for f in fields[1:])
        except ValueError:
            raise _error(f"--positioner-axes {part!r}: not a number") from None
        if point.shape != (3,) or direction.shape != (3,) or not np.all(np.isfinite(np.r_[point, direction])) \
                or np.linalg.norm(direction) < 1e-9:
            raise _error(f"--positioner-axes {part!r}: needs three finite numbers each and a nonzero direction")
        out.append(Axis(name, point, unit(direction)))
    if not 1 <= len(out) <= MAX_AXES:
        raise _error(f"--positioner-axes: give 1 to {MAX_AXES} axes, got {len(out)}")
    return tuple(out)


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
    """A :class:`Cell`; the true axes drawn from ``seed`` (their own stream: the poses do not
    depend on ``error``). ``axes`` (nominal, default :data:`POSITIONER_AXES`) and ``error``
    (mm, deg) apply to a positioner only."""
    check_pair(sensor, sphere)
    if sphere != "positioner":
        if axes is not None:
            raise _error("--positioner-axes needs --sphere-mount positioner")
        return Cell(sensor, sphere)
    nominal = POSITIONER_AXES if axes is None else tuple(axes)
    error_mm, error_deg = (float(v) for v in error)
    if not (0 <= error_mm <= 100 and 0 <= error_deg <= 10):
        raise _error(f"--positioner-error must lie in 0..100 mm and 0..10 deg, got {error_mm:g},{error_deg:g}")
    return Cell(sensor, sphere, nominal, perturb_axes(nominal, error_mm, error_deg, np.random.default_rng([seed, 7])))


def default_truth(cell):
    """(sensor pose KUKA in its mount's frame or None, sphere centre in its mount's frame or None):
    this mount's defaults, None where the seed's default applies."""
    pose = WORLD_SENSOR if cell.sensor == "world" else None
    centre = {"flange": FLANGE_SPHERE, "positioner": TABLE_SPHERE}.get(cell.sphere)
    return pose, centre


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


def cell_poses(cell, setup, rng, centre, n_poses):
    """The default strategy for a cell other than the seed's: ids, true flanges (N, 4, 4) and
    axis angles (N, k) or None (module docstring)."""
    ids, rots = zip(*thesis_orientations(n_poses, setup.max_tilt_deg))
    seen_at = np.array([random_view(setup, rng) for _ in rots])
    angles = draw_axis_angles(len(ids), len(cell.true_axes), rng) if cell.sphere == "positioner" else None
    return list(ids), flanges_for_cell(cell.mounts, setup, np.array(rots), seen_at, centre, angles), angles


def _axes_toml(axes):
    def vec(v):
        return "[" + ", ".join(f"{float(a)!r}" for a in v) + "]"

    rows = [f'  {{ name = "{a.name}", point = {vec(a.point)}, direction = {vec(a.direction)} }}' for a in axes]
    return "[\n" + ",\n".join(rows) + ",\n]"


def toml_parts(cell):
    """(``[sensor]`` lines, ``[sphere]`` lines, ``[positioner]`` section, ``[truth]`` lines) to add
    to a simulated ``setup.toml`` for this cell; empty strings for the seed's cell."""
    if cell.default:
        return "", "", "", ""
    sensor = f'mount = "{cell.sensor}"\n' if cell.sensor != "flange" else ""
    sphere = f'mount = "{cell.sphere}"\n'
    if cell.sphere != "positioner":
        return sensor, sphere, "", ""
    return sensor, sphere, f"[positioner]\naxes = {_axes_toml(cell.nominal_axes)}\n\n", \
        f"axes = {_axes_toml(cell.true_axes)}\n"


def describe(cell):
    """The cell for ``simulation.json``: mounts and (positioner) nominal and true axes."""
    return {"sensor_mount": cell.sensor, "sphere_mount": cell.sphere,
            "nominal_axes": [a.to_dict() for a in cell.nominal_axes],
            "true_axes": [a.to_dict() for a in cell.true_axes]}
