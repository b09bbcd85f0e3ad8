"""Poses from the robot controllers' own files (``handeye.app.ingest.controllers``), issue 40 item 1.

Real files of other cells (``tests/data/controllers``: a FANUC TP program, a KUKA .src/.dat pair,
an ABB RAPID module, a UR RTDE log) are read and compared with an independent reading (plain
regular expressions, scipy's rotations from the vendors' formulas: :mod:`controller_files`).
Cells of :mod:`ingest_truth` written as each controller writes its programs go through
``handeye dataset new`` (and, in the slow tier, ``handeye calibrate`` to the truth). Hostile
files end with exit 2 and one line naming the file, the line and the field.
"""
import json
import pathlib
import re
import time

import numpy as np
import pytest
from controller_files import (
    abb_reading,
    fanuc_configs,
    fanuc_reading,
    kuka_reading,
    matrix,
    transforms,
    write_krl,
    write_ls,
    write_mod,
    write_rtde,
    write_rtde_stream,
    write_urscript,
)
from ingest_truth import make_cell, pose_error

from handeye.app.command.cli import main
from handeye.app.ingest.controller_rtde import STILL, stops
from handeye.app.ingest.controllers import read_controller
from handeye.model.chain import conventions
from handeye.model.common.errors import InputError
from handeye.model.readers.tables import DatasetError

DATA = pathlib.Path(__file__).resolve().parent / "data" / "controllers"


def _same_rotations(convention, ours, theirs):
    """handeye's matrices of its values equal scipy's of the file's numbers (1e-9)."""
    for a, b in zip(ours, theirs):
        assert np.allclose(conventions.matrix_from(convention, a[3:]), matrix(convention, b[3:]), atol=1e-9)


# --- real files against an independent reading -----------------------------------------------------

def test_fanuc_real_program():
    """crs_process_data's surface_cartesian.ls: 21 positions in /MN order, UT 1 refused, then read
    with --accept-frames; numbers and W,P,R rotations as the independent reading has them."""
    path = DATA / "fanuc_surface_cartesian.ls"
    with pytest.raises(DatasetError) as err:
        read_controller(path)
    assert (err.value.row, err.value.column) == (48, "UT") and "UT 1" in str(err.value)
    got = read_controller(path, accept_frames=True)
    names, rows = fanuc_reading(path.read_text())
    assert got.convention == "fanuc" and list(got.ids) == names and len(names) == 21
    assert np.allclose(got.values, rows, atol=1e-9)
    _same_rotations("fanuc", got.values, rows)


def test_fanuc_real_programs_in_german():
    """A German controller's export (cp1252, ``KONFIG``, groups GP2..GP4 of rails): 9 positions as
    the independent reading has them, GP2.. said not read; a program of joint-form positions
    (``J1=  25.000 deg``) is refused naming its first one's J1."""
    path = DATA / "fanuc_german_up023.ls"
    got = read_controller(path, accept_frames=True)
    names, rows = fanuc_reading(path.read_text(encoding="cp1252"))
    assert list(got.ids) == names and len(names) == 9 and np.allclose(got.values, rows, atol=1e-9)
    assert any("read as cp1252" in n for n in got.notes) and any("GP2.. " in n for n in got.notes)
    _same_rotations("fanuc", got.values, rows)
    with pytest.raises(DatasetError) as err:
        read_controller(DATA / "fanuc_joint_folge125.ls", accept_frames=True)
    assert (err.value.row, err.value.column) == (43, "J1") and "joint form" in str(err.value)


def test_kuka_real_program():
    """A KUKA KRC4 pick program (.src + .dat, CRLF): 8 points in the .src's motion order (the
    .dat declares them in another), names as the .src spells them, TOOL_NO 1 refused."""
    src, dat = DATA / "kuka_style1pick1opt1.src", DATA / "kuka_style1pick1opt1.dat"
    with pytest.raises(DatasetError) as err:
        read_controller(src)
    assert err.value.column == "TOOL_NO" and "tool 1" in str(err.value)
    got = read_controller(src, accept_frames=True)
    names, rows = kuka_reading(src.read_text(), dat.read_text())
    assert list(got.ids) == names == ["P12", "P10", "P20", "P30AbovePick", "AtPick3", "P40", "P9", "P8"]
    assert np.allclose(got.values, rows, atol=1e-9) and got.companions == (dat,)
    _same_rotations("kuka", got.values, rows)
    assert list(read_controller(dat, accept_frames=True).ids) == names  # the .dat finds its .src


def test_abb_real_module():
    """A RAPID module of 37 targets (PReposo moved to three times, a MoveC): motion order, tool0 /
    wobj0 read without a word, quaternions w first as the independent reading has them."""
    path = DATA / "abb_ModTotal.mod"
    got = read_controller(path)
    names, rows = abb_reading(path.read_text())
    assert list(got.ids) == names and len(names) == 37 and "read once: PReposo" in " ".join(got.notes)
    assert np.allclose(got.values[:, :3], rows[:, :3], atol=1e-9)
    assert np.allclose(got.values[:, 3:], rows[:, 3:] / np.linalg.norm(rows[:, 3:], axis=1, keepdims=True), atol=1e-12)
    _same_rotations("abb", got.values, rows)


def test_rtde_real_log():
    """A UR RTDE CSV log, record.py's stream at 125 Hz of a robot standing still (11 equal rows, 0.08 s):
    one pose, the median of its rows, in mm (x1000), rotation vectors, actual_q as degrees; the log
    has no tcp_offset, and the notes say the poses are the flange's only with a zero TCP."""
    path = DATA / "ur_rtde_robot_data.csv"
    got = read_controller(path)
    table = np.genfromtxt(path, delimiter=",", names=True)
    pose = np.column_stack([table[f"actual_TCP_pose_{k}"] for k in range(6)])
    assert got.ids is None and len(table) == 11 and len(got.values) == 1 and got.lines == (2,)
    assert np.ptp(pose, axis=0).max() == 0  # the robot stood still: every row the same pose
    assert np.allclose(got.values[:, :3], 1000 * pose[:1, :3]) and np.allclose(got.values[:, 3:], pose[:1, 3:])
    assert np.allclose(got.joints, np.degrees(np.column_stack([table[f"actual_q_{k}"] for k in range(6)]))[:1])
    assert "a log streamed at 125 Hz, still throughout (11 rows, 0.08 s): one pose" in got.notes[0]
    assert any("flange only if the TCP offset is zero" in n for n in got.notes)
    _same_rotations("ur", got.values, pose[:1])


# --- written as the controllers write them: dataset new ----------------------------------------

def _profiles(folder, cell):
    folder.mkdir()
    for k, xz in enumerate(cell.profiles):
        np.savetxt(folder / f"scan_{k + 1:02d}.csv", xz, delimiter=",", header="x,z", comments="")
    return folder


WRITERS = {"fanuc": (write_ls, "prog.ls", 1e-3), "kuka": (write_krl, None, 1e-4), "abb": (write_mod, "prog.mod", 1e-6),
           "ur": (write_urscript, "prog.script", 1e-5), "rtde": (write_rtde, "log.csv", 1e-5)}


def _written(tmp_path, kind, cell):
    writer, name, _ = WRITERS[kind]
    return writer(tmp_path, cell.flange2base) if name is None else writer(tmp_path / name, cell.flange2base)


def _measured(out):
    """The dataset's flange poses as 4x4 transforms, through scipy (not handeye)."""
    lines = (out / "measurements.csv").read_text().splitlines()
    head = lines[0].split(",")
    convention = {"a": "kuka", "w": "fanuc", "q1": "abb", "rx": "ur"}[head[4]]
    rows = np.array([[float(v) for v in line.split(",")[1:head.index("xs")]] for line in lines[1:]])
    return convention, transforms(convention, rows)


@pytest.mark.parametrize("kind", sorted(WRITERS))
def test_written_programs_make_the_dataset(tmp_path, capsys, kind):
    """Each controller's file of a known cell: ``dataset new`` writes the cell's flange poses (to
    the file's rounding) in the file's convention, paired by the pendant's names or by order."""
    cell = make_cell(n=6, seed=11)
    poses = _written(tmp_path, kind, cell)
    out = tmp_path / "cell"
    args = ["dataset", "new", str(out), "--poses", str(poses), "--profiles", str(_profiles(tmp_path / "scans", cell)),
            "--diameter", str(cell.diameter)] + (["--pair", "order"] if kind == "abb" else [])  # ABB's p10, p20: no scan ids
    assert main(args) == 0, capsys.readouterr().err
    summary = capsys.readouterr().out
    convention, got = _measured(out)
    assert convention == {"rtde": "ur"}.get(kind, kind) and f"convention {convention}" in summary
    tol = WRITERS[kind][2]
    assert np.allclose(got[:, :3, 3], cell.flange2base[:, :3, 3], atol=tol * 1000 if kind in ("ur", "rtde") else tol)
    assert np.allclose(got[:, :3, :3], cell.flange2base[:, :3, :3], atol=2e-5)
    if kind == "kuka":
        assert "XHOME (line" in summary  # the $config.dat HOME named, left out
        prov = (out / "PROVENANCE.toml").read_text()
        assert "calib.src" in prov and "calib.dat" in prov
    if kind == "abb":
        assert "2 joint moves (MoveAbsJ" in summary
    if kind in ("ur", "rtde"):  # Polyscope's Waypoint_k_q, RTDE's actual_q: kept only with --robot
        assert "joint angles not written: give --robot MODEL" in summary
        got_joints = read_controller(poses).joints
        assert got_joints.shape == (6, 6) and np.isclose(got_joints[1, 2], np.degrees(0.12 if kind == "ur" else -0.2))


def test_convention_converts_a_controller_file(tmp_path, capsys):
    """--convention converts a controller file's poses (FANUC W,P,R -> KUKA A,B,C); --units,
    which the file states itself, is refused naming the file."""
    cell = make_cell(n=5, seed=12)
    poses, scans = write_ls(tmp_path / "p.ls", cell.flange2base), _profiles(tmp_path / "scans", cell)
    base = ["--poses", str(poses), "--profiles", str(scans), "--diameter", "50.8"]
    assert main(["dataset", "new", str(tmp_path / "k"), *base, "--convention", "kuka"]) == 0
    assert "poses converted fanuc -> kuka" in capsys.readouterr().out
    convention, got = _measured(tmp_path / "k")
    assert convention == "kuka" and np.allclose(got[:, :3, :3], cell.flange2base[:, :3, :3], atol=2e-5)
    assert main(["dataset", "new", str(tmp_path / "m"), *base, "--units", "m"]) == 2
    assert "states its own columns and units: leave out --units" in capsys.readouterr().err


# --- hostile files: exit 2, one line naming file, line and field ------------------------------------

def _ls(tmp_path, cell, **kw):
    return write_ls(tmp_path / "p.ls", cell.flange2base, **kw)


def _edit(path, old, new, count=1):
    text = path.read_bytes().decode()
    assert old in text, old
    path.write_bytes(text.replace(old, new, count).encode())
    return path


HOSTILE = {
    "fanuc tool frame": (lambda t, c: _ls(t, c, ut=2), "p.ls", 16, "UT", "tool frame UT 2"),
    "fanuc user frame": (lambda t, c: _ls(t, c, uf=3), "p.ls", 16, "UF", "user frame UF 3"),
    "fanuc joint form": (lambda t, c: _ls(t, c, joint_form=(1,)), "p.ls", 23, "J1", "joint form"),
    "fanuc missing R": (lambda t, c: _edit(_ls(t, c), ",\tR =", ",\tQ ="), "p.ls", 14, "R", "no R"),
    "fanuc garbage": (lambda t, c: _edit(_ls(t, c), "\tY =", "\tY = 1.2.3 mm,\tYY ="), "p.ls", 17, "Y", "not a number"),
    "fanuc inches": (lambda t, c: _edit(_ls(t, c), "mm,\tY", "in,\tY"), "p.ls", 17, "X", "expected mm"),
    "fanuc unclosed": (lambda t, c: _edit(_ls(t, c), "};\r\n/END", "/END"), "p.ls", None, None, "no closing"),
    "kuka tool": (lambda t, c: write_krl(t, c.flange2base, tool=2), "calib.dat", 17, "TOOL_NO", "tool 2"),
    "kuka joint form": (lambda t, c: _edit(write_krl(t, c.flange2base).with_suffix(".dat"), "DECL E6POS XP3={X",
                                           "DECL E6AXIS XP3={A1 0,A2 0,A3 0,A4 0,A5 0,A6 0,X").with_suffix(".src"),
                        "calib.dat", 10, "E6AXIS", "joint form"),
    "kuka missing C": (lambda t, c: _edit(write_krl(t, c.flange2base).with_suffix(".dat"), ",C ", ",Q ").with_suffix(
        ".src"), "calib.dat", 4, "C", "no component C"),
    "kuka garbage": (lambda t, c: _edit(write_krl(t, c.flange2base).with_suffix(".dat"), ",Y ", ",Y 1e999,W ").with_suffix(
        ".src"), "calib.dat", 4, "Y", "not a finite number"),
    "abb tool": (lambda t, c: write_mod(t / "p.mod", c.flange2base, tool="tGun"), "p.mod", 3, "tool", "tool tGun"),
    "abb tool with tcp": (lambda t, c: write_mod(t / "p.mod", c.flange2base, tool="tGun", tooldata=(
        "[TRUE,[[0,0,150],[1,0,0,0]],[1,[0,0,1],[1,0,0,0],0,0,0]]")), "p.mod", 4, "tool", "tool tGun"),
    "abb wobj": (lambda t, c: write_mod(t / "p.mod", c.flange2base, wobj="wTable"), "p.mod", 3, "wobj", "work object"),
    "abb quaternion": (lambda t, c: _edit(write_mod(t / "p.mod", c.flange2base), "],[0.", "],[1."), "p.mod", 3, "rot",
                       "not a unit quaternion"),
    "abb unclosed": (lambda t, c: _edit(write_mod(t / "p.mod", c.flange2base), "9E+09]];", "9E+09;"), "p.mod", 3, None,
                     "does not close"),
    "urscript tcp": (lambda t, c: write_urscript(t / "p.script", c.flange2base, tcp=(0, 0, 0.12, 0, 0, 0)), "p.script",
                     None, "set_tcp", "set_tcp"),
    "urscript five": (lambda t, c: _edit(write_urscript(t / "p.script", c.flange2base), "p[", "p[0.1, "), "p.script", 3,
                      "p", "holds 7 values"),
    "urscript mm": (lambda t, c: _edit(write_urscript(t / "p.script", c.flange2base), "p[", "p[650"), "p.script", 3, "x",
                    "metres"),
    "rtde columns": (lambda t, c: _edit(write_rtde(t / "log.txt", c.flange2base), "actual_TCP_pose_5", "actual_TCP_5"),
                     "log.txt", 1, None, "no actual_TCP_pose_0..5"),
    "rtde garbage": (lambda t, c: _edit(write_rtde(t / "log.txt", c.flange2base), "\n100.008 -1 ", "\n100.008 -1x "), "log.txt",
                     3, "actual_q_0", "not a number"),
    "rtde tcp offset": (lambda t, c: write_rtde(t / "log.txt", c.flange2base, tcp_offset=(0, 0, 0.1, 0, 0, 0)), "log.txt",
                        2, "tcp_offset_0", "tcp_offset"),
}


@pytest.mark.parametrize("case", sorted(HOSTILE))
def test_hostile_controller_files(tmp_path, capsys, case):
    """A tool or frame not the flange's, a joint-form position, a missing field, a garbage number,
    another unit, an unclosed block: exit 2, one line naming the file, its line and its field."""
    make, name, line, field, words = HOSTILE[case]
    cell = make_cell(n=5, seed=13)
    poses = make(tmp_path, cell)
    scans = _profiles(tmp_path / "scans", cell)
    code = main(["dataset", "new", str(tmp_path / "out"), "--poses", str(poses), "--profiles", str(scans),
                 "--diameter", "50.8"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and "Traceback" not in err, err
    assert f"{name}" in err and words in err, err
    if line is not None:
        assert f", row {line}" in err, err
    if field is not None:
        assert f"column '{field}'" in err, err
    assert not (tmp_path / "out").exists()


def test_accept_frames_reads_one_tool_only(tmp_path, capsys):
    """--accept-frames reads UT 2 as the flange (said in the summary); two tools in one program stay
    refused, naming the second."""
    cell = make_cell(n=5, seed=14)
    scans = str(_profiles(tmp_path / "scans", cell))
    poses = _ls(tmp_path, cell, ut=2)
    args = ["--profiles", scans, "--diameter", "50.8", "--accept-frames"]
    assert main(["dataset", "new", str(tmp_path / "a"), "--poses", str(poses), *args]) == 0
    assert "UT 2 read as the flange (--accept-frames)" in capsys.readouterr().out
    _edit(poses, "UT : 2", "UT : 1", count=1)
    assert main(["dataset", "new", str(tmp_path / "b"), "--poses", str(poses), *args]) == 2
    assert "every pose must be of one tool" in capsys.readouterr().err


# --- slow: calibrated to the truth ------------------------------------------------------------------

@pytest.mark.slow(sibling="test_written_programs_make_the_dataset")
@pytest.mark.parametrize("kind", sorted(WRITERS))
def test_controller_file_calibrates_to_the_truth(tmp_path, capsys, kind):
    """A cell's poses written as each controller writes them, profiles as CSV: ``dataset new``
    then ``calibrate`` land within 4 sd (+5 um, +0.002 deg: the files' rounding) of the truth."""
    cell = make_cell(n=14, seed=21)
    poses = _written(tmp_path, kind, cell)
    out, result = tmp_path / "cell", tmp_path / "result.json"
    assert main(["dataset", "new", str(out), "--poses", str(poses), "--profiles", str(_profiles(tmp_path / "s", cell)),
                 "--diameter", str(cell.diameter), "--center", ",".join(map(str, cell.centre)), "--pair", "order"]) == 0
    assert main(["calibrate", str(out), "--no-loo", "--out", str(result)]) == 0
    capsys.readouterr()
    res = json.loads(result.read_text())
    dt, dr = pose_error(cell, np.array(res["sensor_matrix"]))
    sd_t, sd_r = (float(np.linalg.norm(res["std"][k])) for k in ("sensor_translation_mm", "sensor_rotation_deg"))
    slack = 0.02 if kind == "fanuc" else 0.005  # FANUC writes 3 decimals
    assert dt < 4 * sd_t + slack and dr < 4 * sd_r + 0.002 + (0.002 if kind == "fanuc" else 0), (dt, sd_t, dr, sd_r)


def test_readme_names_the_real_files():
    """Every real file here is listed with its repository and licence in the folder's README."""
    readme = (DATA / "README.md").read_text()
    for f in DATA.iterdir():
        if f.name != "README.md":
            assert f.name in readme
    assert len(re.findall(r"github\.com/", readme)) >= 4


# --- cut, corrupted and mutated files: a result or one input error, never a crash ---------------------

def _mutations(tmp_path, count, seed):
    """``count`` mutated copies of every written format and every real file (cut, bytes flipped,
    a stretch repeated or deleted, syntax junk, 5,000-digit numbers, 10^5 open brackets)."""
    cell = make_cell(n=5, seed=seed)
    base = tmp_path / "seed"
    base.mkdir()
    seeds = {f: f.read_bytes() for f in DATA.iterdir() if f.suffix != ".md"}
    seeds.update({f: f.read_bytes() for f in (write_ls(base / "a.ls", cell.flange2base), write_mod(
        base / "a.mod", cell.flange2base), write_urscript(base / "a.script", cell.flange2base), write_rtde(
        base / "a.csv", cell.flange2base), write_krl(base, cell.flange2base), base / "calib.dat")})
    rng = np.random.default_rng(seed)
    files = sorted(seeds, key=str)
    for k in range(count):
        source = files[k % len(files)]
        data, at = bytearray(seeds[source]), int(rng.integers(len(seeds[source])))
        op = k // len(files) % 6
        if op == 0:
            data = data[:at]
        elif op == 1:
            for i in rng.integers(len(data), size=8):
                data[i] = int(rng.integers(256))
        elif op == 2:
            data = data[:at] + data[at:at + 500] * 20 + data[at:]
        elif op == 3:
            data = data[:at] + bytes(rng.choice(list(b"[]{}(),;:=pPJ\\\"'!#\n 0123456789.eE-+"), 200)) + data[at:]
        elif op == 4:
            data = data[:at] + b"9" * 5000 + data[at:]
        else:
            data = data[:at] + b"[" * 100_000 + data[at:]
        folder = tmp_path / f"m{k}"
        folder.mkdir()
        for f in (seeds if source.suffix in (".src", ".dat") else ()):  # a KUKA file beside its partner
            if f.parent == source.parent and f.stem == source.stem:
                (folder / f.name).write_bytes(seeds[f])
        (folder / source.name).write_bytes(bytes(data))
        yield folder / source.name


@pytest.mark.parametrize("count", [66, pytest.param(3000, marks=pytest.mark.slow(
    sibling="test_hostile_controller_files"))])
def test_mutated_controller_files_end_in_a_result_or_an_input_error(tmp_path, count):
    """Every mutated file is read or refused with an InputError (exit 2 at the command line):
    no other exception, none slower than 3 s of CPU (no reader goes quadratic on a run of 100,000 equal
    characters; a linear read of the largest took 1.2 s of CPU once on the loaded machine, over the 1 s this
    allowed before)."""
    outcomes = {"read": 0, "refused": 0}
    for k, path in enumerate(_mutations(tmp_path, count, seed=40)):
        start = time.process_time()
        try:
            read_controller(path, accept_frames=bool(k % 2))
            outcomes["read"] += 1
        except InputError:
            outcomes["refused"] += 1
        assert time.process_time() - start < 3.0, path
    assert outcomes["refused"] > count // 4 and outcomes["read"] > 0, outcomes


def test_a_dat_of_numbers_is_still_a_table(tmp_path):
    """The suffix alone does not make a KUKA file: a whitespace pose table named ``poses.dat`` is
    read as a table (None here), a KUKA ``.dat`` by its ``DEFDAT``."""
    table = tmp_path / "poses.dat"
    table.write_text("1 650 -120 310 0 0 0\n2 660 -120 310 0 0 0\n")
    assert read_controller(table) is None
    assert read_controller(DATA / "kuka_style1pick1opt1.dat", accept_frames=True).convention == "kuka"


@pytest.mark.parametrize("tool_line, ok", [("BAS (#TOOL,0)", True), ("$TOOL=TOOL_DATA[3]", False),
                                           ("$TOOL=$NULLFRAME", True), ("", False)])
def test_kuka_tool_from_the_program_state(tmp_path, tool_line, ok):
    """Without FDATs (a hand-written program), a point's tool is the last ``BAS(#TOOL,t)`` or
    ``$TOOL=...`` before its motion; none at all is a tool the program does not name."""
    cell = make_cell(n=3, seed=15)
    src = write_krl(tmp_path, cell.flange2base)
    dat = src.with_suffix(".dat")
    dat.write_bytes(re.sub(rb"DECL FDAT [^\n]*\n", b"", dat.read_bytes()))
    text = re.sub(r"(FDAT_ACT=\w+|;FOLD [^\n]*)\r?\n", "", src.read_text())
    src.write_text(text.replace("DEF calib( )\n", f"DEF calib( )\n{tool_line}\nBAS (#BASE,0)\n"))
    if ok:
        assert len(read_controller(src).values) == 3
    else:
        with pytest.raises(DatasetError) as err:
            read_controller(src)
        assert err.value.column == "TOOL_NO" and ("tool 3" in str(err.value) or "names no tool" in str(err.value))


@pytest.mark.slow(sibling="test_rtde_real_log")
def test_rtde_log_with_joints_calibrates_with_its_robot(tmp_path, capsys):
    """A UR5e cell simulated by handeye written as an RTDE log (TCP poses in metres, actual_q in
    radians): with ``--robot ur5e`` the joint angles become j1..j6 (degrees), the loader finds them
    agreeing with the poses, and the calibration lands within 4 sd of the simulated truth."""
    sim = tmp_path / "sim"
    assert main(["simulate", "--out", str(sim), "--robot", "ur5e", "--profiles", "--seed", "3", "--convention", "ur"]) == 0
    lines = (sim / "measurements.csv").read_text().splitlines()
    head = lines[0].split(",")
    rows = [dict(zip(head, line.split(","))) for line in lines[1:]]
    pose = np.array([[float(r[c]) for c in ("x", "y", "z", "rx", "ry", "rz")] for r in rows])
    joints = np.array([[float(r[f"j{k}"]) for k in range(1, 7)] for r in rows])
    table = ["timestamp " + " ".join(f"actual_q_{k}" for k in range(6)) + " " + " ".join(f"actual_TCP_pose_{k}"
                                                                                       for k in range(6))]
    for k, (p, q) in enumerate(zip(pose, joints)):
        table.append(" ".join(f"{v:.12g}" for v in (0.008 * k, *np.radians(q), *(p[:3] / 1000), *p[3:])))
    (tmp_path / "log.csv").write_text("\n".join(table) + "\n")
    setup = (sim / "setup.toml").read_text()
    diameter = re.search(r"diameter = ([\d.]+)", setup).group(1)
    centre = re.search(r"\[sphere\][^\[]*center = \[([^\]]+)\]", setup).group(1).replace(" ", "")
    profiles = [a for r in rows for a in ("--profiles", str(sim / r["profile"]))]
    out, result = tmp_path / "cell", tmp_path / "result.json"
    assert main(["dataset", "new", str(out), "--poses", str(tmp_path / "log.csv"), *profiles, "--pair", "order",
                 "--diameter", diameter, "--center", centre, "--robot", "ur5e"]) == 0
    written = (out / "measurements.csv").read_text().splitlines()
    assert written[0].split(",")[-7:-1] == [f"j{k}" for k in range(1, 7)]
    assert np.allclose([[float(v) for v in line.split(",")[-7:-1]] for line in written[1:]], joints, atol=1e-5)
    assert main(["calibrate", str(out), "--no-loo", "--out", str(result)]) == 0
    capsys.readouterr()
    res = json.loads(result.read_text())
    truth = [float(v) for v in re.search(r"\[truth\]\nsensor_pose = \[([^\]]+)\]", setup).group(1).split(",")]
    t_true = transforms("ur", [truth])[0]
    got = np.array(res["sensor_matrix"])
    dt = float(np.linalg.norm(got[:3, 3] - t_true[:3, 3]))
    dr = float(np.degrees(np.arccos(np.clip((np.trace(t_true[:3, :3].T @ got[:3, :3]) - 1) / 2, -1, 1))))
    sd_t, sd_r = (float(np.linalg.norm(res["std"][k])) for k in ("sensor_translation_mm", "sensor_rotation_deg"))
    assert dt < 4 * sd_t + 0.005 and dr < 4 * sd_r + 0.002, (dt, sd_t, dr, sd_r)


# --- FANUC CONFIG: the arm configuration kept as the dataset's cfx ---------------------------------

def _cfx_of(letters):
    """ABB's cfx of FANUC's letters (bit 0 N: J5 < 0, bit 1 D, bit 2 B), written out here."""
    return {"N": 1, "F": 0}[letters[0]] + {"U": 0, "D": 2}[letters[1]] + {"T": 0, "B": 4}[letters[2]]


def test_fanuc_config_of_the_real_programs():
    """CONFIG (KONFIG in the German export) of every position as a regular expression reads it: the
    letters and turn numbers kept, cfx 1 ('N U T': J5 < 0, elbow up, in front of axis 1) for each."""
    for name, count in (("fanuc_surface_cartesian.ls", 21), ("fanuc_german_up023.ls", 9)):
        path = DATA / name
        got = read_controller(path, accept_frames=True)
        theirs = fanuc_configs(path.read_text(encoding="cp1252"))
        assert len(theirs) == count and [(c[0] + c[2] + c[4], tuple(int(t) for t in c[7:].split(", ")))
                                          for c in got.configs] == theirs
        assert got.configuration.tolist() == [_cfx_of(c[0]) for c in theirs] == [1] * count
        assert "cfx column" in " ".join(got.notes) and f"'N U T, 0, 0, 0' x{count}" in " ".join(got.notes)


def test_fanuc_mixed_configurations_reach_the_dataset_as_a_users_cfx_column(tmp_path, capsys):
    """A program whose positions are in all eight configurations (turn numbers -1..1): the dataset's cfx
    column is each position's, as an independent reading decodes it, the same column a user's own pose CSV
    with cfx gives; the loaded dataset groups the samples by it (the wrist group: the N positions)."""
    from handeye.model.datasets.dataset import load
    from handeye.model.robot import configuration

    cell = make_cell(n=16, seed=16)
    rng = np.random.default_rng(16)
    configs = [f"{'NF'[k % 2]} {'UD'[k // 2 % 2]} {'TB'[k // 4 % 2]}, {', '.join(str(t) for t in rng.integers(-1, 2, 3))}"
               for k in range(16)]
    poses = write_ls(tmp_path / "p.ls", cell.flange2base, configs=configs)
    scans = str(_profiles(tmp_path / "scans", cell))
    assert main(["dataset", "new", str(tmp_path / "a"), "--poses", str(poses), "--profiles", scans, "--diameter",
                 str(cell.diameter)]) == 0, capsys.readouterr().err
    theirs = fanuc_configs(poses.read_text())
    want = [_cfx_of(letters) for letters, _ in theirs]
    assert sorted(set(want)) == list(range(8))
    head, *rows = (tmp_path / "a" / "measurements.csv").read_text().splitlines()
    column = head.split(",").index("cfx")
    assert [int(r.split(",")[column]) for r in rows] == want
    assert list(read_controller(poses).configs) == [c.replace(", ", ", ", 1) for c in configs]
    table = tmp_path / "own.csv"  # the user's own table of the same poses with a cfx column
    fanuc = read_controller(poses).values
    table.write_text("id,x,y,z,w,p,r,cfx\n" + "".join(f"P{k + 1}," + ",".join(f"{v:.6f}" for v in fanuc[k]) + f",{want[k]}\n"
                                                      for k in range(16)))
    assert main(["dataset", "new", str(tmp_path / "b"), "--poses", str(table), "--profiles", scans, "--diameter",
                 str(cell.diameter)]) == 0, capsys.readouterr().err
    head_b, *rows_b = (tmp_path / "b" / "measurements.csv").read_text().splitlines()
    assert [int(r.split(",")[head_b.split(",").index("cfx")]) for r in rows_b] == want
    for folder in ("a", "b"):
        data = load(tmp_path / folder)
        assert data.configuration.tolist() == want
        wrist = [g for g in configuration.groups(data) if g.kind == "wrist" and "j5 < 0" in g.label][0]
        assert wrist.members.tolist() == [letters[0] == "N" for letters, _ in theirs]


@pytest.mark.parametrize("config, shown", [("N X T, 0, 0, 0", "'N X T, 0, 0, 0'"), ("N U T, 0, 0", "'N U T, 0, 0'"),
                                           ("N U T, 0, 0, 12", "'N U T, 0, 0, 12'")])
def test_fanuc_malformed_config_is_named(tmp_path, capsys, config, shown):
    """A CONFIG that is no FANUC configuration (a letter, a turn number missing, a turn of 12), or one not
    closed by its quote: exit 2, one line naming the file, its line and the field."""
    cell = make_cell(n=5, seed=13)
    scans = str(_profiles(tmp_path / "scans", cell))
    configs = ["N U T, 0, 0, 0"] * 5
    configs[2] = config
    for k in range(2):
        poses = (write_ls(tmp_path / "p.ls", cell.flange2base, configs=configs) if k == 0 else
                 _edit(_ls(tmp_path, cell), "CONFIG : 'N U T, 0, 0, 0',", "CONFIG : 'N U T, 0, 0, 0,"))
        code = main(["dataset", "new", str(tmp_path / f"out{k}"), "--poses", str(poses), "--profiles", scans,
                     "--diameter", "50.8"])
        err = capsys.readouterr().err.strip()
        assert code == 2 and len(err.splitlines()) == 1 and "Traceback" not in err, err
        line, what = (28, shown) if k == 0 else (16, "no quoted value")  # P3 is lines 26-31 (P1 from 14, 6 each)
        assert f"p.ls, row {line}" in err and "column 'CONFIG'" in err and what in err, err
        assert "not a FANUC arm configuration" in err, err


# --- UR RTDE logs streamed while the robot moves: one pose per stop -------------------------------

def _angle_deg(a, b):
    return float(np.degrees(np.arccos(np.clip((np.trace(a.T @ b) - 1) / 2, -1, 1))))


def _spans(path):
    """The stops (first row, end row) handeye finds in a log (comma-separated, header, timestamp, q, TCP)."""
    data = np.loadtxt(path, delimiter=",", skiprows=1)
    mm = data[:, 7:13].copy()
    mm[:, :3] *= 1000
    return stops(data[:, 0], mm, np.degrees(data[:, 1:7]), STILL)


def test_rtde_stream_gives_every_stop_at_its_true_pose(tmp_path):
    """A log streamed at 500 Hz (minimum-jerk moves, stops of 0.3-2 s, 0.01 mm of noise on the TCP): the
    14 stops are found, in order, each at its true pose to the noise (< 0.01 mm, < 0.001 deg; the median
    of >= 150 rows has an sd of about 0.001 mm) with the true joints, and each spans its true stop."""
    cell = make_cell(n=14, seed=17)
    path, truth, rows = write_rtde_stream(tmp_path / "log.csv", cell.flange2base, np.random.default_rng(17))
    got = read_controller(path)
    assert len(got.values) == 14 and rows > 10_000
    flanges = transforms("ur", got.values)
    for k in range(14):
        assert np.linalg.norm(flanges[k, :3, 3] - cell.flange2base[k, :3, 3]) < 0.01, k
        assert _angle_deg(flanges[k, :3, :3], cell.flange2base[k, :3, :3]) < 0.001, k
    assert [a + 2 for a, _ in _spans(path)] == list(got.lines)  # each stop's first row (line 1 the header)
    for (a, b), (a0, b0) in zip(_spans(path), truth):  # the true stop, and the end of the move before it within 0.1 mm
        assert a0 - 0.25 * 500 <= a <= a0 and b0 <= b <= b0 + 0.25 * 500, (a, b, a0, b0)
    assert got.notes[0].startswith("a log streamed at 500 Hz, 14 stops in ") and "within 0.1 mm and 0.05 deg" in got.notes[0]
    q = np.loadtxt(path, delimiter=",", skiprows=1)[:, 1:7]
    assert np.allclose(got.joints, np.degrees([np.median(q[a:b], axis=0) for a, b in truth]), atol=1e-3)


def test_rtde_stream_through_dataset_new(tmp_path, capsys):
    """dataset new on a streamed log pairs its stops with the profiles by order (poses to the noise); a
    profile fewer names both counts; a log of a robot that sweeps through the poses without stopping, or
    whose stops are shorter than --still's S, is refused in one line naming the file."""
    cell = make_cell(n=6, seed=18)
    path, _, _ = write_rtde_stream(tmp_path / "log.csv", cell.flange2base, np.random.default_rng(18))
    scans = _profiles(tmp_path / "scans", cell)
    base = ["--poses", str(path), "--diameter", str(cell.diameter)]
    assert main(["dataset", "new", str(tmp_path / "a"), *base, "--profiles", str(scans)]) == 0, capsys.readouterr().err
    assert "6 stops in " in capsys.readouterr().out
    _, got = _measured(tmp_path / "a")
    assert np.allclose(got[:, :3, 3], cell.flange2base[:, :3, 3], atol=0.01)
    (scans / "scan_06.csv").unlink()
    assert main(["dataset", "new", str(tmp_path / "b"), *base, "--profiles", str(scans), "--pair", "order"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "6 poses but 5 profiles" in err and "the 6 stops found in the log" in err, err
    moving, _, _ = write_rtde_stream(tmp_path / "moving.csv", cell.flange2base, np.random.default_rng(19), dwell=None)
    for poses, extra, words in ((moving, [], "with no stop: the TCP is never still within 0.1 mm"),
                                (path, ["--still", "0.1,0.05,2.5"], "for >= 2.5 s")):
        code = main(["dataset", "new", str(tmp_path / "c"), "--poses", str(poses), "--diameter", "50.8", "--profiles",
                     str(scans), *extra])
        err = capsys.readouterr().err.strip()
        assert code == 2 and len(err.splitlines()) == 1 and "Traceback" not in err and words in err, err
        assert f"{poses.name}, row 2, column 'actual_TCP_pose_0'" in err, err
