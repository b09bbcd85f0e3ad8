"""Data and poses made for a cell: ``handeye simulate`` and ``handeye plan`` as functions
(re-exported by :mod:`handeye.app.public.api`, with the same keyword arguments as the CLI's options)."""
from __future__ import annotations

import dataclasses
import pathlib

import numpy as np

from handeye.app.common import options
from handeye.app.common.arguments import _path_argument, _pose_text, load_dataset
from handeye.app.common.errors import RequestError
from handeye.app.present.protocol import ResultProtocol


@dataclasses.dataclass(frozen=True)
class SimulationResult(ResultProtocol):
    """A simulated dataset written by :func:`simulate`.

    Attributes
    ----------
    path : pathlib.Path
        The dataset folder.
    ids : list of str
        Measurements written.
    dropped : list of (str, str)
        Poses that could not see the sphere, with the reason.
    seed : int
    effects : dict
        Hidden effects (name -> value).
    robot : str or None
        ``[robot] model`` of a simulated robot with joints (``--robot``).
    """

    caption = 'handeye simulate'

    path: pathlib.Path
    ids: list
    dropped: list
    seed: int
    effects: dict
    robot: str | None = None

    @property
    def dataset(self):
        """The written dataset, loaded (:func:`load_dataset`)."""
        return load_dataset(self.path)

    def to_dict(self):
        return {"path": str(self.path), "ids": list(self.ids), "dropped": [list(d) for d in self.dropped],
                "seed": self.seed, "effects": {k: np.asarray(v).tolist() for k, v in self.effects.items()},
                **({"robot": self.robot} if self.robot is not None else {})}

    def summary(self):
        lines = [f"wrote {len(self.ids)} simulated measurements to {self.path} (seed {self.seed}, "
                 f"effects {self.effects or 'none'}" + (f", robot {self.robot}" if self.robot else "") + ")"]
        lines += [f"dropped {ident}: {reason}" for ident, reason in self.dropped]
        return "\n".join(lines)


@options.COMMANDS["simulate"].documented
def simulate(out, *, seed=0, effect=(), profiles=False, poses=None, n_poses=36, linearity=0.0, motions="thesis",
             translations=0, truth=None, diameter=None, center=None, convention="kuka", max_tilt=90.0,
             no_start=False, sensor_mount="flange", sphere_mount="world", positioner_axes=None, positioner_error=None,
             robot=None):
    """Write a simulated dataset with known truth (``handeye simulate``; :mod:`handeye.model.simulation.simulate`).

    {parameters}

    Returns
    -------
    SimulationResult
    """
    from handeye.app.common.files import check_output_folder
    from handeye.app.engine.command_request import checked_values
    from handeye.app.engine.request import parse_pose
    from handeye.model.chain import conventions
    from handeye.model.chain.pose import pose_from_transform
    from handeye.model.simulation import motions as motion_strategies
    from handeye.model.simulation import simulate as sim

    v = checked_values("simulate", options.COMMANDS["simulate"].given(locals()))
    seed, n_poses, translations = v["seed"], v["n_poses"], v["translations"]
    conventions.check(convention)
    folder = check_output_folder(out, "--out", empty=True)
    if isinstance(linearity, bool) or not isinstance(linearity, (int, float)) or not 0 <= linearity < 0.1:
        raise RequestError(f"--linearity must lie in [0, 0.1), got {linearity}")
    setup = sim.Setup(linearity=linearity, max_tilt_deg=v["max_tilt"])
    cell, setup = _simulated_cell(setup, seed, sensor_mount, sphere_mount, positioner_axes, positioner_error)
    if truth is not None:
        pose = parse_pose(_pose_text(truth, "--truth"), "--truth", convention=convention)
        setup = dataclasses.replace(setup, sensor_pose=tuple(pose))
    if diameter is not None:
        setup = dataclasses.replace(setup, diameter=v["diameter"])
    if center is not None:
        setup = dataclasses.replace(setup, sphere_centre=tuple(_floats(center, "--center", 3)))
    effects = sim.parse_effects([effect] if isinstance(effect, str) else list(effect))
    arm, setup = _simulated_robot(robot, cell, setup, center is not None, effects)
    ids, flange_poses, angles, joints = None, None, None, None
    if poses is not None:
        if motions != "thesis" or translations:
            raise RequestError("--poses gives the poses: --motions and --translations do not apply")
        ids, flange_poses, angles, joints = _pose_list(poses, cell, arm)
    elif motions != "thesis" or translations:
        if not cell.default:
            raise RequestError("--motions and --translations apply to the sensor on the flange, sphere in the world")
        ids, flanges = motion_strategies.strategy(setup, np.random.default_rng(seed), motions, n_poses, translations)
        flange_poses = pose_from_transform(flanges)
    made = sim.simulate(setup, seed=seed, effects=effects, flange_poses=flange_poses, n_poses=n_poses, ids=ids,
                        cell=cell, axis_angles=angles, robot=arm, joints=joints)
    from handeye.app.common.files import write_folder_atomically

    write_folder_atomically(folder, lambda tmp: sim.write(made, tmp, profiles=profiles, convention=convention,
                                                         **({"start_offset": None} if no_start else {})))
    return SimulationResult(folder, list(made.ids), list(made.dropped), seed, effects,
                            None if arm is None else arm.model_key)


def _pose_list(poses, cell, arm):
    """``simulate --poses``: ids, KUKA poses, the positioner's axis angles (or None) and, when the
    header ends with j1..j6 (a plan's pose list), their joint angles (or None; they need --robot)."""
    from handeye.model.readers.tables import read_pose_list, read_table
    from handeye.model.robot.robots import JOINTS

    table = read_table(pathlib.Path(poses))
    with_joints = bool(table) and [h.strip() for h in table[0]][-len(JOINTS):] == list(JOINTS)
    if with_joints and arm is None:
        raise RequestError(f"{poses}: a pose list with j1..j6 needs --robot MODEL (the robot those angles move)")
    axes = tuple(cell.axis_names) + (JOINTS if with_joints else ())
    ids, flange_poses, *angles = read_pose_list(poses, axes=axes)
    angles = angles[0] if angles else None
    if not with_joints:
        return ids, flange_poses, angles, None
    k = len(cell.axis_names)
    return ids, flange_poses, (angles[:, :k] if k else None), angles[:, k:]


def _simulated_robot(robot, cell, setup, centre_given, effects):
    """The simulated robot with joints (None without ``--robot``) and the setup with its default
    sphere centre (:data:`handeye.model.simulation.simulate_robot.CENTRES`) unless ``--center`` was given."""
    from handeye.model.readers.tables import DatasetError
    from handeye.model.simulation import simulate_robot

    if robot is None:
        robot_effect = next((n for n in ("joint_offsets", "link_lengths", "joint_compliance") if n in effects), None)
        if robot_effect:
            raise RequestError(f"--effect {robot_effect} needs --robot MODEL (the robot it describes)")
        return None, setup
    try:
        arm = simulate_robot.Robot.load(robot)
    except DatasetError as exc:
        raise RequestError(f"--robot {robot}: {exc}") from None
    if not centre_given and cell.default and str(robot) in simulate_robot.CENTRES:
        setup = dataclasses.replace(setup, sphere_centre=simulate_robot.CENTRES[str(robot)])
    return arm, setup


def _simulated_cell(setup, seed, sensor_mount, sphere_mount, positioner_axes, positioner_error):
    """The simulated cell (:class:`handeye.model.simulation.simulate_mounts.Cell`) and the setup with this
    mount's default truth."""
    from handeye.model.simulation import simulate_mounts as sm

    sm.check_pair(sensor_mount, sphere_mount)
    if positioner_error is not None and sphere_mount != "positioner":
        raise RequestError("--positioner-error needs --sphere-mount positioner")
    axes = None if positioner_axes is None else sm.parse_axes(positioner_axes)
    error = sm.POSITIONER_ERROR if positioner_error is None else _floats(positioner_error, "--positioner-error", 2)
    cell = sm.make_cell(sensor_mount, sphere_mount, axes, error, seed)
    pose, centre = sm.default_truth(cell)
    if pose is not None:
        setup = dataclasses.replace(setup, sensor_pose=pose)
    if centre is not None:
        setup = dataclasses.replace(setup, sphere_centre=centre)
    return cell, setup


@dataclasses.dataclass(frozen=True)
class PlanResult(ResultProtocol):
    """Poses chosen (or scored) by :func:`plan`, with their predicted accuracy.

    Attributes
    ----------
    n : int
    ids : list of str
    poses : ndarray, shape (n, 6)
        Flange poses in the robot base, KUKA (mm, degrees).
    logdet : float
        log det of the information matrix (the D-optimality criterion).
    predicted_sd : ndarray, shape (6,)
        Cramer-Rao bound: translation (mm), rotation (degrees).
    skipped : list of (str, str)
        Candidates that cannot see the sphere (or lie outside the workspace), with the reason.
    usable : int
        Candidates that can.
    convention : str
        Robot convention of :meth:`pose_list` and of ``poses_as`` in :meth:`to_dict`.
    scored : bool
        True when the poses were given (``--score``), not chosen.
    margin : tuple of float
        (mm, deg) the nominal sensor pose may be off while every pose still sees the sphere.
    axis_names : tuple of str
        The positioner's axes (sphere on a positioner), else empty.
    axis_angles : ndarray, shape (n, k), or None
        Their angles at each pose, degrees (columns of :meth:`pose_list` after the pose's).
    mounts : tuple of str
        (sensor mount, sphere mount) of the planned cell.
    robot : handeye.model.design.planning_robot.RobotPlan or None
        With a robot (``--robot``): the joint angles of each pose, the predicted sd of the sensor,
        the centre and every robot parameter at the stated noise (``predicted_sd`` is then this
        model's), the parameters not identifiable and the number of poses the targets take.
    """

    caption = 'handeye plan'
    #: Joint-angle columns of the pose list with a robot (degrees).
    joint_columns = ("j1", "j2", "j3", "j4", "j5", "j6")

    n: int
    ids: list
    poses: np.ndarray
    logdet: float
    predicted_sd: np.ndarray
    skipped: list
    usable: int
    convention: str = "kuka"
    scored: bool = False
    margin: tuple = (0.0, 0.0)
    warnings: tuple = ()
    axis_names: tuple = ()
    axis_angles: np.ndarray | None = None
    mounts: tuple = ("flange", "world")
    robot: object | None = None

    @property
    def joints(self):
        """Joint angles j1..j6 (n, 6), degrees, of each pose with a robot; else None."""
        return None if self.robot is None else self.robot.joints

    def poses_in_convention(self):
        from handeye.model.chain import conventions

        return self.poses if self.convention == "kuka" else conventions.convert(self.poses, "kuka", self.convention)

    def to_dict(self):
        """The ``handeye plan --json`` object."""
        from handeye.model.chain import conventions

        missed = self.robot is not None and self.robot.n_needed is None  # the exit 1 of handeye plan
        return {"n": self.n, "error": "even every candidate pose misses the --target" if missed else None,
                "ids": list(self.ids), "poses": np.asarray(self.poses).tolist(), "logdet": self.logdet,
                "predicted_sd": {"sensor_translation_mm": np.asarray(self.predicted_sd[:3]).tolist(),
                                 "sensor_rotation_deg": np.asarray(self.predicted_sd[3:6]).tolist()},
                "skipped": [{"id": i, "reason": r} for i, r in self.skipped],
                "noise_model": "simulator defaults: robot 0.025 mm, profile points 0.01 mm (model.simulate)" if
                self.robot is None else f"centre model: {self.robot.sigma_mm:g} mm per component of a sphere centre, "
                                        "sensor pose, sphere centre and robot parameters estimated",
                "poses_as": {"convention": self.convention, "columns": list(conventions.columns(self.convention)),
                             "poses": np.asarray(self.poses_in_convention()).tolist()},
                "scored": self.scored, "margin": list(self.margin), "warnings": list(self.warnings)} | (
            {} if self.mounts == ("flange", "world") else
            {"sensor_mount": self.mounts[0], "sphere_mount": self.mounts[1], "axis_names": list(self.axis_names),
             "axis_angles": None if self.axis_angles is None else np.asarray(self.axis_angles).tolist()}) | (
            {} if self.robot is None else
            {"joint_names": list(self.joint_columns), "joints": np.asarray(self.joints).tolist(), "robot": self.robot.to_dict()})

    def pose_list(self):
        """The poses as a pose-list CSV in :attr:`convention`, ready for the robot (with a robot,
        followed by their joint angles j1..j6, degrees)."""
        from handeye.model.datasets.dataset import pose_list_text

        if self.robot is not None:
            return pose_list_text(self.ids, self.poses, self.convention, self.joint_columns, self.joints)
        return pose_list_text(self.ids, self.poses, self.convention, self.axis_names, self.axis_angles)

    def summary(self):
        from handeye.model.chain import conventions

        if self.robot is not None:
            return self._robot_summary()
        if self.scored:
            head = f"scored {self.n} given poses (log det {self.logdet:.2f})"
        else:
            head = f"chose {self.n} of {self.usable} usable candidate poses (D-optimal, log det {self.logdet:.2f})"
        if any(self.margin):
            head += f"; each still sees the sphere with the sensor off by {self.margin[0]:g} mm / {self.margin[1]:g} deg"
        lines = [head,
                 "predicted sd (Cramer-Rao bound): translation mm " + " ".join(f"{v:.4f}" for v in self.predicted_sd[:3])
                 + "; rotation deg " + " ".join(f"{v:.4f}" for v in self.predicted_sd[3:6]),
                 f"poses ({self.convention}: {','.join(conventions.columns(self.convention) + self.axis_names)}):"]
        angles = self.axis_angles if self.axis_names else [()] * len(self.ids)
        lines += [f"  {i:>14} " + " ".join(f"{v:10.4f}" for v in (*p, *a))
                  for i, p, a in zip(self.ids, self.poses_in_convention(), angles)]
        lines += [f"  skipped {i}: {r}" for i, r in self.skipped]
        lines += [f"warning: {w}" for w in self.warnings]
        return "\n".join(lines)

    def _robot_summary(self):
        """:meth:`summary` with a robot: the plan's size and why, every sd, the joints of each pose."""
        from handeye.model.chain import conventions
        from handeye.model.design.planning_robot import UNITS, absorbed_why

        r = self.robot
        if self.scored:
            head = f"scored {self.n} given poses for the {r.model}'s {', '.join(r.effects)} (log det {self.logdet:.2f})"
        else:
            head = (f"chose {self.n} of {self.usable} usable candidate poses for the {r.model}'s {', '.join(r.effects)} "
                    f"(D-optimal, log det {self.logdet:.2f}; {r.flips} in the other wrist, {r.unreachable} unreachable)")
        targets = ", ".join(f"{e} {v:g} {UNITS[e]}" for e, v in r.targets.items())
        if r.n_needed is None:
            needed = f"no plan of these candidates reaches the targets ({targets}; full rank from {r.n_min} poses)"
        else:
            needed = (f"{r.n_needed} (the targets {targets} alone: {r.n_targets}; full rank: {r.n_min}"
                      + ("; a residual that can test the fit: " + str(r.n_needed) if r.n_needed > r.n_targets else "")
                      + ")")
        lines = [head, f"poses needed: {needed}; these {self.n} {'meet' if r.reached else 'miss'} the targets",
                 f"predicted sd (Cramer-Rao bound, {r.sigma_mm:g} mm per centre component): translation mm "
                 + " ".join(f"{v:.4f}" for v in r.sd[:3]) + "; rotation deg " + " ".join(f"{v:.4f}" for v in r.sd[3:6])
                 + "; sphere centre mm " + " ".join(f"{v:.4f}" for v in r.sd[6:9])]
        lines += [f"  {e} sd {UNITS[e]}: " + " ".join(f"{p} {v:.4g}" for p, v in sds.items())
                  for e, sds in r.robot_sd().items() if sds]
        lines += [f"  not identifiable: {p} ({absorbed_why(w)})" for p, w in r.dropped.items()]
        lines.append(f"poses ({self.convention}: {','.join(conventions.columns(self.convention) + self.joint_columns)}):")
        lines += [f"  {i:>16} " + " ".join(f"{v:10.4f}" for v in (*p, *q))
                  for i, p, q in zip(self.ids, self.poses_in_convention(), self.joints)]
        lines += [f"  skipped {i}: {why}" for i, why in self.skipped]
        lines += [f"warning: {w}" for w in self.warnings]
        return "\n".join(lines)


def _floats(text, option, count):
    values = _pose_text(text, option).split(",")
    try:
        out = [float(v) for v in values]
    except ValueError:
        raise RequestError(f"{option}: not a number in {text!r}") from None
    if len(out) != count or not np.all(np.isfinite(out)):
        raise RequestError(f"{option} needs {count} finite numbers, got {text!r}")
    return out


@options.COMMANDS["plan"].documented
def plan(*, n=None, candidates=None, dataset=None, out=None, max_tilt=90.0, margin=None, workspace=None, score=None,
         sensor_mount="flange", sphere_mount="world", robot=None, effects=None, target=None, sigma=None):
    """Choose the ``n`` most informative poses, D-optimal (``handeye plan``), or score a given list.

    {parameters}

    Returns
    -------
    PlanResult
    """
    from handeye.app.common.files import check_output_path, write_text_atomically
    from handeye.app.engine.command_request import checked_values
    from handeye.model.datasets.dataset import read_pose_list
    from handeye.model.design import planning, planning_robot
    from handeye.model.simulation import simulate_robot

    v = checked_values("plan", options.COMMANDS["plan"].given(locals()))
    n, sigma = v["n"], v["sigma"]
    margin = (0.0, 0.0) if margin is None else tuple(_floats(margin, "--margin", 2))
    if min(margin) < 0:
        raise RequestError(f"--margin must not be negative, got {margin}")
    setup, centre, convention, mounts, d = _planned_cell(dataset, sensor_mount, sphere_mount, v["max_tilt"])
    if out is not None:  # before the work, and never over a file this command reads or of the dataset
        inputs = [p for p in (candidates, score) if p is not None]
        inputs += [f for f in pathlib.Path(d.path).rglob("*") if f.is_file()] if d is not None else []
        check_output_path(out, "--out", inputs=inputs)
    # the dataset's [robot] model plans for the robot in the cell that has one (the sensor on its flange)
    arm, stated = planning_robot.cell_robot(robot, d if d is not None and (robot or mounts.default) else None)
    if arm is not None:
        if not mounts.default:
            raise RequestError("--robot plans the sensor on the flange and the sphere in the world, not these mounts")
        if d is None:
            centre = np.asarray(simulate_robot.CENTRES.get(str(robot), centre), float)
        rp = planning_robot.request(
            setup, centre, arm, effects, target, n, stated if sigma is None else sigma,
            score if score is not None else candidates, score is not None,
            None if workspace is None else _floats(workspace, "--workspace", 6), margin)
        result = PlanResult(len(rp.ids), list(rp.ids), rp.poses, rp.logdet, rp.sd[:6], rp.skipped, rp.usable,
                            convention, score is not None, margin, rp.warnings, robot=rp)
    else:
        if any(v is not None for v in (effects, target, sigma)):
            raise RequestError("--effects, --target and --sigma plan for a robot's own errors: give --robot MODEL (or a "
                               "--dataset whose setup.toml has [robot] model)")
        n = 12 if n is None else n
        cell_keys = {"axis_names": mounts.axis_names, "mounts": (mounts.sensor, mounts.sphere)}
        if score is not None:
            ids, poses, *angles = read_pose_list(score, axes=mounts.axis_names)
            angles = angles[0] if angles else None
            sd, value = planning.score(poses, setup, centre, mounts, angles)
            return PlanResult(len(ids), list(ids), np.asarray(poses), value, sd, [], len(ids), convention, True, margin,
                              tuple(planning.few_angles(angles, mounts.axis_names)), axis_angles=angles, **cell_keys)
        ids, poses, angles, warnings, skipped = _candidates(setup, centre, mounts, candidates, margin, workspace)
        chosen = planning.plan(ids, poses, n, setup, centre, mounts, angles)
        warnings += planning.few_angles(chosen.angles, mounts.axis_names)
        result = PlanResult(n, list(chosen.ids), np.asarray(chosen.poses), float(chosen.logdet),
                            np.asarray(chosen.predicted_sd), skipped + list(chosen.skipped),
                            len(ids) - len(chosen.skipped), convention, False, margin, tuple(warnings),
                            axis_angles=chosen.angles, **cell_keys)
    if out is not None:
        write_text_atomically(out, result.pose_list(), option="--out")
    return result


def _planned_cell(dataset, sensor_mount, sphere_mount, max_tilt):
    """The cell planned for: its setup, sphere centre, convention and mounts, and the dataset's
    setup (None without ``--dataset``: ``handeye simulate``'s nominal cell of the mounts)."""
    from handeye.model.simulation import simulate as sim

    setup = sim.Setup(linearity=0.0, max_tilt_deg=max_tilt)
    if dataset is not None and (sensor_mount, sphere_mount) != ("flange", "world"):
        raise RequestError("--dataset gives the mounts (its setup.toml): --sensor-mount and --sphere-mount do not apply")
    cell, setup = _simulated_cell(setup, 0, sensor_mount, sphere_mount, None,
                                  (0.0, 0.0) if sphere_mount == "positioner" else None)
    if dataset is None:
        return setup, np.asarray(setup.sphere_centre), "kuka", cell.mounts, None
    from handeye.model.datasets.dataset import Dataset, load_setup

    d = dataset if isinstance(dataset, Dataset) else load_setup(_path_argument(dataset))
    if d.start_pose is None or d.sphere_centre is None:
        raise RequestError(f"--dataset {dataset}: its setup.toml needs a start_pose (the nominal sensor pose) and "
                           "a sphere center to plan around")
    setup = dataclasses.replace(setup, sensor_pose=tuple(d.start_pose), diameter=d.sphere_diameter, side=d.side)
    return setup, d.sphere_centre, d.convention, d.mounts, d


def _candidates(setup, centre, mounts, candidates, margin, workspace):
    """The candidate poses to plan with: ids, poses, axis angles (or None), warnings, and the
    poses skipped outside ``--workspace`` with why."""
    from handeye.model.datasets.dataset import read_pose_list
    from handeye.model.design import planning

    warnings, angles = [], None
    if candidates is not None:
        ids, poses, *angles = read_pose_list(candidates, axes=mounts.axis_names)
        angles = angles[0] if angles else None
    elif not mounts.default:
        ids, poses, angles = planning.cell_candidates(setup, mounts, centre, margin_mm=margin[0], margin_deg=margin[1])
    else:
        ids, poses = planning.thesis_candidates(setup, centre, margin_mm=margin[0], margin_deg=margin[1])
    if candidates is None:
        cuts, radius = planning.view_window(setup, *margin)["cuts"], setup.diameter / 2
        if np.ptp(cuts) < 0.2 * radius:
            warnings.append(
                f"the margin leaves the laser plane cutting the sphere only {cuts.min():.1f}-{cuts.max():.1f} mm from its "
                f"centre (R = {radius:g} mm): with one cut depth a wrong [profile] side and a sensor offset along y are "
                "hard to tell apart, and a scale error of the sensor hard to see; a smaller --margin spreads the cuts")
    skipped = []
    if workspace is not None:
        inside = planning.in_workspace(poses, _floats(workspace, "--workspace", 6))
        skipped = [(i, "flange position outside --workspace") for i, k in zip(ids, inside) if not k]
        ids, poses = [i for i, k in zip(ids, inside) if k], np.asarray(poses)[inside]
        angles = None if angles is None else angles[inside]
    if not ids:
        raise RequestError("no candidate pose is left to plan with (--workspace excludes them all)")
    return ids, poses, angles, warnings, skipped
