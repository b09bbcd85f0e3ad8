"""Every reader of handeye's input under a seeded fuzz (issue 40, ``tests/fuzz_readers.py``): cut,
corrupted and oversized inputs through the command line end in exit 0, 1 or 2 (2 with one
``handeye: error:`` line), never exit 3, never a CPU limit or a hang, in bounded memory.

The default tier runs 152 inputs (four of every reader); the slow test runs 5,000 on one core.
Both run the script in one child process, which forks one grandchild per input: the pytest worker
itself never forks.
"""
import json
import os
import pathlib
import subprocess
import sys

import fuzz_readers
import numpy as np
import pytest

import handeye

#: peak RSS of any one input's process, MB: the forked process starts at the script's ~70-100 MB;
#: the largest input is a sparse 250 MiB profile, read once (a file past a reader's limit is refused
#: by its size)
MAX_RSS_MB = 1000


def _fuzz(tmp_path, count, seed):
    """Run the fuzz script: its outcomes (dicts) and its table."""
    env = dict(os.environ, PYTHONPATH=str(pathlib.Path(handeye.__file__).parents[1]),
               OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1")
    env.pop("HANDEYE_DEBUG", None)
    out = tmp_path / "outcomes.json"
    p = subprocess.run([sys.executable, str(pathlib.Path(fuzz_readers.__file__)), "--count", str(count), "--seed",
                        str(seed), "--json", str(out), "--keep", str(tmp_path / "scratch")], env=env,
                       capture_output=True, text=True, timeout=3600)
    print(p.stdout)  # the table: pytest shows it with -s or on a failure
    assert out.exists(), p.stdout[-3000:] + p.stderr[-3000:]
    return json.loads(out.read_text()), p


def _check(outcomes, count, each_refuses=False):
    readers = {o["reader"] for o in outcomes}
    bugs = [o for o in outcomes if o["code"] not in (0, 1, 2) or (o["code"] == 2 and o["lines"] != 1)]
    assert len(outcomes) == count and not bugs, bugs[:10]
    assert max(o["rss_mb"] for o in outcomes) < MAX_RSS_MB
    assert max(o["cpu"] for o in outcomes) < fuzz_readers.CPU_SECONDS
    for name in readers if each_refuses else ():  # every reader refuses some mutated inputs (and reads others)
        codes = {o["code"] for o in outcomes if o["reader"] == name}
        assert {0, 2} <= codes, (name, codes)
    return readers


def test_a_sample_of_every_reader_fuzzed(tmp_path):
    """152 inputs, four of each of the 38 readers (pose tables, controller files, every profile format
    as a folder and as a shell glob, ROS 2 bags, dataset folders, --setup, saved calibrations)."""
    outcomes, p = _fuzz(tmp_path, 152, seed=40)
    readers = _check(outcomes, 152)
    assert len(readers) == 38 and p.returncode == 0
    assert sum(o["code"] == 0 for o in outcomes) > 10  # mutations that still read: the readers' whole path ran


@pytest.mark.slow(sibling="test_a_sample_of_every_reader_fuzzed")
def test_5000_inputs_across_every_reader(tmp_path):
    """The issue's fuzz: 5,000 inputs, 131-132 per reader, every mutation; 0 exit 3, 0 timeouts or
    hangs, every input's peak RSS under :data:`MAX_RSS_MB`."""
    outcomes, p = _fuzz(tmp_path, 5000, seed=42)
    _check(outcomes, 5000, each_refuses=True)
    mutations = {o["mutation"].rstrip("+") for o in outcomes}
    assert {"cut", "flip", "odd_number", "lying_header", "nested", "encoding", "empty", "folder", "symlink-loop",
            "fifo", "sparse", "repeated"} <= mutations
    assert p.returncode == 0


# --- what the fuzz found, each on its own ----------------------------------------------------------

def test_number_and_column_name_checks_are_linear():
    """A 60,000-digit cell and 10^5 open brackets (9 s and 8 s of CPU before; quadratic regexes)."""
    import time

    from handeye.app.ingest.poses import canonical
    from handeye.app.ingest.tables import is_number

    start = time.process_time()
    assert not is_number("9" * 60_000 + "x") and is_number("9" * 60_000) and is_number("1.5e3") and not is_number("1_0")
    assert canonical("(" * 100_000 + "x") is None and canonical("Pos_X [mm]") == "x" and canonical("A (deg)") == "a"
    assert time.process_time() - start < 0.5


def test_a_three_point_profile_is_a_circle():
    """The fewest points a dataset's profile may have (exit 3 before: the Hyper fit indexed a fourth singular value)."""
    from handeye.model.geometry.circle import hyper

    c = hyper(np.array([0.0, 1.0, -1.0]), np.array([1.0, 0.0, 0.0]))
    assert np.allclose([c.x, c.z, c.r], [0, 0, 1], atol=1e-12)


def test_parse_errors_of_json_and_toml_are_named(tmp_path):
    """A 5,000-digit integer is a plain ValueError of Python's parsers, not their syntax error: in a
    saved calibration, a --setup file, a dataset's setup.toml or a FileStorage JSON it is exit 2."""
    from handeye.app.command.cli import main

    (tmp_path / "cal.json").write_text('{"sensor_matrix": ' + "9" * 5000 + "}")
    assert main(["export", str(tmp_path / "cal.json"), "--format", "ur"]) == 2
    (tmp_path / "ds").mkdir()
    (tmp_path / "ds" / "setup.toml").write_text("[sphere]\ndiameter = " + "9" * 5000 + "\n")
    (tmp_path / "ds" / "measurements.csv").write_text("id,x,y,z,a,b,c,xs,ys,zs\n")
    assert main(["calibrate", str(tmp_path / "ds")]) == 2
    assert main(["dataset", "new", str(tmp_path / "out"), "--poses", str(tmp_path / "ds" / "measurements.csv"),
                 "--profiles", str(tmp_path), "--setup", str(tmp_path / "ds" / "setup.toml")]) == 2


@pytest.mark.parametrize("make", ["fifo", "loop", "zero"])
def test_a_pipe_a_device_or_a_symlink_loop_given_as_a_file(tmp_path, make, capsys):
    """Never opened (a FIFO blocked ``dataset new`` and ``export`` forever, /dev/zero never ended, a
    symlink loop was exit 3): exit 2 naming the file, for a pose file, a bag's file and a saved calibration."""
    from handeye.app.command.cli import main

    def hostile(path):
        {"fifo": lambda: os.mkfifo(path), "zero": lambda: os.symlink("/dev/zero", path),
         "loop": lambda: os.symlink(path.name, path)}[make]()  # a link to itself
        return str(path)

    (tmp_path / "scans").mkdir()
    (tmp_path / "bag").mkdir()
    (tmp_path / "bag" / "metadata.yaml").write_text("rosbag2_bagfile_information: {}\n")
    hostile(tmp_path / "bag" / "bag.db3")
    runs = [["dataset", "new", str(tmp_path / "o1"), "--poses", hostile(tmp_path / "poses.ls"), "--profiles",
             str(tmp_path / "scans"), "--diameter", "50"],
            ["dataset", "new", str(tmp_path / "o2"), "--bag", str(tmp_path / "bag"), "--pose-topic", "/p",
             "--profile-topic", "/s", "--diameter", "50"],
            ["export", hostile(tmp_path / "cal.json"), "--format", "ur"]]
    for argv in runs:
        assert main(argv) == 2, argv
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "handeye: error:" in err[0], err
