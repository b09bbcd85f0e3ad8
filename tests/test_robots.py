"""Nominal robot kinematics (model/robot/robots.py) and joint angles in datasets (issue 28, first part):
the built-in models' forward kinematics against values worked out by hand from their sources,
and the load check that names radians, a TCP and a wrong model."""
from __future__ import annotations

import numpy as np
import pytest

import handeye
from handeye.model.chain.pose import pose_from_transform
from handeye.model.readers.tables import DatasetError
from handeye.model.robot import robots


@pytest.mark.parametrize("name, joints, pose", [
    # KR 60 HA (ROS-I chain): at zero the arm stretches along +x: x = 350 + 850 + 465 + 355 + 170, z = 815 + 145;
    # the flange's z along +x (KUKA's A 0, B 90, C 0)
    ("kr60ha", [0, 0, 0, 0, 0, 0], [2190, 0, 960, 0, 90, 0]),
    # KUKA's home: upper arm up (A2 -90), forearm forward (A3 90): x = 350 + 820 + 170, z = 815 + 850 + 145
    ("kr60ha", [0, -90, 90, 0, 0, 0], [1340, 0, 1810, 0, 90, 0]),
    # A1 turns clockwise seen from above (axis -z): +90 puts the arm along -y
    ("kr60ha", [90, -90, 90, 0, 0, 0], [0, -1340, 1810, -90, 90, 0]),
    # UR5e at zero (UR's DH): x = a2 + a3, y = -(d4 + d6), z = d1 - d5; flange = Rx(90)
    ("ur5e", [0, 0, 0, 0, 0, 0], [-817.2, -232.9, 62.8, 0, 0, 90]),
    ("ur10e", [0, 0, 0, 0, 0, 0], [-1184.25, -290.7, 60.85, 0, 0, 90]),
    # IRB 4600-60/2.05 at zero: x = 175 + 960 + 135, z = 495 + 900 + 175
    ("irb4600", [0, 0, 0, 0, 0, 0], [1270, 0, 1570, 0, 90, 0]),
    # M-20iA at zero in FANUC's world (on J2's height): x = 150 + 835 + 100, z = 790 + 250; W 180, P -90
    ("m20ia", [0, 0, 0, 0, 0, 0], [1085, 0, 1040, 180, -90, 0]),
])
def test_forward_kinematics_of_the_built_in_models(name, joints, pose):
    got = pose_from_transform(robots.load(name).flange2base(np.array([joints], float)))[0]
    np.testing.assert_allclose(got[:3], pose[:3], atol=1e-9)
    want = robots._transform([0, 0, 0], pose[3:][::-1])[:3, :3]  # KUKA A, B, C = yaw, pitch, roll
    have = robots._transform([0, 0, 0], got[3:][::-1])[:3, :3]
    np.testing.assert_allclose(have, want, atol=1e-12)


def test_fanuc_j3_is_coupled_to_j2():
    """FANUC reports J3 against the horizontal: turning J2 alone keeps the forearm's direction."""
    m = robots.load("m20ia")
    a, b = m.flange2base(np.array([[0, 0, 0, 0, 0, 0], [0, 30, 0, 0, 0, 0]], float))
    np.testing.assert_allclose(a[:3, :3], b[:3, :3], atol=1e-12)


def _write(folder, model, joints, poses):
    folder.mkdir()
    (folder / "setup.toml").write_text(f'[robot]\nmodel = "{model}"\n[sphere]\ndiameter = 50\ncenter = [1500, 0, 500]\n')
    rows = ["id,x,y,z,a,b,c,xs,ys,zs,j1,j2,j3,j4,j5,j6"] + [
        ",".join([f"p{i}", *(f"{v:.6f}" for v in p), "1", "2", "200", *(f"{v:.8f}" for v in j)])
        for i, (p, j) in enumerate(zip(poses, joints))]
    (folder / "measurements.csv").write_text("\n".join(rows) + "\n")
    return folder


def _cell(n=15, seed=0):
    rng = np.random.default_rng(seed)
    return np.c_[rng.uniform(-60, 60, n), rng.uniform(-110, -40, n), rng.uniform(40, 120, n),
                 rng.uniform(-90, 90, (n, 3))]


def test_joint_angles_load_and_slips_are_named(tmp_path):
    m = robots.load("kr60ha")
    joints = _cell()
    poses = pose_from_transform(m.flange2base(joints))
    d = handeye.load_dataset(_write(tmp_path / "ok", "kr60ha", joints, poses))
    np.testing.assert_allclose(d.joints, joints, atol=1e-7)
    assert d.robot_model.name == "KUKA KR 60 HA" and d.subset(np.arange(15) < 5).joints.shape == (5, 6)
    with pytest.raises(DatasetError, match="read as radians.*degrees"):
        handeye.load_dataset(_write(tmp_path / "rad", "kr60ha", np.radians(joints), poses))
    with pytest.raises(DatasetError, match=r"wrong \[robot\] model"):
        handeye.load_dataset(_write(tmp_path / "wrong", "irb4600", joints, poses))
    for factor, unit in ((1000.0, "metres"), (25.4, "inches")):  # the positions in another length, not the model
        scaled = poses.copy()
        scaled[:, :3] /= factor
        with pytest.raises(DatasetError, match=rf"column 'x'.*read in {unit} \(x {factor:g}\) the positions agree"):
            handeye.load_dataset(_write(tmp_path / unit, "kr60ha", joints, scaled))
    tcp = np.eye(4)
    tcp[:3, 3] = [0, 0, 120]
    with pytest.raises(DatasetError, match="TCP, not the flange"):
        handeye.load_dataset(_write(tmp_path / "tcp", "kr60ha", joints, pose_from_transform(m.flange2base(joints) @ tcp)))
    folder = _write(tmp_path / "nomodel", "kr60ha", joints, poses)
    (folder / "setup.toml").write_text("[sphere]\ndiameter = 50\ncenter = [1500, 0, 500]\n")
    with pytest.raises(DatasetError, match=r"\[robot\] model.*built in: irb4600, kr60ha, m20ia, ur10e, ur5e"):
        handeye.load_dataset(folder)
    text = (tmp_path / "ok" / "measurements.csv").read_text().replace(",j6\n", "\n", 1)
    (tmp_path / "ok" / "measurements.csv").write_text(text)
    with pytest.raises(DatasetError):  # five of six joint columns
        handeye.load_dataset(tmp_path / "ok")


def test_datasets_without_joint_angles_are_as_before():
    d = handeye.load_dataset("thesis-real")
    assert d.joints is None and d.robot_model is None


def _offset_cell(folder, offsets, seed=0, n=40, noise=0.02):
    """A KR 60 HA cell whose joints are off by ``offsets`` (degrees): the flange poses written are the
    nominal model's of the joint angles (what the controller reports), the sensor sees the sphere
    through the true ones."""
    from handeye.model.chain.pose import transform_from_pose

    rng = np.random.default_rng(seed)
    m = robots.load("kr60ha")
    home = np.array([0, -80, 100, 0, 40, 0.0])
    q = home + rng.uniform(-30, 30, (n, 6))
    sensor = transform_from_pose(np.array([50.0, -30, 180, 10, 80, 5]))
    c = (m.flange2base(home[None])[0] @ sensor @ np.array([0, 0, 250, 1.0]))[:3]
    true = m.flange2base(q + np.asarray(offsets, float))
    xs = np.linalg.solve(true @ sensor, np.tile(np.append(c, 1.0), (n, 1))[..., None])[:, :3, 0]
    xs += rng.normal(0, noise, (n, 3))
    folder.mkdir()
    (folder / "setup.toml").write_text(f'[robot]\nmodel = "kr60ha"\n[sphere]\ndiameter = 50\ncenter = '
                                       f'{[float(v) for v in c]}\n[noise]\ncentre_mm = {noise}\n')
    p = pose_from_transform(m.flange2base(q))
    rows = ["id,x,y,z,a,b,c,xs,ys,zs,j1,j2,j3,j4,j5,j6"] + [
        ",".join([f"p{i}", *(f"{v:.6f}" for v in p[i]), *(f"{v:.6f}" for v in xs[i]), *(f"{v:.6f}" for v in q[i])])
        for i in range(n)]
    (folder / "measurements.csv").write_text("\n".join(rows) + "\n")
    return folder


def test_offset_derivatives_against_central_differences():
    rng = np.random.default_rng(1)
    for name in robots.builtin_names():
        m = robots.load(name)
        q, d0, h = rng.uniform(-90, 90, (4, 6)), rng.normal(0, 0.1, 6), 1e-5
        fk, dfk = robots.offset_derivatives(m, q, d0)
        np.testing.assert_allclose(robots.offset_derivatives(m, q, np.zeros(6))[0], m.flange2base(q), atol=1e-9)
        num = np.stack([(robots.offset_derivatives(m, q, d0 + h * e)[0] - robots.offset_derivatives(m, q, d0 - h * e)[0])
                        / (2 * h) for e in np.eye(6)], 1)
        assert np.abs(num - dfk).max() < 1e-6 * np.abs(dfk).max()


def test_diagnose_names_joint_offsets_on_the_joints_that_are_off(tmp_path):
    """Offsets of 0.05 deg on A2 and -0.03 deg on A3: named with those values (3 sd), the others near
    zero; A1 (a turn of the base: the centre) and A6 (about the flange axis: the sensor) are masked
    and said to be absorbed; the gap shrinks to the noise. Clean data names no robot effect."""
    d = handeye.diagnose(_offset_cell(tmp_path / "off", [0, 0.05, -0.03, 0, 0, 0]))
    named = {e.name: e for e in d.effects}
    assert list(named) == ["joint_offsets"]
    eff = named["joint_offsets"]
    assert set(eff.parameters) == {"j2", "j3", "j4", "j5"}
    truth = {"j2": 0.05, "j3": -0.03, "j4": 0.0, "j5": 0.0}
    for joint, value in truth.items():
        assert abs(eff.parameters[joint] - value) < 3 * eff.std[joint], (joint, eff.parameters[joint])
    assert {"joint_offsets.j1", "joint_offsets.j6"} <= set(d.not_identifiable)
    assert d.chi2_dof_after < 2.0 < 10 * 2.0 < d.chi2_dof_before
    clean = handeye.diagnose(_offset_cell(tmp_path / "clean", [0, 0, 0, 0, 0, 0], seed=1))
    assert not clean.effects


def test_calibrate_with_joint_offsets(tmp_path):
    res = handeye.calibrate(_offset_cell(tmp_path / "off", [0, 0.05, -0.03, 0, 0, 0]), effects="joint_offsets")
    assert res.converged and [e.name for e in res.effects] == ["joint_offsets"]
    eff = res.effects[0]
    assert abs(eff.parameters["j2"] - 0.05) < 3 * eff.std["j2"] and abs(eff.parameters["j3"] + 0.03) < 3 * eff.std["j3"]
    assert any("j1 not estimated" in w and "j6 not estimated" in w for w in res.warnings)
    assert res.rms_mm < 0.05
    with pytest.raises(handeye.InputError, match="joint_offsets needs the joint angles"):
        handeye.calibrate("thesis-sim", effects="joint_offsets")


def _urdf_fk(text, joints_rad):
    """Forward kinematics of a URDF chain read with xml.etree (independent of handeye's writer)."""
    import xml.etree.ElementTree as ET

    from scipy.spatial.transform import Rotation

    def origin(el):
        o = el.find("origin")
        t = np.eye(4)
        t[:3, :3] = Rotation.from_euler("xyz", [float(v) for v in o.get("rpy").split()]).as_matrix()
        t[:3, 3] = [float(v) for v in o.get("xyz").split()]
        return t

    joints = {j.find("parent").get("link"): j for j in ET.fromstring(text.encode()).findall("joint")}
    t, link, k = np.eye(4), "base", 0
    while link in joints:
        j = joints[link]
        t = t @ origin(j)
        if j.get("type") == "revolute":
            turn = np.eye(4)
            axis = np.array([float(v) for v in j.find("axis").get("xyz").split()])
            turn[:3, :3] = Rotation.from_rotvec(axis * joints_rad[k]).as_matrix()
            t, k = t @ turn, k + 1
        link = j.find("child").get("link")
    return t


def test_export_writes_the_corrected_model_as_toml_and_urdf(tmp_path):
    import json

    folder = _offset_cell(tmp_path / "off", [0, 0.05, -0.03, 0, 0, 0])
    handeye.calibrate(folder, effects="joint_offsets", out=tmp_path / "cal.json")
    offsets = np.zeros(6)
    for joint, value in json.loads((tmp_path / "cal.json").read_text())["effects"][0]["parameters"].items():
        offsets[robots.JOINTS.index(joint)] = value
    corrected = robots.load("kr60ha").corrected(offsets)
    q = np.random.default_rng(3).uniform(-90, 90, (6, 6))
    (tmp_path / "model.toml").write_text(handeye.export(tmp_path / "cal.json", format="robot-toml").text)
    np.testing.assert_allclose(robots.load(tmp_path / "model.toml").flange2base(q), corrected.flange2base(q), atol=1e-9)
    urdf = handeye.export(tmp_path / "cal.json", format="robot-urdf").text
    for row, fk in zip(q, corrected.flange2base(q)):
        got = _urdf_fk(urdf, np.radians(row))
        np.testing.assert_allclose(got[:3, 3] * 1000, fk[:3, 3], atol=1e-5)
        np.testing.assert_allclose(got[:3, :3], fk[:3, :3], atol=1e-9)
    assert abs(offsets[1] - 0.05) < 0.005 and offsets[0] == 0 and offsets[5] == 0
