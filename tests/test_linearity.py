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


@pytest.mark.parametrize("linearity, seed", [(0.0005, 41), (0.0005, 44), (0.0016, 0)])
def test_a_linearity_error_never_exits_0_away_from_the_truth(tmp_path, linearity, seed):
    folder = tmp_path / "cell"
    handeye.simulate(out=folder, profiles=True, linearity=linearity, seed=seed, no_start=True)
    truth = transform_from_pose(tomllib.loads((folder / "setup.toml").read_text())["truth"]["sensor_pose"])
    r = handeye.calibrate(folder)
    d = pose_distance(truth, np.asarray(r.sensor2flange, float), r.covariance, r.parameter_names)
    away = d["sd"] > 3 and (d["translation_mm"] > 0.2 or d["rotation_deg"] > 0.05)
    assert not (r.converged and away), (d, [e.name for e in r.effects or []])
    assert r.converged and d["translation_mm"] < 0.3, d  # uncorrected: 0.8-2.9 mm
