"""A seeded fuzz of every reader of handeye's input (issue 40): cut, corrupted and oversized files
through the command line as a user runs it, each in its own forked process with a CPU limit and an
address-space cap.

Run as a script (one process at a time: this one, and the child it forks for each input)::

    PYTHONPATH=.. python tests/fuzz_readers.py --count 5000 --seed 40 [--json out.json] [--keep DIR]

The seeds are valid files of every format, written by the project's own writers (``dataset new``,
``calibrate --out``, ``simulate``) and by independent ones (OpenCV's FileStorage, numpy, rosbags'
Writer, the PLY/PCD writers of ``tests/test_ingest_formats.py``, the controller writers of
``tests/controller_files.py``); each runs to exit 0 before any is mutated. Input ``k`` is reader
``k mod R``'s seed with one mutation drawn by ``numpy.random.default_rng([seed, k])``: cut,
bytes flipped, inserted, deleted or repeated, a number made huge (``1e400``, 5,000 digits, nan,
inf, -0) or of a wrong type, 10^5 open brackets, a header's counts made to lie, a sequence left
unclosed, another encoding (UTF-16, a BOM, latin-1), or the path itself made hostile (empty, a
folder, a symlink loop, a FIFO, a sparse file over or under the size limit, 4 MB of repeated
lines). Each input is run through :func:`handeye.app.command.cli.main` in a child forked for it
(``RLIMIT_CPU`` :data:`CPU_SECONDS`, ``RLIMIT_AS`` :data:`MEMORY_BYTES`, killed after
:data:`WALL_SECONDS` without using CPU: blocked): its exit code, CPU time and peak RSS (``wait4``) are recorded. Exit 0, 1
and 2 are answers (2 with one ``handeye: error:`` line); exit 3, a signal or a kill is a bug.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import os
import pathlib
import resource
import select
import shutil
import signal
import struct
import sys
import tempfile
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # one core: no BLAS threads to fork over
os.environ.setdefault("OMP_NUM_THREADS", "1")
HERE = pathlib.Path(__file__).resolve().parent
if str(HERE) not in sys.path:
    sys.path.insert(0, str(HERE))

import numpy as np  # noqa: E402

CPU_SECONDS = 5               # RLIMIT_CPU of each input's child: SIGXCPU past it
WALL_SECONDS = 10             # killed after this long without using CPU (a hang: blocked)
MEMORY_BYTES = 2 * 2**30      # RLIMIT_AS of each input's child
MAX_FUZZ_FILE = 300 * 2**20   # the largest file written (sparse); deleted after its run
REPEAT_BYTES = 4 * 2**20      # an oversized file of repeated lines
DIAMETER = 50.8


@dataclasses.dataclass(frozen=True)
class Reader:
    """One reader as a user reaches it: its seed folder, the files of it to mutate, the command.

    Attributes
    ----------
    name : str
    folder : str
        The seed folder (under the seed root) copied for each input; the command runs in the copy.
    targets : tuple of str
        The files (relative to the folder) one of which each input mutates.
    argv : tuple of str
        The command line, relative to the folder (``out``: the dataset written).
    """

    name: str
    folder: str
    targets: tuple
    argv: tuple


# --- seeds: valid files of every format ----------------------------------------------------------

def _pose_rows(cell):
    return [(k + 1, *p) for k, p in enumerate(cell.kuka())]


def _points3(xz):
    """The profile as 3-D points of the laser plane (x, 0, z)."""
    return np.column_stack([xz[:, 0], np.zeros(len(xz)), xz[:, 1]])


def _ply(path, pts, fmt):
    """A PLY file by the format's specification (a vertex element with an extra property, an empty face element)."""
    head = (f"ply\nformat {fmt} 1.0\ncomment fuzz seed\nelement vertex {len(pts)}\nproperty double x\n"
            "property double y\nproperty double z\nproperty uchar intensity\nelement face 0\n"
            "property list uchar int vertex_indices\nend_header\n")
    if fmt == "ascii":
        body = "".join(f"{x:.17g} {y:.17g} {z:.17g} 7\n" for x, y, z in pts).encode()
    else:
        body = b"".join(struct.pack("<dddB", *p, 7) for p in pts)
    path.write_bytes(head.encode() + body)


def _pcd(path, pts, data):
    """A PCD v0.7 file by the format's specification."""
    head = ("# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS x y z rgb\nSIZE 4 4 4 4\nTYPE F F F U\n"
            f"COUNT 1 1 1 1\nWIDTH {len(pts)}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {len(pts)}\nDATA {data}\n")
    if data == "ascii":
        body = "".join(f"{x:.6f} {y:.6f} {z:.6f} 0\n" for x, y, z in pts).encode()
    else:
        body = b"".join(struct.pack("<fffI", *p, 0) for p in pts)
    path.write_bytes(head.encode() + body)


def _filestorage(path, pts):
    import cv2

    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    fs.write("profile", pts)
    fs.release()


#: profile format -> (file suffix, writer of one file of 3-D points)
PROFILE_WRITERS = {
    "csv": (".csv", lambda p, pts: np.savetxt(p, pts[:, [0, 2]], delimiter=",", header="x,z", comments="")),
    "txt": (".txt", lambda p, pts: np.savetxt(p, pts)),
    "yml": (".yml", _filestorage),
    "xml": (".xml", _filestorage),
    "fsjson": (".json", _filestorage),
    "npy": (".npy", lambda p, pts: np.save(p, pts)),
    "npz": (".npz", lambda p, pts: np.savez(p, profile=pts)),
    "ply-ascii": (".ply", lambda p, pts: _ply(p, pts, "ascii")),
    "ply-binary": (".ply", lambda p, pts: _ply(p, pts, "binary_little_endian")),
    "pcd-ascii": (".pcd", lambda p, pts: _pcd(p, pts, "ascii")),
    "pcd-binary": (".pcd", lambda p, pts: _pcd(p, pts, "binary")),
}


def _loose(folder, cell, fmt="csv"):
    """``folder`` with ``poses.csv`` and ``scans/`` of profiles in ``fmt``; the scans' names."""
    (folder / "scans").mkdir(parents=True)
    suffix, write = PROFILE_WRITERS[fmt]
    names = []
    for k, xz in enumerate(cell.profiles, start=1):
        write(folder / "scans" / f"scan_{k}{suffix}", _points3(xz))
        names.append(f"scans/scan_{k}{suffix}")
    rows = "".join(f"{k}," + ",".join(f"{v:.6f}" for v in p) + "\n" for k, *p in _pose_rows(cell))
    (folder / "poses.csv").write_text("id,x,y,z,a,b,c\n" + rows)
    return names


def _new(poses, *more):
    return ("dataset", "new", "out", "--poses", poses, "--profiles", "scans", "--diameter", str(DIAMETER), *more)


def _pose_seeds(root, cell):
    """The pose readers: CSV, whitespace, JSON tables and the controllers' files."""
    from controller_files import write_krl, write_ls, write_mod, write_rtde, write_urscript

    readers = []
    for name, file, write, more in (
            ("poses-csv", "poses.csv", None, ()),
            ("poses-txt", "poses.txt", lambda p, c: np.savetxt(p, np.array(_pose_rows(c))), ("--convention", "kuka")),
            ("poses-json", "poses.json", lambda p, c: p.write_text(json.dumps(
                [dict(zip(("id", "x", "y", "z", "a", "b", "c"), r)) for r in _pose_rows(c)], indent=1)), ()),
            ("fanuc-ls", "calib.ls", lambda p, c: write_ls(p, c.flange2base), ()),
            ("kuka-src", "calib.src", lambda p, c: write_krl(p.parent, c.flange2base), ()),
            ("kuka-dat", "calib.dat", lambda p, c: write_krl(p.parent, c.flange2base), ()),
            ("abb-mod", "calib.mod", lambda p, c: write_mod(p, c.flange2base), ()),
            ("urscript", "calib.script", lambda p, c: write_urscript(p, c.flange2base), ()),
            ("ur-rtde", "rtde.csv", lambda p, c: write_rtde(p, c.flange2base), ())):
        folder = root / name
        _loose(folder, cell)
        if write is not None:
            write(folder / file, cell)
        poses = "calib.src" if name == "kuka-dat" else file
        readers.append(Reader(name, name, (file,), _new(poses, *more)))
    return readers


def _profile_seeds(root, cell):
    """The profile readers, each format in a folder (``--profiles scans``) or as the shell's glob of files."""
    readers = []
    for fmt in PROFILE_WRITERS:
        names = _loose(root / f"profile-{fmt}", cell, fmt)
        readers.append(Reader(f"profile-{fmt}", f"profile-{fmt}", tuple(names), _new("poses.csv")))
        readers.append(Reader(f"profile-{fmt}-files", f"profile-{fmt}", tuple(names),
                              _new("poses.csv")[:-3] + tuple(names) + ("--diameter", str(DIAMETER))))
    return readers


def _bag_seeds(root, cell):
    """ROS 2 bags written by rosbags' Writer, sqlite3 and mcap."""
    from ingest_bags import write_bag

    readers = []
    for storage in ("sqlite3", "mcap"):
        folder = root / f"bag-{storage}"
        folder.mkdir()
        write_bag(folder / "bag", cell, storage=storage)
        targets = tuple(f"bag/{f.name}" for f in sorted((folder / "bag").iterdir()))
        readers.append(Reader(f"bag-{storage}", folder.name, targets, (
            "dataset", "new", "out", "--bag", "bag", "--pose-topic", "/robot/flange_pose", "--profile-topic",
            "/sensor/profile", "--diameter", str(DIAMETER), "--convention", "kuka")))
    return readers


def _run_here(argv, cwd):
    """Run the command in this process (a seed written by the project's own writers); its exit code."""
    from handeye.app.command.cli import main

    here = os.getcwd()
    os.chdir(cwd)
    try:
        with open(os.devnull, "w") as null:
            saved, sys.stdout = sys.stdout, null
            try:
                return main(list(argv))
            finally:
                sys.stdout = saved
    finally:
        os.chdir(here)


def _dataset_seeds(root, cell):
    """A dataset folder (``calibrate FOLDER``), a simulated one (the sensor fixed, the sphere on the
    flange), ``--setup`` of ``dataset new`` and a saved calibration (``export FILE``, ``calibrate
    --calibration FILE``)."""
    folder = root / "dataset"
    _loose(folder, cell)
    centre = ",".join(f"{v:.3f}" for v in cell.centre)
    assert _run_here(_new("poses.csv", "--center", centre)[:2] + ("ds",) + _new("poses.csv", "--center", centre)[3:],
                     folder) == 0
    assert _run_here(("calibrate", "ds", "--out", "cal.json"), folder) == 0
    shutil.rmtree(folder / "scans")
    (folder / "poses.csv").unlink()
    ds = tuple(f"ds/{f.relative_to(folder / 'ds').as_posix()}" for f in sorted((folder / "ds").rglob("*")) if f.is_file())
    sim = root / "simulated"
    sim.mkdir()
    assert _run_here(("simulate", "--out", "sim", "--profiles", "--n-poses", "8", "--seed", "3", "--sensor-mount",
                      "world", "--sphere-mount", "flange"), sim) == 0
    setup = root / "setup-new"
    _loose(setup, cell)
    shutil.copy(folder / "ds" / "setup.toml", setup / "old.toml")
    return [Reader("dataset-folder", "dataset", tuple(f for f in ds if "PROVENANCE" not in f), ("calibrate", "ds")),
            Reader("dataset-simulated", "simulated", tuple(f"sim/{f.relative_to(sim / 'sim').as_posix()}"
                                                           for f in sorted((sim / "sim").rglob("*")) if f.is_file()),
                   ("calibrate", "sim")),
            Reader("setup-new", "setup-new", ("old.toml",), _new("poses.csv")[:-2] + ("--setup", "old.toml")),
            Reader("calibration-export", "dataset", ("cal.json",), ("export", "cal.json", "--format", "ur")),
            Reader("calibration-held", "dataset", ("cal.json",), ("calibrate", "ds", "--calibration", "cal.json",
                                                                  "--unknowns", "sphere"))]


def make_seeds(root):
    """Write every reader's valid seed under ``root``; the readers."""
    from ingest_truth import make_cell

    cell = make_cell(n=5, seed=40, points=24, diameter=DIAMETER)
    root.mkdir(parents=True, exist_ok=True)
    return (_pose_seeds(root, cell) + _profile_seeds(root, cell) + _bag_seeds(root, cell)
            + _dataset_seeds(root, cell))


# --- mutations -----------------------------------------------------------------------------------

#: what replaces a number: huge, tiny, not finite, signed zero, of another type
ODD_NUMBERS = (b"1e400", b"-1e400", b"9" * 5000, b"1" + b"0" * 400, b"nan", b"NaN", b"inf", b"-inf", b"Infinity",
               b"-0", b"-0.0", b"1e-400", b"0x1F", b"1_000", b"", b"abc", b"true", b"null", b"[]", b"{}", b'"1"',
               b"1,5", b"--1", b"1e", b"0" * 3000 + b"1", b"9" * 60_000 + b"x", b"2147483648", b"18446744073709551616",
               b"-1", b"0")
#: what the count of a header becomes
LYING_COUNTS = (b"0", b"1", b"-1", b"2", b"999999999", b"2147483647", b"4294967296", b"99999999999999999999", b"1e9")


def _spot(rng, data):
    return int(rng.integers(len(data) + 1))


def _cut(rng, data):
    return data[:_spot(rng, data)]


def _flip(rng, data):
    data = bytearray(data)
    for _ in range(int(rng.integers(1, 9))):
        if data:
            data[int(rng.integers(len(data)))] = int(rng.integers(256))
    return bytes(data)


def _insert(rng, data):
    at = _spot(rng, data)
    junk = rng.choice(list(b"[]{}(),;:=\"'!#\n\r\t 0123456789.eE-+xyzP\\<>/&%\x00\xff"), int(rng.integers(1, 65)))
    return data[:at] + bytes(junk.tolist()) + data[at:]


def _delete(rng, data):
    at = _spot(rng, data)
    return data[:at] + data[at + int(rng.integers(1, 200)):]


def _repeat(rng, data):
    at = _spot(rng, data)
    return data[:at] + data[at:at + int(rng.integers(1, 400))] * int(rng.integers(2, 60)) + data[at:]


def _numbers(data):
    import re

    return [m.span() for m in re.finditer(rb"-?\d+(?:\.\d*)?(?:[eE][-+]?\d+)?", data)]


def _odd_number(rng, data):
    spans = _numbers(data)
    if not spans:
        return _insert(rng, data)
    start, end = spans[int(rng.integers(len(spans)))]
    return data[:start] + ODD_NUMBERS[int(rng.integers(len(ODD_NUMBERS)))] + data[end:]


def _lying_header(rng, data):
    """A number of the first 1,000 bytes (a PLY/PCD count, an npy shape, rows/cols, a bag's count) changed."""
    spans = [s for s in _numbers(data) if s[0] < 1000]
    if not spans:
        return _odd_number(rng, data)
    start, end = spans[int(rng.integers(len(spans)))]
    return data[:start] + LYING_COUNTS[int(rng.integers(len(LYING_COUNTS)))] + data[end:]


def _nested(rng, data):
    opener = (b"[", b"{", b'{"a":', b"<a>", b"- ", b"(")[int(rng.integers(6))]
    at = 0 if rng.random() < 0.3 else _spot(rng, data)
    return data[:at] + opener * 100_000 + data[at:]


def _unclosed(rng, data):
    """The last closing bracket, brace or tag end removed, and everything after it."""
    ends = [data.rfind(c) for c in (b"]", b"}", b">", b")", b"\n")]
    end = max(ends)
    return data[:end] if end > 0 else _cut(rng, data)


def _encoding(rng, data):
    k = int(rng.integers(4))
    if k == 0:
        return data.decode("latin-1").encode("utf-16")
    if k == 1:
        return b"\xef\xbb\xbf" + data
    if k == 2:
        at = _spot(rng, data)
        return data[:at] + "é°µÿ".encode("latin-1") + data[at:]
    return data.replace(b"\n", b"\r") if rng.random() < 0.5 else data.replace(b",", b";").replace(b".", b",")


def _lines(rng, data):
    """A line deleted, duplicated, swapped, or cut short by a cell."""
    lines = data.split(b"\n")
    k = int(rng.integers(len(lines)))
    op = int(rng.integers(4))
    if op == 0:
        del lines[k]
    elif op == 1:
        lines.insert(k, lines[k])
    elif op == 2:
        j = int(rng.integers(len(lines)))
        lines[k], lines[j] = lines[j], lines[k]
    else:
        cells = lines[k].split(b",") if b"," in lines[k] else lines[k].split()
        lines[k] = b",".join(cells[:-1]) if b"," in lines[k] else b" ".join(cells[:-1] + cells[-1:] * 2)
    return b"\n".join(lines)


#: mutation of the bytes -> weight
BYTE_MUTATIONS = {_cut: 3, _flip: 3, _insert: 2, _delete: 2, _repeat: 2, _odd_number: 4, _lying_header: 2, _nested: 1,
                  _unclosed: 1, _encoding: 2, _lines: 2}


def _sparse(rng, path, data):
    """A sparse file: the seed's first bytes, then zeros up to 8 MiB, 60 MiB (under the pose limit),
    250 MiB (under the profile limit) or :data:`MAX_FUZZ_FILE` (over both)."""
    path.write_bytes(data[: int(rng.integers(len(data) + 1))])
    os.truncate(path, (8 * 2**20, 60 * 2**20, 250 * 2**20, MAX_FUZZ_FILE)[int(rng.integers(4))])


def _repeated(rng, path, data):
    """:data:`REPEAT_BYTES` of the seed's last lines repeated (a file far longer than its header says)."""
    tail = b"\n".join(data.rstrip(b"\n").split(b"\n")[-int(rng.integers(1, 4)):]) + b"\n"
    with open(path, "wb") as fh:
        fh.write(data)
        fh.write(tail * (REPEAT_BYTES // max(len(tail), 1)))


def _loop(rng, path, data):
    os.symlink(path.name + ".loop", path.with_name(path.name + ".loop2"))
    os.symlink(path.name + ".loop2", path.with_name(path.name + ".loop"))
    os.symlink(path.name + ".loop", path)


#: mutation of the path (the file replaced by something else) -> weight
PATH_MUTATIONS = {
    "empty": (lambda rng, path, data: path.write_bytes(b""), 1.0),
    "folder": (lambda rng, path, data: path.mkdir(), 1.0),
    "symlink-loop": (_loop, 0.5),
    "dangling": (lambda rng, path, data: os.symlink("nowhere", path), 0.5),
    "fifo": (lambda rng, path, data: os.mkfifo(path), 0.5),
    "dev-zero": (lambda rng, path, data: os.symlink("/dev/zero", path), 0.5),
    "sparse": (_sparse, 0.4),
    "repeated": (_repeated, 0.25),
}


def mutate(rng, path):
    """Mutate the file ``path`` in place by one mutation drawn from ``rng``; its name."""
    names = [f.__name__.lstrip("_") for f in BYTE_MUTATIONS] + list(PATH_MUTATIONS)
    weights = np.array(list(BYTE_MUTATIONS.values()) + [w for _, w in PATH_MUTATIONS.values()], float)
    k = int(rng.choice(len(names), p=weights / weights.sum()))
    data = path.read_bytes()
    if k < len(BYTE_MUTATIONS):
        path.write_bytes(list(BYTE_MUTATIONS)[k](rng, data))
        if rng.random() < 0.15:  # a second mutation on top of the first
            path.write_bytes(list(BYTE_MUTATIONS)[int(rng.integers(len(BYTE_MUTATIONS)))](rng, path.read_bytes()))
            return names[k] + "+"
        return names[k]
    path.unlink()
    PATH_MUTATIONS[names[k]][0](rng, path, data)
    return names[k]


# --- the runner ----------------------------------------------------------------------------------

@dataclasses.dataclass(frozen=True)
class Outcome:
    """One input's run: exit code (None: killed by a signal), CPU seconds, peak RSS (MB), stderr's last line."""

    k: int
    reader: str
    target: str
    mutation: str
    code: int | None
    signal: int | None
    cpu: float
    rss_mb: float
    lines: int
    message: str

    @property
    def bug(self):
        """Exit 3, a signal (SIGXCPU past the CPU limit, a kill past the wall limit, a crash) or an
        exit 2 whose stderr is not one ``handeye: error:`` line."""
        return self.code not in (0, 1, 2) or (self.code == 2 and self.lines != 1)


def _child(argv, cwd, err):
    """In the forked child: the limits, stdout to /dev/null, stderr to ``err``, the command; never returns."""
    code = 99
    try:
        resource.setrlimit(resource.RLIMIT_CPU, (CPU_SECONDS, CPU_SECONDS + 1))
        resource.setrlimit(resource.RLIMIT_AS, (MEMORY_BYTES, MEMORY_BYTES))
        os.chdir(cwd)
        null = os.open(os.devnull, os.O_WRONLY)
        fd = os.open(err, os.O_WRONLY | os.O_CREAT | os.O_TRUNC)
        os.dup2(null, 1)
        os.dup2(fd, 2)
        from handeye.app.command.cli import main

        code = main(list(argv))
        sys.stdout.flush()
    except BaseException:  # noqa: BLE001 - a traceback through main is a bug: written, exit 99
        import traceback

        traceback.print_exc()
    finally:
        sys.stderr.flush()
        os._exit(code if isinstance(code, int) else 98)


def _cpu_of(pid):
    """CPU seconds the process ``pid`` has used so far (``/proc/PID/stat``), or None when it is gone."""
    try:
        fields = pathlib.Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return None
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _wait(pid):
    """Wait for the child; SIGKILL it when it has used no CPU for :data:`WALL_SECONDS` (blocked: a hang,
    however loaded the machine; a computing child is stopped by its ``RLIMIT_CPU``)."""
    fd = os.pidfd_open(pid)
    try:
        last, still = _cpu_of(pid), 0.0
        while not select.select([fd], [], [], 1.0)[0]:
            cpu = _cpu_of(pid)
            still = still + 1.0 if cpu == last else 0.0
            last = cpu
            if still >= WALL_SECONDS:
                os.kill(pid, signal.SIGKILL)
                break
    finally:
        os.close(fd)


def run_one(argv, cwd, err):
    """Run ``argv`` in a child forked for it; ``(exit code or None, signal or None, CPU s, peak RSS MB)``."""
    pid = os.fork()
    if pid == 0:
        _child(argv, cwd, err)
    _wait(pid)
    _, status, usage = os.wait4(pid, 0)
    code = os.waitstatus_to_exitcode(status)
    cpu = usage.ru_utime + usage.ru_stime
    return (code, None, cpu, usage.ru_maxrss / 1024) if code >= 0 else (None, -code, cpu, usage.ru_maxrss / 1024)


def _stderr(err):
    try:
        lines = [x for x in err.read_text(errors="replace").splitlines() if x.strip()]
    except OSError:
        return 0, ""
    errors = sum(x.startswith("handeye: error:") or x.startswith("handeye: internal error") for x in lines)
    return errors, (lines[-1][:300] if lines else "")


def _case(rng, reader, work, seeds):
    """Copy the reader's seed folder into ``work`` and mutate one of its targets; ``(target, mutation)``."""
    shutil.rmtree(work, ignore_errors=True)
    shutil.copytree(seeds / reader.folder, work, symlinks=True)
    target = reader.targets[int(rng.integers(len(reader.targets)))]
    return target, mutate(rng, work / target)


def fuzz(inputs, seed, base, readers=None, progress=None):
    """Run the mutated inputs ``inputs`` (a count, or the numbers of the inputs; input ``k``: reader
    ``k mod R``, ``default_rng([seed, k])``); the outcomes. ``base``: a scratch folder (the seeds,
    one input's copy at a time, removed after its run unless ``inputs`` names them)."""
    base = pathlib.Path(base)
    shutil.rmtree(base / "seeds", ignore_errors=True)
    all_readers = make_seeds(base / "seeds")
    readers = [r for r in all_readers if readers is None or r.name in readers]
    out = []
    for k in range(inputs) if isinstance(inputs, int) else inputs:
        reader = readers[k % len(readers)]
        work = base / f"case{'' if isinstance(inputs, int) else k}"
        target, mutation = _case(np.random.default_rng([seed, k]), reader, work, base / "seeds")
        code, sig, cpu, rss = run_one(reader.argv, work, base / "stderr.txt")
        errors, last = _stderr(base / "stderr.txt")
        out.append(Outcome(k, reader.name, target, mutation, code, sig, round(cpu, 3), round(rss, 1), errors, last))
        if isinstance(inputs, int):
            shutil.rmtree(work, ignore_errors=True)
        if progress is not None:
            progress(out[-1])
    return out


# --- the summary ---------------------------------------------------------------------------------

def summary(outcomes):
    """Per reader: inputs, exits 0/1/2, bugs (exit 3, signals, more than one error line), max CPU, max RSS."""
    rows = {}
    for o in outcomes:
        r = rows.setdefault(o.reader, {"inputs": 0, "exit 0": 0, "exit 1": 0, "exit 2": 0, "bugs": 0, "max cpu s": 0.0,
                                       "max rss MB": 0.0})
        r["inputs"] += 1
        if o.bug:
            r["bugs"] += 1
        else:
            r[f"exit {o.code}"] += 1
        r["max cpu s"] = max(r["max cpu s"], o.cpu)
        r["max rss MB"] = max(r["max rss MB"], o.rss_mb)
    return rows


def table(outcomes):
    """The summary as a text table, a line of totals last."""
    rows = summary(outcomes)
    head = ["reader", "inputs", "exit 0", "exit 1", "exit 2", "bugs", "max cpu s", "max rss MB"]
    total = {"inputs": len(outcomes), **{h: sum(r[h] for r in rows.values()) for h in head[2:6]},
             "max cpu s": max((o.cpu for o in outcomes), default=0.0),
             "max rss MB": max((o.rss_mb for o in outcomes), default=0.0)}
    lines = [f"{head[0]:<26}" + "".join(f"{h:>11}" for h in head[1:])]
    for name, r in [*rows.items(), ("all", total)]:
        lines.append(f"{name:<26}" + "".join(f"{r[h]:>11.2f}" if isinstance(r[h], float) else f"{r[h]:>11}" for h in head[1:]))
    return "\n".join(lines)


def main(argv=None):
    """The fuzz as a script: the table on stdout, each bug as one line, the outcomes as JSON (``--json``)."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--count", type=int, default=5000)
    ap.add_argument("--seed", type=int, default=40)
    ap.add_argument("--readers", help="comma-separated reader names (default: every reader)")
    ap.add_argument("--json", help="write every outcome to this file")
    ap.add_argument("--only", help="comma-separated input numbers: only these, their folders kept (with --keep)")
    ap.add_argument("--keep", help="scratch folder to use and keep (default: a temporary one, removed)")
    args = ap.parse_args(argv)
    start = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="handeye-fuzz-") as tmp:
        base = pathlib.Path(args.keep or tmp)
        inputs = [int(k) for k in args.only.split(",")] if args.only else args.count
        outcomes = fuzz(inputs, args.seed, base, args.readers.split(",") if args.readers else None,
                        lambda o: print(f"BUG {o}", flush=True) if o.bug or args.only else None)
    print(table(outcomes))
    print(f"{len(outcomes)} inputs in {time.monotonic() - start:.0f} s; {sum(o.bug for o in outcomes)} bugs")
    if args.json:
        pathlib.Path(args.json).write_text(json.dumps([dataclasses.asdict(o) for o in outcomes]))
    return 1 if any(o.bug for o in outcomes) else 0


if __name__ == "__main__":
    sys.exit(main())
