"""A realistic simulator of the thesis's cell: robot, laser-line sensor, certified sphere.

Ground truth: the sensor pose on the flange (``sensor_pose``) and the sphere centre in the
robot base. For each measurement the sensor is placed so that its laser plane cuts the
sphere; the flange pose follows from the truth, the robot records it with repeatability noise,
the sensor records a profile of the cut circle, and the centre is reconstructed from the
profile as the seed does (circle fit, ``y = side sqrt(R^2 - r^2)``).

Pose strategies
---------------
``thesis`` (seed 6.4.2): the sensor looks down at the sphere; its orientation is turned about
the base axes x and y and about x*, y* (x, y turned by alpha = 45 deg about z) by
``22.5 deg * n``, ``n = -4..4``: up to 36 poses (``n_poses`` keeps an evenly spread subset).
An operator never places the sphere at the same spot of the sensor's view twice, and neither
does this simulator: the centre is seen at x ~ U(-10, 10) mm, |y| ~ U(3, 20) mm on the
``side`` of the laser plane, z ~ U(210, 270) mm (inside the 190-290 mm measuring range).
A custom list of flange poses can be given instead.

Noise model (documented assumptions)
------------------------------------
* Robot: the recorded flange position differs from the true one by N(0, sigma_robot) per axis,
  sigma_robot = 0.025 mm (the KR 60 HA's +-0.05 mm repeatability read as 2 sigma).
* Sensor: 1280 points over a 100 mm line (sensor x in [-50, 50] mm); the near side of the cut
  circle is seen where the surface is inclined less than 75 deg to the line of sight and z
  lies in 190-290 mm. Each point's z gets N(0, sigma_point), sigma_point = 0.01 mm, and,
  when ``linearity`` is set, a linearity error ``linearity * 100 mm * sin(2 pi (z - 190) / 100)``
  (the data sheet's worst case is 0.0016, +-0.16 % of the range). It is off by default: it is
  a systematic error, not noise, and biases a calibration by up to millimetres.
* Sphere: the certified diameter 59.94507 mm (C11).

Effects that can be hidden in the data (parameters zero when absent)
--------------------------------------------------------------------
* ``sphere_center=dx,dy,dz``: the true centre is the setup's plus (dx, dy, dz) mm (base frame).
* ``sensor_scale=s``: the sensor's coordinates are scaled by 1 + s.
* ``sphere_radius=dr``: the true radius exceeds the setup's by dr mm. Where the fitted circle
  then exceeds the setup's radius (a cut within ``sqrt(2 R dr)`` of the equator) no centre can
  be reconstructed; like a real pipeline, the simulator drops the sample and lists it in
  ``simulation.json`` under ``dropped``.
* ``sign_flip=ID,ID...``: the centre of these samples is reconstructed on the wrong side.
* ``outlier=ID,ID...``: a gross error of 30 mm in a random direction is added to these
  samples' centres.
* ``joint_offsets=j2:0.05,j3:-0.03`` (degrees, needs a robot model): the robot's joints are off
  by these; the flange reaches ``T(q + delta)``, the controller reports ``T(q)`` and ``q``
  (:mod:`handeye.model.simulation.simulate_robot`).
* ``link_lengths=a2:0.3,d4:-0.2`` (mm, needs a robot model): errors of its nominal lengths,
  named as :func:`handeye.model.robot.robot_errors.param_names` names them (``a2``, ``d4`` of a DH model,
  ``j3_x`` of a chain model).
* ``joint_compliance=j2:0.02,j3:0.01`` (degrees per metre of lever, needs a robot model): gravity
  deflection of the shoulder and the elbow (:mod:`handeye.model.robot.robot_errors`).
"""
from __future__ import annotations

import dataclasses
import json
import pathlib

import numpy as np

from handeye.model.chain import mounts as mount_model
from handeye.model.chain.pose import pose_from_transform, transform_from_pose
from handeye.model.common.errors import InputError
from handeye.model.common.rotation import matrix_from_rotvec
from handeye.model.geometry import circle

#: Where the thesis strategy sees the sphere centre in the sensor frame (mm): x, |y| on the
#: setup's side of the laser plane, z (module docstring).
VIEW = ((-10.0, 10.0), (3.0, 20.0), (210.0, 270.0))

EFFECTS = ("sphere_center", "sensor_scale", "sphere_radius", "sign_flip", "outlier", "joint_offsets", "link_lengths",
           "joint_compliance")
#: Effects of the robot's own kinematics (need a robot with joints); the first is six numbers, the
#: others ``{parameter: value}`` (:mod:`handeye.model.robot.robot_errors`).
ROBOT_EFFECTS = ("joint_offsets", "link_lengths", "joint_compliance")
CERTIFIED_DIAMETER = 59.94507
#: Joint-angle columns of a simulation with a robot (degrees; :data:`handeye.model.robot.robots.JOINTS`).
JOINT_COLUMNS = ("j1", "j2", "j3", "j4", "j5", "j6")
THESIS_CENTRE = (1534.1314, -603.2729, 1118.8028)


class SimulationError(InputError):
    """A simulation request that cannot be carried out (bad effect, pose missing the sphere)."""


@dataclasses.dataclass(frozen=True)
class Setup:
    """Ground truth and noise levels of a simulation (module docstring for their meaning)."""

    sensor_pose: tuple = (190.0, 100.0, 125.0, 180.0, -88.0, 0.0)
    sphere_centre: tuple = THESIS_CENTRE
    diameter: float = CERTIFIED_DIAMETER
    side: int = -1
    sigma_robot: float = 0.025
    sigma_point: float = 0.01
    linearity: float = 0.0
    n_points: int = 1280
    line_length: float = 100.0
    z_range: tuple = (190.0, 290.0)
    max_incidence_deg: float = 75.0
    circle_fit: str = "hyper"
    max_tilt_deg: float = 90.0


def robot_errors(effects, model):
    """The robot effects among ``effects`` as full parameter vectors of ``model``
    (:func:`handeye.model.robot.robot_errors.perturbed`'s ``values``); raises SimulationError naming a
    parameter the model does not have."""
    from handeye.model.robot.robot_errors import param_names

    values = {}
    for name in ROBOT_EFFECTS:
        if name not in effects:
            continue
        names = param_names(model, name)
        if name == "joint_offsets":
            values[name] = np.asarray(effects[name], float)
            continue
        unknown = sorted(set(effects[name]) - set(names))
        if unknown:
            raise SimulationError(f"{name}: {', '.join(unknown)} not a parameter of the {model.name}; "
                                  f"its parameters are {', '.join(names)}")
        values[name] = np.array([effects[name].get(n, 0.0) for n in names])
    return values


def _axis(name):
    c = np.cos(np.radians(45.0))
    return {"x": np.array([1.0, 0, 0]), "y": np.array([0, 1.0, 0]),
            "x*": np.array([c, c, 0]), "y*": np.array([-c, c, 0])}[name]


def thesis_orientations(n_poses=36, max_tilt_deg=90.0):
    """(id, sensor-to-base rotation) of the seed's strategy; an evenly spread subset of n_poses.

    The seed tilts the sensor about four horizontal axes in steps of 22.5 degrees up to +-90
    (the flange then points sideways, and for some mounts below the sphere); ``max_tilt_deg``
    spreads the nine tilts of each axis over +-max_tilt_deg instead (ids keep the seed's step
    names only at the default).
    """
    if not 0.0 < max_tilt_deg <= 90.0:
        raise SimulationError(f"max_tilt_deg must lie in (0, 90] degrees, got {max_tilt_deg}")
    items = []
    for name in ("x", "y", "x*", "y*"):
        u = _axis(name)
        z_s = np.array([0.0, 0.0, -1.0])
        base = np.column_stack([u, np.cross(z_s, u), z_s])
        for n in range(-4, 5):
            angle = max_tilt_deg / 4 * n
            items.append((f"{name}{angle:+g}", matrix_from_rotvec(np.radians(angle) * u) @ base))
    if not 1 <= n_poses <= len(items):
        raise SimulationError(f"the thesis strategy has 1 to {len(items)} poses, asked for {n_poses}")
    return [items[k] for k in np.unique(np.round(np.linspace(0, len(items) - 1, n_poses)).astype(int))]


def random_view(setup, rng, size=()):
    """Sphere centres in the sensor frame drawn from :data:`VIEW`, shape ``size + (3,)`` (mm);
    the range of |y| is narrowed to 0.1 R .. 0.7 R for a sphere smaller than the thesis's.

    Draws x, then y, then z (each of ``size``) from ``rng``.
    """
    (x0, x1), (y0, y1), (z0, z1) = VIEW
    radius = setup.diameter / 2  # the laser plane must cut the sphere: |y| well inside R for any sphere
    y0, y1 = min(y0, 0.1 * radius), min(y1, 0.7 * radius)
    return np.stack([rng.uniform(x0, x1, size), setup.side * rng.uniform(y0, y1, size), rng.uniform(z0, z1, size)],
                    axis=-1)


def flanges_for_views(setup, rotations, seen_at, centre=None):
    """Flange poses that show the sphere at ``seen_at`` with the sensor rotated by ``rotations``.

    Parameters
    ----------
    setup : Setup
        Its ``sensor_pose`` (the true sensor pose on the flange) and, unless ``centre`` is
        given, its ``sphere_centre``.
    rotations : ndarray, shape (..., 3, 3)
        Sensor rotations in the robot base frame.
    seen_at : ndarray, shape (..., 3)
        Sphere centre in the sensor frame (mm); broadcast against ``rotations``.
    centre : ndarray, shape (3,), optional
        Sphere centre in the base frame (mm).

    Returns
    -------
    ndarray, shape (..., 4, 4)
        Flange frames in the robot base frame (mm).
    """
    centre = np.asarray(setup.sphere_centre if centre is None else centre, float)
    rotations, seen_at = np.asarray(rotations, float), np.asarray(seen_at, float)
    sensor = np.tile(np.eye(4), np.broadcast_shapes(rotations.shape[:-2], seen_at.shape[:-1]) + (1, 1))
    sensor[..., :3, :3] = rotations
    sensor[..., :3, 3] = centre - (rotations @ seen_at[..., None])[..., 0]
    return sensor @ np.linalg.inv(transform_from_pose(setup.sensor_pose))


def profile_points(centre_in_sensor, radius, setup, rng):
    """Noisy laser-line points (K, 2) of a sphere whose centre is at ``centre_in_sensor``."""
    sx, sy, sz = centre_in_sensor
    if abs(sy) >= radius:
        raise SimulationError(f"the laser plane misses the sphere (|y| = {abs(sy):.1f} mm >= R = {radius:.1f} mm)")
    rho = np.sqrt(radius**2 - sy**2)
    x = np.linspace(-setup.line_length / 2, setup.line_length / 2, setup.n_points)
    u = (x - sx) / rho
    seen = np.abs(u) < np.sin(np.radians(setup.max_incidence_deg))
    x = x[seen]
    z = sz - rho * np.sqrt(1.0 - u[seen] ** 2)
    lo, hi = setup.z_range
    z = z + setup.linearity * (hi - lo) * np.sin(2 * np.pi * (z - lo) / (hi - lo))
    z = z + rng.normal(0.0, setup.sigma_point, z.shape)
    inside = (z >= lo) & (z <= hi)
    if inside.sum() < 10:
        raise SimulationError(f"fewer than 10 profile points inside the measuring range {lo:g}-{hi:g} mm")
    return np.column_stack([x[inside], z[inside]])


@dataclasses.dataclass
class Simulation:
    """A simulated dataset before it is written (all lengths mm, angles deg)."""

    ids: list
    flange_poses: np.ndarray
    centre_in_sensor: np.ndarray
    profiles: list
    setup: Setup
    effects: dict
    true_centre: np.ndarray
    seed: int
    dropped: list = dataclasses.field(default_factory=list)
    cell: object = None
    axis_angles: np.ndarray | None = None
    joints: np.ndarray | None = None
    robot: object = None


def centre_in_sensor(mounts, t_x, centre, flange, table=None):
    """The sphere centre in the sensor frame (3,), mm, from the true chain of one sample.

    ``t_x`` is the sensor in its mount's frame (4x4), ``centre`` the centre in its mount's frame,
    ``flange`` the true flange pose (4x4), ``table`` the true table pose (4x4, positioner).
    """
    sensor2base = flange @ t_x if mounts.sensor == "flange" else t_x
    c = np.append(centre, 1.0)
    if mounts.sphere == "flange":
        c = flange @ c
    elif mounts.sphere == "positioner":
        c = table @ c
    return np.linalg.solve(sensor2base, c)[:3]


@dataclasses.dataclass(frozen=True)
class _Sensor:
    """The simulated sensor: its ``setup``, the hidden ``effects``, the random generator and the true sphere radius."""

    setup: Setup
    effects: dict
    rng: np.random.Generator
    radius_true: float

    def measure(self, ident, k, in_sensor):
        """The centre the sensor reports for pose ``ident`` (number k from 0) whose true sphere
        centre is at ``in_sensor`` (sensor frame, mm): ``(xs, profile points)``, or ``(None, reason)``
        when no centre can be reconstructed (module docstring: ``sphere_radius``)."""
        setup, effects, rng = self.setup, self.effects, self.rng
        radius_setup = setup.diameter / 2
        try:
            pts = profile_points(in_sensor, self.radius_true, setup, rng) * (1.0 + effects.get("sensor_scale", 0.0))
        except SimulationError as exc:
            raise SimulationError(f"pose {ident} (number {k + 1}): {exc}") from None
        side = -setup.side if ident in effects.get("sign_flip", []) else setup.side
        fitted = circle.fit_circle(pts[:, 0], pts[:, 1], setup.circle_fit)
        if fitted.r >= radius_setup:
            # a hidden radius effect makes the circle larger than the setup's sphere near the
            # equator: no real y; a real pipeline loses such a sample, and so does this one
            return None, f"fitted circle radius {fitted.r:.3f} mm >= setup radius {radius_setup:.3f} mm"
        xs = circle.sphere_centre_from_circle(fitted, radius_setup, side)
        if ident in effects.get("outlier", []):
            direction = rng.normal(size=3)
            xs = xs + 30.0 * direction / np.linalg.norm(direction)
        return xs, pts


@dataclasses.dataclass(frozen=True)
class Poses:
    """The poses of a simulation: the caller's flange poses or the cell's default strategy.

    Attributes
    ----------
    flange_poses : array_like, shape (N, 6), optional
        Custom flange poses (KUKA); None: the cell's default strategy of ``n`` thesis orientations.
    ids : list of str, optional
        Ids of custom poses (default ``p1, p2, ...``).
    axis_angles : array_like, shape (N, k), optional
        Positioner axis angles (degrees) of custom poses.
    joints : array_like, shape (N, 6), optional
        With a robot: the joint angles of custom poses (degrees, a planned pose list's), used instead
        of the inverse kinematics (the other wrist stays the other wrist).
    n : int
        Poses of the default strategy (1..36).
    """

    flange_poses: object = None
    ids: object = None
    axis_angles: object = None
    joints: object = None
    n: int = 36


def _poses(setup, rng, centre, poses, cell):
    """(ids, true flanges (N, 4, 4), axis angles (N, k) or None) of a simulation's :class:`Poses`."""
    if poses.flange_poses is not None:
        true_flanges = transform_from_pose(np.asarray(poses.flange_poses, float))
        out_ids = list(poses.ids) if poses.ids is not None else [f"p{k + 1}" for k in range(len(true_flanges))]
        if cell is not None and cell.sphere == "positioner":
            axis_angles = poses.axis_angles
            if axis_angles is None or np.shape(axis_angles) != (len(true_flanges), len(cell.true_axes)):
                raise SimulationError(f"custom poses on a positioner need the axis angles ({', '.join(cell.axis_names)})"
                                      " of every pose")
            return out_ids, true_flanges, np.asarray(axis_angles, float)
        return out_ids, true_flanges, None
    if cell is not None and not cell.default:
        return cell.poses(setup, rng, centre, poses.n)
    out_ids, rots = zip(*thesis_orientations(poses.n, setup.max_tilt_deg))
    seen_at = np.array([random_view(setup, rng) for _ in rots])
    return out_ids, flanges_for_views(setup, np.array(rots), seen_at, centre), None


def simulate(setup=Setup(), seed=0, effects=None, flange_poses=None, n_poses=36, ids=None):
    """Simulate a dataset of the seed's cell (module docstring): :func:`simulate_rig` with the poses
    ``Poses(flange_poses, ids, n=n_poses)``.

    Parameters
    ----------
    setup : Setup
        ``sensor_pose`` and ``sphere_centre`` are the truth in their mounts' frames.
    seed : int
        Seed of ``np.random.default_rng``; the same seed gives the same dataset.
    effects : dict, optional
        Hidden effects (module docstring): ``{'sphere_center': [dx, dy, dz], 'sensor_scale': s,
        'sphere_radius': dr, 'sign_flip': [id, ...], 'outlier': [id, ...]}``, with a robot also
        ``'joint_offsets'`` (six degrees) and ``'link_lengths'``, ``'joint_compliance'``
        (``{parameter: value}``); ``sphere_center`` offsets the centre in its mount's frame.
    flange_poses : array_like, shape (N, 6), optional
        Custom flange poses (KUKA) instead of the thesis strategy.
    n_poses : int
        Poses of the thesis strategy (1..36).
    ids : list of str, optional
        Ids of custom poses (default ``p1, p2, ...``).
    """
    return simulate_rig(setup, seed, effects, Poses(flange_poses, ids, n=n_poses))


def simulate_rig(setup=Setup(), seed=0, effects=None, poses=Poses(), cell=None, robot=None):
    """Simulate a dataset of any cell (module docstring): :func:`simulate`'s ``setup``, ``seed`` and
    ``effects``, the :class:`Poses`, the mounts and a robot with joints.

    ``cell`` is a :class:`handeye.model.simulation.simulate_mounts.Cell` (None: the seed's cell, sensor on the
    flange, sphere in the base; its ``poses`` makes the default poses of another cell), ``robot`` a
    :class:`handeye.model.simulation.simulate_robot.Robot` (or None): each flange pose is reached by the nominal
    inverse kinematics (unreachable poses are dropped), the dataset gets the joint angles, and the robot
    effects move the true flange.
    """
    rng = np.random.default_rng(seed)
    effects = dict(effects or {})
    t_x = transform_from_pose(setup.sensor_pose)
    radius_true = setup.diameter / 2 + effects.get("sphere_radius", 0.0)
    centre = np.asarray(setup.sphere_centre, float) + np.asarray(effects.get("sphere_center", [0, 0, 0]), float)
    out_ids, true_flanges, angles = _poses(setup, rng, centre, poses, cell)
    reported, joints, unreached = true_flanges, None, {}
    if robot is not None:
        joints, reported, true_flanges, unreached = robot.reach(true_flanges, robot_errors(effects, robot.model), poses.joints)
    elif any(name in effects for name in ROBOT_EFFECTS):
        raise SimulationError(f"{next(n for n in ROBOT_EFFECTS if n in effects)} needs a robot with joints")
    mounts = mount_model.Mounts() if cell is None else cell.mounts
    tables = None if angles is None else mount_model.table2base(mounts.axes, angles)
    for name in ("sign_flip", "outlier"):
        unknown = sorted(set(effects.get(name, [])) - set(out_ids))
        if unknown:
            raise SimulationError(f"effect {name}: unknown sample id(s) {unknown}; ids are {', '.join(out_ids)}")
    recorded, centres, profiles, kept, dropped, kept_k = [], [], [], [], [], []
    sensor = _Sensor(setup, effects, rng, radius_true)
    for k, (ident, flange) in enumerate(zip(out_ids, true_flanges)):
        if k in unreached:
            dropped.append((ident, unreached[k]))
            continue
        in_sensor = centre_in_sensor(mounts, t_x, centre, flange, None if tables is None else tables[k])
        xs, pts = sensor.measure(ident, k, in_sensor)
        if xs is None:
            dropped.append((ident, pts))
            continue
        noisy = reported[k].copy()
        noisy[:3, 3] += rng.normal(0.0, setup.sigma_robot, 3)
        recorded.append(pose_from_transform(noisy))
        centres.append(xs)
        profiles.append(pts)
        kept.append(ident)
        kept_k.append(k)
    if not kept:  # an empty dataset is not a simulation: say why instead of writing it
        ident, reason = dropped[0]
        raise SimulationError(f"every pose was dropped (first: {ident}: {reason}); check the effects and the setup")
    return Simulation(kept, np.array(recorded), np.array(centres), profiles, setup, effects, centre, seed, dropped,
                      cell, None if angles is None else angles[kept_k], None if joints is None else joints[kept_k], robot)


def toml_vector(v):
    """A vector as TOML's array of floats (every digit: ``repr``)."""
    return "[" + ", ".join(f"{float(a)!r}" for a in v) + "]"


#: The name a robot model file gets in a simulated dataset (setup.toml's ``[robot] model``).
MODEL_FILE = "robot_model.toml"


def _robot_section(convention, robot, folder):
    """setup.toml's ``[robot]`` (empty for KUKA without a robot model). A model file (not a built-in
    name) is copied into the dataset as :data:`MODEL_FILE`, so that the dataset reads it from any
    working folder (a path in setup.toml is the dataset folder's)."""
    from handeye.model.robot import robots

    model = None if robot is None else robot.model_key
    if model is not None and model not in robots.builtin_names():
        (folder / MODEL_FILE).write_bytes(pathlib.Path(robot.model.spec).read_bytes())
        model = MODEL_FILE
    keys = (f"convention = \"{convention}\"\n" if convention != "kuka" else "") \
        + (f"model = \"{model}\"\n" if model is not None else "")
    return f"[robot]\n{keys}\n" if keys else ""


def write(sim, folder, profiles=False, start_offset=(5.0, -5.0, 5.0, 1.0, 1.0, -1.0), convention="kuka"):
    """Write a simulation as a dataset folder (with ``[truth]``) plus ``simulation.json``.

    The setup's start pose is the truth plus ``start_offset`` (a CAD-like guess; None writes
    no start pose, so that a calibration starts from the closed form); the setup's sphere
    centre and diameter are the nominal ones, without hidden effects. ``convention`` is the
    robot convention of the files (:mod:`handeye.model.chain.conventions`): the flange poses, the
    start pose and the true sensor pose are written in it.
    """
    from handeye.model.chain import conventions

    conventions.check(convention)
    folder = pathlib.Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    names = () if sim.axis_angles is None else sim.cell.axis_names
    names += () if sim.joints is None else JOINT_COLUMNS
    header = ",".join(("id",) + conventions.columns(convention) + ("xs", "ys", "zs") + names) \
        + (",profile" if profiles else "")
    lines = [header]
    if profiles:
        (folder / "profiles").mkdir(exist_ok=True)
    angles = [np.concatenate([np.asarray(a, float), np.asarray(j, float)]) for a, j in
              zip(*(v if v is not None else [()] * len(sim.ids) for v in (sim.axis_angles, sim.joints)))]
    for ident, pose, xs, pts, th in zip(sim.ids, sim.flange_poses, sim.centre_in_sensor, sim.profiles, angles):
        safe = ident.replace("*", "s").replace("+", "p").replace("-", "m")
        written = pose if convention == "kuka" else conventions.convert(pose, "kuka", convention)
        row = [ident] + [f"{v:.12g}" if convention != "kuka" else f"{v:.9f}" for v in written] + [f"{v:.9f}" for v in xs]
        row += [f"{v:.9f}" for v in th]
        if profiles:
            name = f"profiles/{safe}.csv"
            np.savetxt(folder / name, pts, fmt="%.9f", delimiter=",", header="x,z", comments="")
            row.append(name)
        lines.append(",".join(row))
    (folder / "measurements.csv").write_text("\n".join(lines) + "\n")
    s = sim.setup

    def as_written(kuka_pose):
        return kuka_pose if convention == "kuka" else conventions.convert(kuka_pose, "kuka", convention)

    default = sim.cell is None or sim.cell.default
    sensor_keys, sphere_keys, positioner, truth_axes = ("",) * 4 if default else sim.cell.toml_parts()
    start = ("" if start_offset is None else
             f"start_pose = {toml_vector(as_written(np.asarray(s.sensor_pose, float) + np.asarray(start_offset, float)))}\n")
    (folder / "setup.toml").write_text(
        f"# simulated by handeye (seed {sim.seed}); see simulation.json\n"
        + _robot_section(convention, sim.robot, folder)
        + (f"[sensor]\n{sensor_keys}{start}\n" if sensor_keys or start else "")
        + f"[sphere]\n{sphere_keys}diameter = {s.diameter!r}\ncenter = {toml_vector(s.sphere_centre)}\n\n"
        + positioner
        + f"[profile]\nside = {s.side}\n\n"
        f"[truth]\nsensor_pose = {toml_vector(as_written(np.asarray(s.sensor_pose, float)))}\n"
        f"sphere_center = {toml_vector(sim.true_centre)}\n" + truth_axes
        + (f"joint_offsets = {toml_vector(sim.effects['joint_offsets'])}\n" if "joint_offsets" in sim.effects else "")
        + "".join(f"{name} = {{ " + ", ".join(f"{k} = {float(v)!r}" for k, v in sim.effects[name].items()) + " }\n"
                  for name in ROBOT_EFFECTS[1:] if name in sim.effects)
    )
    meta = {"seed": sim.seed, "effects": sim.effects, "setup": dataclasses.asdict(s),
            "dropped": [{"id": i, "reason": r} for i, r in sim.dropped],
            "true_sphere_center": sim.true_centre.tolist(), "profiles_written": bool(profiles)}
    if not default:
        meta["cell"] = sim.cell.describe()
    if sim.robot is not None:
        meta["robot"] = sim.robot.describe()
    (folder / "simulation.json").write_text(json.dumps(meta, indent=1) + "\n")
    return folder
