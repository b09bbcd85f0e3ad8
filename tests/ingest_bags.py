"""ROS 2 bags of an :mod:`ingest_truth` cell, written by rosbags' own Writer (not by handeye).

ROS is SI: positions in metres, quaternions (x, y, z, w). Poses as ``PoseStamped`` or as ``/tf``
(base_link -> link_6 -> tool0, the flange split in two to test the chain); profiles as
``PointCloud2`` (x, 0, z: the laser plane y = 0) or as ``LaserScan`` (the scan plane z = 0 with the
scan's x the measuring direction, so handeye must turn it: handeye (x, y, z) = scan (y, z, x)).
"""
import numpy as np
from ingest_truth import quaternion


def _types():
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_HUMBLE)


def _header(ts, t, frame):
    sec = int(np.floor(t))
    return ts.types["std_msgs/msg/Header"](stamp=ts.types["builtin_interfaces/msg/Time"](sec=sec, nanosec=int(round(
        (t - sec) * 1e9))), frame_id=frame)


def _pose_msg(ts, t, transform):
    g = ts.types
    q = quaternion(transform[:3, :3])
    pose = g["geometry_msgs/msg/Pose"](position=g["geometry_msgs/msg/Point"](*(transform[:3, 3] / 1000.0)),
                                       orientation=g["geometry_msgs/msg/Quaternion"](x=q[1], y=q[2], z=q[3], w=q[0]))
    return g["geometry_msgs/msg/PoseStamped"](header=_header(ts, t, "base_link"), pose=pose)


def _tf(ts, t, parent, child, transform):
    g = ts.types
    q = quaternion(transform[:3, :3])
    tr = g["geometry_msgs/msg/Transform"](translation=g["geometry_msgs/msg/Vector3"](*(transform[:3, 3] / 1000.0)),
                                          rotation=g["geometry_msgs/msg/Quaternion"](x=q[1], y=q[2], z=q[3], w=q[0]))
    return g["geometry_msgs/msg/TransformStamped"](header=_header(ts, t, parent), child_frame_id=child, transform=tr)


def _cloud(ts, t, xz):
    g = ts.types
    pts = np.column_stack([xz[:, 0], np.zeros(len(xz)), xz[:, 1]]).astype(np.float32) / np.float32(1000.0)
    fields = [g["sensor_msgs/msg/PointField"](name=n, offset=4 * k, datatype=7, count=1) for k, n in enumerate("xyz")]
    return g["sensor_msgs/msg/PointCloud2"](header=_header(ts, t, "sensor"), height=1, width=len(pts), fields=fields,
                                            is_bigendian=False, point_step=12, row_step=12 * len(pts),
                                            data=np.frombuffer(pts.tobytes(), np.uint8), is_dense=True)


def scan_ranges(centre_xz, radius, angles, rng, noise=0.01):
    """Ranges (m) of rays at ``angles`` in the scan plane to a circle whose centre is handeye's
    (x, z) = ``centre_xz`` (mm): in the scan frame the centre is (z, x); inf where a ray misses."""
    c = np.array([centre_xz[1], centre_xz[0]])
    d = np.column_stack([np.cos(angles), np.sin(angles)])
    b = d @ c
    disc = b**2 - c @ c + radius**2
    r = np.where(disc > 0, b - np.sqrt(np.maximum(disc, 0)), np.inf)
    return (r + rng.normal(0, noise, r.shape)) / 1000.0


def _scan(ts, t, ranges, angles):
    return ts.types["sensor_msgs/msg/LaserScan"](
        header=_header(ts, t, "scanner"), angle_min=float(angles[0]), angle_max=float(angles[-1]),
        angle_increment=float(angles[1] - angles[0]), time_increment=0.0, scan_time=0.0, range_min=0.05, range_max=1.0,
        ranges=np.asarray(ranges, np.float32), intensities=np.zeros(0, np.float32))


def write_bag(path, cell, poses="pose", profiles="cloud", circles=None, storage="sqlite3", extra_profile=True):
    """Write the cell as a ROS 2 bag: poses at t = k s, each profile 10 ms later; with
    ``extra_profile`` one more profile at t = 1000 s that has no pose. ``circles``: for
    LaserScan, per pose (xc, zc, r) mm of the laser plane's circle."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    ts = _types()
    rng = np.random.default_rng(5)
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    pose_type = "geometry_msgs/msg/PoseStamped" if poses == "pose" else "tf2_msgs/msg/TFMessage"
    prof_type = "sensor_msgs/msg/PointCloud2" if profiles == "cloud" else "sensor_msgs/msg/LaserScan"
    angles = np.radians(np.linspace(-12, 12, 241))
    split = np.eye(4)
    split[:3, 3] = [0, 0, 80.0]  # link_6 -> tool0: 80 mm along z
    with Writer(path, version=9, storage_plugin=plugin) as w:
        pc = w.add_connection("/robot/flange_pose" if poses == "pose" else "/tf", pose_type, typestore=ts)
        sc = w.add_connection("/sensor/profile", prof_type, typestore=ts)
        items = list(enumerate(cell.flange2base)) + ([(None, None)] if extra_profile else [])
        for k, flange in items:
            t = float(k) if k is not None else 1000.0
            if flange is not None:
                msg = (_pose_msg(ts, t, flange) if poses == "pose" else ts.types["tf2_msgs/msg/TFMessage"](
                    transforms=[_tf(ts, t, "base_link", "link_6", flange @ np.linalg.inv(split)),
                                _tf(ts, t, "link_6", "tool0", split)]))
                w.write(pc, int(t * 1e9), ts.serialize_cdr(msg, pose_type))
            j = k if k is not None else 0
            if profiles == "cloud":
                msg = _cloud(ts, t + 0.01, cell.profiles[j])
            else:
                xc, zc, r = circles[j]
                msg = _scan(ts, t + 0.01, scan_ranges((xc, zc), r, angles, rng), angles)
            w.write(sc, int((t + 0.01) * 1e9), ts.serialize_cdr(msg, prof_type))
    return path
