"""An independent cell for the ``handeye dataset new`` tests: plain numpy, nothing of handeye.

A sphere in the robot base, a sensor pose on the flange, flange poses from which the sensor's
laser plane (y = 0 of the sensor frame, x along the line, z the measuring direction) cuts the
sphere, and each profile as the arc of that circle the sensor sees, with noise. The pose
representations (KUKA A,B,C; FANUC W,P,R; quaternions) are written out here from their
definitions, not taken from handeye, so the readers are tested against an independent generator.
"""
import dataclasses

import numpy as np


def rot_x(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def rot_y(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def rot_z(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def zyx_angles(r):
    """(A, B, C) degrees of R = Rz(A) Ry(B) Rx(C) (KUKA; FANUC's W, P, R are C, B, A)."""
    b = -np.arcsin(np.clip(r[2, 0], -1, 1))
    a = np.arctan2(r[1, 0], r[0, 0])
    c = np.arctan2(r[2, 1], r[2, 2])
    return np.degrees([a, b, c])


def quaternion(r):
    """(w, x, y, z) of a rotation matrix, w >= 0 (scipy's, not handeye's)."""
    from scipy.spatial.transform import Rotation

    x, y, z, w = Rotation.from_matrix(r).as_quat()
    q = np.array([w, x, y, z])
    return q if w >= 0 else -q


def homogeneous(r, t):
    out = np.eye(4)
    out[:3, :3], out[:3, 3] = r, t
    return out


@dataclasses.dataclass
class Cell:
    centre: np.ndarray            # sphere centre, robot base, mm
    diameter: float               # mm
    sensor2flange: np.ndarray     # the truth, 4x4, mm
    flange2base: np.ndarray       # (N, 4, 4), mm
    profiles: list                # per pose (K, 2) sensor (x, z), mm
    side: int
    circles: list                 # per pose (xc, zc, r) of the laser plane's circle, mm

    def kuka(self):
        return np.array([[*f[:3, 3], *zyx_angles(f[:3, :3])] for f in self.flange2base])

    def fanuc(self):
        return np.array([[*f[:3, 3], *zyx_angles(f[:3, :3])[::-1]] for f in self.flange2base])

    def quaternions_xyzw(self):
        """x, y, z (mm), qx, qy, qz, qw: ROS order."""
        return np.array([[*f[:3, 3], *quaternion(f[:3, :3])[[1, 2, 3, 0]]] for f in self.flange2base])


def make_cell(n=16, seed=0, side=-1, noise=0.01, points=60, diameter=50.8):
    """A cell of ``n`` poses; every profile an arc of the laser plane's circle on the sphere."""
    rng = np.random.default_rng(seed)
    centre = np.array([650.0, -120.0, 310.0])
    radius = diameter / 2
    x_true = homogeneous(rot_z(np.radians(30)) @ rot_y(np.radians(-85)) @ rot_x(np.radians(5)), [45.0, -60.0, 160.0])
    flanges, profiles, circles = [], [], []
    for _ in range(n):
        tilt, azimuth, roll = np.radians(rng.uniform(0, 55)), rng.uniform(-np.pi, np.pi), rng.uniform(-np.pi, np.pi)
        # sensor axes in the base: z looks down at the sphere, tilted; any roll about it
        r_s = rot_z(azimuth) @ rot_y(tilt) @ rot_x(np.pi) @ rot_z(roll)
        y0 = side * rng.uniform(4.0, 18.0)
        in_sensor = np.array([rng.uniform(-8, 8), y0, rng.uniform(225, 255)])
        sensor2base = homogeneous(r_s, centre - r_s @ in_sensor)
        flanges.append(sensor2base @ np.linalg.inv(x_true))
        r = np.sqrt(radius**2 - y0**2)
        circles.append((in_sensor[0], in_sensor[2], r))
        phi = rng.uniform(-1.1, 1.1, points)
        xz = np.column_stack([in_sensor[0] + r * np.sin(phi), in_sensor[2] - r * np.cos(phi)])
        profiles.append(xz + rng.normal(0, noise, xz.shape))
    return Cell(centre, diameter, x_true, np.array(flanges), profiles, side, circles)


def pose_error(cell, sensor2flange):
    """(translation error mm, rotation error deg) of a calibrated sensor2flange against the truth."""
    d = np.linalg.inv(cell.sensor2flange) @ np.asarray(sensor2flange)
    angle = np.degrees(np.arccos(np.clip((np.trace(d[:3, :3]) - 1) / 2, -1, 1)))
    return float(np.linalg.norm(sensor2flange[:3, 3] - cell.sensor2flange[:3, 3])), float(angle)
