"""Profiles into the robot base: the point cloud of a scan, and each point's uncertainty.

A profile point ``p = (x, 0, z)`` (sensor frame, mm) of pose ``i`` lies in the robot base at

    q = F_i X p,        F_i = flange2base (pose i),  X = sensor2flange (the calibration).

Uncertainty. The calibration's covariance ``C`` (6x6) is of its local chart
``X(d) = (R exp([dw]x), t + dt)`` (``dt`` mm in the flange frame, ``dw`` rad about the sensor's
axes). To first order ``dq = R_F [I, -R_X [p]x] d``, so ``Cov q = J C J^T`` with
``J = R_F [I, -R_X [p]x]``. Its trace, ``sd(p)^2 = tr(C J^T J)``, does not depend on ``R_F``
(orthogonal): it is a quadratic form in ``(1, x, y, z)`` with coefficients computed once, so
the 3-D 1-sd of every point costs a few multiplications. ``sd`` is the root of the trace: the
RMS length of the position error a calibration error causes at that point (the robot's own
repeatability is not in it).

For a validation the derivative of a point's radial distance to a sphere with respect to
the calibration is needed: with ``n`` the unit normal at the point (robot base),
``n^T J = [u, p x v]`` where ``u = R_F^T n`` and ``v = R_X^T u`` (:func:`radial_jacobian`).
"""
from __future__ import annotations

import numpy as np

from handeye.model.common.rotation import skew


def points_in_base(flange2base, sensor2flange, profiles):
    """Every profile point in the robot base.

    Parameters
    ----------
    flange2base : ndarray, shape (N, 4, 4)
        Flange poses, mm.
    sensor2flange : ndarray, shape (4, 4)
        The calibration, mm.
    profiles : sequence of N ndarrays, shape (K_i, 2)
        Sensor x, z of each pose's points, mm.

    Returns
    -------
    points : ndarray, shape (M, 3)
        Robot base, mm (M = sum K_i).
    pose_index : ndarray, shape (M,), int
        The pose each point belongs to.
    """
    m = np.asarray(flange2base, float) @ np.asarray(sensor2flange, float)  # sensor2base per pose
    counts = np.array([len(p) for p in profiles], dtype=np.int64)
    index = np.repeat(np.arange(len(counts)), counts)
    xz = np.concatenate(profiles, axis=0) if len(profiles) else np.zeros((0, 2))
    # q = R[:, 0] x + R[:, 2] z + t, per point through its pose's sensor2base
    points = m[index, :3, 0] * xz[:, :1] + m[index, :3, 2] * xz[:, 1:2] + m[index, :3, 3]
    return points, index


def _generators(sensor2flange):
    """``J = R_F (G0 + x Gx + y Gy + z Gz)``: the four 3x6 pieces of the point Jacobian."""
    r_x = np.asarray(sensor2flange, float)[:3, :3]
    g0 = np.hstack([np.eye(3), np.zeros((3, 3))])
    return [g0] + [np.hstack([np.zeros((3, 3)), -r_x @ skew(axis)]) for axis in np.eye(3)]


def point_sd(points_in_sensor, sensor2flange, covariance):
    """3-D 1-sd (mm) of each point's position in the base from the calibration's covariance.

    Parameters
    ----------
    points_in_sensor : ndarray, shape (M, 2) or (M, 3)
        Sensor x, z of profile points (y = 0), or full x, y, z (a sphere centre), mm.
    sensor2flange : ndarray, shape (4, 4)
    covariance : ndarray, shape (6, 6)
        Of the local chart (mm, rad), module docstring.

    Returns
    -------
    ndarray, shape (M,)
        ``sqrt(tr Cov q)``, mm.
    """
    c = np.asarray(covariance, float)[:6, :6]
    g = _generators(sensor2flange)
    k = np.array([[np.trace(a @ c @ b.T) for b in g] for a in g])  # tr(Ga C Gb^T): coefficient of (a, b)
    p = _in_sensor(points_in_sensor)
    w = np.hstack([np.ones((len(p), 1)), p])  # (1, x, y, z)
    return np.sqrt(np.clip(np.einsum("ma,ab,mb->m", w, k, w), 0.0, None))


def _in_sensor(points):
    """(M, 3) sensor-frame points from (M, 2) x, z (y = 0) or (M, 3)."""
    p = np.asarray(points, float)
    if p.shape[1] == 3:
        return p
    out = np.zeros((len(p), 3))
    out[:, 0], out[:, 2] = p[:, 0], p[:, 1]
    return out


def point_jacobian(xz, flange2base, pose_index, sensor2flange):
    """``dq/dd`` of every point (module docstring); (M, 3, 6) floats, so for small clouds.

    Parameters
    ----------
    xz : ndarray, shape (M, 2)
        Sensor x, z, mm.
    flange2base : ndarray, shape (N, 4, 4)
    pose_index : ndarray, shape (M,)
    sensor2flange : ndarray, shape (4, 4)

    Returns
    -------
    ndarray, shape (M, 3, 6)
        mm per (mm, rad) of the chart.
    """
    g0, gx, _, gz = _generators(sensor2flange)
    xz = np.asarray(xz, float)
    j = g0 + xz[:, 0, None, None] * gx + xz[:, 1, None, None] * gz
    return np.asarray(flange2base, float)[pose_index, :3, :3] @ j


def radial_jacobian(normals, xz, flange2base, pose_index, sensor2flange):
    """``n^T dq/dd``: how each point moves along its normal with the calibration's chart.

    Parameters
    ----------
    normals : ndarray, shape (M, 3)
        Unit vectors, robot base.
    xz, flange2base, pose_index, sensor2flange
        As :func:`point_jacobian`.

    Returns
    -------
    ndarray, shape (M, 6)
        ``[u, p x v]`` with ``u = R_F^T n``, ``v = R_X^T u`` (module docstring).
    """
    r_f = np.asarray(flange2base, float)[pose_index, :3, :3]
    u = np.einsum("mji,mj->mi", r_f, normals)  # R_F^T n
    v = u @ np.asarray(sensor2flange, float)[:3, :3]  # R_X^T u, row-wise
    return np.hstack([u, np.cross(_in_sensor(xz), v)])
