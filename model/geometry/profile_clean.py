"""Profile cleaning: the points of a laser profile that lie on the sphere's arc, and the rest.

A laser-line sensor's profile (points ``(x, z)`` in the sensor's y = 0 plane, mm) holds the arc
where the laser plane cuts the sphere, and on a real cell often more: speckle anywhere in the
measuring window, the table or background behind the sphere (a line), small clusters of spurious
points. A circle fitted to all of them is meaningless (often wider than the sphere, so that the
reconstruction refuses it). Cleaning finds the arc and drops the rest, per profile:

1. **Fast path.** The Hyper fit of every point (:func:`handeye.model.geometry.circle.hyper`): when its
   radius is plausible (``r <= R + tol``) and every point lies within :data:`K_SD` robust sd of it
   (the scale ``1.4826 MAD`` of the distances, at most :data:`FAST_SCALE_MM`), the profile is
   clean and nothing is dropped (a clean profile costs one fit).
2. **RANSAC** over minimal circles: :data:`CANDIDATES` circles through 3 points drawn by a
   generator seeded from the profile's own bytes (deterministic), each scored by the points
   within :data:`BAND_MM` of it. The sphere is the prior: a plane cuts a sphere of radius R in a
   circle of radius ``r <= R``, so candidates with ``r > R + tol`` (``tol`` =
   :data:`RADIUS_TOL`) do not count -- unless such a wider circle, a real arc (sagitta at least
   :data:`SAGITTA_MM` over its points, not a line), holds clearly more points
   (:data:`WIDER_FACTOR`): then the arc is wider than the sphere (a wrong diameter) and is kept
   as it is, so that the reconstruction says so.
3. **M-estimator.** Tukey's biweight (c = 4.685 s) by iteratively reweighted Gauss-Newton on
   the geometric distances ``|p - c| - r``, seeded from the RANSAC circle; the scale
   ``s = 1.4826 MAD`` of the distances within :data:`WINDOW_MM` of the circle, at least
   :data:`SCALE_FLOOR_MM` (0.02 mm: no point within 0.1 mm of its arc is ever dropped -- a
   physical floor, as the row consistency check has one: a real sensor's profile departs from a
   circle by more than its noise, through the sphere's form and the sensor's linearity, and a
   point that close cannot pull the circle; the simulator's sensor has 0.01 mm, RobCalibrator's
   real scanner a MAD of 0.011 mm).
4. Points farther than :data:`K_SD` s from the final circle are dropped ("off the arc"); of the
   rest, runs of fewer than :data:`MIN_RUN` points separated from the arc along the circle by
   more than :data:`GAP_MM` are dropped too ("isolated": speckle that happens to fall on the
   circle where the sensor saw nothing).

Why ``K_SD = 5``: a Gaussian point lies beyond 5 sd with probability 5.7e-7, so over a dataset
of 36 profiles of 1,280 points the expected number of clean points dropped is 0.026 (one in 38
such datasets loses one point); with the scale floored above the noise, fewer still. The scale's
own error (MAD of about a thousand points, 3 %) moves that little. Measured: 0 of 115,643 points
of 180 simulated profiles; on real scans only points at least 9 robust sd off their arcs (README).

A profile with no arc -- fewer than :data:`MIN_ARC_POINTS` points, or than
:data:`MIN_ARC_FRACTION` of its points, on any circle of the sphere -- is reported as such
(``status`` ``'no arc'``), never silently fitted. A profile of fewer than :data:`MIN_ARC_POINTS`
points is left as it is (too few to tell an arc from speckle; the circle fit judges it).
"""
from __future__ import annotations

import dataclasses
import hashlib

import numpy as np

from handeye.model.geometry import circle

#: Points farther than this many robust sd from the arc are dropped (module docstring).
K_SD = 5.0
#: Floor of the robust scale, mm (a laser-line sensor's point noise is not below it).
SCALE_FLOOR_MM = 0.02
#: The fast path takes a profile as clean only when its robust scale is at most this, mm.
FAST_SCALE_MM = 0.1
#: Half-width of the band that scores a RANSAC candidate, mm.
BAND_MM = 0.25
#: The scale is the MAD of the distances within this of the circle, mm.
WINDOW_MM = 1.0
#: Candidates with ``r > R (1 + RADIUS_TOL) + BAND_MM`` are wider than the sphere.
RADIUS_TOL = 0.02
#: Minimal circles drawn (with half the points on the arc, each is of three arc points with
#: probability 1/8: the chance that none of 512 is, 1e-30).
CANDIDATES = 512
#: Above this many points a profile's candidates are scored on this many of them, drawn at random.
SCORE_POINTS = 5000
#: A wider circle beats the sphere's only with this many times its points and a sagitta of at
#: least SAGITTA_MM over them (a line -- the table -- is no arc).
WIDER_FACTOR = 1.5
SAGITTA_MM = 1.0
#: An arc needs at least this many points and this fraction of the profile's.
MIN_ARC_POINTS = 10
MIN_ARC_FRACTION = 0.05
#: Runs of fewer than MIN_RUN points beyond a gap of GAP_MM along the circle are isolated.
MIN_RUN = 4
GAP_MM = 3.0
#: Tukey's biweight constant (95 % efficiency at the normal).
TUKEY_C = 4.685


class Drops:
    """What a cleaning dropped, counted and said (``dropped``: ``(reason, count)`` pairs, ``n_points``): a
    profile's (:class:`Cleaning`) and a cloud's (:class:`handeye.model.geometry.sphere_cloud.CloudFit`)."""

    @property
    def n_dropped(self):
        return int(sum(n for _, n in self.dropped))

    def describe(self):
        """The drops in words, e.g. ``'312 of 1,280 points dropped: off the arc 310, isolated 2'``."""
        if not self.n_dropped:
            return "nothing dropped"
        why = ", ".join(f"{name} {n:,}" for name, n in self.dropped if n)
        return f"{self.n_dropped:,} of {self.n_points:,} points dropped: {why}"


@dataclasses.dataclass(frozen=True)
class Cleaning(Drops):
    """What cleaning did to one profile.

    Attributes
    ----------
    kept : ndarray of bool, shape (K,)
        The points on the arc (all True for a clean profile).
    n_points : int
    status : {'clean', 'cleaned', 'wider', 'no arc'}
        Nothing dropped by the fast path or the full one; points dropped; an arc wider than
        the sphere kept as it is; no arc found.
    dropped : tuple of (str, int)
        Why points were dropped and how many: ``('off the arc', n)``, ``('isolated', n)``.
    circle : handeye.model.geometry.circle.Circle or None
        The robust circle (sensor x, z plane, mm); None without an arc.
    scale_mm : float
        Robust sd of the kept points' distances from it, mm (NaN without an arc).
    """

    kept: np.ndarray
    n_points: int
    status: str
    dropped: tuple = ()
    circle: circle.Circle | None = None
    scale_mm: float = float("nan")

    def to_dict(self):
        return {"points": self.n_points, "dropped": self.n_dropped, "status": self.status,
                "reasons": {name: n for name, n in self.dropped if n},
                "scale_mm": None if not np.isfinite(self.scale_mm) else float(self.scale_mm)}


def seeded(points):
    """A generator seeded by the points' own bytes (a profile's, a cloud's): the same points, the same draws."""
    return np.random.default_rng(int.from_bytes(hashlib.blake2b(np.ascontiguousarray(points).tobytes(),
                                                                digest_size=8).digest(), "little"))


def _distances(x, z, c):
    return np.hypot(x - c.x, z - c.z) - c.r


def robust_scale(d):
    """``1.4826 MAD`` of the distances ``d`` (mm) within WINDOW_MM, at least SCALE_FLOOR_MM."""
    near = np.abs(d[np.abs(d) < WINDOW_MM])
    return max(1.4826 * float(np.median(near)) if near.size >= 3 else WINDOW_MM, SCALE_FLOOR_MM)


def _candidates(x, z, rng):
    """Circles (M, 3: xc, zc, r) through :data:`CANDIDATES` random triples of points (degenerate
    triples give NaN)."""
    idx = np.stack([rng.choice(len(x), 3, replace=False) for _ in range(CANDIDATES)])
    xm, zm = x.mean(), z.mean()
    ax, bx, cx = (x[idx] - xm).T
    az, bz, cz = (z[idx] - zm).T
    a2, b2, c2 = ax**2 + az**2, bx**2 + bz**2, cx**2 + cz**2
    d = 2.0 * (ax * (bz - cz) + bx * (cz - az) + cx * (az - bz))
    with np.errstate(divide="ignore", invalid="ignore"):
        ux = (a2 * (bz - cz) + b2 * (cz - az) + c2 * (az - bz)) / d
        uz = (a2 * (cx - bx) + b2 * (ax - cx) + c2 * (bx - ax)) / d
    return np.column_stack([ux + xm, uz + zm, np.hypot(ax - ux, az - uz)])


def _sagitta(x, z, cand, inside):
    """Sagitta (mm) of each candidate circle over the chord of its points within the band."""
    out = np.zeros(len(cand))
    for m in np.flatnonzero(inside.any(axis=1)):
        px, pz = x[inside[m]], z[inside[m]]
        chord = min(np.hypot(px.max() - px.min(), pz.max() - pz.min()), 2 * cand[m, 2])
        out[m] = cand[m, 2] - np.sqrt(max(cand[m, 2] ** 2 - chord**2 / 4, 0.0))
    return out


def ransac(x, z, radius, rng):
    """The best circle of the sphere and the best wider arc among minimal circles.

    Returns
    -------
    best : handeye.model.geometry.circle.Circle or None
        The candidate with ``r <= R (1 + RADIUS_TOL) + BAND_MM`` that has the most points within
        BAND_MM, None when no candidate is finite.
    n_best : int
        Its points (above :data:`SCORE_POINTS` points counted on that many drawn at random, and
        scaled to the profile's number).
    wider : handeye.model.geometry.circle.Circle or None
        The wider candidate with the most points that is an arc (sagitta >= SAGITTA_MM), when it
        holds WIDER_FACTOR times ``n_best`` or more; else None.
    """
    cand = _candidates(x, z, rng)
    cand = cand[np.all(np.isfinite(cand), axis=1) & (cand[:, 2] > BAND_MM)]
    if not len(cand):
        return None, 0, None
    scale = 1.0
    if len(x) > SCORE_POINTS:  # memory and time bounded: candidates x points
        pick = np.sort(rng.choice(len(x), SCORE_POINTS, replace=False))
        scale, x, z = len(x) / SCORE_POINTS, x[pick], z[pick]
    inside = np.abs(np.hypot(x[None] - cand[:, :1], z[None] - cand[:, 1:2]) - cand[:, 2:]) < BAND_MM
    score = inside.sum(axis=1)
    fits = cand[:, 2] <= radius * (1 + RADIUS_TOL) + BAND_MM
    n_best = int(round(scale * score[fits].max())) if fits.any() else 0
    best = circle.Circle(*map(float, cand[fits][np.argmax(score[fits])])) if fits.any() else None
    wide = np.flatnonzero(~fits & (scale * score >= WIDER_FACTOR * max(n_best, 1)))
    wide = wide[_sagitta(x, z, cand[wide], inside[wide]) >= SAGITTA_MM] if len(wide) else wide
    wider = circle.Circle(*map(float, cand[wide[np.argmax(score[wide])]])) if len(wide) else None
    return best, n_best, wider


def tukey_fit(x, z, start, max_iter=50):
    """Tukey-biweight circle fit by reweighted Gauss-Newton on the geometric distances.

    Parameters
    ----------
    x, z : ndarray, shape (K,)
        Profile points, sensor x and z, mm.
    start : handeye.model.geometry.circle.Circle
        Seed (the RANSAC circle).

    Returns
    -------
    (handeye.model.geometry.circle.Circle, float)
        The circle and the robust scale s of the distances from it (mm).
    """
    p = np.array([start.x, start.z, start.r], float)
    s = robust_scale(_distances(x, z, start))
    for _ in range(max_iter):
        dx, dz = x - p[0], z - p[1]
        rho = np.maximum(np.hypot(dx, dz), 1e-300)
        d = rho - p[2]
        s = robust_scale(d)
        u = d / (TUKEY_C * s)
        w = np.where(np.abs(u) < 1, (1 - u**2) ** 2, 0.0)
        if np.count_nonzero(w) < 3:
            break
        j = np.column_stack([-dx / rho, -dz / rho, -np.ones_like(x)])
        try:
            step = np.linalg.solve((j * w[:, None]).T @ j, -(j * w[:, None]).T @ d)
        except np.linalg.LinAlgError:
            break
        p = p + step
        if np.max(np.abs(step)) < 1e-10 * max(1.0, abs(p[2])):
            break
    fitted = circle.Circle(float(p[0]), float(p[1]), float(abs(p[2])))
    return fitted, robust_scale(_distances(x, z, fitted))


def _isolated(x, z, c, keep):
    """Of the points ``keep``, those in runs of fewer than MIN_RUN points that lie more than
    GAP_MM (or 3 x the median spacing, on a sparse profile) along the circle ``c`` from every other
    kept point (bool mask over all points)."""
    idx = np.flatnonzero(keep)
    if len(idx) <= MIN_RUN:
        return np.zeros(len(x), bool)
    theta = np.arctan2(z[idx] - c.z, x[idx] - c.x)
    order = np.argsort(theta)
    gaps = np.diff(np.r_[theta[order], theta[order[0]] + 2 * np.pi]) * c.r  # the last wraps round
    gap = max(GAP_MM, 3.0 * float(np.median(gaps)))  # a sparse profile's own spacing is no gap
    ends = np.flatnonzero(gaps > gap)
    out = np.zeros(len(x), bool)
    if len(ends) < 2:  # one run (or the whole circle): nothing isolated
        return out
    for a, b in zip(ends, np.r_[ends[1:], ends[0] + len(idx)]):
        run = order[np.arange(a + 1, b + 1) % len(idx)]
        if len(run) < MIN_RUN:
            out[idx[run]] = True
    return out


def _fast(x, z, radius):
    """The fast path's verdict: a Cleaning of a clean profile, or None."""
    try:
        c = circle.hyper(x, z)
    except circle.CircleFitError:
        return None
    d = _distances(x, z, c)
    s = max(1.4826 * float(np.median(np.abs(d))), SCALE_FLOOR_MM)
    if c.r <= radius * (1 + RADIUS_TOL) + BAND_MM and s <= FAST_SCALE_MM and np.max(np.abs(d)) <= K_SD * s:
        return Cleaning(np.ones(len(x), bool), len(x), "clean", (), c, s)
    return None


def clean(points, radius):
    """Clean one profile (module docstring).

    Parameters
    ----------
    points : array_like, shape (K, 2)
        Sensor x, z of the profile's points, mm (the laser plane y = 0).
    radius : float
        The sphere's radius R, mm.

    Returns
    -------
    Cleaning
    """
    pts = np.asarray(points, float).reshape(-1, 2)
    x, z, k = pts[:, 0], pts[:, 1], len(pts)
    if k < MIN_ARC_POINTS:  # too few to tell an arc from speckle: left as they are (the fit judges them)
        return Cleaning(np.ones(k, bool), k, "clean")
    fast = _fast(x, z, radius)
    if fast is not None:
        return fast
    need = max(MIN_ARC_POINTS, int(np.ceil(MIN_ARC_FRACTION * k)))
    best, n_best, wider = ransac(x, z, radius, seeded(pts))
    seed, status = (wider, "wider") if wider is not None else (best, "cleaned")
    if seed is None or (wider is None and n_best < need):
        return Cleaning(np.zeros(k, bool), k, "no arc", (("off the arc", k),))
    fitted, s = tukey_fit(x, z, seed)
    if status == "cleaned" and fitted.r > radius * (1 + RADIUS_TOL) + BAND_MM:
        fitted, s = seed, robust_scale(_distances(x, z, seed))  # the M-step ran wide: the prior's circle
    near = np.abs(_distances(x, z, fitted)) <= K_SD * s
    lone = _isolated(x, z, fitted, near)
    keep = near & ~lone
    if keep.sum() < need:
        return Cleaning(np.zeros(k, bool), k, "no arc", (("off the arc", k),))
    dropped = (("off the arc", int(k - near.sum())), ("isolated", int(lone.sum())))
    if not keep.all() or status == "wider":
        return Cleaning(keep, k, status, tuple(d for d in dropped if d[1]), fitted, s)
    return Cleaning(keep, k, "clean", (), fitted, s)


def no_arc_message(cleaning, radius):
    """Why a profile is refused (status ``'no arc'``), in words."""
    need = max(MIN_ARC_POINTS, int(np.ceil(MIN_ARC_FRACTION * cleaning.n_points)))
    return (f"no arc of the {2 * radius:g} mm sphere found among its {cleaning.n_points:,} points: no circle of radius "
            f"at most {radius:g} mm holds {need} of them within {BAND_MM:g} mm, so they are scattered (speckle, "
            "background) or the sphere was not in view; remove the row or measure again")

