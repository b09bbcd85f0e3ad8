"""``handeye plan --robot``: poses and joint configurations that identify the robot's own errors,
and how many it takes (:mod:`handeye.model.design.planning_robot`)."""
import dataclasses
import json

import numpy as np
import pytest

import handeye
from handeye.app.command import cli
from handeye.model.chain.pose import pose_from_transform, transform_from_pose
from handeye.model.common.rotation import rotvec_from_matrix
from handeye.model.datasets import dataset as datasets
from handeye.model.design import planning, planning_robot, robot_gate
from handeye.model.fit import extended
from handeye.model.robot import robot_errors, robots
from handeye.model.simulation import simulate as sim
from handeye.model.simulation import simulate_robot


@dataclasses.dataclass(frozen=True)
class PlannedArm(simulate_robot.Robot):
    """A simulated robot that goes to the plan's joint angles (its configurations) given to it once
    (``handeye simulate --poses`` with a plan's j1..j6 does the same from the file)."""

    joints: np.ndarray = None

    def reach(self, wanted, errors=None, joints=None):
        q = np.asarray(self.joints if joints is None else joints, float)
        true = robot_errors.perturbed(self.model, q, errors or {})[0]
        return q, self.model.flange2base(q), true, {}


def _arm(name, joints):
    return PlannedArm(name, robots.load(name), joints)


def _setup(name, pose=None):
    setup = dataclasses.replace(sim.Setup(), sphere_centre=simulate_robot.CENTRES[name])
    return setup if pose is None else dataclasses.replace(setup, sensor_pose=tuple(pose))


@pytest.fixture(scope="module")
def ur10e():
    """The default plan for the UR10e's joint offsets (the number of poses the target takes)."""
    return handeye.plan(robot="ur10e")


def test_the_joint_angles_reproduce_the_chosen_flange_poses(ur10e, tmp_path):
    model = robots.load("ur10e")
    fk = model.flange2base(ur10e.joints)
    err = simulate_robot.pose_error(transform_from_pose(ur10e.poses), fk)
    assert np.abs(err).max() < 1e-5  # mm, deg (the poses are written with the IK's 1e-6)
    rp = ur10e.robot
    assert ur10e.n == rp.n_needed == len(ur10e.ids) and rp.reached and rp.n_min <= rp.n_targets <= rp.n_needed
    assert rp.flips > 0 and rp.usable == 108 - rp.unreachable + rp.flips
    # the pose list carries the joints (degrees) after the pose columns
    ur10e.save(tmp_path / "plan.json")
    out = tmp_path / "poses.csv"
    out.write_text(ur10e.pose_list())
    assert out.read_text().splitlines()[0] == "id,x,y,z,a,b,c,j1,j2,j3,j4,j5,j6"
    ids, poses, joints = datasets.read_pose_list(out, axes=robots.JOINTS)
    assert ids == ur10e.ids and np.allclose(joints, ur10e.joints, atol=1e-4) and np.allclose(poses, ur10e.poses, atol=1e-4)
    data = json.loads((tmp_path / "plan.json").read_text())
    assert data["joint_names"] == list(robots.JOINTS) and np.allclose(data["joints"], ur10e.joints)
    for key in ("predicted_sd", "best_sd", "not_identifiable", "n_min", "n_targets", "n_needed", "target_reached",
                "targets", "sigma_mm", "candidates"):
        assert key in data["robot"], key
    assert set(data["robot"]["predicted_sd"]) == {"sensor_translation_mm", "sensor_rotation_deg", "sphere_centre_mm",
                                                  "joint_offsets"}


def test_the_other_wrist_is_a_candidate_of_its_own():
    """A spherical wrist reaches the same flange pose with j4 + 180, -j5, j6 + 180."""
    model = robots.load("kr60ha")
    ids, poses = planning.thesis_candidates(_setup("kr60ha"), simulate_robot.CENTRES["kr60ha"])
    got = planning_robot.reach(model, "kr60ha", ids[:12], transform_from_pose(poses[:12]))
    assert got.flips == 12 and got.ids[12:] == [i + planning_robot.FLIP for i in ids[:12]]
    assert np.allclose(got.joints[12:], planning_robot.other_wrist(got.joints[:12]), atol=1e-6)
    assert np.allclose(model.flange2base(got.joints[12:]), got.flanges[12:], atol=1e-6)


def test_the_first_and_last_joints_and_lengths_along_them_are_named_unidentifiable(ur10e):
    dropped = {d["parameter"]: d for d in ur10e.to_dict()["robot"]["not_identifiable"]}
    assert set(dropped) == {"joint_offsets.j1", "joint_offsets.j6"}
    assert set(dropped["joint_offsets.j1"]["absorbed_by"]) <= {"cx", "cy", "cz"}
    assert "sphere centre" in dropped["joint_offsets.j1"]["why"] and "absorbed by" in dropped["joint_offsets.j1"]["why"]
    assert "wx" in dropped["joint_offsets.j6"]["absorbed_by"] and "rotation" in dropped["joint_offsets.j6"]["why"]
    assert "not identifiable: joint_offsets.j1" in ur10e.summary()
    # the lengths: d1 along the first axis turns into the centre, d6 along the last into the sensor
    model = robots.load("ur10e")
    cand = planning_robot.reach(model, "ur10e", list(ur10e.ids), transform_from_pose(ur10e.poses), wrists=False)
    jac, names = planning_robot.jacobian(model, cand.joints, cand.flanges, transform_from_pose(sim.Setup().sensor_pose),
                                         simulate_robot.CENTRES["ur10e"], ("joint_offsets", "link_lengths"))
    _, left = planning_robot.identifiable(jac, names)
    assert left["link_lengths.d1"] == ["cz"] and left["link_lengths.d6"] == ["tz"]


def test_the_predicted_sd_matches_a_monte_carlo_of_the_planned_poses(ur10e, tmp_path):
    """40 fits of the extended model (sensor, centre, joint offsets) at the stated noise: the scatter
    of every parameter within a loose factor of the plan's Cramer-Rao sd."""
    setup = _setup("ur10e")
    made = sim.simulate_rig(setup, 0, poses=sim.Poses(ur10e.poses, ur10e.ids), robot=_arm("ur10e", ur10e.joints))
    sim.write(made, tmp_path / "d")
    data = handeye.load_dataset(tmp_path / "d")
    flanges, x, c = robots.load("ur10e").flange2base(data.joints), transform_from_pose(setup.sensor_pose), \
        np.asarray(setup.sphere_centre)
    exact = np.einsum("nij,j->ni", np.linalg.inv(flanges @ x), np.append(c, 1.0))[:, :3]
    structure = extended.Structure(centre=True, data_effects=("joint_offsets",))
    rng, mask, sigma = np.random.default_rng(1), np.ones(len(data), bool), ur10e.robot.sigma_mm
    est = []
    for _ in range(40):
        noisy = dataclasses.replace(data, flange_poses=pose_from_transform(flanges),
                                    centre_in_sensor=exact + rng.normal(0.0, sigma, exact.shape))
        prob = extended.Samples(noisy, sigma=sigma)
        robot_gate.gate_robot_effects(prob, structure, mask, x, c)
        fit = prob.fit(structure, mask, prob.point(structure, x, c))
        sensor = prob.transform(fit.x)
        est.append(np.concatenate([sensor[:3, 3] - x[:3, 3], np.degrees(rotvec_from_matrix(x[:3, :3].T @ sensor[:3, :3])),
                                   fit.x[12:15] - c, fit.params["joint_offsets"]]))
    assert prob.params_of("joint_offsets") == ("j2", "j3", "j4", "j5")  # what the plan kept
    ratio = np.std(est, axis=0) / ur10e.robot.sd
    assert np.all((ratio > 0.65) & (ratio < 1.5)), dict(zip(ur10e.robot.names, ratio.round(2)))
    assert 0.85 < np.sqrt(np.mean(ratio**2)) < 1.2


def test_calibrate_reports_the_sd_the_plan_predicts(ur10e, tmp_path):
    """The whole pipeline on the simulator's own noise: calibrate --effects joint_offsets reports the
    plan's sd scaled by its estimated noise (the plan's is at the stated 0.05 mm)."""
    made = sim.simulate_rig(_setup("ur10e"), 2, poses=sim.Poses(ur10e.poses, ur10e.ids), robot=_arm("ur10e", ur10e.joints))
    sim.write(made, tmp_path / "d")
    r = handeye.calibrate(tmp_path / "d", effects="joint_offsets", unknowns="sensor+sphere", no_loo=True)
    reported = next(e for e in r.effects if e.name == "joint_offsets").std
    scale = r.uncertainty.sigma_mm / ur10e.robot.sigma_mm
    for joint, sd in ur10e.robot.robot_sd()["joint_offsets"].items():
        assert reported[joint] == pytest.approx(sd * scale, rel=0.25), joint


def test_the_number_of_poses_it_takes_identifies_hidden_offsets(tmp_path):
    """A cell whose setup.toml names the robot plans for it; on the poses (and wrists) the plan says
    it takes, diagnose names the hidden joint offsets, each within 3 sd of the truth."""
    cell = handeye.simulate(tmp_path / "cell", robot="m20ia", n_poses=4, seed=0)
    p = handeye.plan(dataset=cell.path)
    rp = p.robot
    assert rp is not None and rp.model == "m20ia" and p.n == rp.n_needed and rp.reached
    truth = np.array([0.0, 0.03, -0.02, 0.04, -0.03, 0.0])
    nominal = datasets.load_setup(cell.path).start_pose  # planned without --margin: the sensor where planned
    made = sim.simulate_rig(_setup("m20ia", nominal), 3, {"joint_offsets": truth.tolist()}, sim.Poses(p.poses, p.ids),
                            robot=_arm("m20ia", p.joints))
    sim.write(made, tmp_path / "measured")
    d = handeye.diagnose(tmp_path / "measured")
    named = {e.name: e for e in d.effects}
    assert "joint_offsets" in named, [e.name for e in d.effects]
    found = named["joint_offsets"]
    for k, joint in enumerate(robots.JOINTS):
        if joint in found.parameters:
            assert abs(found.parameters[joint] - truth[k]) < 3 * found.std[joint], (joint, found.parameters, found.std)
    assert set(found.parameters) == {"j2", "j3", "j4", "j5"}


def test_a_target_out_of_reach_is_said_and_exits_1(capsys, tmp_path):
    out = tmp_path / "poses.csv"
    code = cli.main(["plan", "--robot", "ur10e", "--target", "joint_offsets=0.0001", "--json", "--out", str(out)])
    data = json.loads(capsys.readouterr().out)
    assert code == cli.EXIT_NOT_CONVERGED
    assert data["robot"]["n_needed"] is None and data["robot"]["targets_reachable"] is False
    assert not data["robot"]["target_reached"] and data["n"] == data["robot"]["candidates"]["usable"]  # all of them
    assert any("not reached even with all" in w for w in data["warnings"])
    assert out.read_text().count("\n") == data["n"] + 1
    # a given --n that misses a reachable target is planned, and says how many it takes
    p = handeye.plan(robot="ur10e", n=6)
    assert p.n == 6 and p.robot.n_needed > 6
    assert any("degrees of freedom" in w for w in p.warnings)
    assert "poses needed: " in p.summary()


@pytest.mark.parametrize("args, option", [
    (["--robot", "ur10e", "--effects", "joint_offset"], "--effects"),
    (["--robot", "ur10e", "--target", "joint_offsets=0"], "--target"),
    (["--robot", "ur10e", "--target", "joint_offsets=abc"], "--target"),
    (["--robot", "ur10e", "--target", "link_lengths=0.1"], "--target"),
    (["--robot", "ur10e", "--sigma", "-1"], "--sigma"),
    (["--robot", "nosuch"], "--robot"),
    (["--effects", "joint_offsets"], "--effects"),
    (["--target", "joint_offsets=0.1"], "--target"),
])
def test_bad_options_exit_2_naming_the_option(capsys, args, option):
    assert cli.main(["plan", *args]) == cli.EXIT_BAD_INPUT
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and option in err, err


def test_too_few_poses_asked_exit_2_naming_n(capsys):
    assert cli.main(["plan", "--robot", "ur10e", "--n", "3"]) == cli.EXIT_BAD_INPUT
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--n 3" in err and "at least" in err


def test_without_a_robot_plan_is_unchanged(tmp_path):
    p = handeye.plan(n=6, out=tmp_path / "p.csv")
    assert p.robot is None and p.joints is None and "robot" not in p.to_dict() and "joints" not in p.to_dict()
    assert (tmp_path / "p.csv").read_text().splitlines()[0] == "id,x,y,z,a,b,c"
    assert handeye.plan().n == 12


@pytest.mark.slow(sibling="test_the_number_of_poses_it_takes_identifies_hidden_offsets")
def test_a_plan_replays_in_simulate_with_its_joints_and_identifies_the_offsets(tmp_path, capsys):
    """plan --robot writes j1..j6; simulate --poses takes those angles (the other wrist stays the
    other wrist, no inverse kinematics) and diagnose names the hidden offsets on them within 3 sd.
    Angles that do not reach their pose, or j1..j6 without --robot, exit 2 naming it."""
    from handeye.app.command.cli import EXIT_BAD_INPUT, EXIT_OK, main

    plan_csv = tmp_path / "plan.csv"
    assert main(["plan", "--robot", "ur10e", "--out", str(plan_csv)]) == EXIT_OK
    rows = plan_csv.read_text().splitlines()
    assert rows[0].endswith("j1,j2,j3,j4,j5,j6") and any("~flip" in r for r in rows)
    assert main(["simulate", "--out", str(tmp_path / "sim"), "--robot", "ur10e", "--poses", str(plan_csv), "--seed", "4",
                 "--effect", "joint_offsets=j2:0.03,j4:-0.04"]) == EXIT_OK
    data = handeye.load_dataset(tmp_path / "sim")
    planned = {r.split(",")[0]: np.array(r.split(",")[7:], float) for r in rows[1:]}
    np.testing.assert_allclose(data.joints, [planned[i] for i in data.ids], atol=1e-6)
    found = {e.name: e for e in handeye.diagnose(tmp_path / "sim").effects}
    assert list(found) == ["joint_offsets"]
    for joint, value in {"j2": 0.03, "j4": -0.04}.items():
        assert abs(found["joint_offsets"].parameters[joint] - value) < 3 * found["joint_offsets"].std[joint]
    capsys.readouterr()
    bad = tmp_path / "bad.csv"
    bad.write_text(rows[0] + "\n" + ",".join(rows[1].split(",")[:8] + [str(float(rows[1].split(",")[8]) + 1.0)]
                                             + rows[1].split(",")[9:]) + "\n")
    assert main(["simulate", "--out", str(tmp_path / "b"), "--robot", "ur10e", "--poses", str(bad)]) == EXIT_BAD_INPUT
    assert "its joint angles put the UR10e's flange" in capsys.readouterr().err
    assert main(["simulate", "--out", str(tmp_path / "c"), "--poses", str(plan_csv)]) == EXIT_BAD_INPUT
    assert "needs --robot" in capsys.readouterr().err
