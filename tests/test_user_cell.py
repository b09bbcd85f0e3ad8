"""A UR cell with a 2-inch sphere, end to end: simulate -> plan (tilt <= 45 deg, margin 5 mm / 1 deg)
-> record the planned poses with the sensor off its nominal pose by the margin -> calibrate.
Every planned pose sees the sphere, the truth is recovered within noise, every file is UR."""
import numpy as np
import pytest

import handeye
from handeye.model.chain import conventions
from handeye.model.chain.pose import transform_from_pose
from handeye.model.common.rotation import matrix_from_rotvec, rotvec_from_matrix


def _off_by(nominal_kuka, mm, deg, rng):
    """The nominal sensor pose moved by ``mm`` and turned by ``deg`` in random directions."""
    t = transform_from_pose(nominal_kuka)
    d, a = rng.normal(size=3), rng.normal(size=3)
    t[:3, 3] += mm * d / np.linalg.norm(d)
    t[:3, :3] = t[:3, :3] @ matrix_from_rotvec(np.radians(deg) * a / np.linalg.norm(a))
    return t


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_ur_cell_plan_record_calibrate(tmp_path, seed):
    rng = np.random.default_rng(seed)
    cell = handeye.simulate(tmp_path / "cell", seed=seed, convention="ur", diameter=50.8, center="500,-350,200",
                            truth="40,-60,150,0.3,0.2,1.0", max_tilt=45)
    nominal = cell.dataset.start_pose  # the CAD pose the plan relies on
    p = handeye.plan(n=12, dataset=cell.path, max_tilt=45, margin="5,1", out=tmp_path / "planned.csv")
    assert (tmp_path / "planned.csv").read_text().startswith("id,x,y,z,rx,ry,rz\n")
    assert p.convention == "ur" and p.margin == (5.0, 1.0)
    true = _off_by(nominal, 5.0, 1.0, rng)
    rec = handeye.simulate(tmp_path / "rec", seed=seed + 10, convention="ur", diameter=50.8, center="500,-350,200",
                           truth=conventions.pose_from("ur", true), poses=tmp_path / "planned.csv", profiles=True)
    assert rec.dropped == [] and len(rec.ids) == 12  # every planned pose sees the sphere
    assert (rec.path / "measurements.csv").read_text().startswith("id,x,y,z,rx,ry,rz,")
    r = handeye.calibrate(rec.path)
    assert r.converged and r.convention == "ur"
    err_t = np.abs(r.sensor2flange[:3, 3] - true[:3, 3])
    err_r = np.abs(np.degrees(rotvec_from_matrix(true[:3, :3].T @ r.sensor2flange[:3, :3])))
    assert np.all(err_t <= 5 * r.std.sensor_translation_mm + 0.01), (err_t, r.std)
    assert np.all(err_r <= 5 * r.std.sensor_rotation_deg + 0.001), (err_r, r.std)


def test_plan_scores_a_given_list_and_respects_the_workspace(tmp_path):
    p = handeye.plan(n=12, out=tmp_path / "p.csv")
    s = handeye.plan(score=tmp_path / "p.csv")
    assert s.scored and np.allclose(s.predicted_sd, p.predicted_sd, rtol=1e-4)  # the list holds 4 decimals
    w = handeye.plan(n=6, workspace="-1e4,1e4,-1e4,1e4,1100,1e4")
    assert all(pose[2] >= 1100 for pose in w.poses) and any("workspace" in r for _, r in w.skipped)
    with pytest.raises(handeye.InputError, match="margin"):
        handeye.plan(n=6, margin="40,5")  # no room on a 60 mm sphere


def test_a_cell_is_planned_from_its_setup_alone(tmp_path):
    cell = tmp_path / "mycell"
    cell.mkdir()
    (cell / "setup.toml").write_text('[robot]\nconvention = "ur"\n[sensor]\nstart_pose = [40, -60, 150, 0.3, 0.2, 1.0]\n'
                                     "[sphere]\ndiameter = 50.8\ncenter = [500.0, -350.0, 200.0]\n")
    p = handeye.plan(n=8, dataset=cell, max_tilt=45, margin="5,1", out=cell / "poses.csv")
    assert p.convention == "ur" and len(p.ids) == 8
    assert (cell / "poses.csv").read_text().startswith("id,x,y,z,rx,ry,rz\n")
