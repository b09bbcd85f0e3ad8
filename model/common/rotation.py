"""Rotation matrices: the exponential map, its inverse, projection onto SO(3), distances.

Used by the ``local`` parametrisation (``R = Rref exp([delta]x)``) and to compare results as
transforms. Angles here are radians unless a name says ``deg``.
"""
from __future__ import annotations

import numpy as np

from handeye.model.common.statistics import chi2_survival


def skew(v):
    """Cross-product matrix ``[v]x``, shape (..., 3) -> (..., 3, 3)."""
    v = np.asarray(v, dtype=float)
    out = np.zeros(v.shape[:-1] + (3, 3))
    out[..., 0, 1], out[..., 0, 2] = -v[..., 2], v[..., 1]
    out[..., 1, 0], out[..., 1, 2] = v[..., 2], -v[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -v[..., 1], v[..., 0]
    return out


def matrix_from_rotvec(rotvec):
    """Rodrigues' formula ``exp([w]x)``, shape (..., 3) -> (..., 3, 3); w in radians.

    ``exp([w]x) = I + a [w]x + b [w]x^2`` with ``a = sin(t)/t``, ``b = (1 - cos t)/t^2``,
    ``t = |w|``, and ``[w]x^2 = w w^T - t^2 I``; below t = 1e-8 the Taylor series of a and b.
    """
    w = np.asarray(rotvec, dtype=float)
    theta2 = np.einsum("...i,...i->...", w, w)[..., None, None]
    theta = np.sqrt(theta2)
    small = theta < 1e-8
    safe = np.where(small, 1.0, theta)
    a = np.where(small, 1.0 - theta2 / 6.0, np.sin(safe) / safe)
    b = np.where(small, 0.5 - theta2 / 24.0, (1.0 - np.cos(safe)) / safe**2)
    return (1.0 - b * theta2) * np.eye(3) + a * skew(w) + b * (w[..., :, None] * w[..., None, :])


def rotvec_from_matrix(rot):
    """Inverse of :func:`matrix_from_rotvec` (principal branch, angle in [0, pi])."""
    r = np.asarray(rot, dtype=float)
    cos_t = np.clip((np.trace(r, axis1=-2, axis2=-1) - 1.0) / 2.0, -1.0, 1.0)
    vee = np.stack([r[..., 2, 1] - r[..., 1, 2], r[..., 0, 2] - r[..., 2, 0], r[..., 1, 0] - r[..., 0, 1]], -1)
    sin_t = 0.5 * np.linalg.norm(vee, axis=-1)
    theta = np.arctan2(sin_t, cos_t)
    near_pi = cos_t < -0.99
    # general and small angles: w = theta / (2 sin theta) * vee
    with np.errstate(invalid="ignore", divide="ignore"):
        fac = np.where(sin_t > 1e-12, theta / np.where(sin_t > 1e-12, 2.0 * sin_t, 1.0), 0.5)
    w = fac[..., None] * vee
    if np.any(near_pi):
        # near pi: axis from the symmetric part R + R^T = 2 cos I + 2 (1 - cos) n n^T
        sym = (r + np.swapaxes(r, -1, -2)) / 2.0 - cos_t[..., None, None] * np.eye(3)
        col = np.argmax(np.diagonal(sym, axis1=-2, axis2=-1), axis=-1)
        n = np.take_along_axis(sym, col[..., None, None], axis=-1)[..., 0]
        with np.errstate(invalid="ignore", divide="ignore"):  # rows far from pi: 0/0, discarded below
            n = n / np.linalg.norm(n, axis=-1, keepdims=True)
        n = np.where((np.sum(n * vee, -1) < 0)[..., None], -n, n)
        w = np.where(near_pi[..., None], theta[..., None] * n, w)
    return w


def nearest_rotation(m):
    """Nearest rotation (Frobenius norm) to a 3x3 matrix, det = +1 (SVD projection)."""
    u, _, vt = np.linalg.svd(np.asarray(m, dtype=float))
    d = np.sign(np.linalg.det(u @ vt))
    u = u.copy()
    u[..., :, -1] *= d[..., None] if np.ndim(d) else d
    return u @ vt


def nearest_transform(transform):
    """A 4x4 transform with its rotation block replaced by the nearest rotation (SVD);
    non-finite input is returned unchanged."""
    out = np.array(transform, dtype=float)
    if np.all(np.isfinite(out)):
        out[:3, :3] = nearest_rotation(out[:3, :3])
    return out


def rotation_angle_deg(r_a, r_b):
    """Angle in degrees of the relative rotation ``R_a^T R_b``, shape (..., 3, 3) -> (...)."""
    rel = np.swapaxes(np.asarray(r_a), -1, -2) @ np.asarray(r_b)
    return np.degrees(np.linalg.norm(rotvec_from_matrix(rel), axis=-1))


def transform_distance(t_a, t_b):
    """Distance of two transforms: (translation difference in mm, rotation angle in degrees)."""
    t_a, t_b = np.asarray(t_a), np.asarray(t_b)
    dt = np.linalg.norm(t_a[..., :3, 3] - t_b[..., :3, 3], axis=-1)
    return dt, rotation_angle_deg(t_a[..., :3, :3], t_b[..., :3, :3])


def pose_sd(covariance):
    """1-sd ``(translation (3,) mm, rotation (3,) deg)`` of a covariance whose first six parameters are
    ``tx, ty, tz`` (mm) and ``wx, wy, wz`` (rad, about the sensor's axes); None without one."""
    if covariance is None:
        return None
    sd = np.sqrt(np.clip(np.diag(np.asarray(covariance, float)), 0.0, None))
    return sd[:3], np.degrees(sd[3:6])


def chart_shift(given, estimate):
    """The step (6,) of the local chart at ``estimate`` (4x4) that reaches ``given`` (4x4): translation (mm, the
    mount's frame), then rotation (rad, about the estimate's own axes: ``R_given = R_estimate exp([w]x)``)."""
    return np.concatenate([given[:3, 3] - estimate[:3, 3], rotvec_from_matrix(estimate[:3, :3].T @ given[:3, :3])])


def pose_distance(given, estimate, covariance=None, names=None):
    """How far ``given`` (4x4) lies from ``estimate`` (4x4): translation (mm), rotation (deg) and,
    with the estimate's covariance on the local chart (``names`` tx..wz), the Mahalanobis
    distance in its sd and its chi^2_6 p-value."""
    out = {"translation_mm": float(np.linalg.norm(given[:3, 3] - estimate[:3, 3])),
           "rotation_deg": float(rotation_angle_deg(estimate[:3, :3], given[:3, :3])), "sd": None, "p_value": None}
    if covariance is None or names is None:
        return out
    idx = [list(names).index(n) for n in ("tx", "ty", "tz", "wx", "wy", "wz")]
    cov = np.asarray(covariance, float)[np.ix_(idx, idx)]
    delta = chart_shift(given, estimate)
    d2 = float(delta @ np.linalg.pinv(cov) @ delta)
    out.update(sd=float(np.sqrt(max(d2, 0.0))), p_value=float(chi2_survival(d2, 6)))
    return out
