"""Exact leave-one-out refits, every sample at once: damped Newton on the stack of deleted problems.

Problem k is the fit without sample k,

    min_z  f_k(z) = 1/2 sum_i w_ki |W_i e_i(z)|^2,    w_ki = 0 on sample k's rows, else 1,

on the local chart (a point moves by ``retract(z, delta)``). The G problems are iterated
together: their points are a stack Z (G, d), and one call of
:meth:`handeye.model.fit.calibration.CalibrationModel.cost_derivatives` evaluates every row at every
point with the problems' row weights (whitened as the model whitens them), giving ``f_k``, the
gradient ``g_k`` and the exact cost Hessian

    H_k = sum_i w_ki (J_i^T J_i + sum_l (W_i^T W_i e_i)_l grad^2 e_il)

(Nocedal & Wright, *Numerical Optimization*, 2nd ed., eq. 10.5: Gauss-Newton's ``J^T J`` plus the
second-order term it leaves out, which is large when a gross error is among the samples).

**Step.** Newton's step with Levenberg-Marquardt damping (N&W 3.4, 10.3; Marquardt's scaling
``D = diag |H_k|`` for the mixed units, mm and rad):

    (H_k + lambda_k D_k) delta_k = -g_k.

``lambda_k`` is zero (pure Newton: quadratic convergence, N&W Theorem 3.5) while ``H_k`` is
positive definite and steps lower ``f_k``; where ``H_k`` is not, it is raised to twice the
distance of the scaled Hessian's smallest eigenvalue below zero (N&W 3.4); ten-fold at every
rejected step, and lowered ten-fold (to zero below :data:`LAMBDA_START`) at every accepted one.
A step is accepted only when it does not raise its problem's cost (beyond rounding,
``100 eps |f_k|``).

**First step.** Every problem starts at the full fit x, where the full gradient vanishes, so
``g_k(x) = -g_(k)``, sample k's own part, and the first (undamped) step is

    delta_k = (H - H_(k))^-1 g_(k),

the deletion formula (Cook & Weisberg, *Residuals and Influence in Regression*, 1982, ch. 5: the
one-step approximation of a deleted nonlinear fit) with the full cost Hessian. One evaluation of
the rows at x serves every problem.

**Small residuals.** Where Gauss-Newton's rate ``rho`` at the fit is small (given by the caller:
:func:`handeye.app.engine.robust._gauss_newton_rate`), every step uses Gauss-Newton's
``sum_i w_ki J_i^T J_i`` for ``H_k`` (the first is then the classical deletion formula
``(A - B_k)^-1 J_k^T r_k``), as the per-sample refit it replaces: no second derivatives
(several times cheaper per evaluation for thousands of profile points), each step gains the
digits of ``rho``, and the steps land closer than Newton's: the error of Newton's step on
``1/2 |r|^2`` carries the third derivative ``3 J^T grad^2 r``, Gauss-Newton's only terms in the
small residual (simulated profiles, 12 samples: 1e-5 mm left after the first Gauss-Newton step,
2e-4 mm after Newton's). Large residuals (a gross error among the samples) keep the exact
Hessian throughout: there Gauss-Newton creeps or diverges.

**Convergence**, per problem, as the Gauss-Newton refit it replaces (:data:`handeye.app.engine.robust.LOO_XTOL`):
an undamped step no longer than ``xtol (1 + |z|)`` is taken and the problem stops; with
Gauss-Newton's Hessian, converging linearly at the rate ``rho``, already when the distance left
after the step, ``safety rho / (1 - rho) |delta|``, is that small. (With the exact Hessian the
step test alone: after a step that small the distance left is of its square. An estimate of
the quadratic rate from two steps stopped a step early on thesis-real, 2e-6 short.) A problem
whose gradient is at rounding level, ``|g_k|_inf <= GTOL max(1, f_k)``, stops where it is. A
problem that has not stopped within :data:`NEWTON_ITER` iterations, or whose numbers are not
finite, is reported as not converged: the caller refits it another way.

**In closed form.** For the unweighted centre model with the sphere centre known every deleted problem is an
absolute orientation, and :func:`closed_form_errors` solves them all by downdating the whole cross-covariance by
each sample (one batched SVD, at any size; kept for a problem asked again) instead of the refits above.

**Memory.** The problems run in chunks whose largest arrays stay below :data:`CHUNK_BYTES`:
the second derivatives (G_chunk x rows x m x 81 floats) with the exact Hessian, the Jacobians
and their weighted copies (about G_chunk x rows x m x 3 (n + 1)) with Gauss-Newton's.
"""
from __future__ import annotations

import collections
import hashlib
import threading

import numpy as np

from handeye.model.fit.global_fit import centre_targets

#: Iterations of the batched Newton before a problem is handed back as not converged.
NEWTON_ITER = 30
#: Bytes of the largest arrays (module docstring, Memory) per chunk of problems.
CHUNK_BYTES = 50e6
#: A gradient this small relative to max(1, cost) is rounding: the problem stops.
GTOL = 1e-14
#: The damping a rejected undamped step starts with (scaled Hessian: unit diagonal); a damping
#: lowered below it becomes zero (Newton's step again).
LAMBDA_START = 1e-3


def refits(fitted, x, rows, xtol, safety, rate=None):
    """The minimum of each deleted problem (module docstring), all problems at once.

    Parameters
    ----------
    fitted : handeye.model.fit.calibration.CalibrationModel
        The model of the samples fitted at ``x`` (``local`` rotation).
    x : ndarray, shape (d,)
        Its fit: the start of every problem.
    rows : sequence of slice or ndarray
        Per problem, the rows of ``fitted`` it leaves out (one sample's).
    xtol, safety : float
        Step tolerance (relative to ``1 + |z|``) and the safety factor of Gauss-Newton's
        estimated distance left.
    rate : float, optional
        Gauss-Newton's rate at ``x``, below one: every step is Gauss-Newton's. None: the exact
        Hessian throughout.

    Returns
    -------
    z : ndarray, shape (G, d)
        The refitted points.
    converged : ndarray of bool, shape (G,)
        False where the iteration did not converge (``z`` is then its last point).
    """
    count = len(rows)
    z, done = np.empty((count, len(x))), np.zeros(count, bool)
    # the largest arrays: generated second derivatives (9 x 9 per component), or the Jacobian's
    per_problem = 8.0 * fitted.n_meas * fitted.m * (81 if rate is None else 3 * (fitted.n + 1))
    size = max(1, int(CHUNK_BYTES // per_problem))
    for start in range(0, count, size):
        part = range(start, min(start + size, count))
        weights = np.ones((len(part), fitted.n_meas))
        for j, k in enumerate(part):
            weights[j, rows[k]] = 0.0
        z[part.start:part.stop], done[part.start:part.stop] = _newton(fitted, x, weights, xtol, safety, rate)
    return z, done


def _newton(fitted, x, weights, xtol, safety, rate):
    """Damped Newton on the problems of one chunk (row weights ``weights`` (G, N)) from ``x``;
    returns the points (G, d) and which converged (module docstring)."""
    count, exact = len(weights), rate is None
    # distance left to the minimum per unit of the step just taken: Gauss-Newton's linear rate
    left = 1.0 if exact else min(1.0, safety * rate / (1.0 - rate))
    z = np.tile(np.asarray(x, float), (count, 1))
    f, g, h = fitted.cost_derivatives(x, weights, second_order=exact)  # one evaluation serves every problem
    lam = np.zeros(count)  # Levenberg-Marquardt's damping
    done, failed = np.zeros(count, bool), ~_finite(f, g, h)
    for _ in range(NEWTON_ITER):
        act = np.flatnonzero(~done & ~failed)
        flat = np.max(np.abs(g[act]), axis=1) <= GTOL * np.maximum(1.0, np.abs(f[act]))
        done[act[flat]] = True
        act = act[~flat]
        if not act.size:
            break
        step, lam[act] = _damped_steps(h[act], g[act], lam[act])
        size, undamped = np.linalg.norm(step, axis=1), lam[act] == 0
        trial = fitted.retract(z[act], step)
        small = undamped & (left * size <= xtol * (1.0 + np.linalg.norm(trial, axis=1)))
        z[act[small]], done[act[small]] = trial[small], True
        act, trial = act[~small], trial[~small]
        if not act.size:
            break
        f_t, g_t, h_t = fitted.cost_derivatives(trial, weights[act], second_order=exact)
        accept = _finite(f_t, g_t, h_t) & (f_t <= f[act] + 100 * np.finfo(float).eps * np.maximum(1.0, np.abs(f[act])))
        acc, rej = act[accept], act[~accept]
        z[acc], f[acc], g[acc], h[acc] = trial[accept], f_t[accept], g_t[accept], h_t[accept]
        lam[acc] = np.where(lam[acc] / 10 >= LAMBDA_START, lam[acc] / 10, 0.0)
        lam[rej] = np.maximum(10 * lam[rej], LAMBDA_START)
        failed[rej] = lam[rej] > 1e30
    return z, done


def _finite(f, g, h):
    """Problems whose cost, gradient and Hessian are finite."""
    return np.isfinite(f) & np.all(np.isfinite(g), axis=1) & np.all(np.isfinite(h), axis=(1, 2))


def _damped_steps(h, g, lam):
    """Solve ``(H + lambda D) delta = -g`` per problem, ``D = diag |H|`` (Marquardt's scaling),
    through the eigenvectors of the scaled Hessian ``D^-1/2 H D^-1/2``; ``lambda`` is raised
    where it would not make the matrix positive definite (twice the smallest eigenvalue's
    distance below zero, at least :data:`LAMBDA_START`). Returns the steps (G, n) and the
    dampings used (G,)."""
    d = np.abs(np.diagonal(h, axis1=1, axis2=2))
    d = np.maximum(d, 1e-12 * np.maximum(np.max(d, axis=1, keepdims=True), 1e-300))
    s = 1.0 / np.sqrt(d)
    vals, vecs = np.linalg.eigh(h * s[:, :, None] * s[:, None, :])
    lowest, highest = vals[:, 0], vals[:, -1]
    indefinite = lowest <= 1e-12 * np.maximum(highest, 0.0)
    lam = np.where(indefinite, np.maximum(lam, 2.0 * np.maximum(-lowest, 0.0) + LAMBDA_START), lam)
    rotated = np.einsum("gji,gj->gi", vecs, s * g) / (vals + lam[:, None])
    return -s * np.einsum("gij,gj->gi", vecs, rotated), lam


#: Deleted problems solved at once by :func:`closed_form_errors`.
CLOSED_FORM_CHUNK = 16384
#: Problems whose closed-form errors are kept (:func:`closed_form_errors`): a calibration that keeps every sample
#: asks for the same problem twice, before screening and for its final fit (30,000 samples: 55 ms each).
KEPT_PROBLEMS = 4
_kept = collections.OrderedDict()
_kept_lock = threading.Lock()


def closed_form_errors(flange2base, centre_in_sensor, centre, mask):
    """:func:`deleted_absolute_orientations`, kept for the last :data:`KEPT_PROBLEMS` problems (by a digest of
    their numbers: a pure function of them); the arguments and return value are its own."""
    arrays = [np.ascontiguousarray(a, float) for a in (flange2base, centre_in_sensor, centre)]
    key = hashlib.blake2b(b"".join([*(a.tobytes() for a in arrays), np.asarray(mask, bool).tobytes(),
                                    repr([a.shape for a in arrays]).encode()]), digest_size=20).digest()
    with _kept_lock:
        if key in _kept:
            _kept.move_to_end(key)
            kept = _kept[key]
            return None if kept is None else kept.copy()
    errors = deleted_absolute_orientations(*arrays, mask)
    with _kept_lock:
        _kept[key] = None if errors is None else errors.copy()
        while len(_kept) > KEPT_PROBLEMS:
            _kept.popitem(last=False)
    return errors


def forget_kept():
    """Drop the kept closed-form errors (:func:`closed_form_errors`): a benchmark's runs start without them."""
    with _kept_lock:
        _kept.clear()


def deleted_absolute_orientations(flange2base, centre_in_sensor, centre, mask):
    """Leave-one-out prediction errors (G,) of the samples in ``mask`` for the unweighted centre model with the
    sphere centre known: each deleted problem is an absolute orientation
    (:func:`handeye.model.fit.global_fit.absolute_orientation`, Kabsch/Umeyama), solved exactly, and sample k's
    error is ``|X_(-k) p_k - q_k|`` (``q`` the centre in the flange frame,
    :func:`~handeye.model.fit.global_fit.centre_targets`; ``R_k`` is orthogonal, so this is
    ``|T1_k X_(-k) p_k - c|``). None where a deleted problem leaves the rotation undetermined (the caller's
    refits decide there). Each deleted problem's cross-covariance is the whole one downdated by its sample (rank
    one), so all of them are one batched SVD, linear in the samples.

    Parameters
    ----------
    flange2base : ndarray, shape (N, 4, 4)
        Carrier motions, mm.
    centre_in_sensor : ndarray, shape (N, 3)
        Measured centres, mm, sensor frame.
    centre : ndarray, shape (3,)
        The sphere centre, mm, in the carrier's target frame.
    mask : ndarray of bool, shape (N,)
        Samples fitted; each is left out in turn.

    Returns
    -------
    ndarray, shape (G,) or None
        Sample k's error (mm) for the G samples in ``mask``, in order; None below four samples or where a deleted
        problem's rotation is not determined.
    """
    keep = np.asarray(mask, bool)
    p, q = np.asarray(centre_in_sensor, float)[keep], centre_targets(flange2base, centre)[keep]
    n = len(p)
    if n < 4:
        return None
    pc, qc = p - p.mean(axis=0), q - q.mean(axis=0)  # about the centroids of every kept sample
    # without sample k the centroids move by -pc_k / (n - 1), and the cross-covariance is a rank-one downdate
    # of the whole one: H_k = H - n / (n - 1) qc_k pc_k^T; sample k's error n / (n - 1) |R_k pc_k - qc_k|
    whole, errors = qc.T @ pc, np.empty(n)
    for a in range(0, n, CLOSED_FORM_CHUNK):  # a few MB of 3x3 matrices at a time, not 300 MB for a million
        k = slice(a, min(a + CLOSED_FORM_CHUNK, n))
        u, singular, vt = np.linalg.svd(whole - n / (n - 1) * np.einsum("ki,kj->kij", qc[k], pc[k]))
        if np.any(singular[:, 1] <= 1e-9 * np.maximum(singular[:, 0], 1e-300)):
            return None
        u[:, :, -1] *= np.sign(np.linalg.det(u @ vt))[:, None]
        rot = u @ vt  # Kabsch's rotation of each deleted problem (global_fit.absolute_orientation's)
        errors[k] = n / (n - 1) * np.linalg.norm(np.einsum("kij,kj->ki", rot, pc[k]) - qc[k], axis=1)
    return errors
