"""A start anywhere: the closed-form (linear) estimate of the sensor pose.

The chain ``R_i (R_X p_i + t_X) + t_i = c`` (flange pose ``(R_i, t_i)``, sensor pose
``(R_X, t_X)``, centre measured in the sensor ``p_i``, sphere centre ``c``) is linear in
``(vec R_X, t_X, c)`` once the orthogonality of R_X is dropped: with ``r = vec R_X`` row-major,
``R_X p = (I_3 kron p^T) r``, so each measurement gives three rows

    [R_i (I_3 kron p_i^T) | R_i | -I_3] [r; t_X; c] = -t_i      (c unknown), or
    [R_i (I_3 kron p_i^T) | R_i]        [r; t_X]    = c - t_i   (c known).

Linear least squares gives an affine estimate; its 3x3 block is projected onto SO(3) (the
nearest rotation by SVD, det = +1) and ``t_X`` (and ``c``) re-solved with that rotation fixed.
No start pose is needed. The estimate is as good as the spread of the ``p_i`` allows: R_X is
determined by how the sphere's position varies in the sensor frame.
"""
from __future__ import annotations

import numpy as np

from handeye.model.common.errors import InputError
from handeye.model.common.rotation import nearest_rotation


class ClosedFormError(InputError):
    """The poses do not determine the linear problem (its matrix is rank-deficient)."""


def closed_form_estimate(flange2base, centre_in_sensor, sphere_centre=None, rtol=1e-10):
    """Closed-form sensor pose (and sphere centre).

    Parameters
    ----------
    flange2base : array_like, shape (N, 4, 4)
    centre_in_sensor : array_like, shape (N, 3)
        mm, sensor frame.
    sphere_centre : array_like, shape (3,), optional
        Known centre in the base (mm); None estimates it too.

    Returns
    -------
    sensor2flange : ndarray, shape (4, 4)
    centre : ndarray, shape (3,)
        The given or estimated sphere centre, mm.

    Raises
    ------
    ClosedFormError
        When the linear system is rank-deficient (e.g. the sphere is always seen at the same
        point of the sensor frame, or the flange never rotates).
    """
    f2b = np.asarray(flange2base, dtype=float)
    p = np.asarray(centre_in_sensor, dtype=float)
    n = len(p)
    rot, t = f2b[:, :3, :3], f2b[:, :3, 3]
    eye = np.eye(3)
    # R_i (I kron p_i^T): entry (a, 3b + k) = R_i[a, b] p_i[k]
    a_rot = np.einsum("nab,nk->nabk", rot, p).reshape(n, 3, 9)
    unknown_centre = sphere_centre is None
    blocks = [a_rot, rot] + ([np.broadcast_to(-eye, (n, 3, 3))] if unknown_centre else [])
    a = np.concatenate(blocks, axis=2).reshape(3 * n, -1)
    b = (-t if unknown_centre else np.asarray(sphere_centre, float) - t).ravel()
    sol, _, rank, sv = np.linalg.lstsq(a, b, rcond=None)
    if rank < a.shape[1] or sv[-1] < rtol * sv[0]:
        raise ClosedFormError(
            f"the closed-form system is rank-deficient (rank {rank} of {a.shape[1]}): the poses do not "
            "determine the sensor pose linearly (does the sphere move in the sensor frame, and does the flange rotate?)"
        )
    r_x = nearest_rotation(sol[:9].reshape(3, 3))
    # re-solve the translation (and centre) with the rotation fixed
    lhs = np.concatenate([rot] + ([np.broadcast_to(-eye, (n, 3, 3))] if unknown_centre else []), axis=2).reshape(3 * n, -1)
    rhs = (-t - np.einsum("nab,bc,nc->na", rot, r_x, p) + (0.0 if unknown_centre else np.asarray(sphere_centre, float))).ravel()
    sol2, *_ = np.linalg.lstsq(lhs, rhs, rcond=None)
    out = np.eye(4)
    out[:3, :3] = r_x
    out[:3, 3] = sol2[:3]
    return out, (sol2[3:6] if unknown_centre else np.asarray(sphere_centre, float).copy())
