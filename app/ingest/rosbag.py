"""Poses and profiles from a ROS 2 bag (sqlite3 or mcap), read by the pure-Python ``rosbags``.

``rosbags`` is an optional extra (``pip install 'handeye[ros]'``; no ROS installation is needed): this
module imports it, and is imported only once :mod:`handeye.app.ingest.request` found it installed.
Poses: ``geometry_msgs/msg/PoseStamped`` (the flange in the robot base), or ``tf2_msgs/msg/TFMessage``
on ``/tf`` (with ``/tf_static`` when the bag has it) composed from ``base_frame`` to
``flange_frame``. Profiles: ``sensor_msgs/msg/PointCloud2`` (float32 or float64 x, y, z fields) or
``sensor_msgs/msg/LaserScan`` (points ``r (cos t, sin t, 0)`` in the scan's frame: the plane
z = 0). Each profile takes the pose nearest in time (header stamps; the bag's time when a stamp
is zero) within ``max_dt`` seconds; the others are counted. ROS is SI: metres become mm,
quaternions are (x, y, z, w).
"""
from __future__ import annotations

import dataclasses
import pathlib

import numpy as np
from rosbags.highlevel import AnyReader

from handeye.app.ingest.tables import not_a_file
from handeye.model.chain.conventions import matrix_from
from handeye.model.readers.tables import MAX_LINE_BYTES, DatasetError

POSE_TYPES = ("geometry_msgs/msg/PoseStamped", "tf2_msgs/msg/TFMessage")
PROFILE_TYPES = ("sensor_msgs/msg/PointCloud2", "sensor_msgs/msg/LaserScan")
_FLOAT = {7: "f4", 8: "f8"}


@dataclasses.dataclass(frozen=True)
class BagData:
    """What a bag gave.

    Attributes
    ----------
    flange2base : ndarray, shape (N, 4, 4)
        The pose matched to each kept profile, mm.
    profiles : list of ndarray (K, 3)
        Points in the sensor message's frame, mm (NaN rows still in).
    counts : dict
        ``poses``, ``profiles``, ``unmatched`` (profiles without a pose within max_dt), ``max_dt_used``.
    types : tuple of str
        Message types of the pose and the profile topic.
    """

    flange2base: np.ndarray
    profiles: list
    counts: dict
    types: tuple


def _stamp(msg, bag_ns):
    s = msg.header.stamp
    t = s.sec + s.nanosec * 1e-9
    return t if t > 0 else bag_ns * 1e-9


def _transform(translation, q):
    out = np.eye(4)
    out[:3, :3] = matrix_from("abb", [q.w, q.x, q.y, q.z])
    out[:3, 3] = [translation.x * 1000.0, translation.y * 1000.0, translation.z * 1000.0]
    return out


def _cloud_points(msg, file):
    fields = {f.name: f for f in msg.fields}
    missing = [a for a in "xyz" if a not in fields]
    if missing or any(fields[a].datatype not in _FLOAT for a in "xyz"):
        raise DatasetError(file, f"PointCloud2 needs float32/float64 fields x, y, z, has "
                                 f"{', '.join(f'{f.name}:{f.datatype}' for f in msg.fields)}")
    order = ">" if msg.is_bigendian else "<"
    dtype = np.dtype({"names": list("xyz"), "formats": [order + _FLOAT[fields[a].datatype] for a in "xyz"],
                      "offsets": [fields[a].offset for a in "xyz"], "itemsize": msg.point_step})
    data = np.asarray(msg.data, np.uint8).tobytes()
    rows = [np.frombuffer(data, dtype, count=msg.width, offset=r * msg.row_step) for r in range(msg.height)]
    pts = np.concatenate(rows) if rows else np.zeros(0, dtype)
    return np.column_stack([pts["x"], pts["y"], pts["z"]]).astype(float) * 1000.0


def _scan_points(msg):
    r = np.asarray(msg.ranges, float)
    t = msg.angle_min + msg.angle_increment * np.arange(len(r))
    bad = ~np.isfinite(r) | (r < msg.range_min) | (r > msg.range_max)
    r = np.where(bad, np.nan, r)
    return np.column_stack([r * np.cos(t), r * np.sin(t), np.zeros_like(r)]) * 1000.0


def _connections(reader, topic, types, option, file):
    found = [c for c in reader.connections if c.topic == topic]
    if not found:
        have = ", ".join(sorted({f"{c.topic} ({c.msgtype})" for c in reader.connections}))
        raise DatasetError(file, f"{option} {topic}: no such topic (it has {have})")
    if found[0].msgtype not in types:
        raise DatasetError(file, f"{option} {topic}: type {found[0].msgtype}; handeye reads {', '.join(types)}")
    return found


def _tf_poses(reader, conns, base, flange, file):
    """(stamps, transforms) of flange in base composed from /tf (and /tf_static) at each message."""
    if not base or not flange:
        raise DatasetError(file, "a TFMessage pose topic needs --base-frame and --flange-frame")
    static = [c for c in reader.connections if c.topic == "/tf_static"]
    links, stamps, poses = {}, [], []
    for conn, bag_ns, raw in reader.messages(connections=static + conns):
        msg = reader.deserialize(raw, conn.msgtype)
        for tf in msg.transforms:
            links[tf.child_frame_id.lstrip("/")] = (tf.header.frame_id.lstrip("/"), _transform(tf.transform.translation,
                                                                                                tf.transform.rotation))
        if conn.topic == "/tf_static" or not msg.transforms:
            continue
        chain, frame, hops = np.eye(4), flange.lstrip("/"), 0
        while frame != base.lstrip("/") and frame in links and hops <= len(links):  # a loop in the tree ends too
            parent, t = links[frame]
            chain, frame, hops = t @ chain, parent, hops + 1
        if frame == base.lstrip("/"):
            stamps.append(_stamp(msg.transforms[-1], bag_ns))
            poses.append(chain)
    if not poses:
        raise DatasetError(file, f"/tf never links {flange} to {base} (--base-frame, --flange-frame)")
    return np.array(stamps), np.array(poses)


def _stamped(reader, conns, read):
    """``(stamps, [read(message, its type)])`` of every message on ``conns``."""
    stamps, items = [], []
    for conn, bag_ns, raw in reader.messages(connections=conns):
        msg = reader.deserialize(raw, conn.msgtype)
        stamps.append(_stamp(msg, bag_ns))
        items.append(read(msg, conn.msgtype))
    return np.array(stamps), items


def _regular_files(bag):
    """A bag folder's files (or the bag file) all regular files: a FIFO among them would block rosbags'
    open, ``/dev/zero`` never end its read (issue 40's fuzz); else a DatasetError naming the file."""
    try:
        files = sorted(bag.iterdir()) if bag.is_dir() else [bag]
    except OSError as exc:
        raise DatasetError(bag, f"cannot be read: {exc.strerror or exc}") from None
    for f in files:  # a subfolder is rosbags' to refuse or ignore
        if not f.is_file() and not f.is_dir() and not f.name.startswith("."):
            raise DatasetError(f, f"{not_a_file(f)}: not a file of a ROS 2 bag")
        if f.name == "metadata.yaml" and f.is_file() and f.stat().st_size > MAX_LINE_BYTES:  # rosbags' YAML: 5 s per 4 MB
            raise DatasetError(f, f"more than {MAX_LINE_BYTES // 2**20} MiB: not a bag's metadata (a few kB)")


def read_bag(path, pose_topic, profile_topic, base_frame=None, flange_frame=None, max_dt=0.05):
    """Poses and profiles of a ROS 2 bag folder or file, matched by time (module docstring).

    Parameters
    ----------
    path : path-like
    pose_topic, profile_topic : str
    base_frame, flange_frame : str or None
        For a TFMessage pose topic: the robot base and the flange frame.
    max_dt : float
        Largest time between a profile and its pose, s.

    Returns
    -------
    BagData
    """
    file = pathlib.Path(path)
    _regular_files(file)
    try:
        with AnyReader([file]) as reader:
            pconns = _connections(reader, pose_topic, POSE_TYPES, "--pose-topic", file)
            sconns = _connections(reader, profile_topic, PROFILE_TYPES, "--profile-topic", file)
            if pconns[0].msgtype == POSE_TYPES[1]:
                pstamps, poses = _tf_poses(reader, pconns, base_frame, flange_frame, file)
            else:
                pstamps, poses = _stamped(reader, pconns, lambda msg, _: _transform(msg.pose.position, msg.pose.orientation))
                poses = np.array(poses).reshape(-1, 4, 4)
            stamps, clouds = _stamped(reader, sconns, lambda msg, kind: _scan_points(msg) if kind == PROFILE_TYPES[1]
                                      else _cloud_points(msg, file))
    except DatasetError:
        raise
    except Exception as exc:  # noqa: BLE001 - rosbags' own errors (a broken bag) are bad input here
        raise DatasetError(file, f"cannot be read as a ROS 2 bag: {type(exc).__name__}: {exc}") from None
    return _match(file, _Stamped(pstamps, poses, pconns[0].msgtype), _Stamped(stamps, clouds, sconns[0].msgtype),
                  max_dt)


@dataclasses.dataclass(frozen=True)
class _Stamped:
    """One topic's messages: their times (s), what each carried, the message type."""

    stamps: np.ndarray
    items: object
    msgtype: str


def _match(file, pose, profile, max_dt):
    """Each profile with the pose nearest in time, within ``max_dt`` (a :class:`BagData`)."""
    pstamps, poses, stamps, clouds = pose.stamps, pose.items, profile.stamps, profile.items
    if not len(pstamps):
        raise DatasetError(file, "no pose messages on the pose topic")
    order = np.argsort(pstamps)
    pstamps, poses = pstamps[order], poses[order]
    keep, chosen = [], []
    for k, t in enumerate(stamps):
        j = int(np.searchsorted(pstamps, t))
        near = [i for i in (j - 1, j) if 0 <= i < len(pstamps)]
        best = min(near, key=lambda i: abs(pstamps[i] - t))
        if abs(pstamps[best] - t) <= max_dt:
            keep.append(k)
            chosen.append(best)
    if not keep:
        raise DatasetError(file, f"no profile has a pose within --max-dt {max_dt:g} s ({len(stamps)} profiles, "
                                 f"{len(pstamps)} poses)")
    counts = {"poses": int(len(pstamps)), "profiles": int(len(stamps)), "unmatched": int(len(stamps) - len(keep)),
              "max_dt_s": float(max_dt)}
    return BagData(poses[chosen], [clouds[k] for k in keep], counts, (pose.msgtype, profile.msgtype))
