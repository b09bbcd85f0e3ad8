"""What the controller file readers share (:mod:`handeye.app.ingest.controllers` chooses the
reader): a file's text with line numbers, its numbers checked, its positions (:class:`Point`)
put in the order of motion, their tools and frames checked, and the result,
:class:`ControllerPoses`."""
from __future__ import annotations

import bisect
import dataclasses
import math
import pathlib
import re

import numpy as np

from handeye.app.ingest.tables import MAX_TABLE_BYTES, check_text, read_bytes
from handeye.model.readers.tables import DatasetError

#: a decimal number as controllers write them (``.180``, ``-.000``, ``1.5E+02``, ``9E9``)
NUMBER = re.compile(r"^[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$")


@dataclasses.dataclass(frozen=True)
class Point:
    """One position of a controller file, before the frames are checked.

    Attributes
    ----------
    name : str
        As the pendant shows it (``P[3]`` -> ``P3``, KUKA ``XP3`` -> ``P3``, ABB ``p10``).
    line : int
        Line of its declaration (1-based).
    values : ndarray (3 + k,)
        x, y, z (mm) and the orientation in the file's convention.
    tool, base : str or None
        The tool and the frame the file names for it (None: not named).
    tool_ok, base_ok : bool
        True when that tool is the flange, that frame the robot base.
    tool_field, base_field : str
        The field a refusal names (``UT``, ``TOOL_NO``, ``tool``).
    frame_line : int or None
        The line naming the tool and frame, when it is not ``line``.
    config : str or None
        The arm configuration the file gives for it (FANUC ``CONFIG``, normalised ``'N U T, 0, 0, 0'``).
    cfx : int or None
        That configuration as ABB's ``cfx`` (0-7; :func:`handeye.model.robot.configuration.groups`).
    """

    name: str
    line: int
    values: np.ndarray
    tool: str | None = None
    base: str | None = None
    tool_ok: bool = False
    base_ok: bool = False
    tool_field: str = "tool"
    base_field: str = "base"
    frame_line: int | None = None
    config: str | None = None
    cfx: int | None = None


@dataclasses.dataclass(frozen=True)
class ControllerPoses:
    """What a controller file gave.

    Attributes
    ----------
    file : pathlib.Path
    format : str
        The file's kind (``FANUC TP program (.ls)``).
    ids : tuple of str or None
        The positions' names in the order of motion (None: rows, numbered 1..N).
    lines : tuple of int
    values : ndarray (N, 3 + k)
        Flange poses in the robot base in ``convention`` (mm; degrees, radians or a unit
        quaternion w, x, y, z as the convention has them).
    convention : str
        ``fanuc``, ``kuka``, ``abb`` or ``ur``: the file's.
    joints : ndarray (N, 6) or None
        Joint angles (degrees) where the file has them for every pose.
    notes : tuple of str
        Conversions made, what was left out and why.
    companions : tuple of pathlib.Path
        Other files read with it (a KUKA ``.src``'s ``.dat``).
    configuration : ndarray of int (N,) or None
        The arm configuration of each pose as ABB's ``cfx`` (0-7: bit 0 j5 < 0, bit 1 the elbow,
        bit 2 the shoulder; :mod:`handeye.model.robot.configuration`), where the file gives one for
        every pose (FANUC ``CONFIG``); written as the dataset's ``cfx`` column.
    configs : tuple of str or None
        The configurations as the file writes them (``'N U T, 0, 0, 0'``: FANUC's letters and the
        turn numbers of J4, J5, J6).
    """

    file: pathlib.Path
    format: str
    ids: tuple | None
    lines: tuple
    values: np.ndarray
    convention: str
    joints: np.ndarray | None
    notes: tuple
    companions: tuple = ()
    configuration: np.ndarray | None = None
    configs: tuple | None = None


class Text:
    """A controller file's text with line numbers of character offsets."""

    def __init__(self, path):
        self.file = pathlib.Path(path)
        raw = read_bytes(self.file, MAX_TABLE_BYTES, "a pose file")
        check_text(self.file, raw, "a controller program")
        self.note = None
        try:
            self.text = raw.decode("utf-8-sig")
        except UnicodeDecodeError:  # controllers write their code page (a German FANUC's GRÖßE)
            self.text, self.note = raw.decode("cp1252", errors="replace"), f"{self.file.name} read as cp1252"
        self._starts = [0] + [m.end() for m in re.finditer("\n", self.text)]

    def line(self, offset):
        """1-based line of a character offset."""
        return bisect.bisect_right(self._starts, offset)

    def error(self, offset, problem, field=None):
        return DatasetError(self.file, problem, self.line(offset), field)


def number(text, src, offset, field):
    """A finite float of a controller's number token; a DatasetError naming line and field."""
    token = str(text).strip()
    if not NUMBER.match(token):
        raise src.error(offset, f"not a number: {token[:40]!r}", field)
    value = float(token)
    if not math.isfinite(value):
        raise src.error(offset, f"not a finite number: {token[:40]!r}", field)
    return value


def in_motion_order(declared, moved, src, what):
    """The declared points in the order of their first motion (``moved``: names in order, with
    the offset of each move), with notes: points never moved to are left out, points moved to
    twice read once. No motion at all: declaration order. Names are matched case-insensitively
    (KRL and RAPID are). Returns ``(points, notes)``."""
    if not moved:
        return list(declared.values()), [f"no motion instruction: {what} in declaration order"]
    out, seen, notes, twice = [], set(), [], []
    for name, _ in moved:
        key = name.lower()
        if key in seen:
            twice.append(name)
            continue
        seen.add(key)
        out.append(declared[key])
    unused = [p.name for k, p in declared.items() if k not in seen]
    if unused:
        notes.append(f"left out, never moved to: {_listed(unused)}")
    if twice:
        notes.append(f"moved to more than once, read once: {_listed(sorted(set(twice)))}")
    return out, notes


def _listed(names, most=6):
    return ", ".join(names[:most]) + (f" and {len(names) - most} more" if len(names) > most else "")


def frames_checked(points, src, accept, describe):
    """Refuse poses not of the flange in the robot base (module docstring); the notes of what was
    accepted. ``describe(point, which)`` words the refusal (``which``: ``'tool'`` or ``'base'``)."""
    notes = []
    for which in ("tool", "base"):
        bad = [p for p in points if not getattr(p, f"{which}_ok")]
        if not bad:
            continue
        first = bad[0]
        field = getattr(first, f"{which}_field")
        if not accept:
            raise DatasetError(src.file, describe(first, which) + "; give --accept-frames only if it is "
                               + ("zero (its TCP is the flange)" if which == "tool" else "the robot base"),
                               first.frame_line or first.line, field)
        labels = sorted({str(getattr(p, which)) for p in bad})
        if len(labels) > 1 or len(bad) < len(points):
            other = next(p for p in points if str(getattr(p, which)) != str(getattr(first, which)))
            raise DatasetError(src.file, f"{first.name} has {field} {getattr(first, which)}, {other.name} "
                               f"{getattr(other, which)}: with --accept-frames every pose must be of one "
                               f"{'tool' if which == 'tool' else 'frame'}", other.frame_line or other.line, field)
        notes.append(f"{field} {labels[0]} read as the {'flange' if which == 'tool' else 'robot base'} "
                     "(--accept-frames)")
    return notes


def poses_of(points, src, fmt, convention, notes):
    """The :class:`ControllerPoses` of checked points (at least one; ids their names)."""
    if not points:
        raise DatasetError(src.file, f"no Cartesian position in this {fmt}")
    if src.note:
        notes = [src.note, *notes]
    cfx, configs = None, None
    given = [p for p in points if p.cfx is not None]
    if given and len(given) == len(points):
        cfx, configs = np.array([p.cfx for p in points], int), tuple(p.config for p in points)
        counts = {c: configs.count(c) for c in dict.fromkeys(configs)}
        notes = [*notes, "arm configuration of every pose kept as the cfx column (bit 0 j5 < 0, bit 1 the elbow down, "
                         "bit 2 the wrist centre behind axis 1): " + _listed([f"'{c}' x{n}" for c, n in counts.items()])]
    elif given:
        notes = [*notes, f"no cfx column: {_listed([p.name for p in points if p.cfx is None])} give no arm configuration"]
    return ControllerPoses(src.file, fmt, tuple(p.name for p in points), tuple(p.line for p in points),
                           np.array([p.values for p in points], float), convention, None, tuple(notes),
                           configuration=cfx, configs=configs)
