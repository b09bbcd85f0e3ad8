"""Least-squares sphere through a point cloud (geometric fit), and its sensitivities.

The geometric fit minimises the sum of squared radial deviations

    d_k(c, R) = |q_k - c| - R,      J_k = [-(q_k - c)^T / |q_k - c|, -1]    (1 x 4),

by Gauss-Newton with a Levenberg-Marquardt safeguard (Nocedal & Wright, ch. 10.3), started
from the algebraic fit ``|q|^2 = 2 c.q + (R^2 - |c|^2)`` (linear least squares, Kasa's fit in
3-D). Unlike the algebraic fit it is unbiased for noise on a partial sphere, which is what a
laser line sees of it; VDI/VDE 2634 part 2 evaluates its probing errors on this fit.

A cloud that does not fix the four unknowns (all points on one circle: a single profile, or
profiles in parallel planes through one axis) is refused with :class:`SphereFitError`: a
sphere through one circle is any sphere containing it.

Sensitivities. At the fit, ``J^T d = 0``; a perturbation ``dd`` of the deviations (a
calibration or robot error moving the points) moves the fit by
``d beta = -(J^T J)^-1 J^T dd`` (the implicit function theorem), which is how
:mod:`handeye.app.outputs.validate` propagates the calibration's covariance and the robot's
repeatability into the fitted sphere. The points' own scatter gives
``s^2 (J^T J)^-1`` (:meth:`SphereFit.noise_covariance`), which assumes independent points.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from handeye.model.common.errors import InputError

#: The fit's information matrix must be better conditioned than this (relative).
CONDITION_LIMIT = 1e-10


class SphereFitError(InputError):
    """Points that do not determine a sphere."""


@dataclasses.dataclass(frozen=True)
class SphereFit:
    """A fitted sphere.

    Attributes
    ----------
    centre : ndarray, shape (3,)
        mm, in the points' frame.
    radius : float
        mm.
    deviations : ndarray, shape (M,)
        Radial deviation of every point, ``|q - c| - R``, mm.
    normals : ndarray, shape (M, 3)
        Unit vectors from the centre to each point.
    information : ndarray, shape (4, 4)
        ``J^T J`` at the fit (unknowns ``cx, cy, cz, R``).
    iterations : int
    """

    centre: np.ndarray
    radius: float
    deviations: np.ndarray
    normals: np.ndarray
    information: np.ndarray
    iterations: int

    @property
    def rms(self):
        return float(np.sqrt(np.mean(self.deviations ** 2)))

    @property
    def form_error(self):
        """Range of the radial deviations (VDI/VDE 2634-2 probing error form PF), mm."""
        return float(np.ptp(self.deviations))

    def noise_covariance(self):
        """``s^2 (J^T J)^-1`` with ``s^2 = SSR / (M - 4)``: the fit's covariance were the points'
        deviations independent. They are not across one profile (one robot error moves all its
        points): :mod:`handeye.app.outputs.validate` adds that source separately."""
        m = len(self.deviations)
        return float(self.deviations @ self.deviations) / max(m - 4, 1) * np.linalg.inv(self.information)


def algebraic(points):
    """Centre and radius of the algebraic (Kasa) sphere fit; raises SphereFitError."""
    q = np.asarray(points, float)
    if len(q) < 4:
        raise SphereFitError(f"a sphere needs at least 4 points, got {len(q)}")
    mean = q.mean(axis=0)
    d = q - mean  # centred for conditioning
    a = np.hstack([2 * d, np.ones((len(d), 1))])
    sol, *_ = np.linalg.lstsq(a, np.sum(d * d, axis=1), rcond=None)
    c = sol[:3]
    r2 = sol[3] + c @ c
    if not np.isfinite(r2) or r2 <= 0:
        raise SphereFitError("the points do not lie on a sphere (algebraic fit: no real radius)")
    return c + mean, float(np.sqrt(r2))


def _system(q, c, r):
    diff = q - c
    dist = np.linalg.norm(diff, axis=1)
    n = diff / np.where(dist > 0, dist, 1.0)[:, None]
    d = dist - r
    return d, n, np.hstack([-n, -np.ones((len(q), 1))])


def fit(points, max_iter=100, tol=1e-12):
    """Geometric least-squares sphere (module docstring).

    Parameters
    ----------
    points : ndarray, shape (M, 3)
        mm.

    Returns
    -------
    SphereFit
    """
    q = np.asarray(points, float)
    c, r = algebraic(q)
    mean = q.mean(axis=0)
    q0 = q - mean
    c = c - mean
    d, n, jac = _system(q0, c, r)
    info = jac.T @ jac
    lam = 1e-9 * np.trace(info)
    iterations, converged = 0, False
    for iterations in range(1, max_iter + 1):
        info = jac.T @ jac
        _check_information(info)
        grad = jac.T @ d
        step = np.linalg.solve(info + lam * np.diag(np.diag(info)), -grad)
        c_new, r_new = c + step[:3], r + step[3]
        d_new, n_new, jac_new = _system(q0, c_new, r_new)
        if d_new @ d_new <= d @ d:
            c, r, d, n, jac = c_new, r_new, d_new, n_new, jac_new
            lam = max(lam / 10, 1e-15 * np.trace(info))
            if np.linalg.norm(step) <= tol * (1 + abs(r)):
                converged = True
                break
        else:
            lam *= 10
            if lam > 1e10 * np.trace(info):  # no step lowers the cost: stationary to rounding
                converged = np.linalg.norm(grad) <= 1e-8 * (1 + np.linalg.norm(d)) * np.sqrt(np.trace(info))
                break
    if not converged:
        raise SphereFitError(f"the sphere fit did not converge in {iterations} iterations (points far from any "
                             "sphere: a profile of something else in the scan?)")
    info = jac.T @ jac
    _check_information(info)
    return SphereFit(c + mean, float(abs(r)), d, n, info, iterations)


def _check_information(info):
    w = np.linalg.eigvalsh(info)
    if w[0] <= CONDITION_LIMIT * w[-1]:
        raise SphereFitError(
            f"the points do not determine a sphere (information matrix condition {w[-1] / max(w[0], 1e-300):.2g}): "
            "all on one circle? Scan the sphere with profiles from several directions")
