"""Circle fits to a laser profile's (x, z) points, and the sphere centre from a circle.

A laser line cuts the sphere (radius R) in a circle of radius ``r = sqrt(R^2 - y^2)``, where y
is the sensor-y coordinate of the sphere centre (the laser plane is the sensor's y = 0). The
sensor sees an arc of it. Three fits:

* ``kasa`` -- algebraic least squares of ``x^2 + z^2 + a x + b z + c = 0`` (the seed's C15).
  Minimises a distance weighted by the radius, which on short arcs shrinks the circle: biased.
* ``hyper`` -- Al-Sharadqah & Chernov (2009) "Hyper" algebraic fit (SVD form): the same
  algebraic distance under a constraint chosen so that the essential bias vanishes.
* ``geometric`` -- orthogonal-distance fit, minimising ``sum (|p_i - c| - r)^2`` (maximum
  likelihood for isotropic Gaussian noise), by Levenberg-Marquardt from the Hyper estimate.

``sphere_centre_from_circle`` completes the centre with the seed's (6-26, 6-27):
``y = side * sqrt(R^2 - r^2)``; its error grows like ``(r / |y|) sigma_r`` near the equator.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from handeye.model.common.errors import InputError

FITS = ("kasa", "hyper", "geometric")


@dataclasses.dataclass(frozen=True)
class Circle:
    """A fitted circle in the laser plane: centre (x, z) and radius r, mm."""

    x: float
    z: float
    r: float


class CircleFitError(InputError):
    """Too few or degenerate points (e.g. collinear) for a circle."""


def _points(x, z):
    x = np.asarray(x, dtype=float).ravel()
    z = np.asarray(z, dtype=float).ravel()
    if x.shape != z.shape or x.size < 3:
        raise CircleFitError(f"a circle needs at least 3 points, got {x.size}")
    return x, z


def kasa(x, z):
    """Kasa's algebraic fit (the seed's C15)."""
    x, z = _points(x, z)
    a = np.column_stack([x, z, np.ones_like(x)])
    coef, _, rank, _ = np.linalg.lstsq(a, -(x**2 + z**2), rcond=None)
    if rank < 3:
        raise CircleFitError("points are degenerate (collinear or repeated)")
    xc, zc = -0.5 * coef[0], -0.5 * coef[1]
    r2 = xc**2 + zc**2 - coef[2]
    if r2 <= 0:
        raise CircleFitError("no real circle fits these points")
    return Circle(float(xc), float(zc), float(np.sqrt(r2)))


def hyper(x, z):
    """Al-Sharadqah & Chernov's Hyper fit, SVD form (unbiased to second order)."""
    x, z = _points(x, z)
    xm, zm = x.mean(), z.mean()
    u, v = x - xm, z - zm
    w = u**2 + v**2
    m = np.column_stack([w, u, v, np.ones_like(u)])
    # three points (the fewest a profile may have): m is 3 x 4, its null vector the exact circle; the
    # fourth singular value, zero, is not returned (it was indexed: IndexError, exit 3; issue 40's fuzz)
    _, s, vt = np.linalg.svd(m, full_matrices=len(m) < 4)
    if s[2] < 1e-12 * s[0]:
        raise CircleFitError("points are degenerate (collinear or repeated)")
    if len(s) < 4 or s[3] < 1e-12 * s[0]:
        a = vt[3]
    else:
        mean = m.mean(axis=0)
        n_mat = np.array([[8 * mean[0], 4 * mean[1], 4 * mean[2], 2], [4 * mean[1], 1, 0, 0],
                          [4 * mean[2], 0, 1, 0], [2, 0, 0, 0]])
        y = vt.T @ np.diag(s) @ vt
        evals, evecs = np.linalg.eig(y @ np.linalg.inv(n_mat) @ y)
        evals = np.real(evals)
        order = np.argsort(evals)
        k = next(i for i in order if evals[i] > 0)
        a = np.linalg.solve(y, np.real(evecs[:, k]))
    if abs(a[0]) < 1e-300:
        raise CircleFitError("points are degenerate (a line)")
    xc = -a[1] / (2 * a[0]) + xm
    zc = -a[2] / (2 * a[0]) + zm
    r = np.sqrt(a[1] ** 2 + a[2] ** 2 - 4 * a[0] * a[3]) / (2 * abs(a[0]))
    return Circle(float(xc), float(zc), float(r))


def geometric(x, z, start=None, max_iter=100):
    """Orthogonal-distance fit by Levenberg-Marquardt (from ``start`` or the Hyper fit)."""
    from handeye import solvers

    x, z = _points(x, z)
    c0 = start or hyper(x, z)

    def residual(p):
        return np.hypot(x - p[0], z - p[1]) - p[2]

    def jacobian(p):
        d = np.maximum(np.hypot(x - p[0], z - p[1]), 1e-300)
        return np.column_stack([-(x - p[0]) / d, -(z - p[1]) / d, -np.ones_like(x)])

    res = solvers.solve(solvers.Problem(n=3, residual=residual, jacobian=jacobian), [c0.x, c0.z, c0.r], "lm",
                        {"max_iter": max_iter})
    if not np.all(np.isfinite(res.x)):
        raise CircleFitError("the geometric fit diverged")
    return Circle(float(res.x[0]), float(res.x[1]), float(abs(res.x[2])))


def fit_circle(x, z, method="hyper"):
    """Fit a circle with one of :data:`FITS`."""
    if method not in FITS:
        raise ValueError(f"unknown circle fit {method!r}; choose one of {FITS}")
    return {"kasa": kasa, "hyper": hyper, "geometric": geometric}[method](x, z)


def sphere_centre_from_circle(circle, radius, side=-1):
    """Sphere centre in the sensor frame from a circle in the laser plane (seed 6-26, 6-27).

    Raises
    ------
    CircleFitError
        When the circle is larger than the sphere (``r > R``): no real y.
    """
    if circle.r > radius:
        raise CircleFitError(f"fitted circle radius {circle.r:.3f} mm exceeds the sphere radius {radius:.3f} mm")
    return np.array([circle.x, side * np.sqrt(radius**2 - circle.r**2), circle.z])


def distance_jacobian(x, z, fitted):
    """Orthogonal distances ``|p_i - c| - r`` (K,) of points from a circle and their Jacobian
    (K, 3) with respect to ``(xc, zc, r)``."""
    x, z = _points(x, z)
    dx, dz = x - fitted.x, z - fitted.z
    d = np.maximum(np.hypot(dx, dz), 1e-300)
    return d - fitted.r, np.column_stack([-dx / d, -dz / d, -np.ones_like(x)])


def circle_covariance(x, z, fitted, sigma=None):
    """Covariance (3, 3) of ``(xc, zc, r)`` of a circle fitted to points, from the geometric
    model: ``s^2 (J^T J)^-1`` with J the Jacobian of the orthogonal distances and ``s^2`` the
    given point variance ``sigma^2`` or, by default, the distances' mean square (K - 3 degrees
    of freedom)."""
    res, j = distance_jacobian(x, z, fitted)
    s2 = float(res @ res) / max(len(res) - 3, 1) if sigma is None else sigma**2
    return s2 * np.linalg.pinv(j.T @ j)


def centre_jacobian(r, y, side=-1):
    """d(sphere centre x, y, z) / d(circle xc, zc, r), shape ``r.shape + (3, 3)``, of circles of radius ``r`` whose
    centres' |y| is ``y`` (mm; ``inf`` where y has no derivative): ``y = side sqrt(R^2 - r^2)`` makes
    ``dy/dr = -side r / |y|``."""
    r, y = np.broadcast_arrays(np.asarray(r, float), np.asarray(y, float))
    out = np.zeros(r.shape + (3, 3))
    out[..., 0, 0], out[..., 2, 1], out[..., 1, 2] = 1.0, 1.0, -side * r / y
    return out


def centre_covariance(fitted, cov_circle, radius, side=-1):
    """Covariance (3, 3) of the sphere centre in the sensor ``(x, y, z)`` propagated from the
    circle's (:func:`centre_jacobian`): the y error grows like ``(r / |y|) sigma_r`` as the laser plane
    nears the equator."""
    a = centre_jacobian(fitted.r, np.sqrt(max(radius**2 - fitted.r**2, 1e-12)), side)
    return a @ cov_circle @ a.T
