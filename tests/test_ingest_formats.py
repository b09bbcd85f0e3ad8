"""The readers of ``handeye dataset new`` against files written by other code: OpenCV's FileStorage
(YAML, XML, JSON), numpy (.npy, .npz, savetxt), and PLY/PCD writers written here from the formats'
specifications (independently of the readers)."""
import json
import struct

import numpy as np
import pytest

from handeye.app.ingest import clouds, plane, poses
from handeye.app.ingest.pairing import natural_key, pair
from handeye.model.readers.tables import DatasetError

RNG = np.random.default_rng(0)
POINTS = np.column_stack([RNG.uniform(-20, 20, 30), np.zeros(30), RNG.uniform(220, 260, 30)])


def _read(path):
    fmt, matrices = clouds.read_profile_file(path)
    return fmt, matrices


@pytest.mark.parametrize("ext, fmt", [("yml", "FileStorage YAML"), ("xml", "FileStorage XML"),
                                      ("json", "FileStorage JSON")])
def test_opencv_filestorage_with_nan_and_inf_rows(tmp_path, ext, fmt):
    cv2 = pytest.importorskip("cv2")
    pts = POINTS.copy()
    pts[4, 0], pts[9, 2] = np.nan, -np.inf
    path = tmp_path / f"profile.{ext}"
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    fs.write("profile", pts)
    fs.write("second", pts[:, [0, 2]].astype(np.float32))
    fs.release()
    renamed = tmp_path / "no_extension"  # told by the content
    renamed.write_bytes(path.read_bytes())
    got_fmt, matrices = _read(renamed)
    assert got_fmt == fmt and [m[0] for m in matrices] == ["profile", "second"]
    np.testing.assert_array_equal(np.isnan(matrices[0][1]), np.isnan(pts))
    finite, dropped = plane.finite_rows(matrices[0][1])
    assert dropped == 2 and len(finite) == 28
    np.testing.assert_allclose(finite, np.delete(pts, [4, 9], axis=0))
    np.testing.assert_allclose(plane.finite_rows(matrices[1][1])[0],
                               plane.finite_rows(pts[:, [0, 2]].astype(np.float32))[0], rtol=1e-6)


def test_numpy_npy_npz_and_savetxt(tmp_path):
    np.save(tmp_path / "a.npy", POINTS)
    np.savez(tmp_path / "b.npz", first=POINTS[:, [0, 2]], second=POINTS)
    np.savetxt(tmp_path / "c.txt", POINTS)                                 # whitespace, no header
    np.savetxt(tmp_path / "d.csv", POINTS[:, [0, 2]], delimiter=",", header="X,Z", comments="")
    assert _read(tmp_path / "a.npy")[0] == "npy"
    np.testing.assert_allclose(_read(tmp_path / "a.npy")[1][0][1], POINTS)
    fmt, mats = _read(tmp_path / "b.npz")
    assert fmt == "npz" and [m[0] for m in mats] == ["first", "second"]
    np.testing.assert_allclose(_read(tmp_path / "c.txt")[1][0][1], POINTS)
    np.testing.assert_allclose(_read(tmp_path / "d.csv")[1][0][1], POINTS[:, [0, 2]])


def _ply(path, pts, fmt):
    head = (f"ply\nformat {fmt} 1.0\ncomment written by the test\nelement vertex {len(pts)}\nproperty double x\n"
            "property double y\nproperty double z\nproperty uchar intensity\nelement face 0\n"
            "property list uchar int vertex_indices\nend_header\n")
    if fmt == "ascii":
        body = "".join(f"{x:.17g} {y:.17g} {z:.17g} 7\n" for x, y, z in pts).encode()
    else:
        order = "<" if fmt == "binary_little_endian" else ">"
        body = b"".join(struct.pack(order + "dddB", *p, 7) for p in pts)
    path.write_bytes(head.encode() + body)


def _pcd(path, pts, data):
    head = ("# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS x y z rgb\nSIZE 4 4 4 4\nTYPE F F F U\n"
            f"COUNT 1 1 1 1\nWIDTH {len(pts)}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {len(pts)}\nDATA {data}\n")
    if data == "ascii":
        body = "".join(f"{x:.6f} {y:.6f} {z:.6f} 0\n" for x, y, z in pts).encode()
    else:
        body = b"".join(struct.pack("<fffI", *p, 0) for p in pts)
    path.write_bytes(head.encode() + body)


@pytest.mark.parametrize("fmt", ["ascii", "binary_little_endian", "binary_big_endian"])
def test_ply(tmp_path, fmt):
    _ply(tmp_path / "p.ply", POINTS, fmt)
    got_fmt, mats = _read(tmp_path / "p.ply")
    assert got_fmt == "ply"
    np.testing.assert_allclose(mats[0][1], POINTS)


@pytest.mark.parametrize("data", ["ascii", "binary"])
def test_pcd(tmp_path, data):
    _pcd(tmp_path / "p.pcd", POINTS, data)
    got_fmt, mats = _read(tmp_path / "p.pcd")
    assert got_fmt == "pcd"
    np.testing.assert_allclose(mats[0][1], POINTS, atol=1e-4)


def test_plane_found_and_turned_properly():
    """Points in z = 0 (x along the line, y the depth) become handeye (x, z) by a proper rotation."""
    xy0 = POINTS[:, [0, 2, 1]]  # x, depth in y, z = 0
    mapping = plane.decide([("f", xy0)])
    assert mapping.normal == "z" and mapping.x_from == "x" and mapping.z_from == "y"
    assert np.isclose(np.linalg.det(mapping.rotation), 1.0)
    np.testing.assert_allclose(plane.to_xz(xy0, mapping), POINTS[:, [0, 2]])
    assert plane.decide([("f", POINTS)]).identity
    turned = plane.decide([("f", xy0)], axes=((0, -1.0), (1, 1.0)))  # --profile-axes -x,y
    np.testing.assert_allclose(plane.to_xz(xy0, turned)[:, 0], -POINTS[:, 0])


def test_pose_columns_by_alias_and_convention():
    assert [poses.canonical(n) for n in ("Pos_X [mm]", "pose.position.y", "TZ", "orientation.w", "Q1", "rot_x", "A",
                                         "Index", "joint_3", "time")] == \
        ["x", "y", "z", "qw", "qw", "qx", "a", "id", "j3", None]


def test_pose_files_csv_whitespace_json(tmp_path):
    kuka = np.array([[500.0, 10, 300, 10, -80, 5], [510, 0, 310, -170, 20, 179], [490, -5, 305, 45, 0, 90]])
    (tmp_path / "a.csv").write_text("Name,X,Y,Z,A,B,C,time\n" + "".join(
        f"P{k},{','.join(map(str, p))},0.5\n" for k, p in enumerate(kuka)))
    t = poses.read_poses(tmp_path / "a.csv")
    assert t.convention == "kuka" and t.ids == ("P0", "P1", "P2") and "columns ignored: time" in t.notes
    np.testing.assert_allclose(t.values, kuka)
    np.savetxt(tmp_path / "b.txt", kuka)
    with pytest.raises(Exception, match="no header: give --convention"):
        poses.read_poses(tmp_path / "b.txt")
    np.testing.assert_allclose(poses.read_poses(tmp_path / "b.txt", convention="kuka").values, kuka)
    (tmp_path / "c.json").write_text(json.dumps(kuka.tolist()))
    t = poses.read_poses(tmp_path / "c.json", convention="kuka")
    assert t.format == "JSON list of lists" and t.ids is None
    fanuc = poses.read_poses(tmp_path / "c.json", columns=("x", "y", "z", "a", "b", "c"), convention="fanuc")
    assert fanuc.convention == "fanuc" and "poses converted kuka -> fanuc" in fanuc.notes


def test_pairing_by_number_order_and_zero_based():
    names = ["scan_10", "scan_2", "scan_1"]
    assert sorted(names, key=natural_key) == ["scan_1", "scan_2", "scan_10"]
    index, ids, how = pair(names, names, ("1", "2", "10"), 3, "poses.csv")
    assert index == [2, 1, 0] and how.startswith("by id")
    index, ids, how = pair(["a", "b"], ["a", "b"], None, 2, "poses.csv")
    assert index == [0, 1] and ids == ["1", "2"] and how.startswith("by order")
    index, ids, how = pair(["p0", "p1"], ["p0", "p1"], None, 2, "poses.csv")
    assert ids == ["0", "1"] and index == [0, 1]


def test_unknown_format_is_named(tmp_path):
    (tmp_path / "x.bin").write_bytes(b"\x00\x01\x02garbage")
    with pytest.raises(DatasetError, match=r"x\.bin: unknown format"):
        _read(tmp_path / "x.bin")


def test_opencv4_yaml_header_sequences_and_channels(tmp_path):
    """OpenCV 3/4 write ``%YAML:1.0`` and wrap long data over lines; a sequence of matrices gives one
    profile each; a 3-channel matrix (a vector of Point3f) one point per element."""
    (tmp_path / "scans.yml").write_text(
        "%YAML:1.0\n---\nprofiles:\n   - !!opencv-matrix\n      rows: 3\n      cols: 2\n      dt: d\n"
        "      data: [ 1., 240., 2., 241.,\n          .Nan, 242. ]\n   - !!opencv-matrix\n      rows: 3\n"
        "      cols: 1\n      dt: \"3f\"\n      data: [ 1., 0., 240., 2., 0., 241., 3., 0., -.Inf ]\n")
    fmt, mats = _read(tmp_path / "scans.yml")
    assert fmt == "FileStorage YAML" and len(mats) == 2
    np.testing.assert_array_equal(mats[0][1][:2], [[1, 240], [2, 241]])
    assert mats[1][1].shape == (3, 3) and plane.finite_rows(mats[1][1])[1] == 1


def test_sensor_export_headers_and_decimal_commas(tmp_path):
    """A sensor's CSV export names its columns with units (``X [mm]``) and carries more columns; a
    European controller export uses ';' and decimal commas."""
    (tmp_path / "prof.csv").write_text("Index,X [mm],Z [mm],Intensity\n" + "".join(
        f"{k},{x:.4f},{z:.4f},high\n" for k, (x, _, z) in enumerate(POINTS)))
    np.testing.assert_allclose(_read(tmp_path / "prof.csv")[1][0][1], POINTS[:, [0, 2]], atol=1e-4)
    (tmp_path / "poses.csv").write_text("Nr;X;Y;Z;A;B;C\n1;500,5;10;300;10;-80,25;5\n2;510;0,5;310;-170;20;179\n"
                                        "3;490;-5;305;45;0;90\n")
    t = poses.read_poses(tmp_path / "poses.csv")
    assert t.format == "semicolon-separated text, decimal commas" and t.ids == ("1", "2", "3")
    np.testing.assert_allclose(t.values[:2], [[500.5, 10, 300, 10, -80.25, 5], [510, 0.5, 310, -170, 20, 179]])
