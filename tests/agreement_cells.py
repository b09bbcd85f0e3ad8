"""The datasets the studies and notebooks calibrate and diagnose, one of each kind, and the two verdicts on one
(issue 39: calibrate and diagnose agree on every study dataset; ``tests/test_agreement.py``).

Each builder makes its dataset the way its study or notebook does (the study's own generator where it has one,
its first seed), in a folder under ``tmp``, and returns ``(dataset, unknowns)``: what a user would pass to
``handeye.calibrate`` and ``handeye.diagnose``. :func:`verdicts` runs both through the public API.
"""
from __future__ import annotations

import contextlib
import dataclasses
import pathlib

import numpy as np

import handeye
from handeye.app.engine.agreement import same_pose
from handeye.app.engine.describe import STRUCTURE_WARNING
from handeye.app.public import api
from handeye.model.chain.pose import pose_from_transform
from handeye.model.common.rotation import pose_distance
from handeye.model.datasets.dataset import load

REAL = pathlib.Path(__file__).parent / "data" / "robcalibrator"


def _sim(name, **options):
    """A ``handeye simulate`` cell (its CLI options as keywords)."""
    return lambda tmp: (handeye.simulate(tmp / name, **options).dataset, "sensor")


def _study_setup(name, seed, setup=None, poses=None, ids=None, profiles=False, effects=None):
    """A cell of :func:`handeye.model.simulation.simulate.simulate`, as the quick studies draw theirs."""
    from handeye.model.simulation import simulate

    def build(tmp):
        sim = simulate.simulate(setup or simulate.Setup(), seed=seed, flange_poses=poses, ids=ids, effects=effects)
        return load(simulate.write(sim, tmp / name, profiles=profiles)), "sensor"
    return build


def _accuracy(tmp):
    """study_accuracy's first replicate: its design (seed 1000) measured anew (seed 0), with profiles."""
    from handeye.model.simulation import simulate

    setup = simulate.Setup(linearity=0.0)
    design = simulate.simulate(setup, seed=1000)
    return _study_setup("accuracy", 0, setup, design.flange_poses, design.ids, profiles=True)(tmp)


def _classics(tmp):
    """study_classics's cell: the thesis strategy with pure translations (Li et al.'s), its noise at k = 1."""
    from handeye.studies import study_classics

    ids, poses = study_classics._design(12, 1)
    return _study_setup("classics", 0, study_classics._setup(1), poses, ids)(tmp)


def _default(seed):
    """study_default's random cell of ``seed`` (no start pose; odd seeds: profiles only)."""
    def build(tmp):
        from handeye.model.chain import conventions
        from handeye.studies import study_default

        c = study_default.cell(seed)
        sim = handeye.simulate(tmp / f"default{seed}", seed=seed, n_poses=c["n_poses"], max_tilt=c["max_tilt"],
                               diameter=c["diameter"], center=c["center"], convention=c["convention"],
                               truth=conventions.convert(c["truth_kuka"], "kuka", c["convention"]),
                               profiles=c["profiles"], no_start=True)
        return sim.dataset, "sensor"
    return build


def _guarantee(seed):
    """study_guarantee's cell of ``seed`` (even: measured on a ``handeye plan``; odd: the thesis strategy)."""
    def build(tmp):
        from handeye.studies import study_guarantee

        folder = tmp / f"guarantee{seed}"
        folder.mkdir()
        return study_guarantee._planned(folder, seed)[1].dataset, "sensor"
    return build


def _mounts(sensor, sphere, unknowns):
    """study_mounts's cell of seed 1 (a start pose written) for a mount, with the study's unknowns."""
    return lambda tmp: (handeye.simulate(tmp / f"mounts-{sensor}-{sphere}", seed=1, sensor_mount=sensor,
                                         sphere_mount=sphere).dataset, unknowns)


def _planning(tmp):
    """study_planning's planned cell: 12 D-optimal poses of the thesis candidates, measured with profiles."""
    from handeye.model.design import bounds, planning
    from handeye.model.simulation import simulate

    setup = simulate.Setup(linearity=0.0)
    ids, poses = planning.thesis_candidates(setup, np.asarray(setup.sphere_centre))
    chosen, _ = planning.select(bounds.information(poses, setup, np.asarray(setup.sphere_centre)), 12)
    return _study_setup("planning", 500, setup, np.asarray(poses)[chosen], [ids[k] for k in chosen], profiles=True)(tmp)


def _thesis_robot(tmp):
    """study_thesis_robot's thesis-real with the KR 60 HA's joint angles reconstructed."""
    from handeye.model.robot import robots
    from handeye.model.simulation import simulate_robot as sr
    from handeye.studies import study_thesis_robot

    data = handeye.load_dataset("thesis-real")
    joints, ok = sr.inverse_kinematics(robots.load("kr60ha"), np.asarray(data.flange2base()), "kr60ha")
    keep = {i: q for i, q, k in zip(data.ids, joints, ok) if k}
    return load(study_thesis_robot._with_joints(pathlib.Path(data.path), tmp, joints, keep)["joints"]), "sensor"


def _eye_to_hand(tmp):
    """hand_eye_calibration.ipynb's thesis-real read as a sensor in the cell and a sphere on the flange, here with
    its noise stated (0.05 mm, the notebook leaves it out): residuals 6.9 x that are unexplained structure, which
    calibrate refuses and diagnose reports beyond the catalogue -- one verdict."""
    real = handeye.load_dataset("thesis-real")
    folder = tmp / "thesis-real-eye-to-hand"
    folder.mkdir()
    inverted = pose_from_transform(np.linalg.inv(real.flange2base()))
    (folder / "setup.toml").write_text('[sensor]\nmount = "world"\n[sphere]\nmount = "flange"\n'
                                       f"diameter = {real.sphere_diameter}\n[noise]\ncentre_mm = {real.noise_centre_mm}\n")
    rows = ["id,x,y,z,a,b,c,xs,ys,zs"] + [",".join([i, *(f"{v:.10f}" for v in p), *(f"{v:.10f}" for v in x)])
                                          for i, p, x in zip(real.ids, inverted, real.centre_in_sensor)]
    (folder / "measurements.csv").write_text("\n".join(rows) + "\n")
    return load(folder), "sensor+sphere"


def _real(name):
    return lambda tmp: (handeye.load_dataset(str(REAL / name)), "sensor+sphere")


def _builtin(name, unknowns="sensor"):
    return lambda tmp: (handeye.load_dataset(name), unknowns)


#: name -> builder(tmp) -> (dataset, unknowns): every kind of dataset the studies and notebooks use.
DATASETS = {
    "thesis-real": _builtin("thesis-real"),
    "thesis-real sensor+sphere": _builtin("thesis-real", "sensor+sphere"),
    "thesis-sim": _builtin("thesis-sim"),
    "robcalibrator scan-2023-10-31": _real("scan-2023-10-31"),
    "robcalibrator scan-2023-10-30": _real("scan-2023-10-30"),
    "robcalibrator ball-2023-05": _real("ball-2023-05"),
    "robcalibrator ball-2023-05-raw": _real("ball-2023-05-raw"),
    "simulate flange/world": _sim("fw", seed=1),
    "simulate flange/world profiles": _sim("fwp", seed=2, profiles=True),
    "simulate flange/world sensor_scale=0.002": _sim("fws", seed=11, effect=["sensor_scale=0.002"]),
    "simulate flange/world profiles sphere_radius=0.3": _sim("fwr", seed=3, profiles=True,
                                                             effect=["sphere_radius=0.3"]),
    "simulate world/flange": _sim("wf", seed=1, sensor_mount="world", sphere_mount="flange"),
    "simulate world/flange sensor_scale=0.002": _sim("wfs", seed=2, sensor_mount="world", sphere_mount="flange",
                                                     effect=["sensor_scale=0.002"]),
    "simulate flange/positioner": _sim("fp", seed=1, sphere_mount="positioner"),
    "simulate flange/positioner sensor_scale=0.002": _sim("fps", seed=2, sphere_mount="positioner",
                                                          effect=["sensor_scale=0.002"]),
    "simulate kr60ha": _sim("kr", seed=1, robot="kr60ha"),
    "simulate kr60ha joint_offsets=j3:0.05": _sim("kro", seed=1, robot="kr60ha", effect=["joint_offsets=j3:0.05"]),
    "simulate ur10e link_lengths=a2:0.3": _sim("url", seed=1, robot="ur10e", effect=["link_lengths=a2:0.3"]),
    "simulate kr60ha joint_compliance=j2:0.03": _sim("krc", seed=1, robot="kr60ha",
                                                     effect=["joint_compliance=j2:0.03"]),
    "notebook kr60ha wide joint_offsets=j2:0.05,j3:-0.03": _sim("wide", seed=1, robot="kr60ha", n_poses=24,
                                                                effect=["joint_offsets=j2:0.05,j3:-0.03"]),
    "notebook thesis-real eye-to-hand": _eye_to_hand,
    "study accuracy": _accuracy,
    "study classics": _classics,
    "study honest-default seed 0": _default(0),
    "study honest-default seed 1 profiles": _default(1),
    "study global-guarantee seed 0 planned": _guarantee(0),
    "study global-guarantee seed 1": _guarantee(1),
    "study mounts world/flange sensor+sphere": _mounts("world", "flange", "sensor+sphere"),
    "study mounts flange/positioner sensor+positioner": _mounts("flange", "positioner", "sensor+positioner"),
    "study pose-planning": _planning,
    "study discrepancy-power sensor_scale=8e-4": _study_setup("power", 2000, effects={"sensor_scale": 8e-4}),
    "study random-starts": _study_setup("random", 3),
    "study thesis-robot": _thesis_robot,
}


@dataclasses.dataclass
class Verdict:
    """One command's end on a dataset: ``exit`` (0, 1, 2), the effects it names (a model: sign flips are
    samples), its pose (4x4, or None) and what it said (the message or the error)."""

    exit: int
    effects: frozenset
    pose: np.ndarray | None
    said: str
    excluded: tuple = ()
    axes_calibrated: bool = False
    warnings: tuple = ()


@contextlib.contextmanager
def _calibrate_seen():
    """The calibrations ``handeye.diagnose`` runs beside its search, recorded (the same public function a
    user calls, with the user's options: diagnose compares its pose with it)."""
    seen, original = [], api.calibrate

    def recording(*args, **kwargs):
        seen.append(original(*args, **kwargs))
        return seen[-1]
    api.calibrate = recording
    try:
        yield seen
    finally:
        api.calibrate = original


def calibrate_verdict(result, unknowns):
    """:class:`Verdict` of a ``handeye.calibrate`` result (``sphere_center`` named where the search freed the
    centre of a request that held it)."""
    names = {e.name for e in result.effects or ()}
    if "sphere" in result.unknowns.split("+") and "sphere" not in unknowns.split("+"):
        names.add("sphere_center")
    return Verdict(0 if result.converged else 1, frozenset(names), np.asarray(result.sensor2flange, float),
                   result.message, tuple(e.id for e in result.excluded), "positioner" in result.unknowns.split("+"),
                   tuple(result.warnings))


def diagnose_verdict(result):
    """:class:`Verdict` of a ``handeye.diagnose`` result: refused (1) where the discrepancy lies beyond the
    catalogue, else a pose with the effects it names."""
    names = frozenset(e.name for e in result.effects if e.name != "sign_flip")
    refused = bool(result.beyond_catalogue)
    return Verdict(1 if refused else 0, names, np.asarray(result.sensor2flange, float),
                   "; ".join(result.beyond_catalogue) or result.against_calibrate, tuple(result.outliers))


def verdicts(dataset, unknowns):
    """``(calibrate's Verdict, diagnose's Verdict, distance)`` on one dataset: both through the public API,
    calibrate's the very calibration ``handeye.diagnose`` runs beside its search; ``distance`` is
    :func:`~handeye.model.common.rotation.pose_distance` of diagnose's pose from calibrate's in calibrate's
    covariance (None where either gives no pose)."""
    with _calibrate_seen() as seen:
        try:
            diagnosed = diagnose_verdict(handeye.diagnose(dataset, unknowns=unknowns.replace("+positioner", "")))
        except handeye.InputError as exc:
            diagnosed = Verdict(2, frozenset(), None, str(exc))
    if seen and unknowns == seen[0].unknowns:
        own = seen[0]
    else:  # diagnose stopped before calibrating, or cannot take the unknowns (the positioner's): calibrate alone
        try:
            own = handeye.calibrate(dataset, unknowns=unknowns, no_loo=True)
        except handeye.InputError as exc:
            return Verdict(2, frozenset(), None, str(exc)), diagnosed, None
    calibrated = calibrate_verdict(own, unknowns)
    distance = None
    if calibrated.exit == 0 and diagnosed.exit != 2 and own.covariance is not None:
        distance = pose_distance(diagnosed.pose, calibrated.pose, own.covariance, own.parameter_names)
    return calibrated, diagnosed, distance


def _axes_off(calibrated, diagnosed):
    """Calibrate refuses a positioner's held set-up axes, naming ``--unknowns ...+positioner``
    (:mod:`handeye.app.engine.positioner_effect`), where diagnose names ``positioner_axes``: one finding (the
    stages fit the axes only when asked; :mod:`handeye.app.engine.search`)."""
    return ("positioner_axes" in diagnosed.effects and not calibrated.axes_calibrated
            and "the positioner's set-up axes are off" in calibrated.said)


def agree(calibrated, diagnosed, distance):
    """Whether the two verdicts are one: the same exit, and where calibrate gives a pose, diagnose's within 1 sd
    of it (:func:`handeye.app.engine.agreement.same_pose`) with the same effects named; or calibrate's refusal of
    a positioner's set-up axes beside diagnose's ``positioner_axes`` (:func:`_axes_off`). Calibrate's warnings
    suggest no effect its search did not choose (the score tests' warning of structure)."""
    if calibrated.exit == 1 and _axes_off(calibrated, diagnosed):
        return True
    if calibrated.exit != diagnosed.exit:
        return False
    if calibrated.exit != 0:
        return True
    axes = {"positioner_axes"} if calibrated.axes_calibrated else set()  # diagnose's name for what calibrate fits
    suggests = any(w.startswith(STRUCTURE_WARNING) for w in calibrated.warnings)  # an effect the search did not choose
    return (calibrated.effects - axes == diagnosed.effects - axes and distance is not None
            and same_pose(distance) and not suggests)
