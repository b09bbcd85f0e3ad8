"""The global minimum of the centre model: absolute orientation and a reduced quadratic form.

The unweighted centre-model cost of a sensor pose ``(R, t)`` (sensor in flange) and a sphere
centre ``c`` (base) over flange poses ``(R_i, t_i)`` (flange in base) and sphere centres
``p_i`` measured in the sensor frame is

    F(R, t, c) = 1/2 sum_i |R_i (R p_i + t) + t_i - c|^2 .

**Centre known.** Rotations keep lengths, so with ``q_i = R_i^T (c - t_i)`` (the sphere centre
seen from the flange)

    F = 1/2 sum_i |R p_i + t - q_i|^2 ,

the absolute-orientation problem. Its minimum over t is ``t = q_bar - R p_bar`` (means), and
then ``2 F = const - 2 tr(R^T H)`` with ``H = sum_i (q_i - q_bar)(p_i - p_bar)^T``. With the
SVD ``H = U S V^T``, the maximum of ``tr(R^T H)`` over SO(3) is at
``R = U diag(1, 1, det(U V^T)) V^T`` (Kabsch 1976; Umeyama 1991; Arun, Huang & Blostein
1987). The other stationary points of ``tr(R^T H)`` on SO(3) are ``U D V^T`` with the other
sign patterns D of the same determinant; when the two smallest signed singular values
differ they are saddles or the maximum, never minima. So F has one local minimum, the SVD
solution: a solver that ends elsewhere did not end at a minimum, and no next-best minimum
exists (:attr:`Minimum.cost` of the only entry).

**Centre unknown.** F is linear least squares in ``s = (t, c)`` for a fixed R: with
``r = vec R`` (row-major), ``e = M r + B s + d`` where block i of M is ``R_i (I_3 kron p_i^T)``,
of B ``[R_i, -I_3]`` and of d ``t_i``. Eliminating s (the normal equations of s, a 6 x 6
system) leaves a quadratic form in r,

    2 F(R) = r^T Q r + 2 g^T r + k,
    Q = M^T M - M^T B (B^T B)^-1 B^T M,  g = M^T d - M^T B (B^T B)^-1 B^T d,

accumulated in one pass over the data (9 x 9, 9 x 6 and 6 x 6 sums: the cost of a calibration
of any size is then independent of N). Minimising a quadratic form over SO(3) has local
minima in general; it is done here by covering SO(3) with :data:`COVER` rotations (a
super-Fibonacci spiral, Alexa 2022: deterministic and nearly uniform), evaluating the form at
each (one matrix product), and polishing the lowest :data:`SEEDS` points that lie at least
:data:`SEED_SEPARATION_DEG` apart by damped Newton on SO(3) with the exact Riemannian Hessian
(shifted to positive definite where it is not). Distinct ends are the local minima found,
lowest first. The cover's points lie about 11 degrees from their nearest neighbour (every
rotation within about 13 degrees of one), while the calibration's basins span tens of
degrees: every such basin holds cover points, and the lowest points of up to :data:`SEEDS`
basins more than the separation apart are polished. The argument is a dense search, stated
as such, not a certificate (against a brute force of 2,000 random starts it found the global
minimum in 160 of 160 cells).
"""
from __future__ import annotations

import dataclasses
import functools

import numpy as np

from handeye.model.chain import conventions
from handeye.model.common.errors import InputError
from handeye.model.common.rotation import matrix_from_rotvec

#: Rotations covering SO(3) for the centre-free search.
COVER = 4096
#: Cover points polished by Newton on SO(3) ...
SEEDS = 12
#: ... at least this far apart (degrees).
SEED_SEPARATION_DEG = 30.0
#: Two ends within this angle (degrees) and relative cost are one minimum.
SAME_DEG, SAME_COST = 0.5, 1e-7


class GlobalFitError(InputError):
    """The data do not determine the centre model (no rotation or no spread of the centres)."""


@dataclasses.dataclass(frozen=True)
class Minimum:
    """A local minimum of the centre model.

    Attributes
    ----------
    sensor2flange : ndarray, shape (4, 4)
        Sensor frame in the flange frame, mm.
    centre : ndarray, shape (3,)
        Sphere centre in the robot base, mm.
    cost : float
        ``1/2 sum |e_i|^2``, mm^2.
    reached : int
        Seeds that ended here.
    """

    sensor2flange: np.ndarray
    centre: np.ndarray
    cost: float
    reached: int = 1


@dataclasses.dataclass(frozen=True)
class CentreMinima:
    """Every local minimum the search found, lowest first, and how it was found."""

    minima: tuple
    method: str
    starts: int

    @property
    def best(self):
        return self.minima[0]

    @property
    def next_best_cost(self):
        return self.minima[1].cost if len(self.minima) > 1 else None


def absolute_orientation(p, q, weights=None):
    """The rotation and translation minimising ``sum w_i |R p_i + t - q_i|^2`` (Kabsch/Umeyama).

    Parameters
    ----------
    p, q : array_like, shape (N, 3)
        Corresponding points, mm (p in the source frame, q in the target frame).
    weights : array_like, shape (N,), optional
        Non-negative weights (default all 1): the weighted centroids and cross-covariance.

    Returns
    -------
    transform : ndarray, shape (4, 4)
        Source in target.
    singular_values : ndarray, shape (3,)
        Of the cross-covariance; the last two zero: the rotation is not determined.
    """
    p, q = np.asarray(p, float), np.asarray(q, float)
    w = np.ones(len(p)) if weights is None else np.asarray(weights, float)
    pc, qc = w @ p / w.sum(), w @ q / w.sum()
    h = (w[:, None] * (q - qc)).T @ (p - pc)
    u, s, vt = np.linalg.svd(h)
    u[:, -1] *= np.sign(np.linalg.det(u @ vt))
    rot = u @ vt  # U diag(1, 1, det(U V^T)) V^T: Kabsch's solution (rotation.nearest_rotation's)
    out = np.eye(4)
    out[:3, :3], out[:3, 3] = rot, qc - rot @ pc
    return out, s


def centre_targets(flange2base, sphere_centre):
    """``q_i = R_i^T (c - t_i)``: where sample i's centre must lie in the flange frame, mm (N, 3).

    With the centre known, ``|R_i (X p_i) + t_i - c| = |X p_i - q_i|`` (R_i is orthogonal), so
    the centre model is the absolute orientation of ``p`` onto ``q``: weighted too."""
    f2b = np.asarray(flange2base, float)
    return np.einsum("nba,nb->na", f2b[:, :3, :3], np.asarray(sphere_centre, float) - f2b[:, :3, 3])


def centre_cost(flange2base, centre_in_sensor, sensor2flange, centre):
    """``1/2 sum_i |R_i (R p_i + t) + t_i - c|^2`` (mm^2) of a pose and centre."""
    f2b = np.asarray(flange2base, float)
    p = np.asarray(centre_in_sensor, float)
    x = np.asarray(sensor2flange, float)
    in_flange = p @ x[:3, :3].T + x[:3, 3]
    e = np.einsum("nab,nb->na", f2b[:, :3, :3], in_flange) + f2b[:, :3, 3] - np.asarray(centre, float)
    return 0.5 * float(np.sum(e * e))


def centre_minima(flange2base, centre_in_sensor, sphere_centre=None):
    """The local minima of the unweighted centre model (module docstring), lowest first.

    Parameters
    ----------
    flange2base : array_like, shape (N, 4, 4)
        Flange in robot base, mm.
    centre_in_sensor : array_like, shape (N, 3)
        Sphere centres measured in the sensor frame, mm.
    sphere_centre : array_like, shape (3,), optional
        Known centre in the base, mm; None: estimated with the pose.

    Returns
    -------
    CentreMinima

    Raises
    ------
    GlobalFitError
        When the data do not determine the rotation (centres at one sensor point, no rotation).
    """
    f2b = np.asarray(flange2base, float)
    p = np.asarray(centre_in_sensor, float)
    if sphere_centre is not None:
        c = np.asarray(sphere_centre, float)
        x, s = absolute_orientation(p, centre_targets(f2b, c))
        if s[1] <= 1e-12 * max(s[0], 1e-300):
            raise GlobalFitError("the centres seen from the flange do not span a plane: the rotation is not determined")
        best = Minimum(x, c.copy(), centre_cost(f2b, p, x, c))
        return CentreMinima((best,), "absolute orientation (Kabsch/Umeyama SVD): the unique local minimum", 1)
    minima = sorted((_complete(f2b, p, rot, n) for rot, n in _search(reduced_form(f2b, p))), key=lambda m: m.cost)
    return CentreMinima(tuple(minima), f"(t, c) eliminated in closed form; {COVER} rotations covering SO(3), "
                                       f"{SEEDS} polished by Newton on SO(3)", SEEDS)


@dataclasses.dataclass(frozen=True)
class ReducedForm:
    """``2 F(R) = r^T Q r + 2 g^T r + k`` with ``r = vec R`` row-major (module docstring)."""

    q: np.ndarray
    g: np.ndarray
    k: float

    def value(self, rot):
        """2F of rotations (..., 3, 3)."""
        r = np.asarray(rot, float).reshape(np.shape(rot)[:-2] + (9,))
        return np.einsum("...i,ij,...j->...", r, self.q, r) + 2 * r @ self.g + self.k


def reduced_form(flange2base, centre_in_sensor):
    """The quadratic form in vec R left when (t, c) are eliminated (module docstring)."""
    f2b = np.asarray(flange2base, float)
    p = np.asarray(centre_in_sensor, float)
    n = len(p)
    rot, t = f2b[:, :3, :3], f2b[:, :3, 3]
    m = np.einsum("nab,nk->nabk", rot, p).reshape(n, 3, 9)  # R_i (I kron p_i^T)
    b = np.concatenate([rot, np.broadcast_to(-np.eye(3), (n, 3, 3))], axis=2)  # (n, 3, 6)
    mtm = np.einsum("nai,naj->ij", m, m)
    mtb = np.einsum("nai,naj->ij", m, b)
    btb = np.einsum("nai,naj->ij", b, b)
    mtd, btd, dtd = np.einsum("nai,na->i", m, t), np.einsum("nai,na->i", b, t), float(np.sum(t * t))
    if np.linalg.cond(btb) > 1e12:
        raise GlobalFitError("the flange never rotates: the sensor offset and the sphere centre are not separable")
    sol = np.linalg.solve(btb, np.column_stack([mtb.T, btd]))
    q = mtm - mtb @ sol[:, :9]
    q = 0.5 * (q + q.T)
    g = mtd - mtb @ sol[:, 9]
    return ReducedForm(q, g, float(dtd - btd @ sol[:, 9]))


def super_fibonacci(n):
    """``n`` unit quaternions (w, x, y, z) spread nearly uniformly over SO(3) (Alexa 2022)."""
    phi, psi = np.sqrt(2.0), 1.533751168755204288118041
    s = np.arange(n) + 0.5
    r, big = np.sqrt(s / n), np.sqrt(1.0 - s / n)
    alpha, beta = 2 * np.pi * s / phi, 2 * np.pi * s / psi
    return np.column_stack([r * np.sin(alpha), r * np.cos(alpha), big * np.sin(beta), big * np.cos(beta)])


def _angle_deg(a, b):
    """Angles (deg) between rotations a (..., 3, 3) and b (3, 3)."""
    cos = (np.einsum("...ij,ij->...", a, b) - 1.0) / 2.0
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


@functools.lru_cache(maxsize=1)
def _cover():
    """The :data:`COVER` rotations (K, 3, 3) of the super-Fibonacci cover, made once (read-only)."""
    cover = conventions.matrix_from("abb", super_fibonacci(COVER))  # unit quaternions w, x, y, z
    cover.setflags(write=False)
    return cover


def _seeds(form):
    cover = _cover()
    values = form.value(cover)
    picked = []
    for k in np.argsort(values):
        if not picked or np.all(_angle_deg(cover[picked], cover[k]) >= SEED_SEPARATION_DEG):
            picked.append(k)
            if len(picked) == SEEDS:
                break
    return cover[picked]


def _skew_basis():
    e = np.zeros((3, 3, 3))
    e[0, 2, 1], e[0, 1, 2] = 1, -1
    e[1, 0, 2], e[1, 2, 0] = 1, -1
    e[2, 1, 0], e[2, 0, 1] = 1, -1
    return e


def _derivatives(form, rot):
    """2F, its gradient and exact Hessian in w for R exp([w]x) at w = 0, for rotations (K, 3, 3)."""
    k = len(rot)
    r = rot.reshape(k, 9)
    grad_r = r @ form.q + form.g  # (Qr + g)
    a = np.einsum("kab,ibc->kiac", rot, _skew_basis()).reshape(k, 3, 9)  # columns vec(R [e_i]x)
    gmat = grad_r.reshape(k, 3, 3)
    value = np.einsum("ki,ij,kj->k", r, form.q, r) + 2 * r @ form.g + form.k
    grad = 2 * np.einsum("kia,ka->ki", a, grad_r)
    gtr = np.einsum("kba,kbc->kac", gmat, rot)  # G^T R
    sym = 0.5 * (gtr + np.swapaxes(gtr, 1, 2))
    trace = np.trace(gtr, axis1=1, axis2=2)
    hess = 2 * (np.einsum("kia,ab,kjb->kij", a, form.q, a) + sym - trace[:, None, None] * np.eye(3))
    return value, grad, hess


def _newton(form, rot, iterations=60):
    """Damped Newton on SO(3) from every rotation (K, 3, 3); returns the ends."""
    rot = rot.copy()
    mu = np.full(len(rot), 1e-3)
    floor = np.zeros(len(rot), bool)  # at a minimum to rounding: no step lowers the value any more
    for _ in range(iterations):
        value, grad, hess = _derivatives(form, rot)
        eig = np.linalg.eigvalsh(hess)
        scale = np.maximum(np.abs(eig).max(axis=1), 1e-12)
        relative = np.abs(grad).max(axis=1) / scale
        if np.all((relative <= 1e-10) | floor):
            break
        shift = 1.01 * np.maximum(0.0, -eig[:, 0]) + mu * scale  # positive definite: a descent direction
        step = -np.linalg.solve(hess + shift[:, None, None] * np.eye(3), grad[..., None])[..., 0]
        trial = rot @ matrix_from_rotvec(step)
        better = form.value(trial) <= value
        rot[better] = trial[better]
        mu = np.where(better, np.maximum(mu / 10, 1e-12), mu * 10)
        # thesis-real's 2F is 3.7e6: one seed's gradient stalls at 3e-10 of the curvature, every step rejected,
        # and the batch ran all 60 iterations for it (12 ms of a 1 ms search)
        floor = ~better & (relative <= 1e-7) & (eig[:, 0] > 0)
    return rot


def _search(form):
    """Distinct local minima (rotation, how many seeds reached it) of the reduced form."""
    ends = _newton(form, _seeds(form))
    values = form.value(ends)
    out = []
    for k in np.argsort(values):
        for j, (rot, count) in enumerate(out):
            if _angle_deg(ends[k], rot) < SAME_DEG and abs(values[k] - form.value(rot)) <= SAME_COST * max(
                    1.0, abs(values[k])) + 1e-9:
                out[j] = (rot, count + 1)
                break
        else:
            out.append((ends[k], 1))
    return out


def _complete(f2b, p, rot, reached):
    """The minimum with (t, c) re-solved for the rotation ``rot``."""
    n = len(p)
    rots, t = f2b[:, :3, :3], f2b[:, :3, 3]
    lhs = np.concatenate([rots, np.broadcast_to(-np.eye(3), (n, 3, 3))], axis=2).reshape(3 * n, 6)
    s, *_ = np.linalg.lstsq(lhs, (-t - np.einsum("nab,bc,nc->na", rots, rot, p)).ravel(), rcond=None)
    x = np.eye(4)
    x[:3, :3], x[:3, 3] = rot, s[:3]
    return Minimum(x, s[3:6], centre_cost(f2b, p, x, s[3:6]), reached)
