"""``laser_plane``: the laser plane is offset (by o along the sensor's y) or tilted (about the
sensor's x and z axes) from the sensor frame's y = 0. Offset and tilt move every measured
centre by the same rigid motion in the sensor frame, which the sensor pose absorbs exactly:
never identifiable."""
import numpy as np

KIND = "structural"
NAME = "laser_plane"
PARAMS = ("offset", "tilt_x", "tilt_z")
DOC = "offset and tilt of the laser plane in the sensor frame"


def columns(parts):
    r12, xs = parts["R1R2"], parts["xs"]
    ey = r12[:, :, 1]
    tilt_x = np.cross(np.array([1.0, 0.0, 0.0]), xs)  # d(xs)/d(tilt about x) = e_x x xs
    tilt_z = np.cross(np.array([0.0, 0.0, 1.0]), xs)
    return np.stack([ey, np.einsum("nij,nj->ni", r12, tilt_x), np.einsum("nij,nj->ni", r12, tilt_z)], axis=2)
