"""Reading the tables of a dataset: CSV files, numbers, ids, poses in any robot convention.

Shared by :mod:`handeye.model.datasets.dataset` (calibration datasets) and :mod:`handeye.model.datasets.scan`
(scans: poses and profiles only). Every problem raises :class:`DatasetError`, whose text names
file, row and column.
"""
from __future__ import annotations

import csv
import io
import math
import pathlib
import warnings

import numpy as np

from handeye.model.chain import conventions
from handeye.model.common.errors import InputError

#: Plausible magnitude of a robot position (mm); ``[limits] position_mm`` in setup.toml changes it.
LIMIT_POSITION_MM = 20_000.0


class DatasetError(InputError):
    """A dataset is missing, malformed or inconsistent.

    Attributes
    ----------
    file : str
    row : int or None
        1-based line number in the file (the header is line 1).
    column : str or None
    problem : str
    """

    def __init__(self, file, problem, row=None, column=None):
        self.file, self.row, self.column, self.problem = str(file), row, column, problem
        where = self.file
        if row is not None:
            where += f", row {row}"
        if column is not None:
            where += f", column {column!r}"
        super().__init__(f"{where}: {problem}")


def number(text, file, row, column):
    if "_" in str(text):  # Python reads 1_000 as 1000; a CSV of measurements should not
        raise DatasetError(file, f"not a number: {text!r}", row, column)
    try:
        v = float(text)
    except (TypeError, ValueError):
        raise DatasetError(file, f"not a number: {text!r}", row, column) from None
    if not math.isfinite(v):
        raise DatasetError(file, f"not a finite number: {text!r}", row, column)
    return v


#: Principal ranges of controller readings per angle convention (degrees): flange and plate
#: poses must lie in them.
READING_RANGES = {"kuka": (180.0, 90.0, 180.0), "fanuc": (180.0, 90.0, 180.0)}
#: KUKA readings (flange and plate poses, pose lists).
READING_LIMITS = READING_RANGES["kuka"]
#: A start guess may be any rotation (Table 7-2 starts at B = -90.1), but not beyond a turn.
GUESS_LIMITS = (conventions.ANGLE_LIMIT_DEG,) * 3


def check_angles(pose, file, row=None, column_prefix="", limits=READING_LIMITS, names=("a", "b", "c")):
    for name, v, lim in zip(names, pose[3:], limits):
        if abs(v) > lim:
            raise DatasetError(file, f"rotation angle {v} out of range [-{lim:g}, {lim:g}] degrees", row, column_prefix + name)


def row_id(fields, column, seen, file, line):
    """The id of a data row: non-empty and unique (``seen``: id -> first row, updated)."""
    ident = fields[column].strip()
    if not ident:
        raise DatasetError(file, "empty id", line, "id")
    if ident in seen:
        raise DatasetError(file, f"duplicate id {ident!r} (first on row {seen[ident]})", line, "id")
    seen[ident] = line
    return ident


def to_kuka(pose, convention, file, row, column):
    """A pose in ``convention`` as KUKA (mm, deg); errors name file, row and column."""
    try:
        return conventions.convert(pose, convention, "kuka")
    except conventions.ConventionError as exc:
        names = ",".join(conventions.CONVENTIONS[convention])
        raise DatasetError(file, str(exc), row, column or names) from None


def read_pose(fields, idx, convention, file, line, position_mm):
    """The flange pose of one row of ``measurements.csv`` as KUKA (mm, deg): numbers checked,
    angles in the controller's ranges, positions within ``position_mm`` (``[limits]``), then
    converted from ``convention``. ``idx`` maps column names to field positions."""
    pose_columns = conventions.columns(convention)
    pose = np.array([number(fields[idx[c]], file, line, c) for c in pose_columns])
    if convention in READING_RANGES:
        check_angles(pose, file, line, limits=READING_RANGES[convention], names=pose_columns[3:])
    for v, c in zip(pose[:3], pose_columns[:3]):
        if abs(v) > position_mm:
            raise DatasetError(file, f"{v:g} mm is beyond the plausible robot position +-{position_mm:g} mm "
                                     "([limits] position_mm in setup.toml sets it)", line, c)
    return pose if convention == "kuka" else to_kuka(pose, convention, file, line, None)


def pose_list_convention(header):
    """The robot convention a pose list's header names (``id,x,y,z,`` + the convention's columns)."""
    for name in conventions.CONVENTIONS:
        if list(header) == ["id", *conventions.columns(name)]:
            return name
    return None


#: Largest file the readers accept, and longest line (bytes): a dataset of 10^6 rows is ~150 MB.
MAX_FILE_BYTES = 2 * 1024**3
MAX_LINE_BYTES = 1024**2

#: What Python's JSON and TOML parsers raise on text they cannot read: a syntax error (a ValueError),
#: nesting deeper than the parser goes (RecursionError), an integer of more than 4,300 digits (a plain
#: ValueError, not the parser's own error: a reader that caught only that one exited 3; issue 40's fuzz)
PARSE_ERRORS = (ValueError, RecursionError)


def long_line(raw, limit=MAX_LINE_BYTES):
    """``(line number, length)`` of a line of ``raw`` (bytes) longer than ``limit``, or None.

    Looked for in steps of ``limit // 2`` bytes (a line that long holds a whole step without a line
    break), so that a file without line breaks (a sparse file of zeros) is refused before it is
    decoded, split or parsed: 250 MB of them cost numpy's parser 2 GB (issue 40's fuzz).
    """
    step = max(limit // 2, 1)
    for at in range(0, len(raw) - step + 1, step):
        if raw.find(b"\n", at, at + step) >= 0 or raw.find(b"\r", at, at + step) >= 0:
            continue
        start = max(raw.rfind(b"\n", 0, at), raw.rfind(b"\r", 0, at)) + 1
        ends = [e for e in (raw.find(b"\n", at), raw.find(b"\r", at)) if e >= 0]
        length = (min(ends) if ends else len(raw)) - start
        if length > limit:
            return raw.count(b"\n", 0, start) + 1, length
    return None


def parse_problem(exc):
    """One line saying why a JSON or TOML text did not parse (``exc`` one of :data:`PARSE_ERRORS`)."""
    if isinstance(exc, RecursionError):
        return "nested deeper than a reader follows"
    if hasattr(exc, "lineno") and hasattr(exc, "msg"):  # json.JSONDecodeError
        return f"line {exc.lineno}: {exc.msg}"
    text = str(exc)
    if "digits" in text and "integer" in text:
        return "an integer of more digits than Python reads (4,300)"
    return text.splitlines()[0][:120] if text else type(exc).__name__


def _relative(file, owner):
    """``file`` as the dataset names it: relative to the folder of ``owner`` (its measurements.csv), else as given."""
    try:
        return str(file.relative_to(owner.parent))
    except ValueError:
        return str(file)


def read_table(file, file_row=None):
    """Rows of a CSV file; size, line length, encoding and separator checked with a clear message.

    ``file_row``: (measurements.csv, row) when ``file`` is a profile named there.
    """
    where = dict(zip(("row", "column"), (file_row[1], "profile"))) if file_row else {}
    owner = file_row[0] if file_row else file
    try:
        if not file.exists():
            raise DatasetError(owner, f"{_relative(file, owner) if file_row else ''} missing file".strip(), **where)
        if not file.is_file():
            raise DatasetError(file, "is not a regular file (a device, a pipe or a folder?)")
        size = file.stat().st_size
        if size > MAX_FILE_BYTES:
            raise DatasetError(file, f"{size / 1e9:.1f} GB is more than a dataset file may be "
                                     f"({MAX_FILE_BYTES / 1e9:.1f} GB)")
        with open(file, "rb") as fh:
            raw = fh.read(min(size, MAX_FILE_BYTES) + 1)  # read(n) allocates n bytes: not 2 GB per small file
    except OSError as exc:
        raise DatasetError(owner, f"cannot be read: {exc.strerror or exc}", **where) from None
    if len(raw) > MAX_FILE_BYTES:
        raise DatasetError(file, f"more than {MAX_FILE_BYTES / 1e9:.1f} GB: not a dataset file")
    if (long := long_line(raw)) is not None:
        raise DatasetError(file, f"a line of {long[1]} characters: not a CSV dataset file", long[0])
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise DatasetError(file, f"not UTF-8 text (byte {exc.start})") from None
    lines = text.splitlines()
    for k, line in enumerate(lines, start=1):
        if len(line) > MAX_LINE_BYTES:
            raise DatasetError(file, f"a line of {len(line)} characters: not a CSV dataset file", k)
    if lines and "," not in lines[0] and (";" in lines[0] or "\t" in lines[0]):
        sep = "';'" if ";" in lines[0] else "a tab"
        raise DatasetError(file, f"the separator is {sep}; handeye reads comma-separated files (',')", 1)
    try:
        return list(csv.reader(lines))
    except csv.Error as exc:
        raise DatasetError(file, f"cannot be read: {exc}") from None


def read_pose_list(path, with_convention=False, axes=()):
    """Flange poses from a pose list, in any robot convention, told by its header.

    ``id,x,y,z,a,b,c`` is KUKA (mm, degrees), ``id,x,y,z,w,p,r`` FANUC, ``id,x,y,z,q1,q2,q3,q4``
    ABB, ``id,x,y,z,rx,ry,rz`` UR (:mod:`handeye.model.chain.conventions`). ``axes`` names positioner
    axis columns (degrees) that follow the pose columns, in this order.

    Returns ``(ids, poses (N, 6))`` with the poses as KUKA, and the convention when
    ``with_convention``; with ``axes``, ``(ids, poses, angles (N, k))`` (and the convention).
    Raises :class:`DatasetError` naming file, row and column.
    """
    file = pathlib.Path(path)
    table = read_table(file)
    header = [h.strip() for h in table[0]] if table else []
    k = len(axes)
    if k and header[-k:] != list(axes):
        raise DatasetError(file, f"header must end with the positioner axis columns {','.join(axes)}", 1)
    convention = pose_list_convention(header[:len(header) - k])
    if convention is None:
        known = "; ".join(",".join(["id", *conventions.columns(c)]) + f" ({c})" for c in conventions.CONVENTIONS)
        raise DatasetError(file, f"header must name a convention's pose columns: {known}", 1)
    ids, poses, seen, angles = [], [], {}, []
    for line, fields in enumerate(table[1:], start=2):
        if not any(f.strip() for f in fields):
            continue
        if len(fields) != len(header):
            raise DatasetError(file, f"expected {len(header)} fields, got {len(fields)}", line)
        ident = row_id(fields, 0, seen, file, line)
        angles.append([number(fields[j], file, line, header[j]) for j in range(len(header) - k, len(header))])
        pose = np.array([number(fields[j], file, line, header[j]) for j in range(1, len(header) - k)])
        for v, c in zip(pose[:3], header[1:4]):
            if abs(v) > LIMIT_POSITION_MM:
                raise DatasetError(file, f"{v:g} mm is beyond the plausible robot position +-{LIMIT_POSITION_MM:g} mm",
                                   line, c)
        if convention in READING_RANGES:
            check_angles(pose, file, line, limits=READING_RANGES[convention], names=header[4:])
        if convention != "kuka":
            pose = to_kuka(pose, convention, file, line, None)
        ids.append(ident)
        poses.append(pose)
    if not poses:
        raise DatasetError(file, "no poses", 2)
    out = (ids, np.array(poses)) + ((np.array(angles, float).reshape(len(ids), k),) if k else ())
    return out + (convention,) if with_convention else out


def pose_list_text(ids, poses, convention="kuka", axes=(), angles=None):
    """A pose list (CSV text) of KUKA poses (N, 6), written in ``convention``; with ``axes``, the
    positioner axis columns (``angles`` (N, k), degrees) after the pose columns."""
    lines = [",".join(["id", *conventions.columns(convention), *axes])]
    for k, (ident, pose) in enumerate(zip(ids, poses)):
        values = pose if convention == "kuka" else conventions.convert(pose, "kuka", convention)
        fmt = "{:.4f}" if convention == "kuka" else "{:.10g}"
        extra = [f"{v:.4f}" for v in angles[k]] if axes else []
        lines.append(",".join([str(ident)] + [fmt.format(v) for v in values] + extra))
    return "\n".join(lines) + "\n"


def _inside(folder, rel, file, row, column="profile"):
    pfile = folder / rel
    try:
        inside = not pathlib.Path(rel).is_absolute() and pfile.resolve().is_relative_to(folder.resolve())
    except (OSError, RuntimeError, ValueError) as exc:  # a symlink loop, a NUL byte in the name
        raise DatasetError(file, f"{column} path {rel!r} cannot be used: {exc}", row, column) from None
    if not inside:
        raise DatasetError(file, f"{column} path {rel!r} leaves the dataset folder; keep {column}s inside it (the "
                                 "dataset's hash covers only its folder)", row, column)
    return pfile


def _points_fast(pfile, limit, axes="xz"):
    """The points of a clean ``x,z`` (``axes``: ``x,y,z``) file by numpy's C parser, or None (then the
    careful reader runs and names what is wrong)."""
    try:
        if not pfile.is_file() or pfile.stat().st_size > MAX_FILE_BYTES:
            return None
        raw = pfile.read_bytes()
    except OSError:
        return None
    if long_line(raw) is not None:  # numpy would parse it into gigabytes; the careful reader names it
        return None
    if raw.startswith(b"\xef\xbb\xbf"):
        raw = raw[3:]
    head, _, body = raw.partition(b"\n")
    if head.strip() != ",".join(axes).encode() or any(c in body for c in (b"_", b'"', b"'", b";", b"\t", b"#")):
        return None
    try:
        with warnings.catch_warnings():  # an empty file: the careful reader says so, in one line
            warnings.simplefilter("ignore")
            pts = np.loadtxt(io.BytesIO(body), delimiter=",", dtype=float, ndmin=2, comments=None, encoding=None)
    except (ValueError, UnicodeDecodeError):
        return None
    if pts.shape[1:] != (len(axes),) or not np.all(np.isfinite(pts)) or (pts.size and np.max(np.abs(pts)) > limit):
        return None
    return pts


def read_cloud(folder, rel, file, row, limit):
    """Points (K, 3) of a point cloud's CSV with header ``x,y,z`` (sensor frame, mm), read and checked as
    :func:`read_points` reads a profile's (the ``cloud`` column's file)."""
    pfile = _inside(folder, rel, file, row, "cloud")
    pts = _points_fast(pfile, limit, "xyz")
    return pts if pts is not None else _points_careful(pfile, file, row, limit, "xyz")


def read_points(folder, rel, file, row, limit, minimum=3):
    """Points (K, 2) of a profile CSV with header ``x,z`` (sensor x, z, mm); errors name the
    profile file, row and column.

    ``rel`` is the path named in ``file`` (``measurements.csv``) on line ``row``; it must lie
    inside ``folder``: what the dataset's hash covers is what it reads. Coordinates beyond
    ``limit`` (mm) are refused; fewer than ``minimum`` points too (a circle needs 3).
    """
    pfile = _inside(folder, rel, file, row)
    pts = _points_fast(pfile, limit)
    if pts is None:
        pts = _points_careful(pfile, file, row, limit)
    if len(pts) < minimum:
        what = "a circle needs" if minimum >= 3 else "a profile needs"
        raise DatasetError(pfile, f"{what} at least {minimum} point{'s' if minimum > 1 else ''}, got {len(pts)}")
    return pts


def _points_careful(pfile, file, row, limit, axes="xz"):
    rows = read_table(pfile, file_row=(file, row))
    if not rows or [h.strip() for h in rows[0]] != list(axes):
        raise DatasetError(pfile, f"header must be {','.join(axes)!r}", 1)
    pts = []
    for k, r in enumerate(rows[1:], start=2):
        if not any(c.strip() for c in r):
            continue
        if len(r) != len(axes):
            raise DatasetError(pfile, f"expected {len(axes)} fields, got {len(r)}", k)
        point = [number(v, pfile, k, c) for v, c in zip(r, axes)]
        for v, c in zip(point, axes):
            if abs(v) > limit:
                raise DatasetError(pfile, f"{v:g} mm is beyond the sensor's plausible range +-{limit:g} mm "
                                          "([limits] sensor_mm in setup.toml sets it)", k, c)
        pts.append(point)
    return np.array(pts, dtype=float).reshape(-1, len(axes))


#: Below this size ``measurements.csv`` is read row by row only; above, :func:`read_plain_rows`
#: reads a plain file (numbers only, no profiles) column-wise first.
PLAIN_ABOVE_BYTES = 1 << 20


def read_plain_rows(file, pose_columns, convention, limits, extra=()):
    """A large plain ``measurements.csv`` (header ``id`` + ``pose_columns`` + ``xs,ys,zs`` in
    any order, no profile column, no quotes or blank lines) read column-wise with numpy, every
    check of the row-by-row reader vectorised; None whenever anything is out of the ordinary
    (then the row-by-row reader reads it and names the offending file, row and column).

    Parameters
    ----------
    file : pathlib.Path
    pose_columns : tuple of str
        The convention's pose columns (:func:`handeye.model.chain.conventions.columns`).
    convention : str
    limits : dict
        ``position_mm`` and ``sensor_mm`` of ``[limits]``.
    extra : tuple of str
        Further numeric columns (positioner axis angles, degrees; within +-720).

    Returns
    -------
    dict or None
        ``ids`` (tuple of str), ``rows`` (tuple of int, lines), ``poses`` (N, 6) KUKA (mm,
        deg), ``raw`` (N, k) the poses as written, ``centres`` (N, 3) mm, ``extra`` (N, len(extra)).
    """
    try:
        if file.stat().st_size <= min(PLAIN_ABOVE_BYTES, MAX_FILE_BYTES) or file.stat().st_size > MAX_FILE_BYTES:
            return None
        text = file.read_bytes().decode("utf-8-sig")
    except (OSError, UnicodeDecodeError):
        return None
    lines = text.splitlines()
    header = [h.strip() for h in lines[0].split(",")] if lines else []
    wanted = ("id", *pose_columns, "xs", "ys", "zs", *extra)
    if sorted(header) != sorted(wanted) or '"' in text or len(lines) < 2:
        return None
    commas = len(header) - 1
    if any(line.count(",") != commas or len(line) > MAX_LINE_BYTES for line in lines):
        return None
    col = {c: header.index(c) for c in header}
    try:
        values = np.loadtxt(lines[1:], delimiter=",", dtype=float, ndmin=2,
                            usecols=[col[c] for c in wanted[1:]])
    except ValueError:
        return None
    k = len(pose_columns)
    raw, centres, more = values[:, :k], values[:, k:k + 3], values[:, k + 3:]
    at = col["id"]
    ids = tuple(line.split(",", at + 1)[at].strip() for line in lines[1:])
    ranges = READING_RANGES.get(convention)
    if (not np.all(np.isfinite(values)) or not all(ids) or len(set(ids)) != len(ids)
            or np.any(np.abs(raw[:, :3]) > limits["position_mm"]) or np.any(np.abs(centres) > limits["sensor_mm"])
            or np.any(np.abs(more) > 720.0)
            or (ranges is not None and np.any(np.abs(raw[:, 3:6]) > np.asarray(ranges)))):
        return None
    try:
        poses = raw.copy() if convention == "kuka" else np.asarray(conventions.convert(raw, convention, "kuka"), float)
    except conventions.ConventionError:
        return None
    return {"ids": ids, "rows": tuple(range(2, len(lines) + 1)), "poses": poses, "raw": raw, "centres": centres,
            "extra": more}
