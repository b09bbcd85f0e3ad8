"""UR RTDE logs as flange poses: one pose per row, or one per stop of a robot logged while it moves.

``rtde``'s record.py writes a CSV (space or comma separated, with a header) of every output of its
recipe. The pose is ``actual_TCP_pose_0..5`` (else ``target_TCP_pose_0..5``: metres and a rotation
vector in radians, convention ``ur``), the joint angles ``actual_q_0..5`` (else ``target_q_0..5``)
in radians, read as degrees; ``tcp_offset_0..5``, when logged, must be zero. Without it the TCP
offset is not in the log (the summary says so; with ``--robot`` the loader checks the joints against
the poses and names a TCP offset).

A log is one of two kinds:

one row per pose
    each row a measurement stop (a script that logs a row where the sensor measured): read row by
    row, as the rows are.
a stream
    record.py at 125-500 Hz while the robot moves between its measurement stops. The log is a
    stream when it has a ``timestamp`` column, its rows come at least :data:`STREAM_HZ` times a
    second (median step) and the TCP moves between them no faster than :data:`MAX_SPEED_MM_S`
    (median): a robot's TCP, not poses of different stops. Its poses are its **stops**
    (:func:`stops`): stretches where the TCP position stays within ``Still.mm`` of the stretch's
    median, its rotation within ``Still.deg`` and, when logged, every joint within ``Still.deg``,
    for at least ``Still.seconds`` (``--still MM,DEG,S``, default :data:`STILL`: 0.1 mm, 0.05 deg,
    0.2 s; a TCP still to 0.01 mm stays well within the first, a stop of 0.3 s is longer than the
    last). Each stop gives one pose, the median of its rows (rotations: the element-wise median
    of their matrices, made a rotation); the summary says how many stops and rows were found. A
    stream without a stop is refused; a log that is still from its first row to its last is one
    stop however short.
"""
from __future__ import annotations

import dataclasses
import math
import types

import numpy as np

from handeye.app.ingest.controller_common import Point, frames_checked, poses_of
from handeye.app.ingest.tables import read_table
from handeye.model.common.rotation import matrix_from_rotvec, nearest_rotation, rotvec_from_matrix
from handeye.model.readers.tables import DatasetError

#: positions beyond this (m) are no metres
METRES_MAX = 50.0
#: a log sampled at least this often (Hz, median step) can be a stream
STREAM_HZ = 10.0
#: a stream's TCP moves no faster than this between rows (mm/s, median): faster rows are different stops
MAX_SPEED_MM_S = 1000.0


@dataclasses.dataclass(frozen=True)
class Still:
    """What a stop of a streamed log is (module docstring; ``--still MM,DEG,S``).

    Attributes
    ----------
    mm : float
        Largest distance of a stop's TCP positions from their median, mm.
    deg : float
        Largest angle of its TCP rotations from their median, and of each joint from its median, degrees.
    seconds : float
        Shortest stop, s (the time from its first row to its last).
    """

    mm: float = 0.1
    deg: float = 0.05
    seconds: float = 0.2

    def said(self, joints):
        """``'within 0.1 mm and 0.05 deg (joints 0.05 deg) for >= 0.2 s'``."""
        return (f"within {self.mm:g} mm and {self.deg:g} deg{f' (joints {self.deg:g} deg)' if joints else ''} "
                f"for >= {self.seconds:g} s")


#: the default stop (:class:`Still`)
STILL = Still()


def read_rtde(path, accept_frames=False, still=None):
    """The poses (and joint angles) of a UR RTDE CSV log (module docstring); convention ``ur``.

    Parameters
    ----------
    path : path-like
    accept_frames : bool
        A non-zero ``tcp_offset`` read as the flange (``--accept-frames``).
    still : Still or None
        What a stop of a streamed log is (None: :data:`STILL`).

    Returns
    -------
    ControllerPoses
    """
    log = _columns(read_table(path))
    poses, joints, lines, notes = _poses(log, still or STILL)
    tool, ok = "not logged", True
    if log.tcp is not None:
        tool, ok = ",".join(f"{v:g}" for v in log.tcp[0]), bool(np.all(np.abs(log.tcp) < 1e-9))
    else:
        notes.append("tcp_offset not logged: the poses are of the TCP, the flange only if the TCP offset is zero")
    points = [Point(str(k + 1), line, pose, tool, "base", ok, True, "tcp_offset_0", "base")
              for k, (pose, line) in enumerate(zip(poses, lines))]
    src = types.SimpleNamespace(file=log.file, note=None)
    notes += frames_checked(points, src, accept_frames, lambda p, w: f"row {p.name}: tcp_offset {p.tool}, not zero")
    fmt = f"UR RTDE log ({log.kind}{', stops of a stream' if notes[0].startswith('a log streamed') else ''})"
    return dataclasses.replace(poses_of(points, src, fmt, "ur", notes), ids=None, joints=joints)


def _columns(table):
    """The log's numbers: ``file``, ``kind``, ``lines``, ``pose`` (N, 6: m, rad), ``pose_name``, ``joints``
    (N, 6 rad or None), ``joint_name``, ``tcp`` (N, 6 or None), ``time`` (N or None, s)."""
    header = [str(h).strip() for h in (table.header or ())]
    where = {h: k for k, h in enumerate(header)}
    sets = {kind: next((c for c in ([f"{p}_{kind}_{k}" for k in range(6)] for p in ("actual", "target"))
                        if all(h in where for h in c)), None) for kind in ("TCP_pose", "q")}
    if sets["TCP_pose"] is None:
        raise DatasetError(table.file, "no actual_TCP_pose_0..5 (or target_TCP_pose_0..5) columns: "
                                       "record actual_TCP_pose in the RTDE recipe", 1)
    tcp_cols = [f"tcp_offset_{k}" for k in range(6)]
    wanted = sets["TCP_pose"] + (sets["q"] or []) + (tcp_cols if all(c in where for c in tcp_cols) else [])
    wanted += ["timestamp"] if "timestamp" in where else []
    data = np.empty((len(table.rows), len(wanted)))
    for r, (row, line) in enumerate(zip(table.rows, table.lines)):
        if len(row) != len(header):
            raise DatasetError(table.file, f"expected {len(header)} fields, got {len(row)}", line)
        for c, name in enumerate(wanted):
            data[r, c] = _cell(table.file, row[where[name]], line, name)
    if np.max(np.abs(data[:, :3])) > METRES_MAX:
        raise DatasetError(table.file, "positions beyond 50: RTDE poses are metres", table.lines[0], wanted[0])
    cols = {name: k for k, name in enumerate(wanted)}

    def block(names):
        return None if names is None or names[0] not in cols else data[:, cols[names[0]]:cols[names[0]] + 6]

    return types.SimpleNamespace(file=table.file, kind=table.kind, lines=tuple(table.lines), pose=data[:, :6],
                                 pose_name=wanted[0][:-2], joints=block(sets["q"]),
                                 joint_name=(sets["q"] or ["_"])[0][:-2], tcp=block(tcp_cols),
                                 time=data[:, cols["timestamp"]] if "timestamp" in cols else None)


def _poses(log, still):
    """``(poses (n, 6) mm and rad, joints (n, 6) deg or None, lines, notes)``: every row, or the stops of a stream."""
    mm = log.pose.copy()
    mm[:, :3] *= 1000.0
    joints = None if log.joints is None else np.degrees(log.joints)
    notes = [f"joint angles {log.joint_name}_0..5 rad -> deg"] if joints is not None else []
    if not _is_stream(log.time, mm):
        return mm, joints, log.lines, [f"one pose per row ({log.pose_name}_0..5); positions m -> mm (x1000)", *notes]
    found = stops(log.time, mm, joints, still)
    rate, span = 1.0 / float(np.median(np.diff(log.time))), float(log.time[-1] - log.time[0])
    if not found:
        raise DatasetError(log.file, f"a log streamed at {rate:.0f} Hz ({len(mm):,} rows, {span:.1f} s) with no stop: the "
                                     f"TCP is never still {still.said(joints is not None)} (--still MM,DEG,S)",
                           log.lines[0], f"{log.pose_name}_0")
    poses = np.array([_median_pose(mm[a:b]) for a, b in found])
    kept = None if joints is None else np.array([np.median(joints[a:b], axis=0) for a, b in found])
    sizes = [b - a for a, b in found]
    if found == [(0, len(mm))]:
        said = f"still throughout ({len(mm):,} rows, {span:.2f} s): one pose, the median of its rows"
    else:
        said = (f"{len(found)} stop{'s' if len(found) > 1 else ''} in {len(mm):,} rows ({span:.1f} s), each still "
                f"{still.said(joints is not None)}, read as the median of its rows ({min(sizes):,} to {max(sizes):,}); "
                f"{len(mm) - sum(sizes):,} rows moving or too short left out")
    notes.insert(0, f"a log streamed at {rate:.0f} Hz, {said}; positions m -> mm (x1000)")
    return poses, kept, tuple(log.lines[a] for a, _ in found), notes


def _is_stream(time, mm):
    """True when the rows are samples of one motion (module docstring), not one pose each."""
    if time is None or len(time) < 3:
        return False
    step = np.diff(time)
    if not np.all(step > 0) or np.median(step) > 1.0 / STREAM_HZ:
        return False
    speed = np.linalg.norm(np.diff(mm[:, :3], axis=0), axis=1) / step
    return float(np.median(speed)) <= MAX_SPEED_MM_S


def stops(time, poses, joints, still):
    """The stops of a streamed log: ``[(first row, end row), ...]`` (end exclusive, in order).

    A row is a candidate when the TCP moves less than ``still.mm`` (and turns less than
    ``still.deg``, each joint too) from it over a quarter of ``still.seconds`` ahead; each run of
    candidates (with the rows that lag covers) lasting ``still.seconds`` is tested against its
    median, and its longest stretch of rows within the tolerances of that median is a stop when it
    lasts ``still.seconds`` (the run's median then that stretch's).

    Parameters
    ----------
    time : ndarray (N,)
        s, increasing.
    poses : ndarray (N, 6)
        TCP positions (mm) and rotation vectors (rad).
    joints : ndarray (N, 6) or None
        Degrees.
    still : Still

    Returns
    -------
    list of (int, int)
    """
    rot = matrix_from_rotvec(poses[:, 3:])
    lag = max(1, int(round(still.seconds / 4 / float(np.median(np.diff(time))))))
    if len(time) <= lag:
        return [(0, len(time))] if _near(poses, rot, joints, slice(0, len(time)), still).all() else []
    ahead = _within(poses[lag:, :3] - poses[:-lag, :3], rot[:-lag], rot[lag:], None if joints is None
                    else joints[lag:] - joints[:-lag], still)
    candidate = np.zeros(len(time), bool)
    candidate[:-lag] = ahead
    out = []
    for a, b in _runs(candidate):
        b = min(len(time), b + lag)  # the last candidate's lag reaches b + lag - 1
        if a == 0 and b == len(time) or time[b - 1] - time[a] >= still.seconds:
            out += _tested(time, poses, rot, joints, (a, b), still)
    return out


def _tested(time, poses, rot, joints, span, still):
    """The stop in rows ``span`` (module docstring), as a list of zero or one ``(first, end)``."""
    a, b = span
    for _ in range(2):  # the run's median, then that of its stretch within tolerance
        near = _near(poses, rot, joints, slice(a, b), still)
        runs = _runs(near)
        if not runs:
            return []
        first, end = max(runs, key=lambda r: r[1] - r[0])
        a, b = a + first, a + end
    whole = a == 0 and b == len(time)
    return [(a, b)] if whole or time[b - 1] - time[a] >= still.seconds else []


def _near(poses, rot, joints, rows, still):
    """Which of ``rows`` are within the tolerances of those rows' median pose (and joints)."""
    centre = _median_pose(poses[rows])
    c_rot = matrix_from_rotvec(centre[3:])
    return _within(poses[rows, :3] - centre[:3], np.broadcast_to(c_rot, rot[rows].shape), rot[rows],
                   None if joints is None else joints[rows] - np.median(joints[rows], axis=0), still)


def _within(shift, rot_a, rot_b, joint_shift, still):
    """Rows whose position shift (mm), turn from ``rot_a`` to ``rot_b`` and joint shifts (deg) are within ``still``;
    the angle from ``|R_a - R_b|_F = 2 sqrt(2) sin(angle / 2)`` (exact for small angles)."""
    ok = np.linalg.norm(shift, axis=1) <= still.mm
    frob = np.sqrt(np.sum((rot_a - rot_b) ** 2, axis=(1, 2)))
    ok &= np.degrees(2 * np.arcsin(np.clip(frob / (2 * math.sqrt(2)), 0, 1))) <= still.deg
    if joint_shift is not None:
        ok &= np.max(np.abs(joint_shift), axis=1) <= still.deg
    return ok


def _runs(mask):
    """``[(first, end), ...]`` of the runs of True in a bool array (end exclusive)."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(np.int8), [0]])))
    return list(zip(edges[::2].tolist(), edges[1::2].tolist()))


def _median_pose(poses):
    """The median of TCP poses (n, 6: mm, rotation vectors): positions element-wise, rotations the
    element-wise median of their matrices made a rotation (no rotation vector's wrap at 180 deg matters)."""
    rot = nearest_rotation(np.median(matrix_from_rotvec(poses[:, 3:]), axis=0))
    return np.concatenate([np.median(poses[:, :3], axis=0), rotvec_from_matrix(rot)])


def _cell(file, text, line, column):
    try:
        value = float(text)
    except ValueError:
        raise DatasetError(file, f"not a number: {str(text)[:40]!r}", line, column) from None
    if not math.isfinite(value):
        raise DatasetError(file, f"not a finite number: {text!r}", line, column)
    return value
