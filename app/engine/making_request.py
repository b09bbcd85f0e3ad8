"""The options of ``simulate`` and ``plan``, validated in one place.

As :mod:`handeye.app.engine.command_request` does for calibrate, diagnose and compare: each
command turns its options (as its public function was given them, ``COMMANDS[name].given``)
into a request here, then runs, then writes: ``load -> *Request.from_options(options) -> run ->
write``. The checks of the option tables run first (:func:`checked_values`), then what only
these commands know (mounts that make a cell, effects and targets, pose lists, the robot), then
what only the files tell (a pose list's joint angles, a dataset's nominal cell). The model
receives resolved values and raises no error naming an option.
"""
from __future__ import annotations

import dataclasses
import pathlib

import numpy as np

from handeye.app.common.arguments import _path_argument, _pose_text, numbers
from handeye.app.common.errors import RequestError
from handeye.app.common.files import check_output_folder, check_output_path
from handeye.app.engine.command_request import checked_values
from handeye.app.engine.request import parse_pose
from handeye.model.chain.mounts import CELLS, Axis, unit
from handeye.model.chain.pose import pose_from_transform, transform_from_pose
from handeye.model.datasets.dataset import Dataset, load_setup
from handeye.model.design import planning, planning_robot
from handeye.model.readers.mount_setup import _AXIS_NAME, MAX_AXES, RESERVED
from handeye.model.readers.setup_file import NOISE_CENTRE_MM, read_setup
from handeye.model.readers.tables import DatasetError, read_pose_list, read_table
from handeye.model.robot import robot_errors, robots
from handeye.model.robot.robots import JOINTS, check_reported
from handeye.model.simulation import motions, simulate_robot
from handeye.model.simulation import simulate as sim
from handeye.model.simulation import simulate_mounts as sm

#: Largest value of a robot effect's parameter that a simulation accepts (degrees, mm, deg/m).
ROBOT_LIMITS = {"joint_offsets": 5.0, "link_lengths": 20.0, "joint_compliance": 1.0}


def _named(name, value):
    """``'a2:0.3,d4:-0.2'`` of the robot effect ``name`` -> ``{'a2': 0.3, 'd4': -0.2}`` (the names are
    checked against the robot model with it, :func:`_simulated_robot`)."""
    out, limit = {}, ROBOT_LIMITS[name]
    for part in (p.strip() for p in str(value).split(",") if p.strip()):
        key, sep, number = part.partition(":")
        try:
            number = float(number)
        except ValueError:
            number = None
        if not sep or not key.strip() or number is None or not np.isfinite(number) or abs(number) > limit:
            raise RequestError(f"--effect {name}={value}: expected PARAMETER:VALUE,... with |VALUE| <= {limit:g}")
        if key.strip() in out:
            raise RequestError(f"--effect {name}={value}: {key.strip()} given twice")
        out[key.strip()] = number
    if not any(out.values()):
        raise RequestError(f"--effect {name}={value}: give at least one non-zero value")
    return out


def _joint_offsets(value):
    """``'j2:0.05,j3:-0.03'`` -> the six joint offsets, degrees."""
    named = _named("joint_offsets", value)
    if set(named) - set(JOINTS):
        raise RequestError(f"--effect joint_offsets={value}: expected JOINT:DEG,... with JOINT one of {', '.join(JOINTS)} "
                           f"and |DEG| <= {ROBOT_LIMITS['joint_offsets']:g}")
    return [named.get(j, 0.0) for j in JOINTS]


def parse_effects(specs):
    """``--effect``'s ``'NAME=VALUE'`` (one text or a sequence: ``['sphere_center=1,2,3', 'sign_flip=a,b']``)
    -> the effects of :func:`handeye.model.simulation.simulate.simulate_rig` (a robot effect given twice adds
    its parameters)."""
    out = {}
    for spec in [specs] if isinstance(specs, str) else list(specs or ()):
        name, sep, value = str(spec).partition("=")
        name = name.strip()
        if not sep or name not in sim.EFFECTS:
            raise RequestError(f"--effect {spec!r}: expected NAME=VALUE with NAME one of {', '.join(sim.EFFECTS)}")
        parts = [p.strip() for p in value.split(",") if p.strip()]
        if name in ("sign_flip", "outlier"):
            if not parts:
                raise RequestError(f"--effect {spec!r}: give one or more sample ids")
            out[name] = parts
        elif name == "joint_offsets":
            out[name] = _joint_offsets(value)
        elif name in sim.ROBOT_EFFECTS:
            named = _named(name, value)
            twice = sorted(set(named) & set(out.get(name, {})))
            if twice:
                raise RequestError(f"--effect {name}: {twice[0]} given twice")
            out[name] = {**out.get(name, {}), **named}
        else:
            values = numbers(value, f"--effect {name}", 3 if name == "sphere_center" else 1)
            out[name] = values if name == "sphere_center" else values[0]
    return out


def _axes(text):
    """``--positioner-axes`` ``'NAME:px,py,pz:dx,dy,dz;NAME:...'`` (robot base at zero angles, mm) -> tuple of Axis."""
    out = []
    for part in [p.strip() for p in str(text).split(";") if p.strip()]:
        fields = part.split(":")
        if len(fields) != 3:
            raise RequestError(f"--positioner-axes {part!r}: expected NAME:px,py,pz:dx,dy,dz")
        name = fields[0].strip()
        if not _AXIS_NAME.match(name) or name.lower() in RESERVED or name in [a.name for a in out]:
            raise RequestError(f"--positioner-axes: {name!r} is no usable column name (letters, digits, _; unique; "
                               "not a pose or centre column)")
        point, direction = (np.array(numbers(f, f"--positioner-axes {part!r}", 3)) for f in fields[1:])
        if np.linalg.norm(direction) < 1e-9:
            raise RequestError(f"--positioner-axes {part!r}: needs a nonzero direction")
        out.append(Axis(name, point, unit(direction)))
    if not 1 <= len(out) <= MAX_AXES:
        raise RequestError(f"--positioner-axes: give 1 to {MAX_AXES} axes, got {len(out)}")
    return tuple(out)


def _positioner(v):
    """``--positioner-axes`` and ``--positioner-error``: (nominal axes or None, error (mm, deg))."""
    given = [flag for flag in ("positioner_error", "positioner_axes") if v[flag] is not None]
    if given and v["sphere_mount"] != "positioner":
        raise RequestError(f"--{given[0].replace('_', '-')} needs --sphere-mount positioner")
    axes = None if v["positioner_axes"] is None else _axes(v["positioner_axes"])
    if v["positioner_error"] is None:
        return axes, sm.POSITIONER_ERROR
    error = numbers(v["positioner_error"], "--positioner-error", 2)
    if not (0 <= error[0] <= 100 and 0 <= error[1] <= 10):
        raise RequestError(f"--positioner-error must lie in 0..100 mm and 0..10 deg, got {error[0]:g},{error[1]:g}")
    return axes, error


def _cell(setup, mounts, axes=None, error=sm.POSITIONER_ERROR, seed=0):
    """The simulated cell of ``mounts`` (sensor, sphere; :func:`~handeye.model.simulation.simulate_mounts.make_cell`)
    and ``setup`` with this cell's default truth."""
    if mounts not in CELLS:
        pairs = ", ".join(f"{a}/{b}" for a, b in CELLS)
        raise RequestError(f"--sensor-mount {mounts[0]} with --sphere-mount {mounts[1]} is no observable cell "
                           f"(nothing moves the sensor against the sphere); use one of {pairs}")
    cell = sm.make_cell(*mounts, axes, error, seed)
    pose, centre = sm.default_truth(cell)
    return cell, _replaced(setup, sensor_pose=pose, sphere_centre=centre)


def _replaced(setup, **given):
    """``setup`` with the values ``given`` that are not None."""
    return dataclasses.replace(setup, **{name: value for name, value in given.items() if value is not None})


def _robot(name, option=True):
    """The robot with joints of a built-in name or model file (``--robot``'s when ``option``)."""
    try:
        return simulate_robot.Robot.load(name)
    except DatasetError as exc:
        raise RequestError(f"--robot {name}: {exc}" if option else str(exc)) from None


def _pose_list(path, axis_names, arm):
    """A pose list: ids, KUKA poses (N, 6), the positioner's axis angles (N, k) or None, and, when its
    header ends with j1..j6 (a robot plan's; they need the robot ``arm``), the joint angles or None."""
    table = read_table(pathlib.Path(path))
    joints = bool(table) and [h.strip() for h in table[0]][-len(JOINTS):] == list(JOINTS)
    if joints and arm is None:
        raise RequestError(f"{path}: a pose list with j1..j6 needs --robot MODEL (the robot those angles move)")
    ids, poses, *angles = read_pose_list(path, axes=tuple(axis_names) + (JOINTS if joints else ()))
    k, angles = len(axis_names), angles[0] if angles else None
    return ids, poses, (angles[:, :k] if k else None), (angles[:, k:] if joints else None)


def _simulated_setup(v):
    """The simulated cell and its truth and noise (:class:`~handeye.model.simulation.simulate.Setup`)."""
    setup = sim.Setup(linearity=v["linearity"], max_tilt_deg=v["max_tilt"])
    cell, setup = _cell(setup, (v["sensor_mount"], v["sphere_mount"]), *_positioner(v), v["seed"])
    pose = None if v["truth"] is None else parse_pose(_pose_text(v["truth"], "--truth"), "--truth", v["convention"])
    centre = None if v["center"] is None else numbers(v["center"], "--center", 3)
    return cell, _replaced(setup, sensor_pose=None if pose is None else tuple(pose), diameter=v["diameter"],
                           sphere_centre=None if centre is None else tuple(centre))


def _simulated_robot(v, cell, setup, effects):
    """``(robot, cell, setup)``: the robot with joints (None without ``--robot``), the robot ``effects``
    checked against its model, and the cell and setup placed where the robot reaches
    (:data:`~handeye.model.simulation.simulate_robot.CENTRES`, :func:`~handeye.model.simulation.simulate_mounts.placed_at`)
    unless ``--center`` (or ``--truth`` for a fixed sensor, ``--positioner-axes`` for a positioner) places it."""
    if v["robot"] is None:
        needing = next((name for name in sim.ROBOT_EFFECTS if name in effects), None)
        if needing:
            raise RequestError(f"--effect {needing} needs --robot MODEL (the robot it describes)")
        return None, cell, setup
    arm = _robot(v["robot"])
    try:
        sim.robot_errors(effects, arm.model)
    except sim.SimulationError as exc:
        raise RequestError(f"--effect {exc}") from None
    target = simulate_robot.CENTRES.get(str(v["robot"]))
    placing = (("truth",) if cell.sensor == "world" else ("positioner_axes", "center") if cell.sphere == "positioner"
               else ("center",))  # the options that place the cell themselves
    if target is not None and all(v[name] is None for name in placing):
        cell, pose, centre = sm.placed_at(cell, setup.sensor_pose, setup.sphere_centre, target, setup.side)
        setup = dataclasses.replace(setup, sensor_pose=pose, sphere_centre=centre)
    return arm, cell, setup


def _simulated_poses(v, setup, cell, arm):
    """The poses simulated (:class:`~handeye.model.simulation.simulate.Poses`): ``--poses`` (their j1..j6
    checked against the robot), a motion strategy (``--motions``, ``--translations``) or the cell's default."""
    strategy = v["motions"] != "thesis" or v["translations"]
    if v["poses"] is not None:
        if strategy:
            raise RequestError("--poses gives the poses: --motions and --translations do not apply")
        ids, flange_poses, angles, joints = _pose_list(v["poses"], cell.axis_names, arm)
        if joints is not None:
            try:
                arm.joints_given(transform_from_pose(flange_poses), joints)
            except ValueError as exc:
                raise RequestError(f"--poses: {exc}") from None
        return sim.Poses(flange_poses, ids, angles, joints)
    if not strategy:
        return sim.Poses(n=v["n_poses"])
    if not cell.default:
        raise RequestError("--motions and --translations apply to the sensor on the flange, sphere in the world")
    ids, flanges = motions.strategy(setup, np.random.default_rng(v["seed"]), v["motions"], v["n_poses"], v["translations"])
    return sim.Poses(pose_from_transform(flanges), ids)


@dataclasses.dataclass(frozen=True)
class SimulateRequest:
    """``handeye simulate``'s options, resolved: what
    :func:`~handeye.model.simulation.simulate.simulate_rig` runs and :func:`~handeye.model.simulation.simulate.write`
    writes.

    Attributes
    ----------
    folder : pathlib.Path
        The dataset folder (checked: empty or new).
    seed : int
    setup : handeye.model.simulation.simulate.Setup
    effects : dict
        The hidden effects (:func:`parse_effects`).
    poses : handeye.model.simulation.simulate.Poses
    cell : handeye.model.simulation.simulate_mounts.Cell
    robot : handeye.model.simulation.simulate_robot.Robot or None
        A robot with joints (``--robot``).
    written : dict
        The keywords of ``write``: ``profiles``, ``convention`` and (``--no-start``) ``start_offset``.
    """

    folder: pathlib.Path
    seed: int
    setup: object
    effects: dict
    poses: object
    cell: object
    robot: object
    written: dict

    @classmethod
    def from_options(cls, values):
        """The request of the options ``values`` (the public function's keywords); raises
        :class:`handeye.InputError` naming the option at fault."""
        v = checked_values("simulate", values)
        folder = check_output_folder(v["out"], "--out", empty=True)
        cell, setup = _simulated_setup(v)
        effects = parse_effects(v["effect"])
        arm, cell, setup = _simulated_robot(v, cell, setup, effects)
        written = {"profiles": v["profiles"], "convention": v["convention"],
                   **({"start_offset": None} if v["no_start"] else {})}
        return cls(folder, v["seed"], setup, effects, _simulated_poses(v, setup, cell, arm), cell, arm, written)


def robot_effects(effects):
    """``--effects`` (``'joint_offsets,link_lengths'`` or a sequence) -> the robot effects in
    :data:`~handeye.model.robot.robot_errors.NAMES` order."""
    names = [effects] if isinstance(effects, str) else list(effects or ())
    names = [n.strip() for text in names for n in str(text).split(",") if n.strip()]
    unknown = [n for n in names if n not in robot_errors.NAMES]
    if unknown or not names:
        raise RequestError(f"--effects: {'unknown ' + repr(unknown[0]) if unknown else 'none given'}; plan with a "
                           f"robot for {', '.join(robot_errors.NAMES)}")
    return tuple(n for n in robot_errors.NAMES if n in names)


def robot_targets(targets, effects):
    """``--target`` (``'joint_offsets=0.005,link_lengths=0.02'`` or a mapping) over the defaults, for the
    asked ``effects``."""
    out = {name: planning_robot.DEFAULT_TARGETS[name] for name in effects}
    if targets is None:
        return out
    items = list(targets.items()) if isinstance(targets, dict) else [
        part.partition("=")[::2] for text in ([targets] if isinstance(targets, str) else targets)
        for part in str(text).split(",") if part.strip()]
    for name, value in items:
        name = str(name).strip()
        if name not in effects:
            raise RequestError(f"--target {name}={value}: give EFFECT=SD for an effect of --effects ({', '.join(effects)})")
        try:
            sd = float(value)
        except (TypeError, ValueError):
            sd = float("nan")
        if not np.isfinite(sd) or sd <= 0:
            raise RequestError(f"--target {name}={value}: needs a positive 1-sd in {planning_robot.UNITS[name]}")
        out[name] = sd
    return out


def _planned_robot(robot, dataset):
    """The robot a plan is for and the stated noise: ``(Robot or None, sigma mm)``.

    ``robot`` (a built-in name or a model file) wins; else the ``[robot] model`` of ``dataset`` (a
    :class:`~handeye.model.datasets.dataset.Dataset` or a :class:`~handeye.model.datasets.dataset.CellSetup`,
    whose setup.toml is read again for it). ``sigma`` is the dataset's ``[noise] centre_mm``, else
    :data:`~handeye.model.readers.setup_file.NOISE_CENTRE_MM`."""
    sigma, model, key = NOISE_CENTRE_MM, None, robot
    if dataset is not None and hasattr(dataset, "noise_centre_mm"):  # a loaded Dataset
        sigma, model = dataset.noise_centre_mm, dataset.robot_model
        key = key or (None if model is None else model.spec or model.name)
    elif dataset is not None:
        st = read_setup(dataset.path)
        sigma = st.noise.get("centre_mm", NOISE_CENTRE_MM)
        if key is None and st.robot_model is not None:
            key = st.robot_model if st.robot_model in robots.builtin_names() else dataset.path / st.robot_model
    if key is None:
        return None, sigma
    if robot is None and model is not None:
        return simulate_robot.Robot(str(key), model), sigma
    return _robot(key, option=robot is not None), sigma


def _planned_cell(v):
    """The cell planned for: its setup, sphere centre, convention and mounts, and the dataset's setup
    (None without ``--dataset``: ``handeye simulate``'s nominal cell of the mounts)."""
    dataset, mounts = v["dataset"], (v["sensor_mount"], v["sphere_mount"])
    if dataset is not None and mounts != ("flange", "world"):
        raise RequestError("--dataset gives the mounts (its setup.toml): --sensor-mount and --sphere-mount do not apply")
    cell, setup = _cell(sim.Setup(linearity=0.0, max_tilt_deg=v["max_tilt"]), mounts, error=(0.0, 0.0))
    if dataset is None:
        return setup, np.asarray(setup.sphere_centre), "kuka", cell.mounts, None
    d = dataset if isinstance(dataset, Dataset) else load_setup(_path_argument(dataset))
    if d.start_pose is None or d.sphere_centre is None:
        raise RequestError(f"--dataset {dataset}: its setup.toml needs a start_pose (the nominal sensor pose) and "
                           "a sphere center to plan around")
    if d.sphere_diameter is None:
        raise RequestError(f"--dataset {dataset}: its setup.toml needs [sphere] diameter to plan: the plan simulates the "
                           "laser line cutting the sphere")
    setup = dataclasses.replace(setup, sensor_pose=tuple(d.start_pose), diameter=d.sphere_diameter, side=d.side)
    return setup, d.sphere_centre, d.convention, d.mounts, d


def _robot_ask(v, setup, centre, mounts, d):
    """What a plan for the robot's own errors is asked (:class:`~handeye.model.design.planning_robot.PlanAsk`),
    or None: ``--robot``, else the dataset's ``[robot] model`` in the cell that has one (the sensor on its flange)."""
    arm, stated = _planned_robot(v["robot"], d if d is not None and (v["robot"] or mounts.default) else None)
    if arm is None:
        if any(v[name] is not None for name in ("effects", "target", "sigma")):
            raise RequestError("--effects, --target and --sigma plan for a robot's own errors: give --robot MODEL (or a "
                               "--dataset whose setup.toml has [robot] model)")
        return None
    if not mounts.default:
        raise RequestError("--robot plans the sensor on the flange and the sphere in the world, not these mounts")
    if d is None:
        centre = np.asarray(simulate_robot.CENTRES.get(str(v["robot"]), centre), float)
    effects = robot_effects("joint_offsets" if v["effects"] is None else v["effects"])
    return planning_robot.PlanAsk(setup, centre, arm, effects, stated if v["sigma"] is None else v["sigma"],
                                  robot_targets(v["target"], effects), v["score"] is not None)


def _candidates(v, setup, centre, mounts, arm):
    """The poses to plan with: read (``--score``, ``--candidates``; j1..j6 with a robot) or made (the
    thesis strategy's within ``--margin``), those outside ``--workspace`` skipped (a plain ``--score`` keeps
    them): ``(Candidates, skipped [(id, why)], warnings)``."""
    path, margin, warnings = v["score"] if v["score"] is not None else v["candidates"], v["margin"], []
    angles = joints = None
    if path is not None:
        ids, poses, angles, joints = _pose_list(path, mounts.axis_names, arm)
        if joints is not None:
            check_reported(arm.model, joints, transform_from_pose(poses), path)
    elif not mounts.default:
        ids, poses, angles = planning.cell_candidates(setup, mounts, centre, margin_mm=margin[0], margin_deg=margin[1])
    else:
        ids, poses = planning.thesis_candidates(setup, centre, margin_mm=margin[0], margin_deg=margin[1])
    if path is None:
        cuts, radius = planning.view_window(setup, *margin)["cuts"], setup.diameter / 2
        if np.ptp(cuts) < 0.2 * radius:
            warnings.append(
                f"the margin leaves the laser plane cutting the sphere only {cuts.min():.1f}-{cuts.max():.1f} mm from its "
                f"centre (R = {radius:g} mm): with one cut depth a wrong [profile] side and a sensor offset along y are "
                "hard to tell apart, and a scale error of the sensor hard to see; a smaller --margin spreads the cuts")
    skipped = []
    if v["workspace"] is not None and (arm is not None or v["score"] is None):
        inside = planning.in_workspace(poses, v["workspace"])
        skipped = [(i, "flange position outside --workspace") for i, k in zip(ids, inside) if not k]
        ids, poses = [i for i, k in zip(ids, inside) if k], np.asarray(poses)[inside]
        angles, joints = (None if a is None else a[inside] for a in (angles, joints))
    if not ids:
        raise RequestError("no candidate pose is left to plan with (--workspace excludes them all)")
    return planning.Candidates(ids, poses, angles, joints), skipped, tuple(warnings)


@dataclasses.dataclass(frozen=True)
class PlanRequest:
    """``handeye plan``'s options, resolved.

    Attributes
    ----------
    candidates : handeye.model.design.planning.Candidates
        The poses to choose from, or to score.
    skipped : list of (str, str)
        Candidates outside ``--workspace``.
    warnings : tuple of str
        About the candidates made (one cut depth).
    setup, centre, mounts
        The nominal cell: :class:`~handeye.model.simulation.simulate.Setup`, sphere centre in its
        mount's frame (mm), :class:`~handeye.model.chain.mounts.Mounts` (nominal axes).
    convention : str
        Of the pose list written.
    n : int or None
        Poses to choose (None with a robot: the number its targets take).
    scored : bool
        ``--score``: the poses are scored, not chosen.
    margin : tuple of float
        (mm, deg) the nominal sensor pose may be off.
    ask : handeye.model.design.planning_robot.PlanAsk or None
        The plan for the robot's own errors (``--robot`` or the dataset's ``[robot] model``).
    out : path or None
        The pose list to write (checked).
    """

    candidates: object
    skipped: list
    warnings: tuple
    setup: object
    centre: object
    mounts: object
    convention: str
    n: int | None
    scored: bool
    margin: tuple
    ask: object
    out: object

    @classmethod
    def from_options(cls, values):
        """The request of the options ``values`` (the public function's keywords); raises
        :class:`handeye.InputError` naming the option at fault."""
        v = checked_values("plan", values)
        v["margin"] = (0.0, 0.0) if v["margin"] is None else tuple(numbers(v["margin"], "--margin", 2))
        if min(v["margin"]) < 0:
            raise RequestError(f"--margin must not be negative, got {v['margin']}")
        v["workspace"] = None if v["workspace"] is None else numbers(v["workspace"], "--workspace", 6)
        setup, centre, convention, mounts, d = _planned_cell(v)
        if v["out"] is not None:  # before the work, and never over a file this command reads or of the dataset
            inputs = [p for p in (v["candidates"], v["score"]) if p is not None]
            inputs += [f for f in pathlib.Path(d.path).rglob("*") if f.is_file()] if d is not None else []
            check_output_path(v["out"], "--out", inputs=inputs)
        ask = _robot_ask(v, setup, centre, mounts, d)
        centre = centre if ask is None else ask.centre
        candidates, skipped, warnings = _candidates(v, setup, centre, mounts, None if ask is None else ask.robot)
        n = v["n"] if ask is not None or v["n"] is not None else 12
        return cls(candidates, skipped, warnings, setup, centre, mounts, convention, n, v["score"] is not None,
                   v["margin"], ask, v["out"])

    def robot_count(self, found):
        """The number of poses the robot plan chooses of what its candidates identify (``found``:
        :func:`~handeye.model.design.planning_robot.identify`): ``--n``, checked against them, else the
        number the targets take (every usable candidate when none does)."""
        names, usable, least = found.names, len(found.info), found.least
        if len(names) == len(planning_robot.BASE_NAMES):
            raise RequestError(f"--effects {','.join(self.ask.effects)}: these candidates separate none of its "
                               "parameters from the sensor pose and the sphere centre")
        if self.n is None or self.scored:  # every usable one to score, else the number the targets take
            return usable if self.scored or found.needed is None else found.needed
        if not least <= self.n <= usable:
            raise RequestError(f"--n {self.n}: the {len(names)} parameters need at least {least} poses" if self.n < least
                               else f"--n {self.n}: only {usable} usable candidates")
        return self.n
