"""A sensor linearity error (found by a new user, issue 39): ``simulate --linearity`` bends each profile's depth
by ``L * 100 mm * sin(2 pi (z - 190) / 100)``. Uncorrected, on the thesis's 36 orientations a bend of 0.05 mm
(L = 0.0005, a third of a data sheet's 0.0016) moved the pose 0.8-1.2 mm along the ty-wx direction the poses
barely separate, and calibrate exited 0 10-12 sd from the truth (the data sheet's: 2.1-2.9 mm). The profiles'
shape now measures the bend and the centres are rebuilt from corrected profiles (model/geometry/profile_bend.py,
tests/test_profile_bend.py); the pose keeps up to a fifth of the move away from the truth, and its sd says so
(app/engine/bend.py, levels.BEND_DOUBT): no exit 0 away from the truth. Seeds 41 and 44 were the two farthest
(3.3-5.5 sd) before the doubt was in the sd; seed 0 of the data sheet's value was 16.6 sd."""
import tomllib

import numpy as np
import pytest

import handeye
from handeye.model.chain.pose import transform_from_pose
from handeye.model.common.rotation import pose_distance


def _calibrated(tmp_path, linearity, seed, n_poses=36, **options):
    folder = tmp_path / "cell"
    handeye.simulate(out=folder, profiles=True, linearity=linearity, seed=seed, no_start=True, n_poses=n_poses)
    truth = transform_from_pose(tomllib.loads((folder / "setup.toml").read_text())["truth"]["sensor_pose"])
    r = handeye.calibrate(folder, **options)
    d = pose_distance(truth, np.asarray(r.sensor2flange, float), r.covariance, r.parameter_names)
    away = d["sd"] > 3 and (d["translation_mm"] > 0.2 or d["rotation_deg"] > 0.05)
    assert not (r.converged and away), (d, [e.name for e in r.effects or []])
    return r, d


@pytest.mark.parametrize("linearity, seed", [(0.0005, 41), (0.0005, 44), (0.0016, 0)])
def test_a_linearity_error_never_exits_0_away_from_the_truth(tmp_path, linearity, seed):
    r, d = _calibrated(tmp_path, linearity, seed)
    assert r.converged and d["translation_mm"] < 0.3, d  # uncorrected: 0.8-2.9 mm


def test_a_bend_the_tests_do_not_make_clear_is_in_the_sd(tmp_path):
    """8 poses at the data sheet's linearity (found by a new user): the bend is measured (0.24 mm) but not clear at
    1e-6 (p 1.1e-6), and uncorrected the pose lies 3.9 mm off; it had exited 0 at 3.2 sd. The move its correction
    would make is now within 3 of the sd."""
    r, d = _calibrated(tmp_path, 0.0016, 3, n_poses=8)
    assert any("an uncorrected" in w and "depth bend" in w for w in r.warnings), r.warnings


def test_without_cleaning_the_bend_is_still_measured(tmp_path):
    """--no-clean had turned the bend off with the cleaning: exit 0 at 2.1 mm, 11 sd."""
    r, d = _calibrated(tmp_path, 0.0016, 0, no_clean=True)
    assert r.cleaning["bend"]["applied"] and d["translation_mm"] < 0.3, (d, r.cleaning)


def test_the_calibrations_bend_corrects_the_scans_it_validates(tmp_path, capsys):
    """A saved calibration carries the depth bend it corrected (``cleaning.bend``: Legendre coefficients, depths,
    offset), and ``validate`` and ``cloud`` correct a scan's profiles by it: at the data sheet's linearity the
    sphere's form error PF falls from 0.28 to 0.14 mm (RMS of the radial deviations 0.052 to 0.021) on the
    calibration's own scan; a file whose bend is not one is named (exit 2)."""
    import json

    from handeye.app.command.cli import main

    folder, saved = tmp_path / "cell", tmp_path / "cal.json"
    handeye.simulate(out=folder, profiles=True, linearity=0.0016, seed=0, no_start=True)
    assert main(["calibrate", str(folder), "--out", str(saved)]) == 0
    doc = json.loads(saved.read_text())
    plain = tmp_path / "plain.json"
    plain.write_text(json.dumps({**doc, "cleaning": {**doc["cleaning"], "bend": {**doc["cleaning"]["bend"], "applied": False}}}))
    bent, raw = (handeye.validate(folder, f) for f in (saved, plain))
    (a,), (b,) = bent.spheres, raw.spheres
    assert any("corrected by the calibration's depth bend" in n for n in bent.notes)
    assert not any("depth bend" in n for n in raw.notes)
    assert a.rms_mm < 0.6 * b.rms_mm and a.form_error_mm < 0.7 * b.form_error_mm, (a, b)
    assert any("depth bend" in n for n in handeye.cloud(folder, saved).notes)
    broken = tmp_path / "broken.json"
    broken.write_text(json.dumps({**doc, "cleaning": {**doc["cleaning"], "bend": {**doc["cleaning"]["bend"], "beta_mm": [1]}}}))
    capsys.readouterr()
    assert main(["validate", str(folder), "--calibration", str(broken)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "cleaning.bend" in err[0], err
