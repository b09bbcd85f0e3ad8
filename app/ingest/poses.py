"""Flange poses (and joint angles) from a loose table: column names, units, plausibility.

Column names are matched case-insensitively with common aliases (``X``, ``pos_x``,
``position.x``, ``Tx``; ``A,B,C`` KUKA; ``W,P,R`` FANUC; ``rx,ry,rz`` UR; ``qw,qx,qy,qz``,
``q1..q4`` (w first) or ``orientation.x..w`` quaternions; ``id``, ``name``, ``index``). The
names tell the poses' convention; a file without a header needs ``--convention`` (its numbers are
that convention's columns in order, with an optional leading id) or ``--columns``.
Positions are mm in the dataset (``--units m`` multiplies by 1000); angles degrees for KUKA and
FANUC, radians for UR (``--angles`` says what the file holds).
"""
from __future__ import annotations

import dataclasses
import math
import re

import numpy as np

from handeye.app.ingest import controllers
from handeye.app.ingest.tables import read_table
from handeye.model.chain import conventions
from handeye.model.readers.tables import DatasetError
from handeye.model.robot.configuration import cfx_field

#: orientation columns (canonical names) of each convention; abb: quaternion, w first
KINDS = {"kuka": ("a", "b", "c"), "fanuc": ("w", "p", "r"), "ur": ("rx", "ry", "rz"), "abb": ("qw", "qx", "qy", "qz")}
_SINGLE = {**{n: n for n in ("x", "y", "z", "a", "b", "c", "w", "p", "r", "rx", "ry", "rz", "qw", "qx", "qy", "qz")},
           **{f"{p}{a}": a for p in ("p", "t") for a in "xyz"},
           "q1": "qw", "q2": "qx", "q3": "qy", "q4": "qz",
           **{n: "id" for n in ("id", "name", "index", "idx", "pose", "poseid", "no", "nr", "number", "n")},
           **{f"{p}{k}": f"j{k}" for p in ("j", "joint", "axis") for k in range(1, 7)}, "cfx": "cfx"}
_POSITION = {"pos", "position", "translation", "trans", "t", "p", "tcp", "flange", "xyz", "location", "loc"}
_QUATERNION = {"orientation", "quat", "quaternion", "q", "ori", "rotation", "rot"}
_ROTVEC = {"rotvec", "rvec", "r"}
#: below this largest |position| (in the file's units) mm are implausible: metres
METRES_BELOW = 5.0
#: above this largest |position| (in the file's units) metres are implausible: mm
MM_ABOVE = 50.0


#: a bracketed unit of a column name (``[mm]``, ``(deg)``): no bracket inside, so that a cell of 10^5 open
#: brackets is read in linear time (``.*?`` from each one took 8 s of CPU; issue 40's fuzz)
_UNITS = re.compile(r"[\(\[][^\(\)\[\]]*[\)\]]")


def canonical(name):
    """The canonical column name of a header cell (``'Pos_X [mm]'`` -> ``'x'``), or None.

    ``rot.x`` and ``rotation.x`` are quaternion components (ROS's Transform); ``rotvec_x`` a
    rotation vector's."""
    s = _UNITS.sub("", str(name).lower()).strip()
    tokens = [t for t in re.split(r"[\s._\-/:]+", s) if t]
    if not tokens:
        return None
    joined = "".join(tokens)
    if joined in _SINGLE:
        return _SINGLE[joined]
    if len(tokens) >= 2:
        prefix, axis = tokens[-2], tokens[-1]
        if axis in ("x", "y", "z") and prefix in _POSITION:
            return axis
        if axis in ("x", "y", "z", "w") and prefix in _QUATERNION:
            return "q" + axis
        if axis in ("x", "y", "z") and prefix in _ROTVEC:
            return "r" + axis
    return None


@dataclasses.dataclass(frozen=True)
class PoseTable:
    """Poses read from a file.

    Attributes
    ----------
    file : pathlib.Path
    format : str
        The content found (``CSV``, ``JSON list of objects``, ...).
    ids : tuple of str or None
        From the id column; None without one.
    lines : tuple of int
        Line (or JSON item) of each pose in the file.
    values : ndarray, shape (N, 3 + k)
        The flange poses in the robot base in ``convention`` (mm; degrees for kuka and fanuc,
        radians for ur, unit quaternions w, x, y, z for abb).
    convention : str
        The dataset's convention (the file's, or ``--convention`` when it converted).
    source : str
        The convention the file's columns were in.
    columns : tuple of str
        How each file column was read (canonical names; ``-`` ignored).
    notes : tuple of str
        Conversions made (units, angles, quaternion order, convention).
    joints : ndarray (N, 6) or None
        Joint angles (degrees) a controller file gave with the poses.
    companions : tuple of pathlib.Path
        Other files read with it (a KUKA ``.src``'s ``.dat``).
    configuration : ndarray of int (N,) or None
        The arm configuration of each pose as ABB's ``cfx`` (0-7): a table's ``cfx`` column, a FANUC
        program's ``CONFIG`` (:mod:`handeye.app.ingest.controller_fanuc_kuka`); the dataset's ``cfx``.
    """

    file: object
    format: str
    ids: tuple | None
    lines: tuple
    values: np.ndarray
    convention: str
    source: str
    columns: tuple
    notes: tuple
    joints: np.ndarray | None = None
    companions: tuple = ()
    configuration: np.ndarray | None = None


def _names(table, columns, convention, width, what="pose"):
    """Canonical names of the table's columns: from --columns, the header or the convention."""
    if columns is not None:
        if len(columns) != width:
            raise DatasetError(table.file, f"--columns names {len(columns)} columns; the file has {width} per row")
        return list(columns)
    if table.header is not None:
        return [canonical(h) for h in table.header]
    if convention is None:
        raise DatasetError(table.file, "no header: give --convention (kuka|abb|ur|fanuc; its columns in order, with "
                                       "an optional leading id) or --columns")
    cols = ["x", "y", "z", *KINDS[convention]] if what == "pose" else [f"j{k}" for k in range(1, 7)]
    if width == len(cols):
        return cols
    if width == len(cols) + 1:
        return ["id", *cols]
    wanted = ",".join(cols)
    raise DatasetError(table.file, f"{width} numbers per row; the {convention + ' ' if what == 'pose' else ''}columns "
                                   f"{wanted} are {len(cols)} (or {len(cols) + 1} with a leading id)", table.lines[0])


def _kind(names, file):
    """The convention the canonical names make (x,y,z + one orientation set)."""
    found = [k for k, cols in KINDS.items() if set(cols) <= set(names)]
    missing = [c for c in ("x", "y", "z") if c not in names]
    if len(found) != 1 or missing:
        known = ", ".join(n for n in names if n) or "none"
        why = (f"no column {missing[0]!r}" if missing else
               "no complete orientation (a,b,c | w,p,r | rx,ry,rz | qw,qx,qy,qz)" if not found else
               f"orientations of several conventions ({', '.join(found)})")
        raise DatasetError(file, f"{why}; columns recognised: {known} (--columns names them)", 1)
    for n in set(names):
        if n is not None and names.count(n) > 1:
            raise DatasetError(file, f"two columns read as {n!r}", 1, n)
    return found[0]


def _numbers(table, names, wanted):
    """(N, len(wanted)) floats of the named columns; errors name file, row and column."""
    idx = [names.index(c) for c in wanted]
    heads = table.header or names
    out = np.empty((len(table.rows), len(wanted)))
    for r, (row, line) in enumerate(zip(table.rows, table.lines)):
        if len(row) != len(names):
            raise DatasetError(table.file, f"expected {len(names)} fields, got {len(row)}", line)
        for c, j in enumerate(idx):
            try:
                v = float(row[j]) if "_" not in row[j] else float("x")  # Python's 1_000 is no number in a table
            except ValueError:
                raise DatasetError(table.file, f"not a number: {row[j][:30]!r}", line, heads[j]) from None
            if not math.isfinite(v):
                raise DatasetError(table.file, f"not a finite number: {row[j][:30]!r}", line, heads[j])
            out[r, c] = v
    return out


def _ids(table, names):
    if "id" not in names:
        return None
    j, seen = names.index("id"), {}
    for row, line in zip(table.rows, table.lines):
        ident = row[j].strip()
        if not ident:
            raise DatasetError(table.file, "empty id", line, "id")
        if ident in seen:
            raise DatasetError(table.file, f"duplicate id {ident!r} (first on row {seen[ident]})", line, "id")
        seen[ident] = line
    return tuple(row[j].strip() for row in table.rows)


def _check_units(values, units, file):
    """Positions to mm, refusing metres given as mm and mm given as metres."""
    top = float(np.max(np.abs(values[:, :3])))
    if units == "mm" and top < METRES_BELOW and len(values) > 1:
        raise DatasetError(file, f"every position is within +-{top:.3g}: metres, not mm? give --units m")
    if units == "m" and top > MM_ABOVE:
        raise DatasetError(file, f"positions up to {top:g} with --units m: they look like mm (leave out --units m)")
    out = values.copy()
    out[:, :3] *= 1000.0 if units == "m" else 1.0
    return out, (["positions m -> mm (x1000)"] if units == "m" else [])


def _check_angles(values, kind, angles, file):
    """Angles to the convention's units (deg for kuka/fanuc, rad for ur); quaternions normalised."""
    rot, notes = values[:, 3:], []
    if kind in ("kuka", "fanuc"):
        if angles == "rad":
            rot, notes = np.degrees(rot), ["angles rad -> deg"]
        elif np.max(np.abs(rot)) <= math.pi + 1e-6 and np.ptp(rot) > 0 and len(rot) > 2:
            raise DatasetError(file, f"every {kind} angle is within +-pi: radians, not degrees? give --angles rad")
    elif kind == "ur":
        if angles == "deg":
            rot, notes = np.radians(rot), ["rotation vectors deg -> rad"]
        elif np.max(np.linalg.norm(rot, axis=1)) > 2 * math.pi + 1e-6:
            raise DatasetError(file, "a UR rotation vector longer than 2 pi: degrees, not radians? give --angles deg")
    else:
        norm = np.linalg.norm(rot, axis=1)
        bad = np.flatnonzero(np.abs(norm - 1.0) > 0.01)
        if bad.size:
            raise DatasetError(file, f"quaternion of norm {norm[bad[0]]:.4g}, not a unit quaternion", int(bad[0]) + 1)
        rot = rot / norm[:, None]
    return np.column_stack([values[:, :3], rot]), notes


def read_poses(path, convention=None, columns=None, units="mm", angles=None, controller=None):
    """Flange poses of a CSV, whitespace-separated or JSON file (module docstring), or of a robot
    controller's own file (:mod:`handeye.app.ingest.controllers`).

    Parameters
    ----------
    path : path-like
    convention : str or None
        kuka, abb, ur or fanuc: the columns of a headerless file, and the dataset's convention
        (named columns in another convention are converted to it). None: the file's.
    columns : tuple of str or None
        The canonical names of the file's columns (None skips one; ``--columns id,x,y,z,qx,qy,qz,qw``
        for ROS-ordered quaternions, read by :mod:`handeye.app.ingest.request`); overrides the header.
    units : {'mm', 'm'}
        Units of the positions.
    angles : {'deg', 'rad'} or None
        Units of the angles (None: the convention's own).
    controller : dict or None
        How a controller file is read: the keywords of
        :func:`~handeye.app.ingest.controllers.read_controller` (``accept_frames``: a controller file's
        poses in another tool or frame read as the flange's in the base, ``--accept-frames``; ``still``:
        the stops of a streamed RTDE log, ``--still``).

    Returns
    -------
    PoseTable
    """
    found = controllers.read_controller(path, **(controller or {}))
    if found is not None:
        return _from_controller(found, convention, columns, units, angles)
    table = read_table(path, known_name=lambda c: canonical(c) is not None)
    width = len(table.header) if table.header is not None and columns is None else len(table.rows[0])
    names = _names(table, columns, convention, width)
    kind = _kind(names, table.file)
    values, notes = _check_units(_numbers(table, names, ("x", "y", "z") + KINDS[kind]), units, table.file)
    values, more = _check_angles(values, kind, angles, table.file)
    notes += more
    if kind == "abb" and [n for n in names if n in KINDS["abb"]] != list(KINDS["abb"]):
        notes.append("quaternion columns reordered to w,x,y,z")
    target = convention or kind
    if target != kind:
        values = conventions.convert(values, kind, target)
        notes.append(f"poses converted {kind} -> {target}")
    elif kind in ("kuka", "fanuc"):
        values, moved = _in_reading_ranges(values, kind)
        notes += moved
    ignored = tuple(h for h, n in zip(table.header or (), names) if n is None)
    if ignored:
        notes.append(f"columns ignored: {', '.join(ignored)}")
    return PoseTable(table.file, table.kind, _ids(table, names), table.lines, values, target, kind,
                     tuple(n or "-" for n in names), tuple(notes), configuration=_cfx(table, names))


def _cfx(table, names):
    """The ``cfx`` column of a pose table (ABB's arm configuration, an integer 0-7), or None without one."""
    if "cfx" not in names:
        return None
    j = names.index("cfx")
    return np.array([cfx_field(str(row[j]), table.file, line) for row, line in zip(table.rows, table.lines)], int)


def _from_controller(found, convention, columns, units, angles):
    """The :class:`PoseTable` of a controller file's poses: the file tells its columns, units
    and angles (the options that would say them are refused), ``convention`` converts."""
    for given, flag in ((columns is not None, "--columns"), (units != "mm", "--units"), (angles is not None, "--angles")):
        if given:
            raise DatasetError(found.file, f"a {found.format} states its own columns and units: leave out {flag}")
    values, notes = found.values, list(found.notes)
    target = convention or found.convention
    if target != found.convention:
        values = conventions.convert(values, found.convention, target)
        notes.append(f"poses converted {found.convention} -> {target}")
    elif target in ("kuka", "fanuc"):
        values, moved = _in_reading_ranges(values, target)
        notes += moved
    names = ("x", "y", "z") + KINDS[found.convention]
    return PoseTable(found.file, found.format, found.ids, found.lines, values, target, found.convention, names,
                     tuple(notes), found.joints, found.companions, found.configuration)


def _in_reading_ranges(values, kind):
    """Angles outside the controller's ranges (A, C in +-180, B in +-90) re-expressed in them
    (the same rotations)."""
    if np.all(np.abs(values[:, 3:]) <= np.array([180.0, 90.0, 180.0]) + 1e-9):
        return values, []
    return conventions.convert(values, kind, kind), [f"{kind} angles re-expressed in the controller's ranges"]


def read_joints(path):
    """Joint angles j1..j6 (degrees) of a CSV, whitespace-separated or JSON file; returns
    ``(ids or None, (N, 6) array, lines)``. A header (``j1..j6``, ``joint_1``, ``axis1``, ``id``) is
    optional; without one, 6 numbers per row or an id and 6."""
    table = read_table(path, known_name=lambda c: canonical(c) is not None)
    width = len(table.header) if table.header is not None else len(table.rows[0])
    names = _names(table, None, "joints", width, what="joints")
    cols = tuple(f"j{k}" for k in range(1, 7))
    missing = [c for c in cols if c not in names]
    if missing:
        raise DatasetError(table.file, f"no column {missing[0]!r} (joint angles j1..j6, degrees)", 1)
    values = _numbers(table, names, cols)
    if np.max(np.abs(values)) <= math.pi + 1e-6 and np.ptp(values) > 0 and len(values) > 2:
        raise DatasetError(table.file, "every joint angle is within +-pi: radians, not degrees? convert them to degrees")
    return _ids(table, names), values, table.lines


#: a ``--centres`` table's names of the centre's columns (before the pose-like ``x,y,z``)
_CENTRE_NAMES = {"xs": "x", "ys": "y", "zs": "z"}


def _centre_names(table):
    """Canonical names (``id``, ``x``, ``y``, ``z`` or None) of a centres table's columns: ``xs,ys,zs`` where the
    header has them (a pose file's own centre columns), else ``x,y,z``; without a header 3 numbers or an id and 3."""
    if table.header is None:
        width = len(table.rows[0])
        if width not in (3, 4):
            raise DatasetError(table.file, f"{width} numbers per row: a centre is x, y, z (or an id and x, y, z); name "
                                           "the columns in a header (xs,ys,zs)", table.lines[0])
        return ["x", "y", "z"] if width == 3 else ["id", "x", "y", "z"]
    low = [str(h).strip().lower() for h in table.header]
    if set(_CENTRE_NAMES) <= set(low):
        return [_CENTRE_NAMES.get(h, "id" if canonical(h) == "id" else None) for h in low]
    return [canonical(h) if canonical(h) in ("id", "x", "y", "z") else None for h in table.header]


def read_centres(path):
    """Sphere centres a 3-D sensor reported, one per pose (``--centres``): ``(ids or None, (N, 3) array, lines)``,
    sensor frame in the file's units. Columns ``xs,ys,zs`` (else ``x,y,z``) and an optional ``id``; header optional."""
    table = read_table(path, known_name=lambda c: canonical(c) is not None or str(c).strip().lower() in _CENTRE_NAMES)
    names = _centre_names(table)
    missing = [c for c in ("x", "y", "z") if c not in names]
    if missing:
        raise DatasetError(table.file, f"no column {missing[0]!r} (a sphere centre xs,ys,zs or x,y,z, sensor frame)", 1)
    return _ids(table, names), _numbers(table, names, ("x", "y", "z")), table.lines
