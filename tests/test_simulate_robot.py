"""``handeye simulate --robot MODEL`` (model/simulation/simulate_robot.py): the nominal inverse kinematics
round trip for every built-in model, joint angles that pass the load check, hidden joint offsets
that diagnose names with their values, and a clean robot dataset that calibrates at the truth."""
from __future__ import annotations

import json

import numpy as np
import pytest

import handeye
from handeye.app.command.cli import EXIT_BAD_INPUT, EXIT_OK, main
from handeye.app.public import api
from handeye.model.chain.pose import transform_from_pose
from handeye.model.common.rotation import rotvec_from_matrix
from handeye.model.robot import robots
from handeye.model.simulation import simulate_robot


@pytest.mark.parametrize("name", robots.builtin_names())
def test_inverse_kinematics_round_trip(name):
    """FK(IK(T)) == T within 1e-6 mm / 1e-6 deg over random poses the arm reaches (made by its own
    forward kinematics around the seed, so every one is reachable)."""
    model = robots.load(name)
    rng = np.random.default_rng(7)
    target = model.flange2base(np.array(simulate_robot.SEEDS[name]) + rng.uniform(-40, 40, (60, 6)))
    joints, ok = simulate_robot.inverse_kinematics(model, target, name)
    assert ok.mean() >= 0.95, ok.mean()
    fk = model.flange2base(joints[ok])
    err = simulate_robot.pose_error(target[ok], fk)
    assert np.abs(err[:, :3]).max() < 1e-6 and np.abs(err[:, 3:]).max() < 1e-6
    assert np.all(np.abs(joints[ok]) <= 180.0) and np.all(np.isnan(joints[~ok]))


def test_ik_jacobian_against_central_differences():
    rng = np.random.default_rng(2)
    for name in robots.builtin_names():
        model = robots.load(name)
        q, h = rng.uniform(-90, 90, (3, 6)), 1e-5
        fk, jac = simulate_robot._jacobian(model, q)
        num = np.stack([(simulate_robot.pose_error(model.flange2base(q + h * e), fk)
                         - simulate_robot.pose_error(model.flange2base(q - h * e), fk)) / (2 * h) for e in np.eye(6)], -1)
        assert np.abs(num - jac).max() < 1e-5 * np.abs(jac).max(), name


@pytest.mark.parametrize("name", robots.builtin_names())
def test_every_builtin_robot_sees_the_sphere_from_its_default_centre(tmp_path, name):
    made = api.simulate(tmp_path / name, robot=name, n_poses=12)
    data = made.dataset
    assert data.robot_model is not None and data.joints.shape == (len(made.ids), 6)
    assert len(made.ids) >= 11 and made.robot == name
    np.testing.assert_allclose(data.sphere_centre, simulate_robot.CENTRES[name])


def test_kr60ha_writes_joints_that_load(tmp_path, capsys):
    out = tmp_path / "kr"
    assert main(["simulate", "--out", str(out), "--robot", "kr60ha", "--seed", "2"]) == EXIT_OK
    assert "robot kr60ha" in capsys.readouterr().out
    data = handeye.load_dataset(out)  # the load check: the nominal FK reproduces the reported poses
    assert data.robot_model.name == "KUKA KR 60 HA" and data.joints.shape == (36, 6)
    fk = data.robot_model.flange2base(data.joints)
    gap = np.linalg.norm(fk[:, :3, 3] - transform_from_pose(data.flange_poses)[:, :3, 3], axis=1)
    assert gap.max() < 0.15  # robot repeatability only (0.025 mm per axis)
    assert 'model = "kr60ha"' in (out / "setup.toml").read_text()
    meta = json.loads((out / "simulation.json").read_text())
    assert meta["robot"]["model"] == "kr60ha" and not meta["effects"]


def test_joint_offsets_need_a_robot_and_valid_joints(tmp_path, capsys):
    assert main(["simulate", "--out", str(tmp_path / "a"), "--effect", "joint_offsets=j2:0.05"]) == EXIT_BAD_INPUT
    assert "--robot" in capsys.readouterr().err
    for bad in ("j7:0.1", "j2=0.1", "j2:x", "j2:0"):
        code = main(["simulate", "--out", str(tmp_path / "b"), "--robot", "kr60ha", "--effect", f"joint_offsets={bad}"])
        assert code == EXIT_BAD_INPUT, bad
    capsys.readouterr()
    assert main(["simulate", "--out", str(tmp_path / "c"), "--robot", "nosuchrobot"]) == EXIT_BAD_INPUT



def test_a_robot_holds_the_sphere_before_a_fixed_sensor(tmp_path):
    """--robot with the sensor fixed and the sphere on the flange: the mount's own default truth
    (not the robot's default sphere centre, which is a base position), joints that load."""
    assert main(["simulate", "--out", str(tmp_path / "d"), "--robot", "kr60ha", "--sensor-mount", "world",
                 "--sphere-mount", "flange"]) == EXIT_OK
    data = handeye.load_dataset(tmp_path / "d")
    assert data.mounts.sensor == "world" and data.joints.shape == (len(data), 6) and len(data) >= 30
    assert np.linalg.norm(data.sphere_centre) < 500  # in the flange frame


@pytest.mark.parametrize("name", robots.builtin_names())
@pytest.mark.parametrize("mounts", [("world", "flange"), ("flange", "positioner")])
def test_every_robot_reaches_every_cell(tmp_path, name, mounts):
    """A fixed sensor (or a positioner) is placed where the robot works (``simulate_mounts.placed_at``): the
    sensor 1.75 m out had left a UR10e no reachable pose ("every pose was dropped", exit 2)."""
    made = api.simulate(tmp_path / name, robot=name, n_poses=12, sensor_mount=mounts[0], sphere_mount=mounts[1])
    assert len(made.ids) >= 10, made.ids
    world = transform_from_pose(made.dataset.flange_poses)[:, :3, 3]
    np.testing.assert_allclose(np.median(world, axis=0), simulate_robot.CENTRES[name], atol=400)


def test_diagnose_names_the_simulated_joint_offsets(tmp_path):
    made = api.simulate(tmp_path / "off", robot="kr60ha", effect=["joint_offsets=j2:0.05,j3:-0.03"], seed=1)
    data = made.dataset
    np.testing.assert_allclose(data.truth["joint_offsets"], [0, 0.05, -0.03, 0, 0, 0])
    d = handeye.diagnose(made.path)
    named = {e.name: e for e in d.effects}
    assert list(named) == ["joint_offsets"]
    eff = named["joint_offsets"]
    for joint, value in {"j2": 0.05, "j3": -0.03}.items():
        assert abs(eff.parameters[joint] - value) < 3 * eff.std[joint], (joint, eff.parameters[joint])


def test_a_clean_robot_dataset_calibrates_at_the_truth(tmp_path, capsys):
    made = api.simulate(tmp_path / "clean", robot="kr60ha", seed=4)
    assert main(["calibrate", str(made.path)]) == EXIT_OK
    capsys.readouterr()
    data = made.dataset
    result = api.calibrate(made.path)
    truth = transform_from_pose(data.truth["sensor_pose"])
    est = np.asarray(result.sensor2flange)
    assert np.all(np.abs(est[:3, 3] - truth[:3, 3]) <= 3 * result.std.sensor_translation_mm)
    rot = np.degrees(rotvec_from_matrix(truth[:3, :3].T @ est[:3, :3]))
    assert np.all(np.abs(rot) <= 3 * result.std.sensor_rotation_deg), rot
    assert not handeye.diagnose(made.path).effects


def test_unreachable_poses_are_dropped_with_a_reason(tmp_path):
    """The UR5e's 850 mm reach misses a pose of the thesis strategy (the thesis's sensor sits 250 mm
    off the flange); a sphere out of reach drops every pose, which is refused with the reason."""
    from handeye.model.simulation.simulate import SimulationError

    made = api.simulate(tmp_path / "near", robot="ur5e", seed=0)
    assert len(made.ids) >= 30 and len(made.dropped) >= 1
    assert all("cannot reach" in reason for _, reason in made.dropped)
    with pytest.raises(SimulationError, match="every pose was dropped.*cannot reach"):
        api.simulate(tmp_path / "far", robot="ur5e", center="3000,0,500", n_poses=6)


def test_without_a_robot_joint_columns_are_absent(tmp_path):
    made = api.simulate(tmp_path / "plain", n_poses=4)
    assert "j1" not in (made.path / "measurements.csv").read_text() and made.robot is None
