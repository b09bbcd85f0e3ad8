"""A sensor's depth linearity, measured from the profiles' shape and corrected before the circle fits.

A laser-line sensor's depth reading bends: it reports ``z + b(z)`` for a point at depth z, with
``b`` a smooth function over its measuring range (the linearity error of its data sheet: 0.16 %
of a 100 mm range for the seed's sensor, up to 0.16 mm). A sphere's profile is then no circle: a
bend that is not constant over the arc's depths stretches or curls it, and the circle fitted to
it has the wrong radius, so the sphere centre rebuilt from it has the wrong y
(``y = sqrt(R^2 - r^2)``, its error ``r / |y|`` times the radius's). On the seed's 36 orientations
(simulated, a bend of 0.05 mm) that moved the calibrated pose 1.1 mm, 10 of its sd, with every
residual at the stated noise: the centres cannot show it, the profiles' shape can.

**The model.** Every profile ``i`` is a circle ``(a_i, c_i, r_i)`` after its depths are corrected,
and the correction is one function shared by all profiles:

    ``|(x, z - b(z) + mean b) - (a_i, c_i)| = r_i``,  ``b(z) = sum_j beta_j P_j(u)``,

``P_j`` the Legendre polynomials of degree 1..m of the depth ``u`` scaled to [-1, 1] over the
profiles' depths. A constant bend is a translation of the sensor along its z, which every pose
absorbs and no data can see: ``mean b`` (over the profiles' points) is subtracted, so the
correction keeps the data's mean depth. A plane cuts a sphere in a circle at any tilt and offset,
so no other effect of the cell bends a profile (a sensor's isotropic scale keeps it a circle:
``sensor_scale``).

**The fit.** Orthogonal distances, Gauss-Newton on ``(beta, a_i, c_i, r_i)``; each profile's three
circle parameters are eliminated per profile (the Schur complement), so a step costs one pass
over the points whatever their number (Nocedal & Wright 2006, *Numerical Optimization*, ch. 10).
The degree is the one of lowest BIC among 0..:data:`MAX_DEGREE` (the nested models' sums of squares
from one reduced step at ``beta = 0``); the bend is *applied* only where it is clear and physical:
the F test of the chosen degree against none at :data:`ALPHA` **and** the same level for the
coefficients against their jackknife covariance (a bend every profile shows, not the structure
of a few), a bend of at least :data:`MIN_BEND_MM` over the profiles' depths (the arc check's floor:
a laser-line sensor's point noise is not below it, and the form error of a precision sphere is
below it), and nowhere steeper than :data:`MAX_SLOPE`.

**Its uncertainty.** The coefficients' covariance is the delete-one-profile jackknife (one reduced
Newton step per profile from the fit): a real profile departs from a circle by more than its
noise (the sphere's form, speckle correlated along the line), so the points' own scatter would
claim a bend known better than it is. The rebuilt centres' derivatives with respect to ``beta``
(:attr:`Bend.dcentre`) carry it into the pose's covariance (:mod:`handeye.app.engine.bend`).
"""
from __future__ import annotations

import dataclasses

import numpy as np
from numpy.polynomial import legendre

from handeye.model.common.statistics import f_survival
from handeye.model.geometry import circle

#: Highest degree of the bend's polynomial (a data sheet's linearity curve over a sphere's depths).
MAX_DEGREE = 6
#: Level of the tests of a bend against none (one pair per dataset). A bend applied moves every rebuilt
#: centre, and the tests' null distributions are first-order only (short arcs trade a stretch against their
#: radius): at 1e-3, 3 of 64 clean and scaled profile cells of an independent generator (tests/indep_systematic.py)
#: had a bend of 0.17-0.39 mm applied (p 2.5e-5 - 4e-4, a stretch of 0.1-0.3 %). A sensor's linearity error is far
#: clearer than that: ``simulate --linearity 0.0005`` gives p below 1e-30.
ALPHA = 1e-6
#: A bend smaller than this over the profiles' depths (peak to peak, mm) is not applied (module docstring).
MIN_BEND_MM = 0.02
#: A bend steeper than this anywhere (mm per mm of depth) is no sensor's linearity (a data sheet's 0.16 % of the
#: range is a slope of 1 % for a sine over it) but something else the circles miss (few profiles of a small
#: sphere, where the bend and the circles trade off): not applied.
MAX_SLOPE = 0.05
#: Fewer profiles than this: no bend is estimated (the jackknife needs some).
MIN_PROFILES = 8
#: Gauss-Newton steps of the chosen degree's fit.
STEPS = 4


@dataclasses.dataclass(frozen=True)
class Bend:
    """A depth bend of the profiles (module docstring).

    Attributes
    ----------
    degree : int
        Of the polynomial chosen (0: none).
    beta : ndarray, shape (degree,)
        Legendre coefficients, mm.
    covariance : ndarray, shape (degree, degree)
        Of ``beta`` (jackknife over the profiles), mm^2.
    depths : tuple of float
        ``(lo, hi)``: the profiles' depths (sensor z, mm) the polynomial is scaled to.
    offset : float
        ``mean b`` over the profiles' points (mm), subtracted by the correction.
    f : float
        F statistic of the chosen degree against no bend (the points' scatter as its noise).
    p_value : float
        The larger of the F test's and the jackknife Wald test's (``beta^T C^-1 beta / m`` against
        F(m, n - 1): the profiles' own scatter of the bend as its noise).
    bend_mm : float
        Peak-to-peak of the correction over ``depths`` (mm).
    applied : bool
        Whether the profiles were corrected (module docstring: the F test and :data:`MIN_BEND_MM`).
    rows : tuple of int
        The samples whose profiles it was estimated from (positions in the dataset).
    dcentre : ndarray, shape (len(rows), 3, degree), or None
        Derivative of each profile's rebuilt sphere centre (sensor x, y, z) with respect to ``beta``.
    moved : ndarray, shape (len(rows), 3), or None
        How far the correction moved each of their centres (sensor frame, mm); None until applied.
    slope : float
        The bend's steepest slope over ``depths`` (mm per mm).
    """

    degree: int
    beta: np.ndarray
    covariance: np.ndarray
    depths: tuple
    offset: float
    f: float
    p_value: float
    bend_mm: float
    applied: bool
    rows: tuple
    dcentre: np.ndarray | None = None
    moved: np.ndarray | None = None
    slope: float = 0.0

    def correction(self, z):
        """The bend ``b(z) - mean b`` at depths ``z`` (mm; any shape)."""
        z = np.asarray(z, float)
        return (_basis(z.ravel(), self.degree, self.depths) @ self.beta - self.offset).reshape(z.shape)

    def corrected(self, points):
        """Profile points (K, 2: sensor x, z, mm) with their depths corrected."""
        points = np.asarray(points, float)
        return np.column_stack([points[:, 0], points[:, 1] - self.correction(points[:, 1])])

    def to_dict(self):
        """JSON-ready summary."""
        return {"degree": self.degree, "applied": self.applied, "bend_mm": self.bend_mm, "f": self.f,
                "p_value": self.p_value, "slope": self.slope, "depths_mm": list(self.depths), "profiles": len(self.rows),
                "beta_mm": [float(b) for b in self.beta],
                "beta_sd_mm": [float(s) for s in np.sqrt(np.clip(np.diag(self.covariance), 0, None))]}


def _basis(z, m, depths):
    lo, hi = depths
    u = np.clip((2 * z - lo - hi) / max(hi - lo, 1e-9), -1.0, 1.0)
    return legendre.legvander(u, m)[:, 1:]


@dataclasses.dataclass(frozen=True)
class _Points:
    """Every profile's points in one array: ``seg`` the profile of each point, ``starts`` its first, ``basis`` (N, MAX_DEGREE)
    its Legendre columns minus their mean (the correction keeps the mean depth)."""

    x: np.ndarray
    z: np.ndarray
    seg: np.ndarray
    starts: np.ndarray
    n: int
    basis: np.ndarray
    mean_basis: np.ndarray
    depths: tuple


def _points(profiles):
    x = np.concatenate([p[:, 0] for p in profiles])
    z = np.concatenate([p[:, 1] for p in profiles])
    sizes = [len(p) for p in profiles]
    seg = np.repeat(np.arange(len(profiles)), sizes)
    depths = (float(z.min()), float(z.max()))
    full = _basis(z, MAX_DEGREE, depths)
    mean = full.mean(axis=0)
    return _Points(x, z, seg, np.concatenate([[0], np.cumsum(sizes)[:-1]]), len(profiles), full - mean, mean, depths)


def _segment_sum(pts, values):
    """Per-profile sums of ``values`` (N, ...) -> (n, ...) (each profile's points are contiguous)."""
    return np.add.reduceat(values, pts.starts, axis=0)


def _reduced(pts, beta, circles):
    """One Gauss-Newton linearisation at ``beta`` (m,) and ``circles`` (n, 3), the circles eliminated:
    ``(S, g, ssr, per_profile)`` with ``S`` (m, m) and ``g`` (m,) the reduced normal matrix and gradient,
    ``ssr`` the sum of squares and ``per_profile`` ``(JJ^-1, JG, Jr, S_i, g_i)`` for the circles' step,
    the jackknife and the centres' derivatives."""
    m = len(beta)
    basis = pts.basis[:, :m]
    zt = pts.z - basis @ beta
    a, c, r = (circles[pts.seg, k] for k in range(3))
    dx, dz = pts.x - a, zt - c
    d = np.maximum(np.hypot(dx, dz), 1e-300)
    res = d - r
    jac = np.stack([-dx / d, -dz / d, -np.ones_like(d)], axis=1)
    g_cols = -(dz / d)[:, None] * basis
    jj_inv = np.linalg.inv(_segment_sum(pts, jac[:, :, None] * jac[:, None, :]))
    jg = _segment_sum(pts, jac[:, :, None] * g_cols[:, None, :])
    jr = _segment_sum(pts, jac * res[:, None])
    gg = _segment_sum(pts, g_cols[:, :, None] * g_cols[:, None, :])
    gr = _segment_sum(pts, g_cols * res[:, None])
    s_i = gg - np.einsum("nkm,nkl,nlj->nmj", jg, jj_inv, jg)
    g_i = gr - np.einsum("nkm,nkl,nl->nm", jg, jj_inv, jr)
    return s_i.sum(axis=0), g_i.sum(axis=0), float(res @ res), (jj_inv, jg, jr, s_i, g_i)


def _circle_sums(pts, jr, jj_inv):
    """The sum of squares the circles' own Gauss-Newton step removes (no bend)."""
    return float(np.einsum("nk,nkl,nl->", jr, jj_inv, jr))


def _degree(pts, circles):
    """``(degree, ssr by degree)``: BIC's choice among 0..MAX_DEGREE from one reduced step at ``beta = 0``."""
    s, g, ssr, (jj_inv, _, jr, _, _) = _reduced(pts, np.zeros(MAX_DEGREE), circles)
    ssr0 = ssr - _circle_sums(pts, jr, jj_inv)
    ssrs = [ssr0] + [ssr0 - float(g[:m] @ np.linalg.solve(s[:m, :m], g[:m])) for m in range(1, MAX_DEGREE + 1)]
    n_obs = len(pts.z)
    bic = [n_obs * np.log(max(v, 1e-300) / n_obs) + (3 * pts.n + m) * np.log(n_obs) for m, v in enumerate(ssrs)]
    return int(np.argmin(bic)), ssrs


def _fit(pts, circles, m):
    """Gauss-Newton from ``beta = 0``: ``(beta, circles, pieces at the fit, ssr)``."""
    beta = np.zeros(m)
    for _ in range(STEPS):
        s, g, _, (jj_inv, jg, jr, _, _) = _reduced(pts, beta, circles)
        step = -np.linalg.solve(s, g)
        circles = circles - np.einsum("nkl,nl->nk", jj_inv, jr + jg @ step)
        beta = beta + step
    s, g, ssr, pieces = _reduced(pts, beta, circles)
    return beta, circles, s, pieces, ssr


def _jackknife(s, pieces, beta):
    """Covariance (m, m) of ``beta`` by deleting each profile in turn (one reduced Newton step)."""
    _, _, _, s_i, g_i = pieces
    n = len(s_i)
    deleted = beta + np.linalg.solve(s[None] - s_i, g_i[..., None])[..., 0]
    dev = deleted - deleted.mean(axis=0)
    return (n - 1) / n * dev.T @ dev


def _dcentre(pieces, circles, radius, side):
    """Derivatives (n, 3, m) of the rebuilt centres (x, y, z) with respect to ``beta`` at the fit."""
    jj_inv, jg, _, _, _ = pieces
    dcirc = -np.einsum("nkl,nlm->nkm", jj_inv, jg)  # (a, c, r)
    r = circles[:, 2]
    y = np.sqrt(np.maximum(radius**2 - r**2, 1e-12))
    return np.stack([dcirc[:, 0], (-side * r / y)[:, None] * dcirc[:, 2], dcirc[:, 1]], axis=1)


def estimate(profiles, radius, side=-1):
    """The :class:`Bend` of a dataset's (cleaned) profiles, or None with fewer than :data:`MIN_PROFILES`.

    Parameters
    ----------
    profiles : sequence of ndarray, shape (K_i, 2)
        Sensor x, z of each profile's points, mm (sensor frame, the laser plane y = 0).
    radius : float
        The sphere's, mm.
    side : int
        Sign of the sensor-y of the sphere centre (the rebuilt centres' derivatives).
    """
    rows = tuple(k for k, p in enumerate(profiles) if p is not None and len(p) >= 5)
    profiles = [np.asarray(profiles[k], float) for k in rows]
    if len(profiles) < MIN_PROFILES:
        return None
    pts = _points(profiles)
    try:
        start = np.array([[c.x, c.z, c.r] for c in (circle.hyper(p[:, 0], p[:, 1]) for p in profiles)])
        m, ssrs = _degree(pts, start)
    except (circle.CircleFitError, np.linalg.LinAlgError):
        return None
    dof = len(pts.z) - 3 * pts.n - max(m, 1)
    if m == 0:
        f = float((ssrs[0] - ssrs[1]) / (ssrs[1] / dof))
        return Bend(0, np.zeros(0), np.zeros((0, 0)), pts.depths, 0.0, f, f_survival(f, 1, dof), 0.0, False, rows)
    beta, circles, s, pieces, ssr = _fit(pts, start, m)
    f = float(((ssrs[0] - ssr) / m) / (ssr / dof))
    grid = np.linspace(*pts.depths, 201)
    curve = _basis(grid, m, pts.depths) @ beta
    cov = _jackknife(s, pieces, beta)
    wald = float(beta @ np.linalg.lstsq(cov, beta, rcond=None)[0]) / m
    p_value = max(f_survival(f, m, dof), f_survival(wald, m, pts.n - 1))
    bend_mm = float(curve.max() - curve.min())
    slope = float(np.max(np.abs(np.gradient(curve, grid))))
    applied = bool(p_value < ALPHA and bend_mm >= MIN_BEND_MM and slope <= MAX_SLOPE)
    return Bend(m, beta, cov, pts.depths, float(pts.mean_basis[:m] @ beta), f, p_value, bend_mm, applied, rows,
                _dcentre(pieces, circles, radius, side), slope=slope)


def apply(profiles, centres, radius, side=-1, fit="hyper"):
    """A dataset's profiles and sphere centres with their :class:`Bend` applied: ``(profiles, centres, bend)``.

    Rows without a profile keep their centre; every row with one has its centre rebuilt from the
    corrected profile (a centre the file gives beside its profile came from the same bent points).
    Unchanged where the bend is None or not applied.

    Parameters
    ----------
    profiles : sequence of ndarray (K_i, 2) or None
        Per row, sensor x, z (mm) of its cleaned profile.
    centres : sequence of array_like (3,)
        Per row, the sphere centre in the sensor frame (mm).
    radius : float
        mm.
    side : int
    fit : str
        The circle fit that rebuilds a centre (:data:`handeye.model.geometry.circle.FITS`).
    """
    bend = estimate(profiles, radius, side)
    if bend is None or not bend.applied:
        return list(profiles), list(centres), bend
    profiles = [None if p is None else bend.corrected(p) for p in profiles]
    out = []
    for p, c in zip(profiles, centres):
        try:
            out.append(c if p is None else list(circle.sphere_centre_from_circle(circle.fit_circle(p[:, 0], p[:, 1], fit),
                                                                                 radius, side)))
        except circle.CircleFitError:
            out.append(c)
    moved = np.array([np.subtract(out[k], centres[k]) for k in bend.rows], float)
    return profiles, out, dataclasses.replace(bend, moved=moved)
