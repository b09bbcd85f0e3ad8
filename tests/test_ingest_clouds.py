"""A 3-D sensor's cell through ``dataset new`` and ``calibrate`` (issue 40, item 3): a point cloud of the sphere
per pose (``--clouds``), and the centres it reported (``--centres``) without a diameter. The cell is simulated by
this file's own generator (scipy's rotations, not handeye's conventions): a known sensor pose on the flange, a
sphere in the base, flange poses looking at it, points on the cap each pose sees with noise and outliers, and
robot noise on the reported flange."""
import json
import re

import numpy as np
from scipy.spatial.transform import Rotation

import handeye
from handeye.app.command.cli import main

SENSOR = ([40.0, -60.0, 150.0], [20.0, -10.0, 170.0])  # translation mm, KUKA A, B, C (intrinsic Z-Y'-X'') degrees
SPHERE = np.array([650.0, -120.0, 310.0])
DIAMETER = 50.8


def _matrix(t, abc):
    m = np.eye(4)
    m[:3, :3] = Rotation.from_euler("ZYX", abc, degrees=True).as_matrix()
    m[:3, 3] = t
    return m


def _cell(folder, seed=3, n=14):
    """Loose files of a 3-D sensor's cell: ``poses.csv`` (KUKA) and one cloud per pose in ``clouds/`` (npy, ascii
    PLY and CSV in turn); returns the sensor's true pose on the flange (4, 4)."""
    rng = np.random.default_rng(seed)
    x = _matrix(*SENSOR)
    (folder / "clouds").mkdir(parents=True)
    rows = ["id,x,y,z,a,b,c"]
    for k in range(1, n + 1):
        v = rng.normal(size=3)
        v[2] = abs(v[2]) + 0.6
        v /= np.linalg.norm(v)
        origin = SPHERE + rng.uniform(250, 350) * v
        z = SPHERE + rng.uniform(-40, 40, 3) - origin  # looking near the sphere, not always at one sensor point
        z /= np.linalg.norm(z)
        xa = np.cross([0.0, 0.0, 1.0], z)
        xa /= np.linalg.norm(xa)
        s = np.eye(4)
        roll = Rotation.from_euler("z", rng.uniform(-40, 40), degrees=True).as_matrix()
        s[:3, :3] = np.column_stack([xa, np.cross(z, xa), z]) @ roll
        s[:3, 3] = origin
        flange = s @ np.linalg.inv(x)
        d = rng.normal(size=(4000, 3))
        d /= np.linalg.norm(d, axis=1)[:, None]
        d = d[d @ v > np.cos(np.radians(55))][:600]  # the cap facing the sensor
        inv = np.linalg.inv(s)
        pts = (SPHERE + DIAMETER / 2 * d) @ inv[:3, :3].T + inv[:3, 3] + rng.normal(scale=0.03, size=d.shape)
        pts = np.vstack([pts, inv[:3, :3] @ SPHERE + inv[:3, 3] + rng.uniform(-40, 40, (20, 3))])  # outliers
        reported = flange[:3, 3] + rng.normal(scale=0.02, size=3)  # the robot's repeatability
        abc = Rotation.from_matrix(flange[:3, :3]).as_euler("ZYX", degrees=True)
        rows.append(f"{k}," + ",".join(f"{v:.5f}" for v in (*reported, *abc)))
        _write(folder / "clouds", k, pts)
    (folder / "poses.csv").write_text("\n".join(rows) + "\n")
    return x


def _write(folder, k, pts):
    if k % 3 == 0:
        np.save(folder / f"scan_{k}.npy", pts)
    elif k % 3 == 1:
        head = (f"ply\nformat ascii 1.0\nelement vertex {len(pts)}\n"
                "property double x\nproperty double y\nproperty double z\nend_header\n")
        (folder / f"scan_{k}.ply").write_text(head + "".join(f"{p[0]:.5f} {p[1]:.5f} {p[2]:.5f}\n" for p in pts))
    else:
        (folder / f"scan_{k}.csv").write_text("x,y,z\n" + "".join(f"{p[0]:.5f},{p[1]:.5f},{p[2]:.5f}\n" for p in pts))


def _sd_away(result, truth):
    """Per axis, how many reported sd the calibrated pose lies from the truth: translation (mm, the flange's axes)
    and rotation (about the sensor's own axes)."""
    m = np.asarray(result["sensor_matrix"], float)
    std = result["std"]
    dt = np.abs(m[:3, 3] - truth[:3, 3]) / np.asarray(std["sensor_translation_mm"])
    turn = np.degrees(Rotation.from_matrix(truth[:3, :3].T @ m[:3, :3]).as_rotvec())
    dr = np.abs(turn) / np.asarray(std["sensor_rotation_deg"])
    return np.r_[dt, dr]


def test_clouds_calibrate_within_3_sd_through_the_command_line(tmp_path, capsys):
    truth = _cell(tmp_path)
    out = tmp_path / "cell"
    assert main(["dataset", "new", str(out), "--poses", str(tmp_path / "poses.csv"), "--clouds", str(tmp_path / "clouds"),
                 "--diameter", str(DIAMETER), "--center", ",".join(map(str, SPHERE))]) == 0
    summary = capsys.readouterr().out
    assert "clouds    5 ply, 5 text, 4 npy" in summary
    cut = int(re.search(r"(\d+) points cleaned off the sphere in 14 clouds", summary).group(1))
    assert 270 <= cut <= 280  # 20 outliers a cloud, in a box round the sphere: one may fall on its surface
    assert "cloud" in (out / "measurements.csv").read_text().splitlines()[0].split(",")
    assert main(["calibrate", str(out), "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert np.all(_sd_away(result, truth) < 3), _sd_away(result, truth)
    assert result["cleaning"]["what"] == "cloud" and result["cleaning"]["dropped"] == cut
    assert "sphere fit" in result["noise_model"]  # each centre weighed by its fit's covariance


def test_clouds_of_an_unknown_diameter_through_the_api(tmp_path):
    """The radius free: each cloud's diameter is fitted and their spread reported; the calibration weighs each
    centre by its own fit's covariance (larger, the radius free) and still lands within 3 sd."""
    truth = _cell(tmp_path, seed=4)
    made = handeye.new_dataset(tmp_path / "cell", poses=tmp_path / "poses.csv", clouds=[tmp_path / "clouds"],
                               center=list(SPHERE))
    sizes = made.clouds["diameter_mm"]
    assert abs(sizes["mean"] - DIAMETER) < 3 * sizes["sd"] / np.sqrt(14) + 1e-3 and 0.005 < sizes["sd"] < 0.1
    assert "fitted diameters" in made.summary() and "diameter" not in (tmp_path / "cell" / "setup.toml").read_text()
    data = handeye.load_dataset(tmp_path / "cell")
    assert data.sphere_diameter is None and data.centre_cov.shape == (14, 3, 3)
    free = np.median([np.sqrt(np.diag(c)) for c in data.centre_cov], axis=0)
    assert free[2] > 2 * free[0]  # along the view the radius free leaves the centre less certain
    result = handeye.calibrate(tmp_path / "cell").to_dict()
    assert result["converged"] and np.all(_sd_away(result, truth) < 3)


def test_a_cloud_that_is_a_plane_is_named(tmp_path, capsys):
    _cell(tmp_path, n=8)
    rng = np.random.default_rng(0)
    plane = np.column_stack([rng.uniform(-30, 30, (800, 2)), 280 + 0.03 * rng.normal(size=800)])
    np.save(tmp_path / "clouds" / "scan_6.npy", plane)
    code = main(["dataset", "new", str(tmp_path / "cell"), "--poses", str(tmp_path / "poses.csv"), "--clouds",
                 str(tmp_path / "clouds"), "--diameter", str(DIAMETER)])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and not (tmp_path / "cell").exists()
    assert "scan_6.npy" in err and "plane" in err


def test_a_two_column_file_among_clouds_is_named_a_profile(tmp_path, capsys):
    _cell(tmp_path, n=6)
    (tmp_path / "clouds" / "scan_2.csv").write_text("x,z\n1,300\n2,301\n3,302\n")
    code = main(["dataset", "new", str(tmp_path / "cell"), "--poses", str(tmp_path / "poses.csv"), "--clouds",
                 str(tmp_path / "clouds")])
    err = capsys.readouterr().err
    assert code == 2 and "scan_2.csv" in err and "laser profile" in err and "--profiles" in err


def test_reported_centres_need_no_diameter(tmp_path, capsys):
    """The centres a 3-D sensor reports (here: the generator's, from the true sensor pose) in a table of their own:
    no diameter asked for or written, exit 0 at the truth; what needs the diameter says so in one line."""
    truth = _cell(tmp_path, n=10)
    poses = np.loadtxt(tmp_path / "poses.csv", delimiter=",", skiprows=1)
    lines = ["id,xs,ys,zs"]
    for row in poses[::-1]:  # another order: paired by id
        flange = _matrix(row[1:4], row[4:7])
        xs = np.linalg.inv(flange @ truth) @ np.r_[SPHERE, 1.0]
        lines.append(f"{int(row[0])}," + ",".join(f"{v:.5f}" for v in xs[:3]))
    (tmp_path / "centres.csv").write_text("\n".join(lines) + "\n")
    out = tmp_path / "cell"
    assert main(["dataset", "new", str(out), "--poses", str(tmp_path / "poses.csv"), "--centres",
                 str(tmp_path / "centres.csv"), "--center", ",".join(map(str, SPHERE))]) == 0
    assert "pairing   by id" in capsys.readouterr().out
    assert "diameter" not in (out / "setup.toml").read_text()
    assert main(["calibrate", str(out), "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert np.all(_sd_away(result, truth) < 3)
    assert np.abs(np.asarray(result["sensor_matrix"])[:3, 3] - truth[:3, 3]).max() < 0.2
    assert main(["calibrate", str(out), "--effects", "sphere_radius"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "[sphere] diameter" in err


def test_a_profile_without_a_diameter_is_named(tmp_path, capsys):
    out = tmp_path / "cell"
    (out / "profiles").mkdir(parents=True)
    (out / "profiles" / "1.csv").write_text("x,z\n-5,300\n0,298\n5,300\n")
    (out / "setup.toml").write_text("[sphere]\ncenter = [0.0, 0.0, 0.0]\n")
    (out / "measurements.csv").write_text("id,x,y,z,a,b,c,profile\n1,0,0,0,0,0,0,profiles/1.csv\n")
    assert main(["calibrate", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "[sphere] diameter" in err and "row 2" in err
