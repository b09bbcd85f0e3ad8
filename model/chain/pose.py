"""KUKA poses ``(x, y, z, A, B, C)`` and 4x4 homogeneous transforms.

``T = Trans(x, y, z) Rz(A) Ry(B) Rx(C)``, mm and degrees (seed 2.1.2, C2). The forward map is
generated from :func:`handeye.model.chain.symbolic.pose_transform`; the inverse is written here, because it
is a choice, not a derivation.

Gimbal lock
-----------
At ``B = +-90 deg`` only ``A - C`` (B = +90) or ``A + C`` (B = -90) is determined. The
documented choice of :func:`pose_from_transform` there is ``C = 0``: A carries the whole
rotation about the (then common) axis. Near the lock the angles are computed so that the
transform they give back is right to machine precision, however ill-determined A and C are
individually: A from the first column, then C from what remains of R after ``Rz(A) Ry(B)``.
Compare poses as transforms (:func:`handeye.model.common.rotation.transform_distance`), never as angles.
"""
from __future__ import annotations

import functools

import numpy as np

from handeye.model.chain import codegen


@functools.lru_cache(maxsize=None)
def _source():
    def build():
        from handeye.model.chain import symbolic  # sympy only on a cache miss

        inputs, t = symbolic.pose_transform()
        return inputs, list(t[:3, :])

    return codegen.generated_source("pose_transform", build)


@functools.lru_cache(maxsize=None)
def _numpy_pose():
    return codegen.numpy_function(_source())


def transform_from_pose(pose):
    """Homogeneous transform(s) of KUKA pose(s).

    Parameters
    ----------
    pose : array_like, shape (..., 6)
        ``(x, y, z, A, B, C)``: position in mm, intrinsic Z-Y'-X'' angles in degrees.

    Returns
    -------
    ndarray, shape (..., 4, 4)
        ``Trans(x, y, z) Rz(A) Ry(B) Rx(C)``; maps points of the posed frame into the
        reference frame (e.g. ``flange2base`` for a flange pose in the robot base).
    """
    pose = np.asarray(pose, dtype=float)
    if pose.shape[-1] != 6:
        raise ValueError(f"a pose has 6 entries, got shape {pose.shape}")
    batch = pose.shape[:-1]
    vals = _numpy_pose()(*np.moveaxis(pose, -1, 0))
    out = np.zeros(batch + (4, 4))
    out[..., :3, :] = codegen.stack_outputs(vals, batch).reshape(batch + (3, 4))
    out[..., 3, 3] = 1.0
    return out


def matrix_from_kuka(angles):
    """Rotation matrix of KUKA angles ``(A, B, C)`` in degrees, shape (..., 3) -> (..., 3, 3)."""
    angles = np.asarray(angles, dtype=float)
    pose = np.concatenate([np.zeros(angles.shape[:-1] + (3,)), angles], axis=-1)
    return transform_from_pose(pose)[..., :3, :3]


#: Below this value of ``cos B`` the pose is treated as exactly at gimbal lock (C := 0).
GIMBAL_TOLERANCE = 1e-12


def kuka_from_matrix(rot):
    """KUKA angles ``(A, B, C)`` in degrees of rotation matrices, shape (..., 3, 3) -> (..., 3).

    Angles lie in (-180, 180], B in [-90, 90]. At ``cos B < GIMBAL_TOLERANCE`` the choice is
    ``C = 0`` (module docstring).
    """
    r = np.asarray(rot, dtype=float)
    cos_b = np.hypot(r[..., 0, 0], r[..., 1, 0])
    b = np.arctan2(-r[..., 2, 0], cos_b)
    locked = cos_b < GIMBAL_TOLERANCE
    a = np.where(locked, np.arctan2(-r[..., 0, 1], r[..., 1, 1]), np.arctan2(r[..., 1, 0], r[..., 0, 0]))
    # C from M = Ry(B)^T Rz(A)^T R = Rx(C), whose column 1 is (0, cos C, sin C): this absorbs
    # any error of A near the lock, so the angles always give R back.
    ca_, sa = np.cos(a)[..., None], np.sin(a)[..., None]
    cb, sb = np.cos(b), np.sin(b)
    row0 = ca_ * r[..., 0, :] + sa * r[..., 1, :]  # rows of Rz(A)^T R
    row1 = -sa * r[..., 0, :] + ca_ * r[..., 1, :]
    c = np.arctan2(sb * row0[..., 1] + cb * r[..., 2, 1], row1[..., 1])
    out = np.degrees(np.stack([a, b, c], axis=-1))
    return np.where(out <= -180.0, out + 360.0, out)


def pose_from_transform(transform):
    """KUKA pose(s) of homogeneous transform(s).

    Parameters
    ----------
    transform : array_like, shape (..., 4, 4)

    Returns
    -------
    ndarray, shape (..., 6)
        ``(x, y, z, A, B, C)`` in mm and degrees; at gimbal lock ``C = 0`` (module docstring).
    """
    t = np.asarray(transform, dtype=float)
    return np.concatenate([t[..., :3, 3], kuka_from_matrix(t[..., :3, :3])], axis=-1)
