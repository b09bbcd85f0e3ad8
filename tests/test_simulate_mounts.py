"""``handeye simulate`` for every mount: the truth recovered, the chain closed, the seed's cell unchanged."""
import hashlib
import pathlib
import re

import numpy as np
import pytest

from handeye.app.command.cli import EXIT_BAD_INPUT, EXIT_OK, main
from handeye.app.public import api
from handeye.model.chain import mounts as mount_model
from handeye.model.chain.pose import transform_from_pose
from handeye.model.common.rotation import rotvec_from_matrix
from handeye.model.datasets.dataset import load

#: sha256 of the default outputs (``handeye simulate --out D --seed 3`` and with ``--profiles``)
#: made before the mounts were added: the seed's cell must stay byte for byte what it was.
DEFAULT_SHA256 = {(): "7f187b14b4ccf9d3d464178237e8c8c01eec2ffbc03a3e20ab80fa1a63598e8a",
                  ("--profiles",): "69f2055f6b0320cfa1ff7acba47c87dd9ad46732732338fefe9ae4e389754dea"}

CELLS = {"flange/world": ("flange", "world", "sensor+sphere", 1),
         "world/flange": ("world", "flange", "sensor+sphere", 1),
         "flange/positioner": ("flange", "positioner", "sensor+sphere+positioner", 1)}


_DECIMAL = re.compile(r"-?\d+\.\d+(?:[eE][-+]?\d+)?")


def _folder_sha256(folder):
    """SHA-256 of the folder's files with every decimal number rounded to 1e-6 (the profiles' points
    and the circle fits' centres move in their last digits with numpy's SIMD sin/cos and its BLAS
    between releases; a change of the simulation moves them far more)."""
    h = hashlib.sha256()
    for f in sorted(pathlib.Path(folder).rglob("*")):
        if f.is_file():
            h.update(str(f.relative_to(folder)).encode())
            text = f.read_text(encoding="utf-8")
            h.update(_DECIMAL.sub(lambda m: f"{round(float(m.group()), 6) + 0.0:.6f}", text).encode())
    return h.hexdigest()


def _simulate(tmp_path, sensor, sphere, seed, **options):
    return api.simulate(tmp_path / f"{sensor}-{sphere}-{seed}", seed=seed, sensor_mount=sensor, sphere_mount=sphere,
                        **options)


@pytest.mark.parametrize("extra", list(DEFAULT_SHA256))
def test_default_output_is_unchanged_byte_for_byte(tmp_path, capsys, extra):
    assert main(["simulate", "--out", str(tmp_path / "d"), "--seed", "3", *extra]) == EXIT_OK
    assert _folder_sha256(tmp_path / "d") == DEFAULT_SHA256[extra]


def _within_3_sd(result, data, k=3.0):
    """Every calibrated part within ``k`` sd of [truth] (sensor in its mount's frame, local chart)."""
    truth = transform_from_pose(data.truth["sensor_pose"])
    est = np.asarray(result.sensor2flange)
    std = result.std
    assert np.all(np.abs(est[:3, 3] - truth[:3, 3]) <= k * std.sensor_translation_mm + 1e-6)
    rot = np.degrees(rotvec_from_matrix(truth[:3, :3].T @ est[:3, :3]))
    assert np.all(np.abs(rot) <= k * std.sensor_rotation_deg + 1e-6), (rot, std.sensor_rotation_deg)
    dc = np.asarray(result.sphere_centre) - data.truth["sphere_center"]
    assert np.all(np.abs(dc) <= k * std.sphere_center_mm + 1e-6), (dc, std.sphere_center_mm)
    if result.positioner is None or not result.positioner.calibrated:
        return
    for j, (axis, true) in enumerate(zip(result.positioner.axes, data.truth["axes"])):
        tilt = np.degrees(np.arccos(min(1.0, abs(float(axis.direction @ true.direction)))))
        assert tilt <= 3 * result.positioner.tilt_sd_deg[j] + 1e-6, (axis.name, tilt)
        off = axis.point - true.point
        off = off - (off @ true.direction) * true.direction  # the lines' distance at the point: normal to the axis
        assert np.linalg.norm(off) <= 3 * np.linalg.norm(result.positioner.point_sd[j]) + 1e-6, (axis.name, off)


@pytest.mark.parametrize("cell", list(CELLS))
def test_every_mount_recovers_the_truth_within_3_sd(tmp_path, capsys, cell):
    sensor, sphere, unknowns, seed = CELLS[cell]
    made = _simulate(tmp_path, sensor, sphere, seed)
    data = made.dataset
    assert (data.mounts.sensor, data.mounts.sphere) == (sensor, sphere) and len(data) == 36
    code = main(["calibrate", str(made.path), "--unknowns", unknowns])
    capsys.readouterr()
    assert code == EXIT_OK
    result = api.calibrate(made.path, unknowns=unknowns)
    assert result.converged and (result.sensor_mount, result.sphere_mount) == (sensor, sphere)
    _within_3_sd(result, data)


@pytest.mark.parametrize("cell", list(CELLS))
def test_the_chain_closes_at_the_truth(tmp_path, cell):
    sensor, sphere, _, seed = CELLS[cell]
    data = _simulate(tmp_path, sensor, sphere, seed, profiles=True).dataset
    true_mounts = mount_model.Mounts(sensor, sphere, tuple(data.truth.get("axes", ())))
    m = mount_model.motions(data.flange2base(), true_mounts, data.axis_angles)
    xs = np.c_[data.centre_in_sensor, np.ones(len(data))]
    chain = (m @ transform_from_pose(data.truth["sensor_pose"]) @ xs[:, :, None])[:, :3, 0]
    residual = np.linalg.norm(chain - data.truth["sphere_center"], axis=1)
    assert 0.005 < np.sqrt(np.mean(residual**2)) < 0.1  # robot 0.025 mm per axis and the profile's noise
    if sphere == "positioner":  # the nominal axes (1 mm, 0.2 deg off) leave a clearly larger gap
        nominal = mount_model.motions(data.flange2base(), data.mounts, data.axis_angles)
        gap = np.linalg.norm((nominal @ transform_from_pose(data.truth["sensor_pose"]) @ xs[:, :, None])[:, :3, 0]
                             - data.truth["sphere_center"], axis=1)
        assert np.sqrt(np.mean(gap**2)) > 5 * np.sqrt(np.mean(residual**2))


def test_positioner_angles_vary_jointly_over_the_ranges(tmp_path):
    data = _simulate(tmp_path, "flange", "positioner", 1).dataset
    e1, e2 = data.axis_angles.T
    assert len(np.unique(e1)) >= 3 and len(np.unique(e2)) >= 3
    assert np.all(np.abs(e1) <= 45) and np.ptp(e2) > 270
    assert abs(np.corrcoef(e1, e2)[0, 1]) < 0.5


def test_without_positioner_error_sensor_and_sphere_suffice(tmp_path, capsys):
    made = _simulate(tmp_path, "flange", "positioner", 2, positioner_error="0,0",
                     positioner_axes="tilt:1400,100,500:1,0,0;turn:1400,100,700:0,0,1")
    data = made.dataset
    assert data.mounts.axis_names == ("tilt", "turn")
    assert all(np.allclose(a.point, b.point) for a, b in zip(data.truth["axes"], data.mounts.axes))
    result = api.calibrate(made.path, unknowns="sensor+sphere")
    assert result.converged
    _within_3_sd(result, data)


@pytest.mark.parametrize("cell", ["world/flange", pytest.param("flange/positioner", marks=pytest.mark.slow(
    sibling="test_effects_and_profiles_work_for_every_mount[world/flange]"))])
def test_effects_and_profiles_work_for_every_mount(tmp_path, cell):
    sensor, sphere, unknowns, seed = CELLS[cell]
    made = _simulate(tmp_path, sensor, sphere, seed, profiles=True,
                     effect=["sphere_center=1,-2,3", "sensor_scale=0.0005", "outlier=y+0", "sign_flip=x+0"])
    data = made.dataset
    nominal = {"flange": (0.0, 0.0, 150.0), "positioner": (1650.0, 0.0, 900.0)}[sphere]
    assert np.allclose(data.sphere_centre, nominal)  # setup.toml: the nominal centre in its mount's frame
    assert np.allclose(data.truth["sphere_center"], np.add(nominal, (1, -2, 3)))
    assert (pathlib.Path(made.path) / "profiles").is_dir()
    result = api.calibrate(made.path, unknowns=unknowns)
    excluded = {e.id for e in result.excluded}
    assert {"y+0", "x+0"} <= excluded  # the gross errors are found, whatever the mount
    radius = api.simulate(tmp_path / "radius", seed=seed, sensor_mount=sensor, sphere_mount=sphere,
                          effect="sphere_radius=0.3")
    assert radius.dropped and len(radius.ids) + len(radius.dropped) == 36


@pytest.mark.parametrize("argv", [("--sensor-mount", "world", "--sphere-mount", "world"),
                                  ("--sensor-mount", "flange", "--sphere-mount", "flange"),
                                  ("--sensor-mount", "world", "--sphere-mount", "positioner"),
                                  ("--positioner-axes", "e1:0,0,0:0,0,1"),
                                  ("--positioner-error", "1,1"),
                                  ("--sphere-mount", "positioner", "--positioner-axes", "x:0,0,0:0,0,1"),
                                  ("--sphere-mount", "positioner", "--positioner-error", "1")])
def test_bad_mount_options_exit_2_with_one_line(tmp_path, capsys, argv):
    code = main(["simulate", "--out", str(tmp_path / "bad"), *argv])
    err = capsys.readouterr().err
    assert code == EXIT_BAD_INPUT
    assert len(err.strip().splitlines()) == 1 and "--" in err
    assert not (tmp_path / "bad").exists() or not any((tmp_path / "bad").iterdir())


@pytest.mark.parametrize("cell", ["world/flange", "flange/positioner"])
def test_plan_chooses_poses_and_angles_that_see_the_sphere(tmp_path, capsys, cell):
    sensor, sphere, unknowns, _ = CELLS[cell]
    out = tmp_path / "plan.csv"
    chosen = api.plan(n=10, out=out, sensor_mount=sensor, sphere_mount=sphere)
    names = ("e1", "e2") if sphere == "positioner" else ()
    assert chosen.axis_names == names and chosen.mounts == (sensor, sphere)
    assert out.read_text().splitlines()[0] == ",".join(("id", "x", "y", "z", "a", "b", "c") + names)
    if names:
        assert chosen.axis_angles.shape == (10, 2) and not chosen.warnings
    scored = api.plan(score=out, sensor_mount=sensor, sphere_mount=sphere)
    assert abs(scored.logdet - chosen.logdet) < 1e-3
    # the simulator's true cell (axes 1 mm / 0.2 deg off the nominal ones) still sees the sphere at every pose
    assert main(["simulate", "--out", str(tmp_path / "sim"), "--poses", str(out), "--sensor-mount", sensor,
                 "--sphere-mount", sphere, "--seed", "1"]) == EXIT_OK
    result = api.calibrate(tmp_path / "sim", unknowns=unknowns)
    assert result.converged
    # the sd comes from the fit's own residuals: with 10 poses and up to 17 unknowns (13 dof) the error over
    # it is Student-t distributed, and 3 sd of a normal is the t quantile of the same coverage (99.73 %)
    from scipy.stats import t as student

    dof = 3 * 10 - {"sensor+sphere": 9, "sensor+sphere+positioner": 17}[unknowns]
    _within_3_sd(result, load(tmp_path / "sim"), k=float(student.ppf(0.99865, dof)))


def test_plan_takes_the_mounts_from_the_dataset(tmp_path, capsys):
    made = _simulate(tmp_path, "flange", "positioner", 1)
    chosen = api.plan(n=8, dataset=made.path)
    assert chosen.axis_names == ("e1", "e2") and chosen.axis_angles.shape == (8, 2)
    assert main(["plan", "--dataset", str(made.path), "--sphere-mount", "flange", "--sensor-mount", "world"]) \
        == EXIT_BAD_INPUT
    assert len(capsys.readouterr().err.strip().splitlines()) == 1
