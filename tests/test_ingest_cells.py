"""``handeye dataset new`` builds every cell (issue 40): the sensor fixed in the cell with the sphere on
the flange, and the sphere on a positioner whose axis angles come as the pose file's ``E1,E2`` columns;
``setup.toml`` is written, not typed from the README, and the next command it suggests runs."""
import csv
import json
import shlex
import shutil

import numpy as np
import pytest

import handeye
from handeye.app.command.cli import main

AXES = "e1:1500,0,600:0,1,0;e2:1500,0,800:0,0,1"


def _loose(tmp_path, capsys, *mounts):
    """A simulated cell's measurements.csv and profiles as loose files: poses named P1.. with upper-case
    columns (``E1,E2`` on a positioner), one CSV profile per pose in scans/."""
    sim = tmp_path / "sim"
    assert main(["simulate", "--out", str(sim), "--profiles", "--n-poses", "8", "--seed", "3", *mounts]) == 0
    capsys.readouterr()
    rows = list(csv.DictReader(open(sim / "measurements.csv")))
    axes = [c for c in ("e1", "e2") if c in rows[0]]
    (tmp_path / "scans").mkdir()
    lines = ["name,X,Y,Z,A,B,C" + "".join(f",{a.upper()}" for a in axes)]
    for k, r in enumerate(rows, start=1):
        lines.append(",".join([f"P{k}"] + [r[c] for c in ("x", "y", "z", "a", "b", "c", *axes)]))
        shutil.copy(sim / r["profile"], tmp_path / "scans" / f"scan_{k}.csv")
    (tmp_path / "poses.csv").write_text("\n".join(lines) + "\n")
    return handeye.load_dataset(sim), [str(f) for f in sorted((tmp_path / "scans").iterdir())]


def _positioner_dataset(tmp_path, capsys):
    """The positioner cell's loose files through ``dataset new``: (simulated dataset, loose scans, the
    dataset made, its summary)."""
    sim, scans = _loose(tmp_path, capsys, "--sphere-mount", "positioner", "--positioner-error", "0,0")
    out = tmp_path / "cell"
    assert main(["dataset", "new", str(out), "--poses", str(tmp_path / "poses.csv"), "--profiles", *scans,
                 "--diameter", "59.94507", "--sphere-mount", "positioner", "--positioner-axes", AXES]) == 0
    summary = capsys.readouterr().out
    new = handeye.load_dataset(out)
    assert "positioner axis columns e1, e2 kept" in summary and "ignored" not in summary
    assert new.mounts.sphere == "positioner" and [a.name for a in new.mounts.axes] == ["e1", "e2"]
    np.testing.assert_allclose(new.axis_angles, sim.axis_angles, atol=1e-6)
    return sim, scans, new, summary


def test_a_sphere_on_a_positioner_from_a_pose_file_with_axis_columns(tmp_path, capsys):
    """The axis columns kept and the axes written; ``--setup`` gives the mounts and the axes as it
    gives the diameter."""
    sim, scans, new, summary = _positioner_dataset(tmp_path, capsys)
    assert summary.split("next      ")[1].strip() == f"handeye calibrate {new.path} --unknowns sensor+sphere"
    again = tmp_path / "again"
    assert main(["dataset", "new", str(again), "--poses", str(tmp_path / "poses.csv"), "--profiles", *scans,
                 "--setup", str(sim.path / "setup.toml")]) == 0
    got = handeye.load_dataset(again).mounts
    assert (got.sensor, got.sphere) == ("flange", "positioner")
    np.testing.assert_allclose([[*a.point, *a.direction] for a in got.axes],
                               [[*a.point, *a.direction] for a in new.mounts.axes])


@pytest.mark.slow(sibling="test_a_sphere_on_a_positioner_from_a_pose_file_with_axis_columns")
def test_the_next_command_a_positioner_dataset_suggests_runs(tmp_path, capsys):
    """The calibration ``dataset new`` suggests runs as printed (it failed when the axis columns were
    dropped) and finds the centre on the table (5 s CPU: the positioner's held-axes test)."""
    sim, _, new, summary = _positioner_dataset(tmp_path, capsys)
    assert main(shlex.split(summary.split("next      ")[1].strip())[1:] + ["--no-loo", "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert np.linalg.norm(np.array(result["sphere_center"]) - [1650.0, 0.0, 900.0]) < 1.0


def test_a_sensor_fixed_in_the_cell_and_a_sphere_on_the_flange(tmp_path, capsys):
    sim, scans = _loose(tmp_path, capsys, "--sensor-mount", "world", "--sphere-mount", "flange")
    out = tmp_path / "cell"
    assert main(["dataset", "new", str(out), "--poses", str(tmp_path / "poses.csv"), "--profiles", *scans,
                 "--diameter", "59.94507", "--sensor-mount", "world", "--sphere-mount", "flange",
                 "--center", "0,0,150"]) == 0
    capsys.readouterr()
    new = handeye.load_dataset(out)
    assert (new.mounts.sensor, new.mounts.sphere) == ("world", "flange")
    np.testing.assert_allclose(new.sphere_centre, [0, 0, 150])
    np.testing.assert_allclose(new.raw_poses, sim.raw_poses, atol=1e-6)


@pytest.mark.parametrize("args, words", [
    (["--sphere-mount", "positioner"], "--sphere-mount positioner needs --positioner-axes"),
    (["--positioner-axes", AXES], "--positioner-axes needs --sphere-mount positioner"),
    (["--sensor-mount", "world"], "--sensor-mount world with --sphere-mount world is no cell"),
    (["--sphere-mount", "positioner", "--positioner-axes", "e1:1500,0,600:0,1,0;e3:1500,0,800:0,0,1"],
     "poses.csv, row 1: no column 'e3'"),
])
def test_cell_options_that_do_not_fit_are_named(tmp_path, capsys, args, words):
    (tmp_path / "poses.csv").write_text("id,x,y,z,a,b,c,e1,e2\n1,1500,0,900,0,90,0,0,0\n2,1510,0,900,0,90,0,10,20\n")
    (tmp_path / "p1.csv").write_text("x,z\n1,240\n2,241\n3,243\n")
    (tmp_path / "p2.csv").write_text("x,z\n1,240\n2,241\n3,243\n")
    code = main(["dataset", "new", str(tmp_path / "out"), "--poses", str(tmp_path / "poses.csv"), "--profiles",
                 str(tmp_path / "p1.csv"), str(tmp_path / "p2.csv"), "--diameter", "50", *args])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and words in err[0], err
    assert not (tmp_path / "out").exists()
