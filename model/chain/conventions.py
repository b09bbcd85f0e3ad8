"""Robot-brand pose conventions, all generated from :func:`handeye.model.chain.symbolic.rotation_from`.

=========  =======================  ==========================================================
name       pose columns             orientation
=========  =======================  ==========================================================
kuka       x, y, z, a, b, c         A, B, C (deg): Rz(A) Ry(B) Rx(C), intrinsic Z-Y'-X''
abb        x, y, z, q1, q2, q3, q4  unit quaternion (w, x, y, z)
ur         x, y, z, rx, ry, rz      rotation vector (rad): exp([r]x)
fanuc      x, y, z, w, p, r         W, P, R (deg): fixed X-Y-Z, Rz(R) Ry(P) Rx(W)
=========  =======================  ==========================================================

Positions are in mm in every convention. Worked example: the thesis's CAD sensor pose,
KUKA ``(156.99, 87.55, 115, 180, -90, 0)``, is FANUC ``(156.99, 87.55, 115, 0, -90, 180)``,
ABB ``(156.99, 87.55, 115, 0, 0.7071, 0, 0.7071)`` and UR
``(156.99, 87.55, 115, 2.2214, 0, 2.2214)`` (a half turn about (1, 0, 1) / sqrt 2).

Inverses: ``kuka`` and ``fanuc`` share the Z-Y-X decomposition of :mod:`handeye.model.chain.pose` (C = 0 /
W = 0 at the singularity), ``abb`` returns the quaternion with w >= 0 (Shepperd's method),
``ur`` the rotation vector of angle in [0, pi].
"""
from __future__ import annotations

import functools

import numpy as np

from handeye.model.chain import codegen
from handeye.model.chain.names import CONVENTIONS  # noqa: F401  (re-exported: the public names)
from handeye.model.chain.pose import kuka_from_matrix
from handeye.model.common.errors import InputError
from handeye.model.common.rotation import rotvec_from_matrix

#: The lengths a pose file's positions are wrongly written in, by their factor to mm: each a reading of the
#: file that a slip check tries (the convention detective, the nominal robot model's gate).
LENGTH_UNITS = {10.0: "centimetres", 25.4: "inches", 1000.0: "metres"}

#: No angle (KUKA, FANUC; degrees) may exceed a full turn, start guesses included.
ANGLE_LIMIT_DEG = 360.0
#: Tolerance on |q| - 1 for ABB quaternions (they are normalised within it).
QUATERNION_TOLERANCE = 1e-3


class ConventionError(InputError):
    """Orientation values that are not valid in their convention."""


def columns(convention):
    """Pose column names of a convention, e.g. ``('x', 'y', 'z', 'a', 'b', 'c')``."""
    return ("x", "y", "z") + CONVENTIONS[check(convention)]


def check(convention):
    if convention not in CONVENTIONS:
        raise ConventionError(f"unknown convention {convention!r}; choose one of {', '.join(CONVENTIONS)}")
    return convention


@functools.lru_cache(maxsize=None)
def _function(convention):
    def build():
        from handeye.model.chain import symbolic

        sym, rot = symbolic.rotation_from(convention)
        return sym, list(rot)

    return codegen.numpy_function(codegen.generated_source(f"rotation_{convention}", build))


def validate(convention, values):
    """Check (and for ABB normalise) orientation values (..., k); raises ConventionError."""
    v = np.asarray(values, dtype=float)
    if not np.all(np.isfinite(v)):
        raise ConventionError("orientation values must be finite")
    if convention == "abb":
        norm = np.linalg.norm(v, axis=-1, keepdims=True)
        if np.any(np.abs(norm - 1.0) > QUATERNION_TOLERANCE):
            raise ConventionError(f"an ABB quaternion must have unit norm (|q| = {float(np.max(norm)):.6g})")
        v = v / norm
    elif convention in ("kuka", "fanuc"):
        if np.any(np.abs(v) > ANGLE_LIMIT_DEG):
            raise ConventionError(f"angles must lie in [-{ANGLE_LIMIT_DEG:g}, {ANGLE_LIMIT_DEG:g}] degrees")
    elif np.any(np.linalg.norm(v, axis=-1) > 2 * np.pi + 1e-9):
        raise ConventionError("a UR rotation vector is at most 2 pi rad long")
    return v


def matrix_from(convention, values):
    """Rotation matrices (..., 3, 3) of orientation values (..., k) in a convention."""
    v = validate(check(convention), values)
    batch = v.shape[:-1]
    return codegen.stack_outputs(_function(convention)(*np.moveaxis(v, -1, 0)), batch).reshape(batch + (3, 3))


def values_from_matrix(convention, rot):
    """Orientation values (..., k) of rotation matrices in a convention (module docstring)."""
    check(convention)
    r = np.asarray(rot, dtype=float)
    if convention == "kuka":
        return kuka_from_matrix(r)
    if convention == "fanuc":
        return kuka_from_matrix(r)[..., ::-1]
    if convention == "ur":
        return rotvec_from_matrix(r)
    return quaternion_from_matrix(r)


def quaternion_from_matrix(rot):
    """Unit quaternion (w, x, y, z), w >= 0, of rotation matrices (Shepperd's method)."""
    r = np.asarray(rot, dtype=float)
    tr = np.trace(r, axis1=-2, axis2=-1)
    cand = np.stack([
        np.stack([1 + tr, r[..., 2, 1] - r[..., 1, 2], r[..., 0, 2] - r[..., 2, 0], r[..., 1, 0] - r[..., 0, 1]], -1),
        np.stack([r[..., 2, 1] - r[..., 1, 2], 1 + 2 * r[..., 0, 0] - tr, r[..., 0, 1] + r[..., 1, 0],
                  r[..., 0, 2] + r[..., 2, 0]], -1),
        np.stack([r[..., 0, 2] - r[..., 2, 0], r[..., 0, 1] + r[..., 1, 0], 1 + 2 * r[..., 1, 1] - tr,
                  r[..., 1, 2] + r[..., 2, 1]], -1),
        np.stack([r[..., 1, 0] - r[..., 0, 1], r[..., 0, 2] + r[..., 2, 0], r[..., 1, 2] + r[..., 2, 1],
                  1 + 2 * r[..., 2, 2] - tr], -1),
    ], -2)
    diag = np.stack([tr, r[..., 0, 0], r[..., 1, 1], r[..., 2, 2]], -1)
    q = np.take_along_axis(cand, np.argmax(diag, axis=-1)[..., None, None], axis=-2)[..., 0, :]
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    return np.where(q[..., :1] < 0, -q, q)


def transform_from(convention, pose):
    """4x4 transforms (..., 4, 4) of poses (..., 3 + k) in a convention (mm)."""
    p = np.asarray(pose, dtype=float)
    out = np.zeros(p.shape[:-1] + (4, 4))
    out[..., :3, :3] = matrix_from(convention, p[..., 3:])
    out[..., :3, 3] = p[..., :3]
    out[..., 3, 3] = 1.0
    return out


def pose_from(convention, transform):
    """Poses (..., 3 + k) in a convention of 4x4 transforms."""
    t = np.asarray(transform, dtype=float)
    return np.concatenate([t[..., :3, 3], values_from_matrix(convention, t[..., :3, :3])], axis=-1)


def convert(pose, source, target):
    """A pose from one convention to another."""
    return pose_from(target, transform_from(source, pose))
