"""Profiles in the sensor's own frame, turned by ``handeye dataset new`` into handeye's (laser
plane y = 0), keep their turn as ``[profile] own_axes``: calibrate reports the pose of the
sensor's own frame, and export writes that one (a new user's ROS export was 90 deg off their
sensor's frame before). The cell here is handeye's simulator, its profiles rewritten by plain
numpy as 3-column points in the plane z = 0 (a sensor that reports x along the line, y the
depth), so the true pose of the files' frame is the simulated truth turned by hand."""
from __future__ import annotations

import csv
import json

import numpy as np
import pytest

import handeye
from handeye.app.cli import main
from handeye.model.pose import transform_from_pose


@pytest.fixture(scope="module")
def turned(tmp_path_factory):
    root = tmp_path_factory.mktemp("own")
    sim = root / "sim"
    assert main(["simulate", "--out", str(sim), "--profiles", "--seed", "7", "--n-poses", "16"]) == 0
    rows = list(csv.DictReader((sim / "measurements.csv").open()))
    files = root / "files"
    files.mkdir()
    for k, row in enumerate(rows, start=1):
        xz = np.loadtxt(sim / row["profile"], delimiter=",", skiprows=1)
        # the sensor's own frame: x = handeye x, y = handeye z (depth), z = -handeye y (the plane z = 0)
        np.save(files / f"scan_{k:03d}.npy", np.column_stack([xz[:, 0], xz[:, 1], np.zeros(len(xz))]))
    with (root / "poses.csv").open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["x", "y", "z", "a", "b", "c"])
        w.writerows([[row[c] for c in ("x", "y", "z", "a", "b", "c")] for row in rows])
    # the files' frame in handeye's: p_h = R p_file with (x, y, z)_file = (x_h, z_h, -y_h)
    rot = np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])
    truth = transform_from_pose(handeye.load_dataset(sim).truth["sensor_pose"])
    turn = np.eye(4)
    turn[:3, :3] = rot
    return root, sim, truth @ turn, rot


def test_dataset_new_keeps_the_turn_and_calibrate_reports_the_own_frame(turned, tmp_path, capsys):
    root, sim, truth_own, rot = turned
    out = tmp_path / "cell"
    side = handeye.load_dataset(sim).side
    code = main(["dataset", "new", str(out), "--poses", str(root / "poses.csv"), "--profiles", str(root / "files"),
                 "--diameter", "59.94507", "--side", str(-side), "--center",
                 ",".join(map(str, handeye.load_dataset(sim).sphere_centre))])
    assert code == 0, capsys.readouterr()
    capsys.readouterr()
    data = handeye.load_dataset(out)
    np.testing.assert_allclose(data.own_axes, rot, atol=1e-12)
    result = handeye.calibrate(out, no_loo=True, out=tmp_path / "cal.json")
    assert result.converged
    own = np.array(result.to_dict()["sensor_matrix_own"])
    assert np.linalg.norm(own[:3, 3] - truth_own[:3, 3]) < 0.2
    assert np.degrees(np.arccos(np.clip((np.trace(own[:3, :3].T @ truth_own[:3, :3]) - 1) / 2, -1, 1))) < 0.1
    assert "the sensor's own frame" in result.summary()
    exported = handeye.export(tmp_path / "cal.json", format="matrix").text
    matrix = np.array([[float(v) for v in line.split()] for line in exported.splitlines() if not line.startswith("#")])
    np.testing.assert_allclose(matrix, own, atol=1e-8)  # export writes the own frame
    cal = json.loads((tmp_path / "cal.json").read_text())
    np.testing.assert_allclose(cal["own_axes"], rot)


def test_own_axes_must_be_a_rotation(turned, tmp_path):
    _, sim, _, _ = turned
    import shutil

    folder = tmp_path / "bad"
    shutil.copytree(sim, folder)
    setup = folder / "setup.toml"
    setup.write_text(setup.read_text().replace("[profile]", "[profile]\nown_axes = [[1, 0, 0], [0, 1, 0], [0, 0, -1]]"))
    with pytest.raises(handeye.InputError, match=r"\[profile\] own_axes.*proper rotation"):
        handeye.load_dataset(folder)


def test_a_typed_sensor_pose_is_of_the_own_frame(turned, tmp_path, capsys):
    """--sensor-pose on a turned dataset is the sensor's own pose (what export wrote): scored as
    the same pose as the calibration's."""
    root, sim, truth_own, rot = turned
    out = tmp_path / "cell"
    data = handeye.load_dataset(sim)
    assert main(["dataset", "new", str(out), "--poses", str(root / "poses.csv"), "--profiles", str(root / "files"),
                 "--diameter", "59.94507", "--side", str(-data.side), "--center",
                 ",".join(map(str, data.sphere_centre))]) == 0
    capsys.readouterr()
    result = handeye.calibrate(out, no_loo=True)
    own = result.to_dict()["sensor_pose_own"]
    score = handeye.calibrate(out, sensor_pose=own, no_loo=True)
    assert "own frame" in score.source and not score.contradicted
    assert score.distance["translation_mm"] < 1e-6 and score.distance["rotation_deg"] < 1e-6


def test_every_path_of_a_turned_dataset_agrees(turned, tmp_path, capsys):
    """The paths a review found 90 deg off: cloud and validate with a typed own pose, export of a
    Python result, a closed-form result, a saved score, a diagnosis, and an export read back."""
    root, sim, truth_own, rot = turned
    data = handeye.load_dataset(sim)
    out = tmp_path / "cell"
    assert main(["dataset", "new", str(out), "--poses", str(root / "poses.csv"), "--profiles", str(root / "files"),
                 "--diameter", "59.94507", "--side", str(-data.side), "--center",
                 ",".join(map(str, data.sphere_centre))]) == 0
    capsys.readouterr()
    result = handeye.calibrate(out, no_loo=True, out=tmp_path / "cal.json")
    own = np.array(result.to_dict()["sensor_matrix_own"])
    own_pose = ",".join(map(repr, result.to_dict()["sensor_pose_own"]))

    def matrix(exported):
        return np.array([[float(v) for v in ln.split()] for ln in exported.text.splitlines() if not ln.startswith("#")])

    np.testing.assert_allclose(matrix(handeye.export(result, format="matrix")), own, atol=1e-8)  # a Python result
    kim = handeye.calibrate(out, method="kim-cho", keep_all=True, out=tmp_path / "kc.json")
    assert "own_axes" in kim.to_dict()
    score = handeye.calibrate(out, sensor_pose=own_pose, no_loo=True, out=tmp_path / "score.json")
    np.testing.assert_allclose(matrix(handeye.export(tmp_path / "score.json", format="matrix")), own, atol=1e-6)
    assert "the sensor's own" in score.summary()
    handeye.diagnose(out, out=tmp_path / "diag.json")
    np.testing.assert_allclose(matrix(handeye.export(tmp_path / "diag.json", format="matrix")), own, atol=0.2)
    by_file = handeye.cloud(out, tmp_path / "cal.json", out=tmp_path / "a.ply")
    by_pose = handeye.cloud(out, sensor_pose=own_pose, out=tmp_path / "b.ply")
    for key in ("min", "max"):
        np.testing.assert_allclose(by_pose.to_dict()["bounds_mm"][key], by_file.to_dict()["bounds_mm"][key], atol=1e-6)
    handeye.validate(out, sensor_pose=own_pose)  # sees the sphere (a pose 90 deg off does not)
    exported = tmp_path / "exported.json"
    exported.write_text(handeye.export(tmp_path / "cal.json", format="json").text)
    back = handeye.compare(out, tmp_path / "cal.json", exported)
    assert back.between["translation_mm"] < 1e-6 and back.between["rotation_deg"] < 1e-6  # read back in its frame


def test_a_setup_s_side_is_not_turned_twice(turned, tmp_path, capsys):
    """--setup takes [profile] side from a setup.toml, which is in handeye's frame already."""
    root, sim, _, _ = turned
    data = handeye.load_dataset(sim)
    first, second = tmp_path / "a", tmp_path / "b"
    args = ["--poses", str(root / "poses.csv"), "--profiles", str(root / "files")]
    assert main(["dataset", "new", str(first), *args, "--diameter", "59.94507", "--side", str(-data.side)]) == 0
    assert main(["dataset", "new", str(second), *args, "--setup", str(first / "setup.toml")]) == 0
    capsys.readouterr()
    assert handeye.load_dataset(second).side == handeye.load_dataset(first).side == data.side
