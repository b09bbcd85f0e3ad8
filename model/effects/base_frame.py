"""``base_frame``: a constant error of the robot base frame (translation b, small rotation beta).

``e = (I + [beta]x) q + b - c`` with ``q = R1 (R2 xs + t2) + t1`` the centre seen through the
chain: columns ``I`` for b and ``-[q]x`` for beta. Since every q is (nearly) the sphere centre,
both are absorbed by the sphere centre: never identifiable from these data.
"""
import numpy as np

KIND = "structural"
NAME = "base_frame"
PARAMS = ("bx", "by", "bz", "beta_x", "beta_y", "beta_z")
DOC = "constant error of the robot base frame"


def columns(parts):
    q = parts["q"]
    n = len(q)
    skew = np.zeros((n, 3, 3))
    skew[:, 0, 1], skew[:, 0, 2], skew[:, 1, 2] = -q[:, 2], q[:, 1], -q[:, 0]
    skew[:, 1, 0], skew[:, 2, 0], skew[:, 2, 1] = q[:, 2], -q[:, 1], q[:, 0]
    return np.concatenate([np.broadcast_to(np.eye(3), (n, 3, 3)), -skew], axis=2)
