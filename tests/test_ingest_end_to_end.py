"""``handeye dataset new`` then ``handeye calibrate`` on cells written by other tools.

The truth comes from :mod:`ingest_truth` (plain numpy, not handeye's simulator); the files are
written by OpenCV (FileStorage), numpy and rosbags. The calibrated sensor pose must lie within a
few of its own standard deviations of the truth, and both commands must exit 0; profiles in
another frame than handeye's give a pose of their own frame.
"""
import json

import numpy as np
import pytest
from ingest_truth import make_cell, pose_error

from handeye.app.command.cli import main


def _new_and_calibrate(tmp_path, capsys, args, unknowns=None):
    out = tmp_path / "cell"
    assert main(["dataset", "new", str(out), *args]) == 0
    summary = capsys.readouterr().out
    result = tmp_path / "result.json"
    cal = ["calibrate", str(out), "--no-loo", "--out", str(result)] + (["--unknowns", unknowns] if unknowns else [])
    assert main(cal) == 0
    capsys.readouterr()
    return out, summary, json.loads(result.read_text())


def _assert_near_truth(cell, res, k=4.0, turn=None):
    """``res``'s pose within k sd of the truth; ``turn`` (R, ``p_handeye = R p_file``, known to the
    test) of profiles written in another frame: the result is of the files' frame, the truth's
    ``S [R 0; 0 1]``, turned back here by numpy."""
    matrix = np.array(res["sensor_matrix"])
    assert (res.get("sensor_frame") == "own") == (turn is not None)
    if turn is not None:
        matrix[:3, :3] = matrix[:3, :3] @ np.asarray(turn, float).T
    dt, dr = pose_error(cell, matrix)
    sd_t = float(np.linalg.norm(res["std"]["sensor_translation_mm"]))
    sd_r = float(np.linalg.norm(res["std"]["sensor_rotation_deg"]))
    assert dt < k * sd_t + 0.005, (dt, sd_t)
    assert dr < k * sd_r + 0.002, (dr, sd_r)
    return dt, dr


def test_fanuc_json_poses_with_opencv_yaml_profiles(tmp_path, capsys):
    """A FANUC cell: poses as a JSON list of objects (W, P, R), profiles written by OpenCV's
    FileStorage (YAML, 3 columns with the laser plane y = 0, NaN rows), paired by the ids."""
    cv2 = pytest.importorskip("cv2")
    cell = make_cell(n=14, seed=3)
    poses = [{"name": f"P{k + 1}", "pos": {"x": p[0], "y": p[1], "z": p[2]}, "W": p[3], "P": p[4], "R": p[5]}
             for k, p in enumerate(cell.fanuc())]
    order = list(range(len(poses)))[::-1]  # the file lists them backwards: pairing is by id, not order
    (tmp_path / "poses.json").write_text(json.dumps({"poses": [poses[k] for k in order]}))
    (tmp_path / "scans").mkdir()
    for k, xz in enumerate(cell.profiles):
        pts = np.column_stack([xz[:, 0], np.zeros(len(xz)), xz[:, 1]])
        pts[[2, 7]] = np.nan
        fs = cv2.FileStorage(str(tmp_path / "scans" / f"scan_{k + 1:02d}.yml"), cv2.FILE_STORAGE_WRITE)
        fs.write("profile", pts)
        fs.release()
    centre = ",".join(map(str, cell.centre))
    out, summary, res = _new_and_calibrate(tmp_path, capsys, ["--poses", str(tmp_path / "poses.json"), "--profiles",
                                                              str(tmp_path / "scans"), "--diameter", str(cell.diameter),
                                                              "--center", centre])
    assert "convention fanuc" in summary and "14 FileStorage YAML" in summary and "28 NaN/inf rows" in summary
    assert "by id in the file name" in summary and f"handeye calibrate {out}\n" in summary + "\n"
    assert "[robot]\nconvention = \"fanuc\"" in (out / "setup.toml").read_text()
    prov = (out / "PROVENANCE.toml").read_text()
    assert prov.count("[[source]]") == 15 and "sha256" in prov
    _assert_near_truth(cell, res)


def test_whitespace_poses_with_npy_and_csv_profiles(tmp_path, capsys):
    """Headerless whitespace text (id and ROS-ordered quaternions, --columns), metres; profiles as
    .npy (2 columns x, z) and CSV (np.savetxt, header x,y,z); sphere centre unknown."""
    cell = make_cell(n=14, seed=4, side=1)
    q = cell.quaternions_xyzw()
    q[:, :3] /= 1000.0
    np.savetxt(tmp_path / "poses.txt", np.column_stack([np.arange(1, 15), q]), fmt=["%d"] + ["%.9f"] * 7)
    (tmp_path / "prof").mkdir()
    for k, xz in enumerate(cell.profiles):
        if k % 2:
            np.save(tmp_path / "prof" / f"p{k + 1}.npy", xz)
        else:
            pts = np.column_stack([xz[:, 0], np.zeros(len(xz)), xz[:, 1]])
            np.savetxt(tmp_path / "prof" / f"p{k + 1}.csv", pts, delimiter=",", header="x,y,z", comments="")
    out, summary, res = _new_and_calibrate(
        tmp_path, capsys, ["--poses", str(tmp_path / "poses.txt"), "--columns", "id,x,y,z,qx,qy,qz,qw", "--units", "m",
                           "--profiles", str(tmp_path / "prof" / "*.npy"), "--profiles", str(tmp_path / "prof" / "*.csv"),
                           "--diameter", str(cell.diameter), "--side", "1"], unknowns="sensor+sphere")
    assert "convention abb" in summary and "--unknowns sensor+sphere" in summary
    assert "positions m -> mm" in summary and "reordered to w,x,y,z" in summary
    _assert_near_truth(cell, res)
    assert np.linalg.norm(np.array(res["sphere_center"]) - cell.centre) < 4 * np.linalg.norm(res["std"]["sphere_center_mm"])


def test_ros2_bag_pose_stamped_and_pointcloud2(tmp_path, capsys):
    """A ROS 2 bag (rosbags' own Writer, sqlite3): PoseStamped in metres and quaternions (x, y, z, w),
    PointCloud2 float32 profiles 10 ms after each pose, and one profile with no pose near it."""
    pytest.importorskip("rosbags")
    from ingest_bags import write_bag

    cell = make_cell(n=14, seed=6)
    bag = write_bag(tmp_path / "bag", cell)
    centre = ",".join(map(str, cell.centre))
    out, summary, res = _new_and_calibrate(tmp_path, capsys, [
        "--bag", str(bag), "--pose-topic", "/robot/flange_pose", "--profile-topic", "/sensor/profile",
        "--diameter", str(cell.diameter), "--center", centre, "--convention", "kuka"])
    assert "14 poses (geometry_msgs/msg/PoseStamped), 15 profiles" in summary and "1 without a pose" in summary
    assert "convention kuka" in summary and "laser plane y = 0" in summary
    _assert_near_truth(cell, res)


def test_ros2_bag_tf_chain_and_laserscan_turned_into_the_plane(tmp_path, capsys):
    """/tf (base_link -> link_6 -> tool0) and LaserScan profiles (scan plane z = 0, the scan's x the
    measuring direction) in an mcap bag: the plane's axes are found and turned (recorded), and the
    calibrated frame is the files' own (the truth's turned)."""
    pytest.importorskip("rosbags")
    from ingest_bags import write_bag

    cell = make_cell(n=14, seed=7)
    bag = write_bag(tmp_path / "bag", cell, poses="tf", profiles="scan", circles=cell.circles, storage="mcap",
                    extra_profile=False)
    centre = ",".join(map(str, cell.centre))
    out, summary, res = _new_and_calibrate(tmp_path, capsys, [
        "--bag", str(bag), "--pose-topic", "/tf", "--base-frame", "base_link", "--flange-frame", "tool0",
        "--profile-topic", "/sensor/profile", "--diameter", str(cell.diameter), "--center", centre])
    assert "laser plane z = 0: handeye x = file y, y = file z, z = file x (R" in summary and "convention abb" in summary
    prov = (out / "PROVENANCE.toml").read_text()
    assert "rotation_handeye_from_file" in prov and "[[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]]" in prov
    _assert_near_truth(cell, res, turn=[[0, 1, 0], [0, 0, 1], [1, 0, 0]])


def test_abb_csv_with_ply_profiles_whose_z_grows_towards_the_sensor(tmp_path, capsys):
    """Profiles (binary PLY, written here) in a frame turned half a turn about x from handeye's
    (z a height towards the sensor, as RobCalibrator's scanner writes it): the cap faces +z, so z
    is flipped (and y with it); --side is given in the files' frame and written in handeye's."""
    import struct

    from ingest_truth import quaternion

    cell = make_cell(n=14, seed=8, side=-1)
    rows = "".join(f"{k + 1},{','.join(f'{v:.9f}' for v in (*f[:3, 3], *quaternion(f[:3, :3])))}\n"
                   for k, f in enumerate(cell.flange2base))
    (tmp_path / "poses.csv").write_text("id,x,y,z,q1,q2,q3,q4\n" + rows)
    (tmp_path / "ply").mkdir()
    for k, xz in enumerate(cell.profiles):
        pts = np.column_stack([xz[:, 0], np.zeros(len(xz)), -xz[:, 1]])  # the file's z = -handeye's z, y = -y
        head = f"ply\nformat binary_little_endian 1.0\nelement vertex {len(pts)}\nproperty float x\nproperty float y\n" \
               "property float z\nend_header\n"
        (tmp_path / "ply" / f"line{k + 1}.ply").write_bytes(head.encode() + b"".join(struct.pack("<fff", *p) for p in pts))
    out, summary, res = _new_and_calibrate(tmp_path, capsys, [
        "--poses", str(tmp_path / "poses.csv"), "--profiles", str(tmp_path / "ply"), "--diameter", str(cell.diameter),
        "--center", ",".join(map(str, cell.centre)), "--side", "1"])
    assert "faced +z in 14 of 14" in summary and "y = file -y, z = file -z" in summary
    assert "--side +1 (the profiles' y) is side -1 in handeye's y" in summary
    assert "side = -1" in (out / "setup.toml").read_text()
    _assert_near_truth(cell, res, turn=[[1, 0, 0], [0, -1, 0], [0, 0, -1]])
