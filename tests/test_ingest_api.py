"""``handeye.new_dataset`` from Python, ``--json``, joint angles with a robot model, and the files written."""
import json
import tomllib

import numpy as np
import pytest
from ingest_truth import make_cell, zyx_angles

import handeye
from handeye.app.command.cli import main


def test_python_api_npz_of_all_profiles(tmp_path):
    """One .npz holding every profile (each array one, paired by the number in its key), poses
    CSV with ids; the result is typed, JSON-ready and loads as a dataset."""
    cell = make_cell(n=6, seed=21)
    rows = "".join(f"{k + 1},{','.join(f'{v:.6f}' for v in p)}\n" for k, p in enumerate(cell.kuka()))
    (tmp_path / "poses.csv").write_text("id,x,y,z,a,b,c\n" + rows)
    arrays = {f"profile_{k + 1}": xz for k, xz in enumerate(cell.profiles)}
    arrays["profile_3"] = np.vstack([arrays["profile_3"], [[np.nan, 1.0]]])
    np.savez(tmp_path / "all.npz", **dict(reversed(arrays.items())))
    r = handeye.new_dataset(tmp_path / "out", poses=tmp_path / "poses.csv", profiles=str(tmp_path / "all.npz"),
                            diameter=cell.diameter, center=cell.centre, start=[45, -60, 160, 30, -85, 5])
    assert isinstance(r, handeye.NewDatasetResult) and r.ids == tuple(str(k) for k in range(1, 7))
    assert r.dropped == {"3": 1} and r.next_command == f"handeye calibrate {tmp_path / 'out'}"
    d = json.loads(json.dumps(r.to_dict()))
    assert d["measurements"] == 6 and d["inputs"]["profiles"] == {"npz": 1}
    assert "wrote" in r.summary() and len(r.summary().splitlines()) <= 10
    data = handeye.load_dataset(tmp_path / "out")
    np.testing.assert_allclose(data.flange_poses, cell.kuka(), atol=1e-5)
    np.testing.assert_allclose(data.profiles[0], cell.profiles[0], atol=1e-5)
    setup = tomllib.loads((tmp_path / "out" / "setup.toml").read_text())
    assert setup["sensor"]["start_pose"] == [45, -60, 160, 30, -85, 5] and setup["profile"]["side"] == -1
    prov = tomllib.loads((tmp_path / "out" / "PROVENANCE.toml").read_text())
    assert {s["role"] for s in prov["source"]} == {"poses", "profile"}
    assert prov["dropped_nonfinite"] == {"3": 1} and prov["pairing"]["pairs"]["3"].endswith("all.npz[profile_3]")


@pytest.mark.parametrize("robot", ["kr60ha", "file"])
def test_json_summary_and_joints_with_a_robot(tmp_path, capsys, robot):
    """--joints (a whitespace file with a header) with --robot (a built-in name, or a model file,
    copied into the dataset): j1..j6 and [robot] model written, the poses the nominal model's
    forward kinematics (the loader checks them)."""
    from handeye.model.robot import robots

    model = robots.load("kr60ha")
    if robot == "file":
        (tmp_path / "my_robot.toml").write_text(robots.to_toml(model))
        robot = str(tmp_path / "my_robot.toml")
    rng = np.random.default_rng(3)
    joints = np.array([0, -90, 90, 0, 45, 0]) + rng.uniform(-10, 10, (4, 6))
    flanges = model.flange2base(joints)
    poses = np.array([[*f[:3, 3], *zyx_angles(f[:3, :3])] for f in flanges])
    np.savetxt(tmp_path / "poses.txt", poses, header="X Y Z A B C", comments="# ")
    np.savetxt(tmp_path / "joints.txt", joints, header="j1 j2 j3 j4 j5 j6", comments="")
    (tmp_path / "prof").mkdir()
    cell = make_cell(n=4, seed=2)
    for k in range(4):
        np.savetxt(tmp_path / "prof" / f"{k}.txt", cell.profiles[k])
    code = main(["dataset", "new", str(tmp_path / "out"), "--poses", str(tmp_path / "poses.txt"), "--profiles",
                 str(tmp_path / "prof"), "--joints", str(tmp_path / "joints.txt"), "--robot", robot,
                 "--diameter", "50.8", "--json"])
    out = json.loads(capsys.readouterr().out)
    assert code == 0 and out["ids"] == ["0", "1", "2", "3"] and out["next"].endswith("--unknowns sensor+sphere")
    header = (tmp_path / "out" / "measurements.csv").read_text().splitlines()[0]
    assert header == "id,x,y,z,a,b,c,xs,ys,zs,j1,j2,j3,j4,j5,j6,profile"
    named = "kr60ha" if robot == "kr60ha" else "robot_model.toml"
    assert f'model = "{named}"' in (tmp_path / "out" / "setup.toml").read_text()
    assert (tmp_path / "out" / "robot_model.toml").is_file() == (robot != "kr60ha")
    np.testing.assert_allclose(handeye.load_dataset(tmp_path / "out").joints, joints, atol=1e-5)


def test_the_cli_module_still_imports_only_the_standard_library():
    import subprocess
    import sys

    code = ("import sys, handeye.app.command.cli as c; c.build_parser(); "
            "print(any(m.startswith(('numpy', 'handeye.app.ingest')) for m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


@pytest.mark.parametrize("storage", ["sqlite3"])
def test_bag_topic_errors_name_the_topic(tmp_path, capsys, storage):
    pytest.importorskip("rosbags")
    from ingest_bags import write_bag

    bag = write_bag(tmp_path / "bag", make_cell(n=3, seed=1), storage=storage)
    code = main(["dataset", "new", str(tmp_path / "out"), "--bag", str(bag), "--pose-topic", "/nope", "--profile-topic",
                 "/sensor/profile", "--diameter", "50.8"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "--pose-topic /nope: no such topic" in err[0] and "/robot/flange_pose" in err[0]
    code = main(["dataset", "new", str(tmp_path / "out"), "--bag", str(bag), "--pose-topic", "/robot/flange_pose",
                 "--profile-topic", "/sensor/profile", "--diameter", "50.8", "--max-dt", "0.001"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and "no profile has a pose within --max-dt 0.001 s" in err[0]


def test_setup_file_fills_the_options_not_given(tmp_path, capsys):
    cell = make_cell(n=4, seed=9)
    rows = "".join(f"{k + 1},{','.join(f'{v:.6f}' for v in p)}\n" for k, p in enumerate(cell.fanuc()))
    (tmp_path / "poses.csv").write_text("id,x,y,z,w,p,r\n" + rows)
    (tmp_path / "prof").mkdir()
    for k in range(4):
        np.savetxt(tmp_path / "prof" / f"s{k + 1}.csv", cell.profiles[k], delimiter=",")
    (tmp_path / "old.toml").write_text("[robot]\nconvention = \"kuka\"\n[sphere]\ndiameter = 50.8\n"
                                       "center = [650.0, -120.0, 310.0]\n[profile]\nside = 1\n")
    code = main(["dataset", "new", str(tmp_path / "out"), "--poses", str(tmp_path / "poses.csv"), "--profiles",
                 str(tmp_path / "prof"), "--setup", str(tmp_path / "old.toml"), "--side", "-1"])
    assert code == 0 and "poses converted fanuc -> kuka" in capsys.readouterr().out
    setup = tomllib.loads((tmp_path / "out" / "setup.toml").read_text())
    assert setup["sphere"] == {"diameter": 50.8, "center": [650.0, -120.0, 310.0]} and setup["profile"]["side"] == -1
    assert setup["robot"]["convention"] == "kuka"
    np.testing.assert_allclose(handeye.load_dataset(tmp_path / "out").flange_poses, cell.kuka(), atol=1e-5)
