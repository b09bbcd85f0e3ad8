"""The thesis's state of the art as working baselines: Kim & Cho (2001) and Li et al. (2011).

Both are linear (closed-form) hand-eye methods that the seed reviews (2.6, Appendix A) and
rules out on paper (Table 4-1). Here they run on the same data as the nonlinear least squares.

Kim & Cho [KCK2001], the relative-motion form ``A X = X B`` (seed 2-44)
    ``A = T_Q^-1 T_P`` is the flange motion between two robot poses P and Q, ``X`` the sensor
    pose on the flange. A fixed sphere seen as ``p`` at P and ``q`` at Q gives ``A X p = X q``
    (the equation does not contain the sphere's position: it need not be known). In the 12
    entries ``U`` of X's first three rows this is linear, ``D U = F``, with ``D`` and ``F``
    generated from :func:`handeye.model.chain.symbolic.axxb_linear` (``point`` form; the ``matrix`` form of
    Appendix A needs four or more points per pose, :func:`kim_cho_matrix`). Stacking every
    pair of samples (2-46) and solving by linear least squares gives an affine ``X``; the
    result is its nearest rigid transform (SVD projection of the rotation block).

    The linear problem is well posed only when the relative rotations turn about at least two
    non-parallel axes *and* the measured points ``p`` span 3-D: the 12 entries are fitted
    freely, so the columns of the rotation block are seen only through the spread of ``p``.
    Data where the sphere is always seen near one sensor point (rotations about the sphere)
    leave it ill-conditioned, and so do data where every pose has the same flange position
    (thesis-sim: rotations about the flange origin only). Then ``T_i X p_i = t + R_i (R_X p_i +
    t_X) = c`` for every i, and the top rows of X scaled by any factor ``s`` give
    ``t + s (c - t)``, the same point for every i: a null direction of the 12 linear unknowns
    (the sphere position is not an input) that only the orthogonality of R_X, which the linear
    method ignores, would exclude.
    :class:`MissingMotions` says so.

Li et al. [LCJ+2011], two steps (seed 2-40 to 2-42)
    1. Pure robot translations (flange rotation R_0 unchanged, the sphere fixed) give the
       rotation: from (2-40), ``R_0 R_s (X_l1 - X_l2) = T_02 - T_01``. The seed prints (2-41)
       with the opposite sign, ``R_0 R_s (X_l2 - X_l1) = T_02 - T_01``, which would be solved
       by ``-R_s`` (a reflection): a typo (tests/test_classics.py shows it). Linear least
       squares for the 3 x 3 matrix, then projection onto SO(3). Two non-parallel
       translations suffice (their cross product is added as a third direction).
    2. With R_s known, every pose gives (2-42) ``c = X_v + R_0 T_s``,
       ``X_v = R_0 R_s X_l + T_0``: ``T_s`` by least squares with the sphere centre ``c``
       known, or ``T_s`` and ``c`` together when the robot also rotates about the sphere.
"""
from __future__ import annotations

import dataclasses
import functools

import numpy as np

from handeye.model.chain import codegen
from handeye.model.common.errors import InputError
from handeye.model.common.rotation import nearest_rotation, nearest_transform, rotation_angle_deg, rotvec_from_matrix

#: Flange rotations closer than this (degrees) count as equal: a pure translation.
SAME_ROTATION_DEG = 0.01
#: Translations shorter than this (mm) are not a motion.
MIN_TRANSLATION_MM = 1.0
#: Smallest accepted ratio of the smallest to the largest column-scaled singular value of D:
#: beyond a condition number of 1e4 the linear estimate amplifies 0.01 mm of noise to
#: decimetres (rotations about the sphere alone reach 1.6e6).
CONDITION_LIMIT_INV = 1e-4


class MissingMotions(InputError):
    """The dataset lacks the robot motions a method needs (the message says which)."""


@dataclasses.dataclass
class ClassicResult:
    """Estimate of a closed-form method.

    Attributes
    ----------
    sensor2flange : ndarray, shape (4, 4)
        Rigid sensor pose on the flange (mm).
    linear : ndarray, shape (4, 4)
        The least-squares solution before projection onto SO(3) (its rotation block is not
        orthogonal when the data are noisy).
    sphere_centre : ndarray, shape (3,) or None
        Estimated (Li, step 2 with unknown centre) or None.
    method : str
    details : dict
        What was used: motion pairs, singular values, orthogonality error ``|R^T R - I|``.
    """

    sensor2flange: np.ndarray
    linear: np.ndarray
    sphere_centre: np.ndarray | None
    method: str
    details: dict


@functools.lru_cache(maxsize=None)
def _axxb_function(form):
    def build():
        from handeye.model.chain import symbolic

        s = symbolic.axxb_linear(form)
        inputs = list(s["a"]) + (list(s["b"]) if form == "matrix" else list(s["p"]) + list(s["q"]))
        return inputs, list(s["D"]) + list(s["F"])

    return codegen.numpy_function(codegen.generated_source(f"axxb_{form}", build))


def axxb_system(a, b=None, p=None, q=None):
    """Stacked ``D``, ``F`` of Kim & Cho for K motions.

    Parameters
    ----------
    a : ndarray, shape (K, 4, 4)
        Relative flange motions ``T_Q^-1 T_P``.
    b : ndarray, shape (K, 4, 4), optional
        Matrix form: ``B`` per motion.
    p, q : ndarray, shape (K, 3), optional
        Point form: the point measured at P and at Q (sensor frame, mm).

    Returns
    -------
    D : ndarray, shape (12 K, 12) or (3 K, 12)
    F : ndarray, shape (12 K,) or (3 K,)
    """
    a = np.asarray(a, float)
    args = [a[:, i, j] for i in range(3) for j in range(4)]
    if b is not None:
        b = np.asarray(b, float)
        args += [b[:, i, j] for i in range(4) for j in range(4)]
        rows, fun = 12, _axxb_function("matrix")
    else:
        args += [np.asarray(p, float)[:, k] for k in range(3)] + [np.asarray(q, float)[:, k] for k in range(3)]
        rows, fun = 3, _axxb_function("point")
    out = codegen.stack_outputs(fun(*args), (len(a),))
    return out[:, : 12 * rows].reshape(-1, 12), out[:, 12 * rows:].reshape(-1)


#: ``auto`` pairs: every pair up to this many, else each sample with its next few (cyclically).
MAX_PAIRS = 20_000


def motion_pairs(n, pairs="auto"):
    """Index pairs (P, Q) of samples.

    ``all``: every i < j (N (N - 1) / 2); ``consecutive``: (i, i + 1); ``auto`` (default):
    ``all`` while that is at most :data:`MAX_PAIRS`, else each sample with its next
    ``MAX_PAIRS // N`` samples, cyclically (memory stays bounded for large datasets).
    """
    if pairs == "auto":
        if n * (n - 1) // 2 <= MAX_PAIRS:
            pairs = "all"
        else:
            k = max(1, MAX_PAIRS // n)
            i = np.repeat(np.arange(n), k)
            return np.column_stack([i, (i + np.tile(np.arange(1, k + 1), n)) % n])
    if pairs == "all":
        i, j = np.triu_indices(n, 1)
        return np.column_stack([i, j])
    if pairs == "consecutive":
        return np.column_stack([np.arange(n - 1), np.arange(1, n)])
    raise ValueError(f"pairs must be 'auto', 'all' or 'consecutive', got {pairs!r}")


def _solve_linear(d, f, what):
    """Least squares of D U = F with a column-scaled rank check; U and the scaled singular values."""
    scale = np.linalg.norm(d, axis=0)
    scale[scale == 0] = 1.0
    sv = np.linalg.svd(d / scale, compute_uv=False)
    if sv[-1] <= CONDITION_LIMIT_INV * sv[0]:
        raise MissingMotions(what(sv))
    return np.linalg.lstsq(d / scale, f, rcond=None)[0] / scale, sv


def kim_cho(flange2base, centre_in_sensor, pairs="auto"):
    """Kim & Cho's linear AX = XB for one fixed sphere (module docstring).

    Parameters
    ----------
    flange2base : ndarray, shape (N, 4, 4)
        Flange frames in the robot base (mm).
    centre_in_sensor : ndarray, shape (N, 3)
        Sphere centre measured in the sensor frame (mm).
    pairs : {'auto', 'all', 'consecutive'}
        Motion pairs to stack (:func:`motion_pairs`).

    Returns
    -------
    ClassicResult

    Raises
    ------
    MissingMotions
        Fewer than three samples, or motions that leave D rank-deficient.
    """
    t = np.asarray(flange2base, float)
    xs = np.asarray(centre_in_sensor, float)
    if len(t) < 3:
        raise MissingMotions(f"kim-cho needs at least 3 poses of a fixed sphere (2 motion pairs); the data have {len(t)}")
    idx = motion_pairs(len(t), pairs)
    a = np.linalg.solve(t[idx[:, 1]], t[idx[:, 0]])  # T_Q^-1 T_P
    d, f = axxb_system(a, p=xs[idx[:, 0]], q=xs[idx[:, 1]])

    def what(sv):
        w = rotvec_from_matrix(t[idx[:, 0], :3, :3].transpose(0, 2, 1) @ t[idx[:, 1], :3, :3])
        turned = np.degrees(np.linalg.norm(w, axis=1)) > 1.0
        axes = w[turned] / np.linalg.norm(w[turned], axis=1, keepdims=True)
        axis_rank = np.linalg.matrix_rank(axes, tol=0.05) if len(axes) else 0
        spread = np.linalg.svd(xs - xs.mean(axis=0), compute_uv=False)
        moved = float(np.max(np.linalg.norm(t[:, :3, 3] - t[0, :3, 3], axis=1)))
        text = (f"kim-cho: the stacked D U = F is (nearly) rank-deficient (scaled singular values {sv[-1]:.1e} .. {sv[0]:.1e}); "
                f"it needs relative rotations about at least 2 non-parallel axes (these data: {axis_rank}), measured "
                f"sphere centres that span 3-D in the sensor frame (spread, singular values: "
                f"{', '.join(f'{v:.2g}' for v in spread)} mm)")
        if moved < MIN_TRANSLATION_MM:
            text += (f", and flange positions that differ: here every pose has the same flange position (spread "
                     f"{moved:.2g} mm), so X with its top rows scaled by any factor solves the linear equations as "
                     "well (only the orthogonality the linear method ignores would fix the scale)")
        return text

    u, sv = _solve_linear(d, f, what)
    x_lin = np.vstack([u.reshape(3, 4), [0, 0, 0, 1]])
    r = x_lin[:3, :3]
    return ClassicResult(nearest_transform(x_lin), x_lin, None, "kim-cho", {
        "pairs": len(idx), "equations": len(d), "singular_values": sv.tolist(),
        "condition": float(sv[0] / sv[-1]), "orthogonality_error": float(np.linalg.norm(r.T @ r - np.eye(3)))})


def kim_cho_matrix(a, b):
    """Kim & Cho with 4 x 4 ``B`` matrices (Appendix A; four or more points per pose).

    Parameters
    ----------
    a : ndarray, shape (K, 4, 4)
        Relative flange motions ``T_Q^-1 T_P``.
    b : ndarray, shape (K, 4, 4)
        ``(X_S^Q X_W^T)(X_S^P X_W^T)^-1`` per motion, with the sensor-frame points at Q and P.

    Returns
    -------
    ClassicResult
    """
    d, f = axxb_system(a, b=b)
    u, sv = _solve_linear(d, f, lambda sv: f"kim-cho (matrix form): D is rank-deficient ({sv[-1]:.1e}); at least two "
                                           "motions with non-parallel rotation axes are needed")
    x_lin = np.vstack([u.reshape(3, 4), [0, 0, 0, 1]])
    return ClassicResult(nearest_transform(x_lin), x_lin, None, "kim-cho", {"pairs": len(a), "singular_values": sv.tolist()})


def translation_pairs(flange2base, same_deg=SAME_ROTATION_DEG, min_mm=MIN_TRANSLATION_MM):
    """Pairs (i, j) of samples related by a pure robot translation.

    Samples whose flange rotations differ by less than ``same_deg`` form a group; each group
    gives the pairs (first, other) with translations longer than ``min_mm``.

    Returns
    -------
    ndarray, shape (K, 2), int
    """
    t = np.asarray(flange2base, float)
    group = -np.ones(len(t), int)
    for i in range(len(t)):
        if group[i] < 0:
            same = (rotation_angle_deg(t[i, :3, :3], t[:, :3, :3]) < same_deg) & (group < 0)
            group[same] = i
    out = [(g, j) for j, g in enumerate(group) if j != g and np.linalg.norm(t[j, :3, 3] - t[g, :3, 3]) > min_mm]
    return np.array(out, int).reshape(-1, 2)


def li_two_step(flange2base, centre_in_sensor, sphere_centre=None, sign="derived"):
    """Li et al.'s two-step method (module docstring).

    Parameters
    ----------
    flange2base : ndarray, shape (N, 4, 4)
    centre_in_sensor : ndarray, shape (N, 3)
    sphere_centre : ndarray, shape (3,), optional
        Sphere centre in the base frame (mm). None: estimated in step 2 (needs rotations).
    sign : {'derived', 'printed'}
        ``printed`` uses the seed's (2-41) as printed (wrong sign), for the test that shows it.

    Returns
    -------
    ClassicResult
    """
    t = np.asarray(flange2base, float)
    xs = np.asarray(centre_in_sensor, float)
    pairs = translation_pairs(t)
    moves = np.einsum("kji,kj->ki", t[pairs[:, 0], :3, :3], t[pairs[:, 1], :3, 3] - t[pairs[:, 0], :3, 3])
    seen = xs[pairs[:, 0]] - xs[pairs[:, 1]]  # (X_l1 - X_l2): R_s seen = R_0^T (T_02 - T_01)
    if sign == "printed":
        seen = -seen
    rank = np.linalg.matrix_rank(moves, tol=MIN_TRANSLATION_MM) if len(moves) else 0
    if rank < 2:
        raise MissingMotions(
            f"li-two-step step 1 needs pure robot translations: at least two pairs of poses with the same flange "
            f"orientation (within {SAME_ROTATION_DEG} deg) whose translations (> {MIN_TRANSLATION_MM} mm) are not "
            f"parallel; these data have {len(pairs)} such pair(s) spanning {rank} direction(s)")
    if rank == 2:  # a rotation maps the cross product of two directions to the cross product of their images
        k = np.argmax(np.linalg.norm(np.cross(moves[0], moves), axis=1))
        moves = np.vstack([moves, np.cross(moves[0], moves[k])])
        seen = np.vstack([seen, np.cross(seen[0], seen[k])])
    r_lin = np.linalg.lstsq(seen, moves, rcond=None)[0].T  # R seen_k = moves_k, least squares
    r_s = nearest_rotation(r_lin)
    # step 2: R_0 T_s (- c) = -(R_0 R_s x_l + T_0)  [+ c on the right when c is known]
    r0, t0 = t[:, :3, :3], t[:, :3, 3]
    virtual = np.einsum("nij,jk,nk->ni", r0, r_s, xs) + t0
    if sphere_centre is not None:
        lhs = r0.reshape(-1, 3)
        sol = np.linalg.lstsq(lhs, (np.asarray(sphere_centre, float) - virtual).reshape(-1), rcond=None)[0]
        centre = None
    else:
        if np.max(rotation_angle_deg(r0[0], r0)) < 1.0:
            raise MissingMotions("li-two-step step 2 without a known sphere centre needs robot rotations about the "
                                 "sphere (flange orientations differing by more than 1 deg); these data have none")
        lhs = np.concatenate([r0, -np.broadcast_to(np.eye(3), r0.shape)], axis=2).reshape(-1, 6)
        sol = np.linalg.lstsq(lhs, -virtual.reshape(-1), rcond=None)[0]
        centre = sol[3:]
    out = np.eye(4)
    out[:3, :3], out[:3, 3] = r_s, sol[:3]
    lin = out.copy()
    lin[:3, :3] = r_lin
    return ClassicResult(out, lin, centre, "li-two-step", {
        "translation_pairs": pairs.tolist(), "directions": int(rank),
        "orthogonality_error": float(np.linalg.norm(r_lin.T @ r_lin - np.eye(3))), "det_linear": float(np.linalg.det(r_lin))})
