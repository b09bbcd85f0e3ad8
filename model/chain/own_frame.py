"""The sensor's own frame and handeye's: the one turn between them.

``handeye dataset new`` turns profiles given in the sensor's own frame (its driver's points)
into handeye's (laser plane y = 0, z the stand-off) and keeps the turn as ``[profile] own_axes``:
R with ``p_handeye = R p_own``. Every pose the user reads or types is of the own frame; handeye
computes in its own. A sensor pose S (sensor frame in its mount's frame) of handeye's frame is
``S_own = S [R 0; 0 1]`` of the own frame. Poses are turned here, once where they come in
(:func:`to_internal`) and once where they go out (:func:`to_own`); ``own_axes`` None is no turn.

The covariance of the local chart ``t + dt, R_s exp([dw]x)`` (``dw`` about the sensor's axes)
turns with the frame: ``R_s exp([dw]x) R = R_s R exp([R^T dw]x)``, so ``dw_own = R^T dw``.
"""
from __future__ import annotations

import numpy as np

from handeye.model.chain.pose import pose_from_transform, transform_from_pose


def _turn(own_axes, forward):
    turn = np.eye(4)
    rot = np.asarray(own_axes, float)
    turn[:3, :3] = rot if forward else rot.T
    return turn


def to_own(matrix, own_axes):
    """The 4x4 sensor pose ``matrix`` of handeye's frame as the sensor's own frame's (``S R``)."""
    return matrix if matrix is None or own_axes is None else np.asarray(matrix, float) @ _turn(own_axes, True)


def to_internal(matrix, own_axes):
    """The inverse of :func:`to_own`: a 4x4 sensor pose of the own frame as handeye's (``S R^T``)."""
    return matrix if matrix is None or own_axes is None else np.asarray(matrix, float) @ _turn(own_axes, False)


def kuka_to_internal(pose, own_axes):
    """A KUKA pose ``x, y, z, A, B, C`` of the own frame as handeye's frame's (KUKA too)."""
    if pose is None or own_axes is None:
        return pose
    return pose_from_transform(to_internal(transform_from_pose(pose), own_axes))


def covariance_to_own(covariance, own_axes, forward=True, first=3):
    """A covariance whose rows ``first`` .. ``first + 2`` are the sensor's rotation ``dw`` (handeye's
    axes) with those rows and columns about the own frame's axes (``dw_own = R^T dw``); ``forward``
    False the inverse; ``first`` None: no rotation among its parameters (unchanged). The other
    parameters (translation, sphere, effects) are left as they are."""
    if covariance is None or own_axes is None or first is None:
        return covariance
    jac = step_to_own(len(covariance), own_axes, first, forward)
    return jac @ np.asarray(covariance, float) @ jac.T


def step_to_own(n, own_axes, first=3, forward=True):
    """The (n, n) map of a step of parameters whose entries ``first`` .. ``first + 2`` are the
    sensor's rotation about handeye's axes to the step about the own frame's (``dw_own = R^T dw``;
    ``forward`` False the inverse); the identity elsewhere."""
    jac = np.eye(n)
    jac[first:first + 3, first:first + 3] = np.asarray(own_axes, float).T if forward else np.asarray(own_axes, float)
    return jac
