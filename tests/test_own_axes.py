"""Profiles in the sensor's own frame, turned by ``handeye dataset new`` into handeye's (laser
plane y = 0), keep their turn as ``[profile] own_axes``; every pose the user reads or types is of
the sensor's own frame: calibrate's JSON and text, ``--start``, ``--sensor-pose``, setup.toml's
start pose, export, cloud, validate, compare, the report and diagnose (a new user's ROS export was
90 deg off their sensor's frame before, and two frames leaked to the user). The cell here is
handeye's simulator, its profiles rewritten by plain numpy as 3-column points in the plane z = 0
(a sensor that reports x along the line, y the depth); the truth of the files' frame is the
simulated truth turned by hand, and every pose is checked against it by plain numpy (matrices
from KUKA angles, quaternions and roll-pitch-yaw written out here), not by handeye's conversions."""
from __future__ import annotations

import csv
import json
import re
import shutil

import numpy as np
import pytest
from scipy.spatial import cKDTree

import handeye
from handeye.app.command.cli import main

#: the files' frame in handeye's: p_h = R p_file with (x, y, z)_file = (x_h, z_h, -y_h)
ROT = np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])
TURN = np.eye(4)
TURN[:3, :3] = ROT


def _rx(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def _ry(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def _rz(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def kuka(pose):
    """4x4 of a KUKA pose x, y, z (mm), A, B, C (deg): Rz(A) Ry(B) Rx(C)."""
    m = np.eye(4)
    a, b, c = np.radians(pose[3:6])
    m[:3, :3] = _rz(a) @ _ry(b) @ _rx(c)
    m[:3, 3] = pose[:3]
    return m


def kuka_of(m):
    """KUKA x, y, z, A, B, C of a 4x4 (the inverse of :func:`kuka`, B in (-90, 90))."""
    r = m[:3, :3]
    return np.r_[m[:3, 3], np.degrees([np.arctan2(r[1, 0], r[0, 0]), -np.arcsin(r[2, 0]), np.arctan2(r[2, 1], r[2, 2])])]


def near(m, truth, mm=0.2, deg=0.1):
    """``m`` within ``mm`` and ``deg`` of ``truth`` (4x4 each)."""
    angle = np.degrees(np.arccos(np.clip((np.trace(m[:3, :3].T @ truth[:3, :3]) - 1) / 2, -1, 1)))
    return np.linalg.norm(m[:3, 3] - truth[:3, 3]) < mm and angle < deg


def numbers(text):
    return [float(v) for v in re.findall(r"-?\d+\.\d+(?:e[-+]?\d+)?", text)]


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
    truth = kuka(handeye.load_dataset(sim).truth["sensor_pose"])
    return root, sim, truth @ TURN, ROT


def _new(turned, out, *extra):
    root, sim, _, _ = turned
    data = handeye.load_dataset(sim)
    return main(["dataset", "new", str(out), "--poses", str(root / "poses.csv"), "--profiles", str(root / "files"),
                 "--diameter", "59.94507", "--side", str(-data.side), "--center",
                 ",".join(map(str, data.sphere_centre)), *extra])


@pytest.fixture(scope="module")
def cell(turned, tmp_path_factory):
    """A dataset made by dataset new with a start pose typed in the own frame (10 mm, 2 deg off the
    truth), calibrated once with --out and --report."""
    _, _, truth_own, _ = turned
    tmp = tmp_path_factory.mktemp("cell")
    start = kuka_of(truth_own) + np.array([10.0, -5.0, 4.0, 2.0, -1.5, 1.0])
    assert _new(turned, tmp / "cell", "--start", ",".join(map(repr, start.tolist()))) == 0
    result = handeye.calibrate(tmp / "cell", no_loo=True, out=tmp / "cal.json", report=tmp / "report.html")
    return tmp, result, start


def test_dataset_new_writes_the_own_frame_and_its_marker(turned, cell, capsys):
    _, _, truth_own, rot = turned
    tmp, _, start = cell
    data = handeye.load_dataset(tmp / "cell")
    np.testing.assert_allclose(data.own_axes, rot, atol=1e-12)
    setup = (tmp / "cell" / "setup.toml").read_text()
    assert 'poses = "own"' in setup
    written = np.array(numbers(setup.split("start_pose")[1].splitlines()[0]))
    np.testing.assert_allclose(written, start, atol=1e-9)  # as typed: the own frame
    # turned into handeye's on load, once: the start's matrix of handeye's frame is S_own R^T
    np.testing.assert_allclose(kuka(data.start_pose), kuka(start) @ TURN.T, atol=1e-9)
    assert data.poses_read is None


def test_calibrate_reports_the_own_frame(turned, cell):
    _, _, truth_own, rot = turned
    tmp, result, start = cell
    assert result.converged
    out = result.to_dict()
    assert not [k for k in out if k.endswith("_own")]
    assert out["sensor_frame"] == "own"
    assert near(np.array(out["sensor_matrix"]), truth_own)
    assert near(kuka(out["sensor_pose"]), truth_own) and near(kuka(out["sensor_pose_kuka"]), truth_own)
    np.testing.assert_allclose(kuka(out["start_pose"]), kuka(start), atol=1e-6)  # the start as typed, own frame
    gimbal = any("Euler singularity" in w for w in out["warnings"])  # of the angles reported, the own frame's
    assert gimbal == (abs(abs(kuka_of(np.array(out["sensor_matrix"]))[4]) - 90) < 1.0)
    saved = json.loads((tmp / "cal.json").read_text())
    np.testing.assert_allclose(saved["sensor_matrix"], out["sensor_matrix"], atol=1e-12)
    # the Python attributes are of the own frame too: what a caller passes on (cloud, compare) is what it read
    assert result.pose_frame == "own" and near(np.asarray(result.sensor2flange), truth_own)
    np.testing.assert_allclose(result.std.sensor_rotation_deg, out["std"]["sensor_rotation_deg"], rtol=1e-12)
    cov = np.array(out["covariance"]["matrix"])
    np.testing.assert_allclose(np.degrees(np.sqrt(np.diag(cov)[3:6])), out["std"]["sensor_rotation_deg"], rtol=1e-9)
    text = result.summary()
    first = next(line for line in text.splitlines() if line.startswith("start pose"))
    np.testing.assert_allclose(kuka(numbers(first.split(":", 1)[1])[-6:]), kuka(start), atol=1e-4)
    line = next(line for line in text.splitlines() if line.startswith("sensor pose"))
    assert near(kuka(numbers(line.split(":", 1)[1])[-6:]), truth_own)
    assert "sensor's own frame" in text


def _exported(source, fmt):
    return handeye.export(source, format=fmt).text


def test_export_writes_the_own_frame(turned, cell):
    _, _, truth_own, _ = turned
    tmp, result, _ = cell
    for source in (tmp / "cal.json", result):
        text = _exported(source, "matrix")
        m = np.array([[float(v) for v in ln.split()] for ln in text.splitlines() if not ln.startswith("#")])
        assert near(m, truth_own)
    ros = _exported(tmp / "cal.json", "ros2")
    v = {k: float(x) for k, x in re.findall(r"--(q?[xyzw]) (-?[\d.]+)", ros)}
    x, y, z, w = v["qx"], v["qy"], v["qz"], v["qw"]
    q = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                  [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                  [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
    m = np.eye(4)
    m[:3, :3], m[:3, 3] = q, 1000 * np.array([v["x"], v["y"], v["z"]])
    assert near(m, truth_own)
    urdf = _exported(tmp / "cal.json", "urdf")
    xyz = [float(t) for t in re.search(r'xyz="([^"]+)"', urdf).group(1).split()]
    roll, pitch, yaw = [float(t) for t in re.search(r'rpy="([^"]+)"', urdf).group(1).split()]
    m = np.eye(4)
    m[:3, :3], m[:3, 3] = _rz(yaw) @ _ry(pitch) @ _rx(roll), 1000 * np.array(xyz)
    assert near(m, truth_own)
    doc = json.loads(_exported(tmp / "cal.json", "json"))
    assert doc["sensor_frame"] == "own" and near(np.array(doc["sensor_matrix"]), truth_own)


def test_typed_poses_are_of_the_own_frame(turned, cell):
    """--sensor-pose (score, cloud, validate) and a 4x4 given to compare are of the own frame."""
    root, _, truth_own, _ = turned
    tmp, result, _ = cell
    own = np.array(result.to_dict()["sensor_matrix"])
    typed = ",".join(map(repr, kuka_of(own).tolist()))
    score = handeye.calibrate(tmp / "cell", sensor_pose=typed, no_loo=True)
    assert "own frame" in score.source and not score.contradicted
    assert score.distance["translation_mm"] < 1e-6 and score.distance["rotation_deg"] < 1e-6
    np.testing.assert_allclose(score.to_dict()["sensor_matrix"], own, atol=1e-6)
    assert near(np.array(score.to_dict()["estimate"]["sensor_matrix"]), truth_own)
    # cloud: every point is F_i S_own p_file, by numpy from the files and the poses
    by_file = handeye.cloud(tmp / "cell", tmp / "cal.json")
    by_pose = handeye.cloud(tmp / "cell", sensor_pose=typed)
    np.testing.assert_allclose(by_pose.points, by_file.points, atol=1e-6)
    rows = list(csv.DictReader((root / "poses.csv").open()))
    mine = np.concatenate([(kuka([float(r[c]) for c in "xyzabc"]) @ own @ np.c_[
        np.load(root / "files" / f"scan_{k:03d}.npy"), np.ones((len(np.load(root / "files" / f"scan_{k:03d}.npy")), 1))
    ].T).T[:, :3] for k, r in enumerate(rows, start=1)])
    assert cKDTree(mine).query(by_file.points)[0].max() < 1e-5  # the profiles written with 6 decimals
    # validate: the sphere measured through the own pose is the setup's
    for given in ({"calibration": tmp / "cal.json"}, {"sensor_pose": typed}):
        sphere = handeye.validate(tmp / "cell", **given).to_dict()["spheres"][0]
        assert np.linalg.norm(sphere["centre_offset_mm"]) < 0.2 and abs(sphere["size_error_mm"]) < 0.1
    # compare: a 4x4 of the own frame, the file, and the export read back (each in its frame)
    exported = tmp / "exported.json"
    exported.write_text(_exported(tmp / "cal.json", "json"))
    back = handeye.compare(tmp / "cell", tmp / "cal.json", exported)
    assert back.between["translation_mm"] < 1e-6 and back.between["rotation_deg"] < 1e-6
    typed4 = handeye.compare(tmp / "cell", own, tmp / "cal.json")
    assert typed4.between["translation_mm"] < 1e-6 and typed4.between["rotation_deg"] < 1e-6
    # a file that names no frame (the matrix copied from --json) is of the user's own frame, as a typed 4x4
    bare = tmp / "bare.json"
    bare.write_text(json.dumps({"sensor_matrix": own.tolist()}))
    np.testing.assert_allclose(handeye.cloud(tmp / "cell", bare).points, by_file.points, atol=1e-6)
    assert handeye.compare(tmp / "cell", bare, tmp / "cal.json").between["translation_mm"] < 1e-6
    # the result's own attributes, passed on, are what its JSON says: of the own frame
    np.testing.assert_allclose(handeye.cloud(tmp / "cell", result.sensor2flange).points, by_file.points, atol=1e-6)
    other = tmp / "other.json"  # a file of another sensor's own frame is refused, never turned by the wrong axes
    other.write_text(json.dumps({**json.loads((tmp / "cal.json").read_text()), "own_axes": np.eye(3).tolist()}))
    with pytest.raises(handeye.InputError, match="own_axes"):
        handeye.cloud(tmp / "cell", other)
    for entry in typed4.to_dict()["scores"].values():
        np.testing.assert_allclose(entry["sensor_matrix"], own, atol=1e-6)
    assert numbers(typed4.summary().splitlines()[3])[:3] == pytest.approx(kuka_of(own)[:3], abs=1e-3)


def test_report_and_diagnose_are_of_the_own_frame(turned, cell):
    _, _, truth_own, _ = turned
    tmp, result, _ = cell
    page = (tmp / "report.html").read_text()
    embedded = json.loads(re.search(r'id="handeye-result">(.*?)</script>', page, re.S).group(1))
    assert near(np.array(embedded["sensor_matrix"]), truth_own)
    card = page[page.index("<section id='card'>"):]
    assert near(kuka(numbers(card.split("<table class='pose'>")[1].split("</table>")[0])[:6]), truth_own)
    diag = handeye.diagnose(tmp / "cell", out=tmp / "diag.json")
    out = diag.to_dict()
    assert out["sensor_frame"] == "own" and near(np.array(out["sensor_matrix"]), truth_own)
    assert near(kuka(out["sensor_pose"]), truth_own) and near(kuka(out["sensor_pose_as"]["pose"]), truth_own)
    line = next(ln for ln in diag.summary().splitlines() if ln.startswith("sensor pose"))
    assert near(kuka(numbers(line.split(":", 1)[1])[-6:]), truth_own)
    text = _exported(tmp / "diag.json", "matrix")
    m = np.array([[float(v) for v in ln.split()] for ln in text.splitlines() if not ln.startswith("#")])
    assert near(m, truth_own)
    kim = handeye.calibrate(tmp / "cell", method="kim-cho", keep_all=True).to_dict()
    assert kim["sensor_frame"] == "own" and near(np.array(kim["sensor_matrix"]), truth_own, 1.0, 0.5)


def test_an_older_dataset_and_file_still_read(turned, cell, tmp_path):
    """A setup.toml written before ``poses = "own"`` has its start pose in handeye's turned frame:
    read so, said in one line, and the same answer; an older calibration file (sensor_frame
    "profiles" or none: handeye's turned frame) reads as before."""
    _, _, truth_own, _ = turned
    tmp, result, start = cell
    old = tmp_path / "old"
    shutil.copytree(tmp / "cell", old)
    setup = (old / "setup.toml").read_text()
    start_h = kuka_of(kuka(start) @ TURN.T)  # the turned frame's start, by numpy
    line = next(ln for ln in setup.splitlines() if ln.startswith("start_pose"))
    setup = setup.replace(line, "start_pose = [" + ", ".join(map(repr, start_h.tolist())) + "]")
    (old / "setup.toml").write_text(setup.replace('poses = "own"\n', ""))
    again = handeye.calibrate(old, no_loo=True)
    np.testing.assert_allclose(again.to_dict()["sensor_matrix"], result.to_dict()["sensor_matrix"], atol=1e-5)
    np.testing.assert_allclose(kuka(again.to_dict()["start_pose"]), kuka(start), atol=1e-6)
    notes = [w for w in again.warnings if "poses" in w]
    assert len(notes) == 1 and "turned frame" in notes[0] and "turned frame" in again.summary()
    doc = json.loads((tmp / "cal.json").read_text())
    internal = np.array(doc["sensor_matrix"]) @ TURN.T
    for frame in ("profiles", None):
        older = dict(doc, sensor_matrix=internal.tolist(), covariance=None)
        older.pop("sensor_frame")
        if frame:
            older["sensor_frame"] = frame
        (tmp_path / "older.json").write_text(json.dumps(older))
        text = _exported(tmp_path / "older.json", "matrix")
        m = np.array([[float(v) for v in ln.split()] for ln in text.splitlines() if not ln.startswith("#")])
        np.testing.assert_allclose(m, doc["sensor_matrix"], atol=1e-9)
        assert "turned frame" in text


def test_own_axes_must_be_a_rotation(turned, tmp_path):
    _, sim, _, _ = turned
    import shutil

    folder = tmp_path / "bad"
    shutil.copytree(sim, folder)
    setup = folder / "setup.toml"
    setup.write_text(setup.read_text().replace("[profile]", "[profile]\nown_axes = [[1, 0, 0], [0, 1, 0], [0, 0, -1]]"))
    with pytest.raises(handeye.InputError, match=r"\[profile\] own_axes.*proper rotation"):
        handeye.load_dataset(folder)


def test_a_setup_s_start_and_a_held_pose_are_of_the_own_frame(turned, cell, tmp_path):
    """--setup takes the start pose of the own frame across (and an older setup's, of handeye's
    turned frame, turned into the own); ``[sensor] pose`` held is of the own frame."""
    _, _, truth_own, _ = turned
    tmp, result, start = cell
    older = tmp_path / "older.toml"
    start_h = kuka_of(kuka(start) @ TURN.T)
    setup = (tmp / "cell" / "setup.toml").read_text()
    line = next(ln for ln in setup.splitlines() if ln.startswith("start_pose"))
    older.write_text(setup.replace(line, "start_pose = [" + ", ".join(map(repr, start_h.tolist())) + "]")
                     .replace('poses = "own"\n', ""))
    for source in (tmp / "cell" / "setup.toml", older):
        out = tmp_path / source.stem
        assert _new(turned, out, "--setup", str(source)) == 0
        written = numbers((out / "setup.toml").read_text().split("start_pose")[1].splitlines()[0])
        np.testing.assert_allclose(kuka(written), kuka(start), atol=1e-9)
    held = tmp_path / "held"
    shutil.copytree(tmp / "cell", held)
    own = kuka_of(truth_own)
    (held / "setup.toml").write_text((held / "setup.toml").read_text().replace(
        "[sensor]\n", "[sensor]\npose = [" + ", ".join(map(repr, own.tolist())) + "]\n"))
    sphere = handeye.calibrate(held, unknowns="sphere", no_loo=True).to_dict()
    np.testing.assert_allclose(sphere["sensor_matrix"], truth_own, atol=1e-9)
    assert np.linalg.norm(np.array(sphere["sphere_center"]) - handeye.load_dataset(held).sphere_centre) < 0.2


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


def _rotvec(w):
    """Rodrigues' rotation of a rotation vector (rad), written out."""
    angle = np.linalg.norm(w)
    if angle == 0:
        return np.eye(3)
    k = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]]) / angle
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


def test_the_identifiability_analysis_is_of_the_own_axes(turned, cell):
    """The rank analysis the JSON reports (scaled singular values, weakest direction) is of the
    Jacobian in the own frame's chart: its columns by central differences of the residual at the
    sensor pose moved by dt (mm) and turned about its own axes by dw (rad), written out here (in
    handeye's axes the weakest direction names other rotations)."""
    from handeye.app.engine.robust import _subset
    from handeye.model.datasets.observations import build
    from handeye.model.design.identifiability import analyse

    tmp, result, _ = cell
    own = np.asarray(result.sensor2flange)
    data = handeye.load_dataset(tmp / "cell")
    used = np.array([r["used"] for r in result.to_dict()["residuals"]], bool)
    model = _subset(build(data, result.model, "local", result.unknowns), used)

    def residual(step):
        moved = own.copy()
        moved[:3, 3] += step[:3]
        moved[:3, :3] = own[:3, :3] @ _rotvec(step[3:])
        return model.residual(model.point_from(moved @ TURN.T))  # the own frame's pose in handeye's

    h = 1e-6
    jac = np.column_stack([(residual(h * e) - residual(-h * e)) / (2 * h) for e in np.eye(6)])
    want = analyse(jac, ("tx", "ty", "tz", "wx", "wy", "wz"))
    got = result.identifiability
    np.testing.assert_allclose(got.singular_values, want.singular_values, rtol=1e-5)
    assert got.weakest_direction.keys() == want.weakest_direction.keys()
    for k, v in want.weakest_direction.items():
        assert abs(got.weakest_direction[k] - v) < 1e-3, (k, got.weakest_direction, want.weakest_direction)
    assert result.to_dict()["identifiability"]["singular_values"] == pytest.approx(list(got.singular_values))
    turn = np.eye(6)
    turn[3:, 3:] = ROT.T  # dw_own = R^T dw: the same Jacobian in handeye's chart is jac @ turn
    theirs = analyse(jac @ turn, want.names)  # what the JSON said before: of handeye's axes (here permuted)
    assert theirs.weakest_direction != got.weakest_direction, theirs.weakest_direction
