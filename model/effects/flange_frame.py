"""``flange_frame``: a constant error of the flange frame (translation f, small rotation phi):
``T1 -> T1 (I + [phi]x, f)``. It composes with the sensor pose on the flange, so the sensor
pose absorbs it exactly: never identifiable."""
import numpy as np

KIND = "structural"
NAME = "flange_frame"
PARAMS = ("fx", "fy", "fz", "phi_x", "phi_y", "phi_z")
DOC = "constant error of the flange frame"


def columns(parts):
    r1, u = parts["R1"], parts["u"]  # u = R2 xs + t2: the centre in the flange frame
    n = len(u)
    skew = np.zeros((n, 3, 3))
    skew[:, 0, 1], skew[:, 0, 2], skew[:, 1, 2] = -u[:, 2], u[:, 1], -u[:, 0]
    skew[:, 1, 0], skew[:, 2, 0], skew[:, 2, 1] = u[:, 2], -u[:, 1], u[:, 0]
    return np.concatenate([r1, -r1 @ skew], axis=2)
