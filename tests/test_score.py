"""Scoring a given sensor pose and comparing two calibrations (issue 29, part 4;
handeye.app.engine.score), diagnose --unknowns sensor+sphere (part 5), and the JSON of every exit.

The data come from the seeded generator of conftest.py (centres through a known chain) and
handeye's simulator with profiles; the claims are about the verdicts: the true pose is not
contradicted, a pose 1 mm off is, and the comparison names the file that is closer to the truth."""
from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
from conftest import simulate

import handeye
from handeye.app.command.cli import main
from handeye.app.engine.score import vuong
from handeye.model.chain.pose import transform_from_pose
from handeye.model.common.rotation import pose_distance

TRUTH = (190.0, 100.0, 130.0, 178.0, -88.0, 0.5)


def _pose_text(pose):
    return ",".join(f"{v:.6f}" for v in pose)


@pytest.fixture(scope="module")
def cell(tmp_path_factory):
    return simulate(tmp_path_factory.mktemp("score") / "cell", seed=11, n=24, noise_mm=0.05, truth=TRUTH)


def test_true_pose_is_not_contradicted_and_exits_0(cell, capsys):
    code = main(["calibrate", str(cell), "--sensor-pose", _pose_text(TRUTH), "--no-loo", "--json"])
    out = json.loads(capsys.readouterr().out)
    assert code == 0
    assert out["scored"] is True and out["error"] is None
    assert out["contradicted"] is False
    assert out["f_test"]["p_value"] > 1e-3
    np.testing.assert_allclose(out["sensor_matrix"], transform_from_pose(TRUTH), atol=1e-9)  # held, not fitted
    assert out["distance_to_estimate"]["sd"] < 5.0  # the truth lies within a few sd of the data's own estimate
    assert set(out["rms_mm"]) == {"centre"}  # no profiles: only the centre model
    assert len(out["residuals"]) == 24


def test_pose_one_mm_off_is_contradicted_still_exit_0(cell, capsys):
    off = np.array(TRUTH) + [1.0, 0, 0, 0, 0, 0]
    code = main(["calibrate", str(cell), "--sensor-pose", _pose_text(off), "--no-loo"])
    text = capsys.readouterr().out
    assert code == 0  # the score is the answer; its verdict says the pose is wrong
    assert "the data contradict the given pose" in text
    result = handeye.calibrate(cell, sensor_pose=off, no_loo=True)
    assert result.contradicted
    assert result.given.rms_mm["centre"] > 5 * result.estimate_score.rms_mm["centre"]
    assert result.distance["translation_mm"] == pytest.approx(1.0, abs=0.2)


def test_calibration_file_with_sensor_among_unknowns_is_scored(cell, tmp_path, capsys):
    saved = tmp_path / "cal.json"
    handeye.calibrate(cell, no_loo=True, out=saved)
    code = main(["calibrate", str(cell), "--calibration", str(saved), "--no-loo", "--json"])
    out = json.loads(capsys.readouterr().out)
    assert code == 0 and out["scored"] and out["source"] == str(saved)
    assert out["distance_to_estimate"]["translation_mm"] < 1e-6  # its own calibration: the same pose
    assert not out["contradicted"]


def test_sensor_plus_sphere_fits_the_centre_with_the_pose_held(cell):
    result = handeye.calibrate(cell, unknowns="sensor+sphere", sensor_pose=TRUTH, no_loo=True)
    assert result.centre_fitted
    np.testing.assert_allclose(result.given.centre, [1534.0, -603.0, 1119.0], atol=0.1)
    assert not result.contradicted


def test_a_score_refuses_what_does_not_apply(cell):
    with pytest.raises(handeye.InputError, match="--effects does not apply to a score"):
        handeye.calibrate(cell, sensor_pose=TRUTH, effects="sensor_scale")
    with pytest.raises(handeye.InputError, match="closed form"):
        handeye.calibrate(cell, sensor_pose=TRUTH, method="kim-cho")
    with pytest.raises(handeye.InputError, match="not both"):
        handeye.calibrate(cell, sensor_pose=TRUTH, calibration="x.json")
    with pytest.raises(handeye.InputError, match="--sensor-pose"):
        handeye.calibrate(cell, sensor_pose="1,2,x")


def test_sensor_pose_holds_the_sensor_when_not_among_unknowns(cell):
    """--unknowns sphere --sensor-pose: the old rule for a part given, the sphere calibrated."""
    result = handeye.calibrate(cell, unknowns="sphere", sensor_pose=TRUTH, no_loo=True)
    assert result.converged and result.unknowns == "sphere"
    np.testing.assert_allclose(result.sensor2flange, transform_from_pose(TRUTH), atol=1e-9)


def test_compare_names_the_better_file(cell, tmp_path, capsys):
    a, b = tmp_path / "a.json", tmp_path / "b.json"
    handeye.calibrate(cell, no_loo=True, out=a)
    far = np.array(TRUTH) + [0.0, 0.6, 0.0, 0.0, 0.0, 0.0]
    handeye.calibrate(cell, sensor_pose=far, no_loo=True, out=b)  # a scored pose saved: a calibration file all the same
    code = main(["compare", str(cell), str(a), str(b), "--json"])
    out = json.loads(capsys.readouterr().out)
    assert code == 0 and out["error"] is None
    assert out["better"] == str(a) and out["significant"]
    assert out["vuong"]["z"] < 0  # A fits better
    assert out["between"]["translation_mm"] == pytest.approx(0.6, abs=0.1)
    code = main(["compare", str(cell), str(a), str(a)])
    assert code == 0 and "equally well" in capsys.readouterr().out


def test_compare_refuses_a_calibration_of_another_mount(cell, tmp_path):
    other = tmp_path / "world.json"
    other.write_text(json.dumps({"sensor_matrix": np.eye(4).tolist(), "sensor_mount": "world"}))
    with pytest.raises(handeye.InputError, match="mounted on the world"):
        handeye.compare(cell, other, other)


def test_vuong_and_distance_by_hand():
    class S:
        def __init__(self, per):
            self.per_sample = np.asarray(per, float)

    z, p = vuong(S([1.0, 2.0, 3.0, 4.0]), S([0.5, 1.0, 1.0, 1.5]))
    d = np.array([0.5, 1.0, 2.0, 2.5])
    assert z == pytest.approx(2.0 * d.mean() / d.std(ddof=1))
    assert 0 < p < 0.05
    a, b = transform_from_pose([0, 0, 0, 0, 0, 0]), transform_from_pose([3, 4, 0, 10, 0, 0])
    d = pose_distance(b, a, np.diag([1.0, 1.0, 1.0, 1e-4, 1e-4, 1e-4]), ["tx", "ty", "tz", "wx", "wy", "wz"])
    assert d["translation_mm"] == pytest.approx(5.0)
    assert d["rotation_deg"] == pytest.approx(10.0)
    assert d["sd"] == pytest.approx(np.hypot(5.0, np.radians(10.0) / 1e-2))


def test_diagnose_estimates_the_centre_and_agrees_with_calibrate(cell, tmp_path, capsys):
    folder = tmp_path / "nocentre"
    shutil.copytree(cell, folder)
    setup = folder / "setup.toml"
    setup.write_text("\n".join(ln for ln in setup.read_text().splitlines() if not ln.startswith("center")) + "\n")
    assert main(["diagnose", str(folder)]) == 2
    err = capsys.readouterr().err
    assert "--unknowns sensor+sphere" in err and "unknowns='" not in err  # the option, not Python syntax
    code = main(["diagnose", str(folder), "--unknowns", "sensor+sphere", "--json"])
    out = json.loads(capsys.readouterr().out)
    assert code == 0 and out["unknowns"] == "sensor+sphere"
    assert not [e for e in out["effects"] if e["name"] == "sphere_center"]  # estimated, not named as an effect
    np.testing.assert_allclose(out["sphere_center"], [1534.0, -603.0, 1119.0], atol=0.1)
    assert out["against_calibrate"].startswith("the same pose as `handeye calibrate`'s")
    assert "within 1 sd" in out["against_calibrate"]
    own = handeye.calibrate(folder, unknowns="sensor+sphere", no_loo=True)
    np.testing.assert_allclose(out["sensor_matrix"], own.sensor2flange, atol=0.05)


def test_diagnose_says_why_its_pose_differs(cell, tmp_path):
    """A centre taught 1.5 mm off: diagnose names sphere_center, and so does calibrate (the model the
    search chooses): the two give the same pose."""
    folder = tmp_path / "taught"
    shutil.copytree(cell, folder)
    setup = folder / "setup.toml"
    setup.write_text(setup.read_text().replace("center = [1534.0", "center = [1535.5"))
    result = handeye.diagnose(folder)
    assert "sphere_center" in [e.name for e in result.effects]
    assert result.against_calibrate.startswith("the same pose as `handeye calibrate`'s")
    assert "within 1 sd" in result.against_calibrate
    held = handeye.calibrate(folder, effects="none", no_loo=True)  # the taught centre held: refused
    assert not held.converged and "sphere_center" in held.message


def test_json_on_bad_input_names_the_error_and_the_file(tmp_path, capsys):
    code = main(["calibrate", str(tmp_path / "missing"), "--json"])
    captured = capsys.readouterr()
    out = json.loads(captured.out)
    assert code == 2 and out["exit_code"] == 2 and out["command"] == "calibrate"
    assert "no dataset folder" in out["error"] and out["file"] == str(tmp_path / "missing")
    assert captured.err.startswith("handeye: error:")  # the one line on stderr stays
    with pytest.raises(SystemExit) as stop:  # an argparse error ends the parse itself
        main(["calibrate", "--json", "--method", "nope"])
    out = json.loads(capsys.readouterr().out)
    assert stop.value.code == 2 and "--method" in out["error"]


def test_json_on_exit_1_has_the_error(cell, capsys, break_solver):
    code = main(["calibrate", str(cell), "--json", "--no-loo", "--method", "lm"])
    out = json.loads(capsys.readouterr().out)
    if code == 1:
        assert out["error"] == out["message"] and out["error"]
    else:  # the closed-form restart rescued it: then no error
        assert code == 0 and out["error"] is None


def test_centre_columns_optional_with_profiles(tmp_path):
    folder = tmp_path / "sim"
    assert main(["simulate", "--out", str(folder), "--profiles", "--n-poses", "12", "--seed", "2"]) == 0
    with_columns = handeye.calibrate(folder, no_loo=True)
    lines = (folder / "measurements.csv").read_text().splitlines()
    header = lines[0].split(",")
    keep = [k for k, c in enumerate(header) if c not in ("xs", "ys", "zs")]
    (folder / "measurements.csv").write_text("\n".join(",".join(ln.split(",")[k] for k in keep) for ln in lines) + "\n")
    without = handeye.calibrate(folder, no_loo=True)
    np.testing.assert_allclose(without.sensor2flange, with_columns.sensor2flange, atol=1e-6)
    rows = (folder / "measurements.csv").read_text().splitlines()
    parts = rows[3].split(",")
    parts[-1] = ""
    rows[3] = ",".join(parts)
    (folder / "measurements.csv").write_text("\n".join(rows) + "\n")
    with pytest.raises(handeye.InputError, match=r"row 4, column 'profile': no profile"):
        handeye.load_dataset(folder)


def test_no_verdict_when_the_data_own_calibration_does_not_converge(cell, capsys, break_solver):
    break_solver()  # every final solve ends at a non-finite point
    code = main(["calibrate", str(cell), "--sensor-pose", _pose_text(TRUTH), "--no-loo", "--json"])
    out = json.loads(capsys.readouterr().out)
    assert code == 1 and out["contradicted"] is None and out["converged"] is False
    assert out["error"].startswith("no verdict: the data's own calibration did not converge")
    assert out["verdict"] == out["error"]


def test_a_saved_contradicted_score_is_not_a_usable_calibration(cell, tmp_path):
    saved = tmp_path / "off.json"
    handeye.calibrate(cell, sensor_pose=np.array(TRUTH) + [2.0, 0, 0, 0, 0, 0], no_loo=True, out=saved)
    doc = json.loads(saved.read_text())
    assert doc["converged"] is False and doc["sensor_mount"] == "flange"
    with pytest.raises(handeye.InputError, match="did not converge"):
        handeye.export(saved, format="matrix")


def test_positioner_cells_are_not_scored(tmp_path):
    folder = tmp_path / "pos"
    assert main(["simulate", "--out", str(folder), "--sphere-mount", "positioner", "--n-poses", "12"]) == 0
    truth = handeye.load_dataset(folder).truth["sensor_pose"]
    with pytest.raises(handeye.InputError, match="positioner.*--unknowns sphere\\+positioner"):
        handeye.calibrate(folder, sensor_pose=truth)
    with pytest.raises(handeye.InputError, match="positioner"):
        handeye.compare(folder, np.eye(4), np.eye(4))


def test_points_model_is_tested_on_its_circles(tmp_path):
    folder = tmp_path / "sim"
    assert main(["simulate", "--out", str(folder), "--profiles", "--n-poses", "12", "--seed", "4"]) == 0
    truth = handeye.load_dataset(folder).truth["sensor_pose"]
    result = handeye.calibrate(folder, sensor_pose=truth, model="points", no_loo=True)
    assert result.model == "measurement" and result.f_test[1] > 1e-3 and not result.contradicted
    assert set(result.given.rms_mm) == {"centre", "measurement", "points"}


def test_a_free_centre_starts_from_the_chain_not_a_failed_estimate(cell):
    """The centre fitted with the given pose held starts from the unweighted centre model's own
    least squares (the mean of the centres through the chain), so a failed estimate's NaN centre
    does not reach the score."""
    from handeye.app.engine.score import Scorer

    data = handeye.load_dataset(cell)
    scorer = Scorer(data, np.ones(len(data), bool), "centre", 0.025, centre_free=True)
    pose = scorer.score(transform_from_pose(TRUTH), centre=np.full(3, np.nan))
    np.testing.assert_allclose(pose.centre, [1534.0, -603.0, 1119.0], atol=0.1)
    assert np.isfinite(pose.ssr)
