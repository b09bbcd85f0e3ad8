"""Data and poses made for a cell: ``handeye simulate`` and ``handeye plan`` as functions
(re-exported by :mod:`handeye.app.public.api`, with the same keyword arguments as the CLI's options)."""
from __future__ import annotations

import dataclasses
import pathlib

import numpy as np

from handeye.app.common import options
from handeye.app.common.arguments import load_dataset
from handeye.app.present.protocol import ResultProtocol
from handeye.model.chain import conventions


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
    linearity : float
        The sensor's depth linearity error in the profiles (``--linearity``: a fraction of the 100 mm range).
    """

    caption = 'handeye simulate'

    path: pathlib.Path
    ids: list
    dropped: list
    seed: int
    effects: dict
    robot: str | None = None
    #: the sensor's depth linearity error written into the profiles (a fraction of its range; 0: none)
    linearity: float = 0.0

    @property
    def dataset(self):
        """The written dataset, loaded (:func:`load_dataset`)."""
        return load_dataset(self.path)

    def to_dict(self):
        return {"path": str(self.path), "ids": list(self.ids), "dropped": [list(d) for d in self.dropped],
                "seed": self.seed, "effects": {k: np.asarray(v).tolist() for k, v in self.effects.items()},
                **({"robot": self.robot} if self.robot is not None else {}),
                **({"linearity": self.linearity} if self.linearity else {})}

    def summary(self):
        lines = [f"wrote {len(self.ids)} simulated measurements to {self.path} (seed {self.seed}, "
                 f"effects {self.effects or 'none'}" + (f", robot {self.robot}" if self.robot else "")
                 + (f", sensor linearity {self.linearity:g} of the 100 mm range in the profiles" if self.linearity else "")
                 + ")"]
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
    from handeye.app.common.files import write_folder_atomically
    from handeye.app.engine.making_request import SimulateRequest
    from handeye.model.simulation import simulate as sim

    r = SimulateRequest.from_options(options.COMMANDS["simulate"].given(locals()))
    made = sim.simulate_rig(r.setup, r.seed, r.effects, r.poses, r.cell, r.robot)
    write_folder_atomically(r.folder, lambda tmp: sim.write(made, tmp, **r.written))
    return SimulationResult(r.folder, list(made.ids), list(made.dropped), r.seed, r.effects,
                            None if r.robot is None else r.robot.model_key, r.setup.linearity)


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
        return self.poses if self.convention == "kuka" else conventions.convert(self.poses, "kuka", self.convention)

    def to_dict(self):
        """The ``handeye plan --json`` object."""
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

        names, values = (self.joint_columns, self.joints) if self.robot is not None else (self.axis_names, self.axis_angles)
        return pose_list_text(self.ids, self.poses, self.convention, names, values)

    def summary(self):
        lines = self._robot_summary() if self.robot is not None else self._sensor_summary()
        lines += [f"  skipped {i}: {why}" for i, why in self.skipped] + [f"warning: {w}" for w in self.warnings]
        return "\n".join(lines)

    def _sensor_summary(self):
        """:meth:`summary`'s lines of a plan of the sensor pose (and a positioner's axes)."""
        head = (f"scored {self.n} given poses (log det {self.logdet:.2f})" if self.scored else
                f"chose {self.n} of {self.usable} usable candidate poses (D-optimal, log det {self.logdet:.2f})")
        if any(self.margin):
            head += f"; each still sees the sphere with the sensor off by {self.margin[0]:g} mm / {self.margin[1]:g} deg"
        lines = [head,
                 "predicted sd (Cramer-Rao bound): translation mm " + " ".join(f"{v:.4f}" for v in self.predicted_sd[:3])
                 + "; rotation deg " + " ".join(f"{v:.4f}" for v in self.predicted_sd[3:6]),
                 f"poses ({self.convention}: {','.join(conventions.columns(self.convention) + self.axis_names)}):"]
        angles = self.axis_angles if self.axis_names else [()] * len(self.ids)
        lines += [f"  {i:>14} " + " ".join(f"{v:10.4f}" for v in (*p, *a))
                  for i, p, a in zip(self.ids, self.poses_in_convention(), angles)]
        return lines

    def _robot_summary(self):
        """:meth:`summary`'s lines with a robot: the plan's size and why, every sd, the joints of each pose."""
        from handeye.model.design.planning_robot import UNITS, absorbed_why

        r = self.robot
        head = (f"scored {self.n} given poses for the {r.model}'s {', '.join(r.effects)} (log det {self.logdet:.2f})"
                if self.scored else
                f"chose {self.n} of {self.usable} usable candidate poses for the {r.model}'s {', '.join(r.effects)} "
                f"(D-optimal, log det {self.logdet:.2f}; {r.flips} in the other wrist, {r.unreachable} unreachable)")
        targets = ", ".join(f"{e} {v:g} {UNITS[e]}" for e, v in r.targets.items())
        needed = (f"no plan of these candidates reaches the targets ({targets}; full rank from {r.n_min} poses)"
                  if r.n_needed is None else f"{r.n_needed} (the targets {targets} alone: {r.n_targets}; full rank: {r.n_min}"
                  + ("; a residual that can test the fit: " + str(r.n_needed) if r.n_needed > r.n_targets else "") + ")")
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
        return lines


@options.COMMANDS["plan"].documented
def plan(*, n=None, candidates=None, dataset=None, out=None, max_tilt=90.0, margin=None, workspace=None, score=None,
         sensor_mount="flange", sphere_mount="world", robot=None, effects=None, target=None, sigma=None):
    """Choose the ``n`` most informative poses, D-optimal (``handeye plan``), or score a given list.

    {parameters}

    Returns
    -------
    PlanResult
    """
    from handeye.app.common.files import write_text_atomically
    from handeye.app.engine.making_request import PlanRequest

    r = PlanRequest.from_options(options.COMMANDS["plan"].given(locals()))
    result = _robot_plan(r) if r.ask is not None else _sensor_plan(r)
    if r.out is not None:
        write_text_atomically(r.out, result.pose_list(), option="--out")
    return result


def _robot_plan(r):
    """:func:`plan` for the robot's own errors too (:mod:`handeye.model.design.planning_robot`) of the
    request ``r``."""
    from handeye.model.design import planning_robot

    found = planning_robot.identify(r.candidates, r.ask)
    rp = planning_robot.choose(found, r.robot_count(found))
    rp = dataclasses.replace(rp, skipped=r.skipped + rp.skipped)
    return PlanResult(len(rp.ids), list(rp.ids), rp.poses, rp.logdet, rp.sd[:6], rp.skipped, rp.usable, r.convention,
                      r.scored, r.margin, rp.warnings, robot=rp)


def _sensor_plan(r):
    """:func:`plan` of the sensor pose (and a positioner's axes) of the request ``r``: the D-optimal choice,
    or the score of the given poses."""
    from handeye.model.design import planning

    c, mounts = r.candidates, r.mounts
    cell_keys = {"axis_names": mounts.axis_names, "mounts": (mounts.sensor, mounts.sphere)}
    if r.scored:
        sd, value = planning.score(c.flange_poses, r.setup, r.centre, mounts, c.angles)
        return PlanResult(len(c.ids), list(c.ids), np.asarray(c.flange_poses), value, sd, [], len(c.ids), r.convention,
                          True, r.margin, tuple(planning.few_angles(c.angles, mounts.axis_names)), axis_angles=c.angles,
                          **cell_keys)
    chosen = planning.plan(c, r.n, r.setup, r.centre, mounts)
    return PlanResult(r.n, list(chosen.ids), np.asarray(chosen.poses), float(chosen.logdet),
                      np.asarray(chosen.predicted_sd), r.skipped + list(chosen.skipped), len(c.ids) - len(chosen.skipped),
                      r.convention, False, r.margin, r.warnings + tuple(planning.few_angles(chosen.angles, mounts.axis_names)),
                      axis_angles=chosen.angles, **cell_keys)
