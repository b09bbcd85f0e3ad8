"""A 3-D sensor's point cloud of the sphere, one per pose: its centre fitted with the centre's covariance, cleaned.

A structured-light camera or a 3-D scanner sees the cap of the sphere that faces it (points
``q_k`` in the sensor frame, mm) and, often, more: speckle, a piece of the table or of the
sphere's stand. Cleaning and fitting go as a profile's do (:mod:`handeye.model.geometry.profile_clean`),
one dimension up:

1. **Fast path.** The geometric least-squares sphere of every point (:func:`handeye.model.geometry.sphere.fit`,
   radius free); when its robust sd (``1.4826 MAD``, at least :data:`~handeye.model.geometry.profile_clean.SCALE_FLOOR_MM`)
   is at most :data:`~handeye.model.geometry.profile_clean.FAST_SCALE_MM` and every point lies within
   :data:`~handeye.model.geometry.profile_clean.K_SD` of it, nothing is dropped.
2. **RANSAC** over :data:`CANDIDATES` minimal spheres through 4 points (a generator seeded by the
   cloud's bytes: deterministic), each scored by the points within :data:`BAND_MM` of it
   (with a known diameter only spheres within :data:`~handeye.model.geometry.profile_clean.RADIUS_TOL`
   of it count), then **Tukey's biweight** by reweighted Gauss-Newton from the best one; points
   beyond ``K_SD`` robust sd are dropped ("off the sphere").
3. **The fit** of the points kept: Gauss-Newton on ``d_k = |q_k - c| - r`` with the radius held at
   the stated one (unknowns ``c``) or free (``c, r``); the covariance of the unknowns is
   ``s^2 (J^T J)^-1`` with ``s^2 = SSR / (m - p)`` (independent points, the fit's own scatter),
   and the centre's is its 3 x 3 block: what weighs the centre in the calibration
   (:func:`handeye.model.datasets.observations.profile_covariance`).

A cloud that is no sphere is refused with :class:`CloudError`, never fitted: fewer than
:data:`MIN_POINTS` points; points that lie on a plane about as well as on the sphere
(a plane, or a cap too flat to fix the centre: the plane's robust sd at most :data:`PLANE_RATIO`
times the sphere's); a cap narrower than :data:`MIN_CAP_DEG` seen from the centre; no sphere
holding :data:`MIN_FRACTION` of the points; with a stated diameter, a cloud whose own fitted
diameter differs from it by more than :data:`DIAMETER_SD` of its sd and
:data:`~handeye.model.geometry.profile_clean.RADIUS_TOL` of it (a wrong diameter, or no sphere of it).
"""
from __future__ import annotations

import dataclasses

import numpy as np

from handeye.model.common.errors import InputError
from handeye.model.geometry import profile_clean, sphere

#: A cloud needs at least this many points (after NaN rows are dropped).
MIN_POINTS = 20
#: Points kept must be at least this fraction of the cloud's.
MIN_FRACTION = 0.2
#: Half-width of the band that scores a RANSAC sphere, mm.
BAND_MM = profile_clean.BAND_MM
#: Minimal spheres drawn (with half the points on the sphere, one of 4 inliers with probability 1/16:
#: the chance that none of 512 is, 4e-15).
CANDIDATES = 512
#: Candidates are scored on at most this many points drawn at random.
SCORE_POINTS = 5000
#: The plane's robust sd over the sphere's below which the cloud is a plane (or too flat a cap).
PLANE_RATIO = 3.0
#: The smallest cap (half-angle seen from the centre, degrees) whose centre is fitted.
MIN_CAP_DEG = 10.0
#: With a stated diameter, the cloud's own diameter may differ from it by this many sd (and RADIUS_TOL).
DIAMETER_SD = 5.0


class CloudError(InputError):
    """A point cloud that is no sphere (module docstring): its row cannot give a centre."""


@dataclasses.dataclass(frozen=True)
class CloudFit(profile_clean.Drops):
    """The sphere fitted to one cloud.

    Attributes
    ----------
    centre : ndarray, shape (3,)
        Sphere centre, sensor frame, mm.
    covariance : ndarray, shape (3, 3)
        The centre's covariance from the fit, sensor frame, mm^2.
    radius : float
        The radius fitted (or held at the stated one), mm.
    radius_sd : float
        Its sd, mm; 0 where held.
    free_diameter : float
        The diameter of the fit with the radius free, mm (the stated one checked against it).
    radius_held : bool
    kept : ndarray of bool, shape (K,)
        The points on the sphere.
    n_points : int
    dropped : tuple of (str, int)
        ``('off the sphere', n)`` when points were dropped.
    scale_mm : float
        Robust sd of the kept points' radial deviations, mm.
    rms_mm : float
        RMS of the kept points' radial deviations from the fit, mm.
    cap_deg : float
        Half-angle of the cap the kept points cover, seen from the centre, degrees.
    """

    centre: np.ndarray
    covariance: np.ndarray
    radius: float
    radius_sd: float
    free_diameter: float
    radius_held: bool
    kept: np.ndarray
    n_points: int
    dropped: tuple
    scale_mm: float
    rms_mm: float
    cap_deg: float

    @property
    def status(self):
        return "cleaned" if self.n_dropped else "clean"

    def to_dict(self):
        return {"points": self.n_points, "dropped": self.n_dropped, "status": self.status,
                "reasons": {name: n for name, n in self.dropped if n}, "scale_mm": float(self.scale_mm),
                "diameter_mm": 2 * self.radius, "diameter_sd_mm": 2 * self.radius_sd, "radius_held": self.radius_held,
                "cap_deg": self.cap_deg, "centre_sd_mm": np.sqrt(np.diag(self.covariance)).tolist()}


def _deviations(q, c, r):
    diff = q - c
    dist = np.linalg.norm(diff, axis=1)
    return dist - r, diff / np.maximum(dist, 1e-300)[:, None]


def _minimal_spheres(q, rng):
    """Spheres ``(M, 4: c, r)`` through :data:`CANDIDATES` random quadruples (degenerate ones dropped)."""
    idx = np.stack([rng.choice(len(q), 4, replace=False) for _ in range(CANDIDATES)])
    mean = q.mean(axis=0)
    p = q[idx] - mean  # (M, 4, 3)
    a = np.concatenate([2 * p, np.ones(p.shape[:2] + (1,))], axis=2)
    b = np.sum(p * p, axis=2)
    ok = np.abs(np.linalg.det(a)) > 1e-9 * np.max(np.abs(a), axis=(1, 2)) ** 4
    if not ok.any():
        return np.zeros((0, 4))
    sol = np.linalg.solve(a[ok], b[ok][..., None])[..., 0]
    r2 = sol[:, 3] + np.sum(sol[:, :3] ** 2, axis=1)
    good = r2 > 0
    return np.column_stack([sol[good, :3] + mean, np.sqrt(r2[good])])


def ransac(q, radius, rng):
    """The minimal sphere ``(c (3,), r)`` holding the most points within :data:`BAND_MM` (of spheres of
    ``radius`` within RADIUS_TOL where ``radius`` is given), and that count; ``(None, 0)`` without one."""
    cand = _minimal_spheres(q, rng)
    if radius is not None and len(cand):
        cand = cand[np.abs(cand[:, 3] - radius) <= radius * profile_clean.RADIUS_TOL + BAND_MM]
    if not len(cand):
        return None, 0
    pts, scale = q, 1.0
    if len(q) > SCORE_POINTS:
        pts, scale = q[np.sort(rng.choice(len(q), SCORE_POINTS, replace=False))], len(q) / SCORE_POINTS
    score = np.zeros(len(cand))
    for k in range(0, len(cand), 64):  # memory bounded: 64 candidates x SCORE_POINTS at a time
        c = cand[k:k + 64]
        dist = np.linalg.norm(pts[None] - c[:, None, :3], axis=2)
        score[k:k + 64] = np.sum(np.abs(dist - c[:, 3:]) < BAND_MM, axis=1)
    best = int(np.argmax(score))
    return (cand[best, :3], float(cand[best, 3])), int(round(scale * score[best]))


def _gauss_newton(q, c, r, weights=None, free_radius=True, max_iter=50):
    """Weighted Gauss-Newton on ``|q - c| - r`` from ``(c, r)``: ``(c, r, deviations, J)``; ``J`` is
    ``(K, 4)`` or ``(K, 3)`` (radius held)."""
    w = np.ones(len(q)) if weights is None else weights
    c, r = np.asarray(c, float).copy(), float(r)
    for _ in range(max_iter):
        d, n = _deviations(q, c, r)
        jac = np.hstack([-n, -np.ones((len(q), 1))]) if free_radius else -n
        try:
            step = np.linalg.solve((jac * w[:, None]).T @ jac, -(jac * w[:, None]).T @ d)
        except np.linalg.LinAlgError:
            break
        c = c + step[:3]
        r = r + (step[3] if free_radius else 0.0)
        if np.max(np.abs(step)) < 1e-12 * (1.0 + abs(r)):
            break
    d, n = _deviations(q, c, r)
    return c, r, d, (np.hstack([-n, -np.ones((len(q), 1))]) if free_radius else -n)


def _tukey(q, c, r, free_radius):
    """Tukey's biweight fit from ``(c, r)``: ``(c, r, s)`` with ``s`` the robust scale of the deviations."""
    for _ in range(30):
        d, _ = _deviations(q, c, r)
        s = profile_clean.robust_scale(d)
        u = d / (profile_clean.TUKEY_C * s)
        w = np.where(np.abs(u) < 1, (1 - u**2) ** 2, 0.0)
        if np.count_nonzero(w) < 4:
            break
        c_new, r_new, _, _ = _gauss_newton(q, c, r, w, free_radius, max_iter=1)
        moved = np.max(np.abs(c_new - c)) + abs(r_new - r)
        c, r = c_new, r_new
        if moved < 1e-10 * (1.0 + abs(r)):
            break
    return c, r, profile_clean.robust_scale(_deviations(q, c, r)[0])


def _plane_scale(q):
    """Robust sd (mm) of the points' distances from their best plane (least squares)."""
    centred = q - q.mean(axis=0)
    normal = np.linalg.svd(centred, full_matrices=False)[2][-1]
    return 1.4826 * float(np.median(np.abs(centred @ normal - np.median(centred @ normal))))


def _inliers(q, radius):
    """``(c, r, s, kept)``: the robust sphere (radius free, or near ``radius``) and the points within K_SD s."""
    fast = _fast(q)
    if fast is not None:
        return fast
    best, n_best = ransac(q, radius, profile_clean.seeded(q))
    if best is None or n_best < MIN_FRACTION * len(q):
        plane = _plane_scale(q)
        if plane <= BAND_MM:
            raise CloudError(f"its points lie on a plane (robust sd {plane:.3g} mm from it): no sphere")
        raise CloudError(f"no sphere{_of(radius)} holds {MIN_FRACTION:.0%} of its {len(q):,} points within {BAND_MM:g} mm "
                         "(scattered points, or the sphere out of view)")
    c, r, s = _tukey(q, best[0], best[1], True)
    return c, r, s, np.abs(_deviations(q, c, r)[0]) <= profile_clean.K_SD * s


def _of(radius):
    return "" if radius is None else f" of diameter near {2 * radius:g} mm"


def _fast(q):
    """The least-squares sphere of every point when every point lies within K_SD robust sd of it, else None."""
    try:
        fitted = sphere.fit(q)
    except sphere.SphereFitError:
        return None
    s = max(1.4826 * float(np.median(np.abs(fitted.deviations))), profile_clean.SCALE_FLOOR_MM)
    if s > profile_clean.FAST_SCALE_MM or np.max(np.abs(fitted.deviations)) > profile_clean.K_SD * s:
        return None
    return fitted.centre, fitted.radius, s, np.ones(len(q), bool)


def _cap_deg(q, c):
    """Half-angle (degrees) of the cap the points cover, seen from ``c``: the widest angle from their mean direction."""
    n = _deviations(q, c, 0.0)[1]
    axis = n.mean(axis=0)
    axis /= max(np.linalg.norm(axis), 1e-300)
    return float(np.degrees(np.arccos(np.clip(np.min(n @ axis), -1.0, 1.0))))


def fit_cloud(points, radius=None):
    """The sphere of one cloud, cleaned, with its centre's covariance (module docstring).

    Parameters
    ----------
    points : array_like, shape (K, 3)
        The cloud's points, sensor frame, mm (finite).
    radius : float, optional
        The sphere's stated radius, mm: held in the fit; None: fitted (radius free).

    Returns
    -------
    CloudFit

    Raises
    ------
    CloudError
        A cloud that is no sphere (module docstring), in one sentence.
    """
    q = np.asarray(points, float).reshape(-1, 3)
    if len(q) < MIN_POINTS:
        raise CloudError(f"{len(q)} points: a sphere's centre is fitted from at least {MIN_POINTS}")
    c, r, s, kept = _inliers(q, radius)
    if kept.sum() < max(MIN_POINTS, MIN_FRACTION * len(q)):
        raise CloudError(f"only {int(kept.sum())} of its {len(q):,} points lie on a sphere{_of(radius)}")
    inner = q[kept]
    plane = _plane_scale(inner)
    if plane <= PLANE_RATIO * s:
        raise CloudError(f"its points lie on a plane (robust sd {plane:.3g} mm from it, {s:.3g} mm from the best sphere): a "
                         "plane, or a cap too flat to fix a sphere's centre")
    cap = _cap_deg(inner, c)
    if cap < MIN_CAP_DEG:
        raise CloudError(f"the cap seen spans {cap:.1f} deg from the centre (at least {MIN_CAP_DEG:g}): too small to fix "
                         "the sphere's centre")
    free = _final(inner, c, r, True)
    if radius is None:
        return _record(free, free, kept, len(q), s, cap)
    diameter_sd = 2 * float(np.sqrt(free[3][3, 3]))
    if abs(2 * free[1] - 2 * radius) > max(DIAMETER_SD * diameter_sd, 2 * radius * profile_clean.RADIUS_TOL):
        raise CloudError(f"its sphere's diameter is {2 * free[1]:.4g} +- {diameter_sd:.2g} mm, not the stated "
                         f"{2 * radius:g} mm: a wrong diameter, or no sphere of it")
    return _record(_final(inner, free[0], radius, False), free, kept, len(q), s, cap)


def _final(q, c, r, free_radius):
    """``(c, r, deviations, covariance of the unknowns)`` of the unweighted fit of the kept points."""
    c, r, d, jac = _gauss_newton(q, c, r, None, free_radius)
    info = jac.T @ jac
    w = np.linalg.eigvalsh(info)
    if w[0] <= sphere.CONDITION_LIMIT * w[-1]:
        raise CloudError(f"the points do not fix the sphere's centre (information condition {w[-1] / max(w[0], 1e-300):.2g})")
    dof = max(len(q) - jac.shape[1], 1)
    return c, float(abs(r)), d, float(d @ d) / dof * np.linalg.inv(info)


def _record(fit, free, kept, n, scale, cap):
    c, r, d, cov = fit
    held = cov.shape[0] == 3
    return CloudFit(centre=np.asarray(c, float), covariance=np.array(cov[:3, :3]), radius=r,
                    radius_sd=0.0 if held else float(np.sqrt(cov[3, 3])), free_diameter=2 * free[1], radius_held=held,
                    kept=kept, n_points=n, dropped=(("off the sphere", int(n - kept.sum())),) if not kept.all() else (),
                    scale_mm=float(scale), rms_mm=float(np.sqrt(np.mean(d**2))), cap_deg=cap)


def diameter_spread(fits):
    """``(mean, sd, min, max)`` of the fitted diameters (mm) of ``fits`` (CloudFit) whose radius was free; None
    without any."""
    values = np.array([2 * f.radius for f in fits if f is not None and not f.radius_held])
    if not len(values):
        return None
    return float(values.mean()), float(values.std(ddof=1)) if len(values) > 1 else 0.0, float(values.min()), float(values.max())
