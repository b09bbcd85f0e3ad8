"""Using a calibration: export (read back by independent parsers), point clouds, validation.

The parsers here rebuild the 4x4 from each format's text with scipy's Rotation and xml.etree,
never with handeye's conventions; the scan generator is written here, not handeye's simulator.
"""
import json
import re
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

import handeye
from handeye.app.command import cli
from handeye.app.outputs import formats as export
from handeye.app.outputs import saved
from handeye.model.chain import conventions
from handeye.model.geometry import cloud, sphere

TOL_MM, TOL_DEG = 1e-6, 1e-6


# ---------------------------------------------------------------- independent parsers
def _numbers(text):
    return [float(v) for v in re.findall(r"[-+]?\d+\.\d+(?:[eE][-+]?\d+)?|[-+]?\d+(?:[eE][-+]?\d+)?", text)]


def _transform(rot, trans_mm):
    t = np.eye(4)
    t[:3, :3] = rot.as_matrix()
    t[:3, 3] = trans_mm
    return t


def parse(fmt, text):
    """The 4x4 (mm) a format's text describes, by an independent reading of the format."""
    body = "\n".join(line for line in text.splitlines() if not line.lstrip().startswith(("#", ";", "!")))
    if fmt == "ur":
        v = _numbers(re.search(r"set_tcp\(p\[(.*?)\]\)", body).group(1))
        return _transform(Rotation.from_rotvec(v[3:]), np.array(v[:3]) * 1000)
    if fmt == "ros2":
        opt = dict(re.findall(r"--(\w+) (\S+)", body))
        q = [float(opt[k]) for k in ("qx", "qy", "qz", "qw")]
        return _transform(Rotation.from_quat(q), np.array([float(opt[k]) for k in "xyz"]) * 1000)
    if fmt == "urdf":
        origin = ET.fromstring(text[text.index("<joint"):]).find("origin")
        xyz = [float(v) for v in origin.get("xyz").split()]
        rpy = [float(v) for v in origin.get("rpy").split()]
        return _transform(Rotation.from_euler("xyz", rpy), np.array(xyz) * 1000)  # extrinsic x, y, z = fixed axes
    if fmt == "kuka":
        frame = dict(re.findall(r"([XYZABC]) ([-+\d.eE]+)", re.search(r"TOOL_DATA\[\d+\]=\{(.*?)\}", body).group(1)))
        return _transform(Rotation.from_euler("ZYX", [float(frame[k]) for k in "ABC"], degrees=True),
                          [float(frame[k]) for k in "XYZ"])
    if fmt == "abb":
        inner = re.search(r"\[TRUE, \[\[(.*?)\], \[(.*?)\]\]", body)
        pos, q = _numbers(inner.group(1)), _numbers(inner.group(2))
        return _transform(Rotation.from_quat([q[1], q[2], q[3], q[0]]), pos)
    if fmt == "fanuc":
        v = {int(k): float(x) for k, x in re.findall(r"PR\[\d+,(\d)\]=\(?([-+\d.eE]+)\)?", text)}
        return _transform(Rotation.from_euler("xyz", [v[4], v[5], v[6]], degrees=True), [v[1], v[2], v[3]])
    if fmt == "matrix":
        return np.array([_numbers(line) for line in body.strip().splitlines()])
    return np.array(json.loads(text)["sensor_matrix"])


def _close(a, b):
    dt = float(np.linalg.norm(a[:3, 3] - b[:3, 3]))
    dr = float(np.degrees(Rotation.from_matrix(a[:3, :3].T @ b[:3, :3]).magnitude()))
    return dt, dr


# ---------------------------------------------------------------- calibrations to export
def _calibration(kuka_pose, sd=(0.1, 0.2, 0.3, 1e-3, 2e-3, 3e-3)):
    m = conventions.transform_from("kuka", np.asarray(kuka_pose, float))
    return saved.Calibration(m, np.diag(np.square(sd)), "test")


SINGULAR = {
    "kuka B=-90 (thesis CAD)": [156.99, 87.55, 115.0, 180.0, -90.0, 0.0],
    "kuka B=+90": [10.0, -20.0, 30.0, 33.0, 90.0, -12.0],
    "kuka B=-89.9999": [189.69, 99.71, 130.36, -181.40 + 360, -89.9999, 0.155],
    "ur half turn": list(conventions.pose_from("kuka", _transform(Rotation.from_rotvec(np.pi * np.array([1, 0, 1]) /
                                                                                         np.sqrt(2)), [1, 2, 3]))),
    "ur near half turn": list(conventions.pose_from("kuka", _transform(
        Rotation.from_rotvec((np.pi - 1e-9) * np.array([0.3, -0.4, 0.866]) / np.linalg.norm([0.3, -0.4, 0.866])),
        [-400, 250, 80]))),
    "identity": [0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    "quaternion w=0": [5.0, 6.0, 7.0, 180.0, 0.0, 0.0],
}


@pytest.mark.parametrize("fmt", export.FORMATS)
@pytest.mark.parametrize("case", sorted(SINGULAR))
def test_every_format_reads_back_to_the_transform_near_its_singularity(fmt, case):
    cal = _calibration(SINGULAR[case])
    dt, dr = _close(parse(fmt, export.text(cal, fmt)), cal.sensor2flange)
    assert dt <= TOL_MM and dr <= TOL_DEG, (case, fmt, dt, dr)


@pytest.mark.parametrize("fmt", export.FORMATS)
def test_every_format_reads_back_on_random_poses(fmt):
    rng = np.random.default_rng(14)
    for _ in range(50):
        rot = Rotation.random(random_state=rng)
        cal = saved.Calibration(_transform(rot, rng.uniform(-500, 500, 3)), None, "random")
        dt, dr = _close(parse(fmt, export.text(cal, fmt)), cal.sensor2flange)
        assert dt <= TOL_MM and dr <= TOL_DEG, (fmt, dt, dr)


@pytest.fixture(scope="module")
def ur_cell(tmp_path_factory):
    """A UR cell (UR convention, 50.8 mm sphere, no start pose), simulated with profiles and
    calibrated, its result saved as calibrate --out does."""
    root = tmp_path_factory.mktemp("ur")
    handeye.simulate(root / "cell", seed=5, profiles=True, convention="ur", diameter=50.8, no_start=True,
                     truth="60,-40,90,0.3,-1.2,2.0")
    result = handeye.calibrate(root / "cell", out=root / "result.json")
    assert result.converged
    return root, result


@pytest.mark.parametrize("fmt", export.FORMATS)
def test_exports_of_saved_calibrations_equal_their_matrix(fmt, ur_cell, tmp_path):
    root, result = ur_cell
    sim = handeye.calibrate("thesis-sim", out=tmp_path / "sim.json")
    for path, res in ((root / "result.json", result), (tmp_path / "sim.json", sim)):
        text = handeye.export(path, format=fmt, parent="tool0", child="laser").text
        dt, dr = _close(parse(fmt, text), np.asarray(res.sensor2flange))
        assert dt <= TOL_MM and dr <= TOL_DEG, (path, fmt, dt, dr)


def test_exports_carry_units_names_and_the_uncertainty(ur_cell):
    root, result = ur_cell
    sd = np.sqrt(np.diag(result.covariance))
    ur = handeye.export(root / "result.json", format="ur").text
    assert f"{sd[0] / 1000:.3g}" in ur and "metres" in ur  # UR: the sd in metres too
    ros = handeye.export(root / "result.json", format="ros2", parent="tool0", child="laser").text
    assert "--frame-id tool0 --child-frame-id laser" in ros
    urdf = handeye.export(root / "result.json", format="urdf", parent="tool0", child="laser").text
    joint = ET.fromstring(urdf[urdf.index("<joint"):])
    assert (joint.get("type"), joint.find("parent").get("link"), joint.find("child").get("link")) == (
        "fixed", "tool0", "laser")
    ET.fromstring("<r>" + urdf + "</r>")  # the comment is valid XML too
    for fmt in ("kuka", "abb", "fanuc", "matrix"):
        assert f"{np.degrees(sd[3]):.3g}" in handeye.export(root / "result.json", format=fmt).text
    data = json.loads(handeye.export(root / "result.json", format="json").text)
    assert np.allclose(data["calibration"]["covariance"], result.covariance[:6, :6])


def test_export_refuses_what_it_cannot_use(tmp_path, capsys):
    bad = tmp_path / "bad.json"
    cases = {
        "missing.json": "missing file",
        "notjson": "not JSON",
        "nomatrix": "no sensor_matrix",
        "skew": "not a rigid transform",
    }
    docs = {"notjson": "{", "nomatrix": json.dumps({"a": 1}),
            "skew": json.dumps({"sensor_matrix": (np.eye(4) * [1, 1, 2, 1]).tolist()})}
    for name, message in cases.items():
        path = tmp_path / name
        if name in docs:
            path.write_text(docs[name])
        assert cli.main(["export", str(path)]) == 2
        assert message in capsys.readouterr().err
    doc = handeye.calibrate("thesis-sim").to_dict()
    bad.write_text(json.dumps(dict(doc, converged=False, message="iteration limit")))
    assert cli.main(["export", str(bad), "--format", "ur"]) == 2
    assert "did not converge" in capsys.readouterr().err
    assert cli.main(["export", str(bad), "--format", "ur", "--force"]) == 0
    assert cli.main(["export", str(bad), "--out", str(bad)]) == 2  # never over its input
    assert "reads" in capsys.readouterr().err
    assert cli.main(["export", str(bad), "--force", "--format", "urdf", "--child", "a b"]) == 2
    assert cli.main(["export", "--sensor-pose", "1,2,3,0,0", "--format", "ur"]) == 2


# ---------------------------------------------------------------- clouds
def test_point_jacobian_and_sd_against_central_differences():
    rng = np.random.default_rng(3)
    x = _transform(Rotation.random(random_state=rng), [190, 100, 125])
    f2b = np.stack([_transform(Rotation.random(random_state=rng), rng.uniform(-900, 900, 3)) for _ in range(4)])
    profiles = [rng.uniform(-50, 50, (5, 2)) + [0, 240] for _ in range(4)]
    xz = np.concatenate(profiles)
    pts, idx = cloud.points_in_base(f2b, x, profiles)
    jac = cloud.point_jacobian(xz, f2b, idx, x)
    h = 1e-6
    for k in range(6):
        d = np.zeros(6)
        d[k] = h

        def moved(sign):
            xd = x.copy()
            xd[:3, 3] += sign * d[:3]
            xd[:3, :3] = x[:3, :3] @ Rotation.from_rotvec(sign * d[3:]).as_matrix()
            return cloud.points_in_base(f2b, xd, profiles)[0]

        numeric = (moved(1) - moved(-1)) / (2 * h)
        assert np.allclose(numeric, jac[:, :, k], atol=1e-5)
    a = rng.normal(size=(6, 6))
    cov = a @ a.T * 1e-3
    direct = np.sqrt(np.einsum("mij,jk,mik->m", jac, cov, jac))
    assert np.allclose(cloud.point_sd(xz, x, cov), direct, rtol=1e-12)
    p3 = rng.normal(size=(6, 3)) * 50  # full sensor points (a sphere centre has y != 0)
    j3 = np.concatenate([np.eye(3)[None].repeat(6, 0), -x[:3, :3] @ np.stack(
        [[[0, -q[2], q[1]], [q[2], 0, -q[0]], [-q[1], q[0], 0]] for q in p3])], axis=2)
    assert np.allclose(cloud.point_sd(p3, x, cov), np.sqrt(np.einsum("mij,jk,mik->m", j3, cov, j3)), rtol=1e-12)
    normals = rng.normal(size=(len(xz), 3))
    assert np.allclose(cloud.radial_jacobian(normals, xz, f2b, idx, x), np.einsum("mi,mik->mk", normals, jac))


def test_cloud_of_simulated_profiles_lies_on_the_true_sphere(ur_cell, tmp_path):
    root, result = ur_cell
    truth = json.loads((root / "cell" / "simulation.json").read_text())["setup"]
    c = handeye.cloud(root / "cell", root / "result.json", out=tmp_path / "c.ply")
    radial = np.linalg.norm(c.points - truth["sphere_centre"], axis=1) - truth["diameter"] / 2
    rms = float(np.sqrt(np.mean(radial ** 2)))
    assert rms <= 0.05, rms  # the simulated noise: 0.01 mm per point, 0.025 mm robot per axis
    assert len(c.points) > 10_000 and c.sd is not None and np.all(c.sd > 0)
    # the PLY read back by hand: header, then little-endian records
    raw = (tmp_path / "c.ply").read_bytes()
    head, body = raw.split(b"end_header\n", 1)
    lines = head.decode().splitlines()
    assert lines[:2] == ["ply", "format binary_little_endian 1.0"]
    assert f"element vertex {len(c.points)}" in lines
    rec = np.frombuffer(body, dtype=[("x", "<f8"), ("y", "<f8"), ("z", "<f8"), ("pose", "<i4"), ("sd", "<f4")])
    assert np.array_equal(np.c_[rec["x"], rec["y"], rec["z"]], c.points)
    assert np.array_equal(rec["pose"], c.pose_index) and np.allclose(rec["sd"], c.sd, rtol=1e-6)
    handeye.cloud(root / "cell", root / "result.json", out=tmp_path / "c.csv", format="csv")
    table = np.genfromtxt(tmp_path / "c.csv", delimiter=",", names=True, dtype=None, encoding="utf-8")
    assert np.allclose(np.c_[table["x"], table["y"], table["z"]], c.points, atol=1e-6)


def test_cloud_needs_profiles_not_a_sphere(tmp_path, capsys):
    assert cli.main(["cloud", "thesis-sim", "--sensor-pose", "5,0,5,0,-90,0", "--out", str(tmp_path / "a.ply")]) == 2
    assert "profile" in capsys.readouterr().err
    scan = tmp_path / "part"
    (scan / "p").mkdir(parents=True)
    (scan / "measurements.csv").write_text("id,x,y,z,rx,ry,rz,profile\n1,0.5,0,0.3,0,3.14159,0,p/1.csv\n2,0.6,0,0.3,0,"
                                           "3.14159,0,\n")
    (scan / "p" / "1.csv").write_text("x,z\n-10,200\n0,201\n10,200.5\n")
    assert cli.main(["cloud", str(scan), "--sensor-pose", "0,0,100,0,0,0", "--out", str(tmp_path / "part.ply")]) == 0
    out = capsys.readouterr().out
    assert "3 points from 1 poses" in out and "skipped 1 rows" in out


def test_profile_reader_fast_and_careful_paths_agree(tmp_path):
    from handeye.model.readers import tables
    from handeye.model.readers.tables import DatasetError

    rng = np.random.default_rng(0)
    pts = rng.uniform(-40, 40, (200, 2))
    clean = "x,z\n" + "\n".join(f"{a!r},{b!r}" for a, b in pts.tolist()) + "\n"
    messy = "\ufeffx,z\r\n" + "\r\n\r\n".join(f" {a!r} , {b!r} " for a, b in pts.tolist()) + "\r\n\r\n"
    for name, text in (("clean.csv", clean), ("messy.csv", messy)):
        (tmp_path / name).write_text(text, encoding="utf-8")
        assert np.array_equal(tables.read_points(tmp_path, name, tmp_path / "m.csv", 2, 5000.0), pts)
    for bad, where in (("1_0,2", "row 3"), ("nan,1", "row 3"), ("1,9e9", "column 'z'"), ("1;2", "row 3")):
        (tmp_path / "bad.csv").write_text("x,z\n0,1\n" + bad + "\n")
        with pytest.raises(DatasetError, match=where):
            tables.read_points(tmp_path, "bad.csv", tmp_path / "m.csv", 2, 5000.0)


# ---------------------------------------------------------------- a scan generator of our own
def _scan(folder, sensor2flange, spheres, n_poses=24, noise=0.0, seed=0, diameters=None):
    """Write a scan: for each pose the laser plane (sensor y = 0) cuts one of ``spheres``
    ((centre, radius) in the base) at a random height; the flange pose follows from the sensor
    pose. Independent of handeye.model.simulation.simulate."""
    rng = np.random.default_rng(seed)
    (folder / "p").mkdir(parents=True)
    rows = ["id,x,y,z,a,b,c,profile"]
    for i in range(n_poses):
        centre, radius = spheres[i % len(spheres)]
        rot = Rotation.from_euler("ZYX", [rng.uniform(-180, 180), rng.uniform(-40, 40), 180 + rng.uniform(-40, 40)],
                                  degrees=True)
        ys = rng.uniform(-0.8, 0.8) * radius  # the plane's distance from the centre
        in_sensor = np.array([rng.uniform(-10, 10), ys, rng.uniform(200, 260)])
        s2b = _transform(rot, centre - rot.apply(in_sensor))
        f2b = s2b @ np.linalg.inv(sensor2flange)
        r = np.sqrt(radius ** 2 - ys ** 2)
        phi = np.linspace(np.pi + 0.3, 2 * np.pi - 0.3, 300)  # the side facing the sensor (z smaller)
        x = in_sensor[0] + r * np.cos(phi)
        z = in_sensor[2] + r * np.sin(phi) + rng.normal(0, noise, phi.shape)
        np.savetxt(folder / "p" / f"{i}.csv", np.c_[x, z], delimiter=",", header="x,z", comments="")
        pose = conventions.pose_from("kuka", f2b)
        rows.append(f"s{i}," + ",".join(f"{v:.12f}" for v in pose) + f",p/{i}.csv")
    (folder / "measurements.csv").write_text("\n".join(rows) + "\n")
    diameters = diameters or [2 * r for _, r in spheres]
    setup = "".join(f"[{name}]\ndiameter = {d!r}\ncenter = {list(map(float, c))}\n\n"
                    for name, d, (c, _) in zip(("sphere", "sphere2"), diameters, spheres))
    (folder / "setup.toml").write_text(setup + "[noise]\nrobot_mm = 0.001\n")
    return folder


X_TRUE = _transform(Rotation.from_euler("ZYX", [180, -88, 0], degrees=True), [190, 100, 125])
C1, C2 = np.array([1500.0, -600.0, 1100.0]), np.array([1500.0, -300.0, 1100.0])


def test_validate_equals_an_independent_sphere_fit_of_the_same_cloud(tmp_path):
    scan = _scan(tmp_path / "s", X_TRUE, [(C1, 25.0)], noise=0.01, seed=1)
    cal = saved.Calibration(X_TRUE, None, "truth")
    v = handeye.validate(scan, cal)
    c = handeye.cloud(scan, cal)

    def radial(p):
        return np.linalg.norm(c.points - p[:3], axis=1) - p[3]

    ref = least_squares(radial, np.r_[c.points.mean(axis=0), 20.0], xtol=1e-15, ftol=1e-15, gtol=1e-15)
    s = v.spheres[0]
    assert np.allclose(s.centre, ref.x[:3], atol=1e-8) and abs(s.radius_mm - ref.x[3]) < 1e-8
    dev = radial(ref.x)
    assert abs(s.form_error_mm - np.ptp(dev)) < 1e-8
    assert abs(s.size_error_mm - (2 * ref.x[3] - 50.0)) < 1e-8
    assert abs(s.size_error_mm) < 0.01 and np.linalg.norm(s.centre_offset_mm) < 0.01
    d = v.to_dict()["sphere"]
    assert {"radius_mm", "centre", "form_error_mm", "size_error_mm", "rms_mm"} <= set(d)
    assert v.n_points == len(c.points) and v.n_poses == 24


def test_validate_spacing_of_two_spheres_and_a_wrong_diameter(tmp_path):
    scan = _scan(tmp_path / "two", X_TRUE, [(C1, 25.0), (C2, 20.0)], noise=0.0, seed=2)
    v = handeye.validate(scan, saved.Calibration(X_TRUE, None, "truth"))
    assert abs(v.spacing.setup_distance_mm - 300.0) < 1e-9
    assert abs(v.spacing.error_mm) < 1e-6 and abs(v.spheres[1].size_error_mm) < 1e-6
    assert v.to_dict()["spacing"]["error_mm"] == v.spacing.error_mm
    # a setup that states the wrong diameter: PS shows it when the calibration is independent of it
    wrong = _scan(tmp_path / "wrong", X_TRUE, [(C1, 25.0)], diameters=[50.2], seed=3)
    assert abs(handeye.validate(wrong, saved.Calibration(X_TRUE, None, "truth")).spheres[0].size_error_mm + 0.2) < 1e-6
    # a calibration off by 1 mm in x moves every point with the sensor: the centre and PF show it
    off = X_TRUE.copy()
    off[0, 3] += 1.0
    bad = handeye.validate(scan, saved.Calibration(off, None, "off by 1 mm")).spheres[0]
    assert bad.form_error_mm > 0.2 and np.linalg.norm(bad.centre_offset_mm) > 0.3


@pytest.mark.slow(sibling="test_point_jacobian_and_sd_against_central_differences")
def test_validation_sd_matches_monte_carlo_of_the_calibration(tmp_path):
    """The calibration part of the 1-sd: draw calibrations from the covariance, refit."""
    scan = _scan(tmp_path / "mc", X_TRUE, [(C1, 25.0)], noise=0.0, seed=4, n_poses=12)
    cov = np.diag([0.05, 0.08, 0.1, 4e-4, 3e-4, 5e-4]) ** 2
    v = handeye.validate(scan, saved.Calibration(X_TRUE, cov, "cov"))
    rng = np.random.default_rng(9)
    radii = []
    for _ in range(200):
        d = rng.multivariate_normal(np.zeros(6), cov)
        x = X_TRUE.copy()
        x[:3, 3] += d[:3]
        x[:3, :3] = X_TRUE[:3, :3] @ Rotation.from_rotvec(d[3:]).as_matrix()
        radii.append(handeye.validate(scan, saved.Calibration(x, None, "draw")).spheres[0].radius_mm)
    predicted = v.spheres[0].sd_sources["calibration"]["radius_mm"]
    assert 0.75 < np.std(radii) / predicted < 1.3, (np.std(radii), predicted)


def test_single_profile_does_not_determine_a_sphere(tmp_path, capsys):
    scan = _scan(tmp_path / "one", X_TRUE, [(C1, 25.0)], n_poses=1)
    assert cli.main(["validate", str(scan), "--sensor-pose", "190,100,125,180,-88,0"]) == 2
    assert "do not determine a sphere" in capsys.readouterr().err
    with pytest.raises(sphere.SphereFitError):
        sphere.fit(np.random.default_rng(0).normal(size=(3, 3)))


def test_table_7_5_epsilon_is_sample_x0_at_table_7_4s_pose():
    """The thesis prints epsilon = (0.24, -0.67, -0.11) mm for its validation measurement: it is
    the centre residual of sample x+0 at the pose of Table 7-4 in y and z; x has the opposite
    sign (and 0.014 mm from the pose's printed rounding) -- a lost minus in the print."""
    v = handeye.validate("thesis-real", sensor_pose="189.69,99.71,130.36,-181.40,-89.24,0.155")
    eps = dict(zip(v.centres.ids, v.centres.epsilon))["x+0"]
    assert abs(eps[1] - -0.67) < 0.01 and abs(eps[2] - -0.11) < 0.01
    assert abs(eps[0] - -0.24) < 0.02 and abs(eps[0] - 0.24) > 0.4  # x: opposite sign
    # one pose chosen to show it hides the rest: other samples miss the centre by millimetres
    norms = np.linalg.norm(v.centres.epsilon, axis=1)
    assert np.median(norms) > 3.0


# ---------------------------------------------------------------- what the first users and the review found
def test_comments_cannot_inject_robot_code(tmp_path):
    doc = {"sensor_matrix": np.eye(4).tolist(), "dataset": "x\nmovej([0,0,0,0,0,0])\r--><joint name='evil'/>"}
    path = tmp_path / "r.json"
    path.write_text(json.dumps(doc))
    for fmt in ("ur", "ros2", "kuka", "abb", "fanuc", "matrix"):
        text = handeye.export(path, format=fmt).text
        live = [line for line in text.splitlines() if "movej" in line]
        assert all(line.lstrip().startswith(("#", ";", "!")) or line.lstrip()[:4].strip().rstrip(":").isdigit()
                   for line in live), (fmt, live)
    urdf = handeye.export(path, format="urdf").text
    assert len(ET.fromstring("<r>" + urdf + "</r>").findall("joint")) == 1


def test_fanuc_comments_show_the_sd_rounded_and_negatives_in_parentheses():
    cal = _calibration([10, 20, 30, 0, -88, 0], sd=(0.0277, 0.0696, 0.0678, 5.7e-4, 5.7e-4, 5.74e-4))
    text = export.text(cal, "fanuc")
    assert "1sd X 0.0277 mm" in text and "1sd rot z 0.0329 deg" in text
    assert "PR[99,5]=(-88.00000000) ;" in text
    assert all(len(line.split("! ", 1)[1]) <= 32 for line in text.splitlines() if "! " in line)


def test_cloud_csv_quotes_ids_and_format_follows_the_extension(tmp_path, capsys):
    scan = _scan(tmp_path / "s", X_TRUE, [(C1, 25.0)], n_poses=3)
    table = (scan / "measurements.csv").read_text().replace("s1,", '"a,""b",')
    (scan / "measurements.csv").write_text(table)
    cal = saved.Calibration(X_TRUE, None, "truth")
    c = handeye.cloud(scan, cal, out=tmp_path / "c.csv")  # no format: the extension says CSV
    import csv

    rows = list(csv.reader((tmp_path / "c.csv").open()))
    assert all(len(r) == 5 for r in rows) and {r[4] for r in rows[1:]} == set(c.ids)
    assert cli.main(["cloud", str(scan), "--sensor-pose", "190,100,125,180,-88,0", "--out",
                     str(tmp_path / "c.csv"), "--format", "ply"]) == 2
    assert "--format ply" in capsys.readouterr().err


def test_old_and_hand_made_result_files(tmp_path, capsys):
    doc = handeye.calibrate("thesis-sim").to_dict()
    old = {k: v for k, v in doc.items() if k != "covariance"}
    cases = {"old.json": (old, 0), "short.json": (dict(old, correlation={"names": ["tx"], "matrix": [[1.0]]}), 2),
             "nullstd.json": (dict(old, std={"sensor_translation_mm": None, "sensor_rotation_deg": [1, 1, 1]}), 2),
             "conv.json": (dict(doc, converged="false"), 2), "bare.json": ({"sensor_matrix": doc["sensor_matrix"]}, 0)}
    for name, (content, code) in cases.items():
        (tmp_path / name).write_text(json.dumps(content))
        assert cli.main(["export", str(tmp_path / name), "--format", "ur"]) == code, (name, capsys.readouterr().err)
    deep = tmp_path / "deep.json"
    deep.write_text("[" * 100_000 + "]" * 100_000)
    assert cli.main(["export", str(deep)]) == 2
    assert np.array_equal(parse("matrix", handeye.export(np.eye(4), format="matrix").text), np.eye(4))  # an array
    assert cli.main(["export", "--sensor-pose", "40,-60,150,0.3,0.2,1.0", "--format", "ur"]) == 2
    assert "--convention" in capsys.readouterr().err
    assert cli.main(["export", "--sensor-pose", "0.04,-0.06,0.15,0.3,0.2,1.0", "--convention", "ur"]) == 2
    assert "metres" in capsys.readouterr().err


def test_validate_says_whose_data_and_judges_against_stated_limits(ur_cell, tmp_path, capsys):
    root, result = ur_cell
    own = handeye.validate(root / "cell", root / "result.json")
    assert own.own_data is True and "own data" in own.notes[0]
    truth = json.loads((root / "cell" / "simulation.json").read_text())["setup"]
    handeye.simulate(tmp_path / "held", seed=6, profiles=True, convention="ur", diameter=50.8, no_start=True,
                     truth="60,-40,90,0.3,-1.2,2.0", center=",".join(map(str, truth["sphere_centre"])))
    held = handeye.validate(tmp_path / "held", root / "result.json", mpe="0.5,0.05")
    assert held.own_data is False and "independent" in held.notes[0]
    assert held.passed and abs(held.spheres[0].size_error_mm) < 3 * held.spheres[0].size_error_sd_mm + 0.01
    args = ["validate", str(tmp_path / "held"), "--calibration", str(root / "result.json")]
    assert cli.main(args + ["--mpe", "0.5,0.05"]) == 0
    assert cli.main(args + ["--mpe", "0.001,0.001"]) == 1  # limits exceeded: exit 1, said
    assert "FAILED" in capsys.readouterr().out
    assert cli.main(args + ["--mpe", "0.1,0.1,0.1"]) == 2  # SD without a second sphere
    with pytest.raises(SystemExit) as exit_:
        cli.main(args + ["--exclude", "abc"])
    assert exit_.value.code == 2
    with pytest.raises(handeye.InputError, match="exclude"):
        handeye.validate(tmp_path / "held", root / "result.json", exclude=None)


def test_scan_setups_that_cannot_be_read(tmp_path, capsys):
    scan = _scan(tmp_path / "s", X_TRUE, [(C1, 25.0)], n_poses=3)
    (scan / "setup.toml").write_text("[sphere2]\ndiameter = 50.0\ncenter = [0, 0, 0]\n")
    assert cli.main(["validate", str(scan), "--sensor-pose", "190,100,125,180,-88,0"]) == 2
    assert "[sphere2] without [sphere]" in capsys.readouterr().err
    (scan / "setup.toml").write_text("[sphere]\ndiameter = 50.0\n[sphere2]\n")
    assert cli.main(["validate", str(scan), "--sensor-pose", "190,100,125,180,-88,0"]) == 2
    assert "[sphere2] diameter" in capsys.readouterr().err
    (scan / "p" / "0.csv").write_text("x,z\n")
    (scan / "setup.toml").write_text("[sphere]\ndiameter = 50.0\n")
    assert cli.main(["cloud", str(scan), "--sensor-pose", "190,100,125,180,-88,0", "--out", str(tmp_path / "a.ply")]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "at least 1 point" in err
