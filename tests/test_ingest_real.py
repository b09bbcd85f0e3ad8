"""``handeye dataset new`` alone on RobCalibrator's loose files, as the cell wrote them
(``tests/data/robcalibrator-raw``, third-party real data, MIT): the datasets it makes calibrate as
the ones the 200-line ``tests/data/robcalibrator/convert.py`` made of the same files.

What the command has to find by itself: a JSON object holding one list of FANUC poses and a
headerless whitespace file (``--convention fanuc``); OpenCV FileStorage YAML whose points are a flat
``scan_line: [x, y, z, ...]`` with ``.Nan``; z a height towards the sensor (turned half a turn
about x, so ``--side`` in the files' y becomes the converter's side); ``1_3C_line.yml`` paired by
its first number; the folder's ``calibration.sec`` skipped. The ball's speckle needs the loader's
profile cleaning (``handeye.model.geometry.profile_clean``); without it that case is skipped.
"""
import pathlib

import numpy as np
import pytest

import handeye
from handeye.app.command.cli import main

DATA = pathlib.Path(__file__).resolve().parent / "data"
RAW, CONVERTED = DATA / "robcalibrator-raw", DATA / "robcalibrator"
pytestmark = pytest.mark.skipif(not (RAW.is_dir() and CONVERTED.is_dir()),
                                reason="tests/data/robcalibrator-raw and robcalibrator are absent")

#: folder of loose files -> (pose file, diameter mm, side in the files' y (SphCtrDirc), converted dataset)
CASES = {"scan-2023-10-31": ("RobPoses.rob", 80.0, -1, "scan-2023-10-31"),
         "ball": ("robpose.txt", 25.4, 1, "ball-2023-05")}


def _angle_deg(r1, r2):
    return float(np.degrees(np.arccos(np.clip((np.trace(r1.T @ r2) - 1) / 2, -1, 1))))


@pytest.mark.parametrize("name", list(CASES))
def test_dataset_new_alone_calibrates_as_the_converter(name, tmp_path, capsys):
    if name == "ball":
        pytest.importorskip("handeye.model.geometry.profile_clean", reason="the ball's speckle needs the loader's cleaning")
    poses, diameter, side, converted = CASES[name]
    out = tmp_path / name
    code = main(["dataset", "new", str(out), "--poses", str(RAW / name / poses), "--convention", "fanuc",
                 "--profiles", str(RAW / name), "--diameter", str(diameter), "--side", str(side)])
    summary = capsys.readouterr().out
    assert code == 0 and "y = file -y, z = file -z" in summary
    new, old = handeye.load_dataset(out), handeye.load_dataset(CONVERTED / converted)
    assert len(new) == len(old) and new.side == old.side and new.convention == old.convention == "fanuc"
    np.testing.assert_allclose(new.raw_poses, old.raw_poses, atol=1e-9)  # the converter copied them unchanged
    a = handeye.calibrate(new, unknowns="sensor+sphere", no_loo=True)
    b = handeye.calibrate(old, unknowns="sensor+sphere", no_loo=True)
    assert a.converged and b.converged
    # measured with the loader's cleaning: 10-31 identical to 0.01 mm, the ball 0.01 mm and 0.02 deg apart; a is
    # of the files' own frame (dataset new kept their turn, y = -y, z = -z), b of the converter's, handeye's
    turn = np.diag([1.0, -1.0, -1.0, 1.0])
    np.testing.assert_allclose(new.own_axes, turn[:3, :3], atol=1e-12)
    b_own = b.sensor2flange @ turn
    assert np.linalg.norm(a.sensor2flange[:3, 3] - b_own[:3, 3]) < 0.1
    assert _angle_deg(a.sensor2flange[:3, :3], b_own[:3, :3]) < 0.1
