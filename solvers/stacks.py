"""Linear algebra on stacks: one small vector or matrix per row (leading axis k).

The batched solvers (:mod:`handeye.solvers.batch`) keep one row per start; everything they
compute is a row-wise product, norm or solve. Two rules shape this module:

* **A row computes the same whatever the stack.** Each function does the same arithmetic, in
  the same order, on row i of a stack of 1 or of 10^5 rows, so a start ends bit for bit
  where it ends alone. The path taken depends on the row's width, never on k.
* **Narrow rows loop over columns.** numpy reduces along a short last axis slowly (about
  30 ns per row for a width-2 ``max``), but adds and multiplies whole columns at about 1 ns
  per row; up to :data:`NARROW` columns, the reductions below are written as column
  operations (a sum ``a0 + a1 + ...`` left to right), wider rows use numpy's reductions.
"""
from __future__ import annotations

import math

import numpy as np

#: widths up to this loop over columns (module docstring)
NARROW = 16


def _flat(a):
    """A stack (k, ...) as (k, width), also when k = 0."""
    return a.reshape(len(a), math.prod(a.shape[1:]))


def row_sum(a):
    """Sum over each row of a stack (k, ...): left to right when narrow."""
    flat = _flat(a)
    if flat.shape[1] > NARROW:
        return flat.sum(axis=1)
    if not flat.shape[1]:
        return np.zeros(len(a))
    if len(flat) == 1:  # one row: the same additions in the same order, on Python floats (no array overhead)
        values = flat[0].tolist()
        total = values[0]
        for v in values[1:]:
            total += v
        return np.array([total])
    out = flat[:, 0].copy()
    for col in flat.T[1:]:
        out += col
    return out


def max_abs_rows(a):
    """``max_j |a[i, j]|`` of a stack (k, n); NaN for width 0."""
    if not a.shape[1]:
        return np.full(len(a), np.nan)
    if a.shape[1] > NARROW or len(a) < 64:  # a maximum is exact in any order: choose by speed
        return np.max(np.abs(a), axis=1)
    out = np.abs(a[:, 0])
    for col in a.T[1:]:
        out = np.maximum(out, np.abs(col))
    return out


def dot_rows(a, b):
    """Row-wise inner products of two stacks (k, n)."""
    return row_sum(a * b)


def norm_rows(a):
    """Euclidean norm of each row of a stack (k, n)."""
    return np.sqrt(dot_rows(a, a))


def finite_rows(*arrays):
    """Rows where every entry of every array (leading axis k) is finite."""
    ok = np.ones(len(arrays[0]), dtype=bool)
    for a in arrays:
        if a.ndim == 1:
            ok &= np.isfinite(a)
            continue
        flat = _flat(a)
        if flat.shape[1] > NARROW or len(flat) < 64:  # exact either way: choose by speed
            ok &= np.isfinite(flat).all(axis=1)
        else:
            for col in flat.T:
                ok &= np.isfinite(col)
    return ok


def matvec(a, v):
    """``a[i] v[i]`` for stacks a (k, m, n), v (k, n)."""
    if a.shape[2] > NARROW or a.shape[1] > NARROW or not a.shape[2]:
        return (a @ v[:, :, None])[:, :, 0]
    out = a[:, :, 0] * v[:, :1]
    for j in range(1, a.shape[2]):
        out += a[:, :, j] * v[:, j : j + 1]
    return out


def transpose_times(j, r):
    """``j[i]^T r[i]`` for stacks j (k, m, n), r (k, m): the gradient of ``1/2 |r|^2``."""
    return matvec(np.swapaxes(j, 1, 2), r)


def quad_rows(p, b):
    """Row-wise ``p[i]^T b[i] p[i]``."""
    return dot_rows(matvec(np.swapaxes(b, 1, 2), p), p)


def half_squares(r):
    """``1/2 |r[i]|^2`` for a stack of residuals (k, m)."""
    return 0.5 * dot_rows(r, r)


def gram(j):
    """``j[i]^T j[i]`` for a stack (k, m, n)."""
    return np.swapaxes(j, 1, 2) @ j


def solve_rows(a, b):
    """Solve ``a[i] p[i] = b[i]`` (LAPACK per row); ``ok[i]`` False where ``a[i]`` is singular."""
    try:
        return np.linalg.solve(a, b[..., None])[..., 0], np.ones(len(a), dtype=bool)
    except np.linalg.LinAlgError:
        out = np.full(b.shape, np.nan)
        ok = np.zeros(len(a), dtype=bool)
        for i in range(len(a)):
            try:
                out[i] = np.linalg.solve(a[i], b[i])
                ok[i] = True
            except np.linalg.LinAlgError:
                pass
        return out, ok


def lstsq_rows(a, b):
    """Minimum-norm least-squares solutions of ``a[i] p = b[i]`` and the ranks of ``a[i]``.

    As ``numpy.linalg.lstsq(rcond=None)``: singular values below ``eps max(m, n) s_max`` count
    as zero.
    """
    m, n = a.shape[1:]
    try:
        u, s, vt = np.linalg.svd(a, full_matrices=False)
    except np.linalg.LinAlgError:
        rows = [np.linalg.lstsq(ai, bi, rcond=None) for ai, bi in zip(a, b)]
        return np.stack([r[0] for r in rows]), np.array([r[2] for r in rows])
    keep = s > np.finfo(float).eps * max(m, n) * s[:, :1]
    with np.errstate(divide="ignore", invalid="ignore"):
        coef = np.where(keep, transpose_times(u, b) / np.where(keep, s, 1.0), 0.0)
    return transpose_times(vt, coef), keep.sum(axis=1)
