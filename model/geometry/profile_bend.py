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

**The fit.** Orthogonal distances, each divided by the sd the correction leaves it (the correction
scales a point's depth noise by ``1 - b'(z)``: without the division, and that sd's derivative in the
step, a bend that squeezes the noise lowers the sum of squares, and clean profiles read as stretched,
a bias growing as the noise's square). Gauss-Newton on ``(beta, a_i, c_i, r_i)``, each step halved
until the sum of squares falls; each profile's three circle parameters are eliminated per profile
(the Schur complement), so a step costs one pass over the points whatever their number (Nocedal &
Wright 2006, *Numerical Optimization*, ch. 10).
The degree is the one of lowest BIC among 0..:data:`MAX_DEGREE` (the nested models' sums of squares
from one reduced step at ``beta = 0``); the bend is *applied* only where it is clear and physical:
the F test of the chosen degree against none at :data:`ALPHA` **and** Hotelling's T^2 of the
coefficients against their jackknife covariance at the same level (a bend every profile shows, not
the structure of a few), a bend of at least :data:`MIN_BEND_MM` over the profiles' depths (the arc check's floor:
a laser-line sensor's point noise is not below it, and the form error of a precision sphere is
below it), and nowhere steeper than :data:`MAX_SLOPE`.

**Its uncertainty.** The coefficients' covariance is the delete-one-profile jackknife (one reduced
Newton step per profile from the fit): a real profile departs from a circle by more than its
noise (the sphere's form, speckle correlated along the line), so the points' own scatter would
claim a bend known better than it is. The rebuilt centres' derivatives with respect to ``beta``
(:attr:`Bend.dcentre`) carry it into the pose's covariance (:mod:`handeye.app.engine.bend`, which adds
what the jackknife does not cover, and for a bend suggested but not applied, what its correction would do).
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
#: Degree of the bend whose power the profiles' test is stated with (a depth stretch and a curvature).
SEEN_DEGREE = 2
#: Gauss-Newton steps of the chosen degree's fit.
STEPS = 4
#: Above this many profiles the bend is fitted on that many spread over the rows (the estimate's sd is then
#: already far below the floor); every row's centre is still corrected and differentiated.
MAX_FIT_PROFILES = 2000
#: Each profile is thinned to at most this many points (evenly) for the fit and the derivatives: the seed's
#: sensor's 1,280 points per profile, so that a line scanner's profiles are fitted whole.
MAX_POINTS = 1280
#: Points per block of a pass over the profiles (the pass's arrays are about 70 numbers a point).
BLOCK_POINTS = 100_000


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
        The larger of the F test's and Hotelling's (``T^2 (n - m) / (m (n - 1))`` against F(m, n - m),
        ``T^2 = beta^T C^-1 beta`` with the jackknife's C: the profiles' own scatter of the bend as its noise).
    bend_mm : float
        Peak-to-peak of the correction over ``depths`` (mm).
    applied : bool
        Whether the profiles were corrected (module docstring: both tests at :data:`ALPHA`, at least
        :data:`MIN_BEND_MM`, nowhere steeper than :data:`MAX_SLOPE`; :attr:`why` says which failed).
    rows : tuple of int
        The samples whose profiles it was estimated from (positions in the dataset).
    dcentre : ndarray, shape (len(rows), 3, degree), or None
        Derivative of each profile's rebuilt sphere centre (sensor x, y, z) with respect to ``beta``.
    moved : ndarray, shape (len(rows), 3), or None
        How far the correction moved (or, not applied, would move) each of their centres (sensor frame, mm);
        None without a bend.
    slope : float
        The bend's steepest slope over ``depths`` (mm per mm).
    mean_basis : ndarray, shape (degree,), or None
        The basis's mean over the profiles' points (``offset = mean_basis @ beta``).
    seen : tuple or None
        What the profiles see of a bend of degree :data:`SEEN_DEGREE` (a stretch and a curvature: the first
        terms of any linearity error), at no bend: its information ``(SEEN_DEGREE, SEEN_DEGREE)`` per mm^2
        (the reduced normal matrix over the points' variance) and the rebuilt centres' derivatives
        ``(len(rows), 3, SEEN_DEGREE)``; what :mod:`handeye.app.engine.bend` states the power of. None when
        the fit ran on a subsample.
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
    mean_basis: np.ndarray | None = None
    seen: tuple | None = None

    def correction(self, z):
        """The bend ``b(z) - mean b`` at depths ``z`` (mm; any shape)."""
        z = np.asarray(z, float)
        return (_basis(z.ravel(), self.degree, self.depths) @ self.beta - self.offset).reshape(z.shape)

    def correction_sd(self, z):
        """1 sd (mm) of :meth:`correction` at depths ``z`` (1-D), from :attr:`covariance`."""
        basis = _basis(np.asarray(z, float).ravel(), self.degree, self.depths) - self.mean_basis
        return np.sqrt(np.einsum("ij,jk,ik->i", basis, self.covariance, basis))

    def corrected(self, points):
        """Profile points (K, 2: sensor x, z, mm) with their depths corrected."""
        points = np.asarray(points, float)
        return np.column_stack([points[:, 0], points[:, 1] - self.correction(points[:, 1])])

    def subset(self, mask):
        """This bend on the samples of ``mask`` (bool over the dataset's samples): :attr:`rows`, :attr:`dcentre`
        and :attr:`moved` of the samples kept, renumbered; what was estimated from every profile stays."""
        mask = np.asarray(mask, bool)
        position = np.cumsum(mask) - 1
        keep = [k for k, r in enumerate(self.rows) if mask[r]]
        return dataclasses.replace(self, rows=tuple(int(position[self.rows[k]]) for k in keep),
                                   dcentre=None if self.dcentre is None else self.dcentre[keep],
                                   moved=None if self.moved is None else self.moved[keep],
                                   seen=None if self.seen is None else (self.seen[0], self.seen[1][keep]))

    @property
    def reason(self):
        """Why a bend BIC chose was not applied (None where it was, or where BIC chose none)."""
        if self.applied or self.degree == 0:
            return None
        if self.p_value >= ALPHA:
            return f"not clear: p = {self.p_value:.2g} >= {ALPHA:g}"
        if self.bend_mm < MIN_BEND_MM:
            return f"below {MIN_BEND_MM:g} mm"
        return f"steeper than a linearity error: above {100 * MAX_SLOPE:g} %"

    @property
    def why(self):
        """Why it was applied or not, in words."""
        if self.applied:
            return "corrected before the circle fits"
        return "none (BIC chooses no bend)" if self.degree == 0 else f"not corrected ({self.reason})"

    def to_dict(self):
        """JSON-ready summary."""
        return {"degree": self.degree, "applied": self.applied, "why": self.why, "bend_mm": self.bend_mm, "f": self.f,
                "p_value": self.p_value, "slope": self.slope, "depths_mm": list(self.depths), "profiles": len(self.rows),
                "beta_mm": [float(b) for b in self.beta], "offset_mm": float(self.offset),
                "beta_sd_mm": [float(s) for s in np.sqrt(np.clip(np.diag(self.covariance), 0, None))]}


def from_saved(saved):
    """The applied bend a saved calibration's ``cleaning.bend`` (:meth:`Bend.to_dict`) states, to correct other
    scans of the same sensor with (:meth:`Bend.corrected`); None where none was applied. Raises ValueError naming
    the key that does not hold what it should."""
    if not isinstance(saved, dict) or saved.get("applied") is not True:
        return None
    try:
        degree, depths = int(saved["degree"]), tuple(float(v) for v in saved["depths_mm"])
        beta, offset = np.array(saved["beta_mm"], float), float(saved["offset_mm"])
    except KeyError as exc:
        raise ValueError(f"no {exc.args[0]} (a file written before the bend was saved whole: calibrate again)") from None
    except (TypeError, ValueError):
        raise ValueError("degree, depths_mm, beta_mm and offset_mm must be numbers") from None
    if not (1 <= degree <= MAX_DEGREE and beta.shape == (degree,) and len(depths) == 2 and depths[0] < depths[1]
            and np.all(np.isfinite(beta)) and np.all(np.isfinite(depths)) and np.isfinite(offset)):
        raise ValueError(f"not a bend: degree 1-{MAX_DEGREE} with as many finite beta_mm, depths_mm lo < hi")
    return Bend(degree, beta, np.zeros((degree, degree)), depths, offset, float(saved.get("f", np.nan)),
                float(saved.get("p_value", np.nan)), float(saved.get("bend_mm", np.nan)), True, ())


def _basis(z, m, depths):
    lo, hi = depths
    u = np.clip((2 * z - lo - hi) / max(hi - lo, 1e-9), -1.0, 1.0)
    return legendre.legvander(u, m)[:, 1:]


def _slope_basis(z, m, depths):
    """d :func:`_basis` / dz (K, m), per mm (zero beyond ``depths``, where the basis is held)."""
    lo, hi = depths
    scale = 2.0 / max(hi - lo, 1e-9)
    u = (2 * z - lo - hi) * scale / 2
    inside = np.abs(u) <= 1.0
    u = np.clip(u, -1.0, 1.0)
    return np.column_stack([legendre.legval(u, legendre.legder(np.eye(m + 1)[j])) * scale * inside
                            for j in range(1, m + 1)]).reshape(len(z), m)


@dataclasses.dataclass(frozen=True)
class _Points:
    """A block of profiles' points in one array: ``seg`` the profile of each point (in the block), ``starts``
    the first point of each, ``basis`` (K, MAX_DEGREE) its Legendre columns minus their mean over every
    block (the correction keeps the mean depth)."""

    x: np.ndarray
    z: np.ndarray
    seg: np.ndarray
    starts: np.ndarray
    n: int
    basis: np.ndarray
    slope_basis: np.ndarray


@dataclasses.dataclass(frozen=True)
class _Blocks:
    """Profiles in blocks of at most :data:`BLOCK_POINTS` points, the depths the basis is scaled to and the
    basis's mean over every point."""

    blocks: tuple
    depths: tuple
    mean_basis: np.ndarray
    n: int
    n_points: int


def _thinned(p):
    return p[:: -(-len(p) // MAX_POINTS)]


def _blocks(profiles, depths=None, mean=None):
    """``profiles`` (thinned to :data:`MAX_POINTS` each) as :class:`_Blocks`; ``depths`` and ``mean`` (of the
    basis): these profiles' own unless given."""
    profiles = [_thinned(p) for p in profiles]
    if depths is None:
        depths = (min(float(p[:, 1].min()) for p in profiles), max(float(p[:, 1].max()) for p in profiles))
    groups, current, size = [], [], 0
    for p in profiles:
        if current and size + len(p) > BLOCK_POINTS:
            groups.append(current)
            current, size = [], 0
        current.append(p)
        size += len(p)
    groups.append(current)
    raw = [np.concatenate([p[:, 1] for p in group]) for group in groups]
    bases = [_basis(z, MAX_DEGREE, depths) for z in raw]  # once: their mean, then centred in place
    n_points = sum(len(z) for z in raw)
    mean = sum(b.sum(axis=0) for b in bases) / n_points if mean is None else mean
    blocks = []
    for group, z, basis in zip(groups, raw, bases):
        sizes = [len(p) for p in group]
        basis -= mean
        blocks.append(_Points(np.concatenate([p[:, 0] for p in group]), z, np.repeat(np.arange(len(group)), sizes),
                              np.concatenate([[0], np.cumsum(sizes)[:-1]]), len(group), basis,
                              _slope_basis(z, MAX_DEGREE, depths)))
    return _Blocks(tuple(blocks), depths, mean, len(profiles), n_points)


def _segment_sum(pts, values):
    """Per-profile sums of ``values`` (K, ...) -> (n, ...) (each profile's points are contiguous)."""
    return np.add.reduceat(values, pts.starts, axis=0)


def _reduced_block(pts, beta, circles):
    """:func:`_reduced` of one block (``circles`` its profiles')."""
    m = len(beta)
    basis, slope = pts.basis[:, :m], pts.slope_basis[:, :m]
    a, c, r = (circles[pts.seg, k] for k in range(3))
    res, jac = circle.distance_jacobian(pts.x, pts.z - basis @ beta, circle.Circle(a, c, r))
    # the correction scales a point's depth noise by 1 - b'(z): its distance is that noise's, so it is
    # divided by the sd it has (isotropic noise as measured), and the scale's derivative enters too
    # (without them a bend that squeezes the depth noise lowers the sum of squares: a bias growing as the
    # noise's square, clean profiles read as stretched)
    nx2, nz2, keep = jac[:, 0] ** 2, jac[:, 1] ** 2, 1.0 - slope @ beta
    w = np.sqrt(nx2 + nz2 * keep**2)
    g_cols = (jac[:, 1:2] * basis) / w[:, None] + (res * nz2 * keep / w**3)[:, None] * slope
    res, jac = res / w, jac / w[:, None]
    jj_inv = np.linalg.inv(_segment_sum(pts, jac[:, :, None] * jac[:, None, :]))
    jg = _segment_sum(pts, jac[:, :, None] * g_cols[:, None, :])
    jr = _segment_sum(pts, jac * res[:, None])
    gg = _segment_sum(pts, g_cols[:, :, None] * g_cols[:, None, :])
    gr = _segment_sum(pts, g_cols * res[:, None])
    s_i = gg - np.einsum("nkm,nkl,nlj->nmj", jg, jj_inv, jg)
    g_i = gr - np.einsum("nkm,nkl,nl->nm", jg, jj_inv, jr)
    return float(res @ res), (jj_inv, jg, jr, s_i, g_i)


def _reduced(data, beta, circles):
    """One Gauss-Newton linearisation at ``beta`` (m,) and ``circles`` (n, 3), the circles eliminated:
    ``(S, g, ssr, per_profile)`` with ``S`` (m, m) and ``g`` (m,) the reduced normal matrix and gradient,
    ``ssr`` the sum of squares and ``per_profile`` ``(JJ^-1, JG, Jr, S_i, g_i)`` for the circles' step,
    the jackknife and the centres' derivatives; block by block (:class:`_Blocks`)."""
    ssr, pieces, first = 0.0, [], 0
    for pts in data.blocks:
        block_ssr, block = _reduced_block(pts, beta, circles[first:first + pts.n])
        ssr, first = ssr + block_ssr, first + pts.n
        pieces.append(block)
    per_profile = tuple(np.concatenate(parts) for parts in zip(*pieces))
    return per_profile[3].sum(axis=0), per_profile[4].sum(axis=0), ssr, per_profile


def _circle_sums(jr, jj_inv):
    """The sum of squares the circles' own Gauss-Newton step removes (no bend)."""
    return float(np.einsum("nk,nkl,nl->", jr, jj_inv, jr))


def _degree(data, circles):
    """``(degree, ssr by degree, S, pieces)``: BIC's choice among 0..MAX_DEGREE from one reduced step at
    ``beta = 0``, and that step's reduced normal matrix and per-profile pieces (:func:`_reduced`)."""
    s, g, ssr, pieces = _reduced(data, np.zeros(MAX_DEGREE), circles)
    jj_inv, jr = pieces[0], pieces[2]
    ssr0 = ssr - _circle_sums(jr, jj_inv)
    ssrs = [ssr0] + [ssr0 - float(g[:m] @ np.linalg.solve(s[:m, :m], g[:m])) for m in range(1, MAX_DEGREE + 1)]
    n_obs = data.n_points
    bic = [n_obs * np.log(max(v, 1e-300) / n_obs) + (3 * data.n + m) * np.log(n_obs) for m, v in enumerate(ssrs)]
    return int(np.argmin(bic)), ssrs, s, pieces


def _fit(data, circles, m):
    """Gauss-Newton from ``beta = 0``, each step halved until the sum of squares falls: ``(beta, circles, S,
    pieces at the fit, ssr)``."""
    beta = np.zeros(m)
    s, g, ssr, pieces = _reduced(data, beta, circles)
    for _ in range(STEPS):
        jj_inv, jg, jr = pieces[:3]
        step = -np.linalg.solve(s, g)
        dcirc = -np.einsum("nkl,nl->nk", jj_inv, jr + jg @ step)
        for _ in range(8):  # halved until the sum of squares falls (a step too long for the linearisation)
            trial = _reduced(data, beta + step, circles + dcirc)
            if trial[2] <= ssr:
                break
            step, dcirc = step / 2, dcirc / 2
        else:
            break
        beta, circles = beta + step, circles + dcirc
        s, g, ssr, pieces = trial
    return beta, circles, s, pieces, ssr


def _circles_at(data, beta, circles, steps=3):
    """Each profile's circle with the bend ``beta`` held (Gauss-Newton on the circles alone)."""
    for _ in range(steps):
        _, _, _, (jj_inv, _, jr, _, _) = _reduced(data, beta, circles)
        circles = circles - np.einsum("nkl,nl->nk", jj_inv, jr)
    return circles


def _jackknife(s, pieces, beta):
    """Covariance (m, m) of ``beta`` by deleting each profile in turn (one reduced Newton step)."""
    _, _, _, s_i, g_i = pieces
    n = len(s_i)
    deleted = beta + np.linalg.solve(s[None] - s_i, g_i[..., None])[..., 0]
    dev = deleted - deleted.mean(axis=0)
    return (n - 1) / n * dev.T @ dev


def _dcentre(pieces, circles, radius, side):
    """Derivatives (n, 3, m) of the rebuilt centres (x, y, z) with respect to ``beta``; a circle as wide as
    the sphere (its centre's y has no derivative) gets none."""
    jj_inv, jg = pieces[0], pieces[1]
    dcirc = -np.einsum("nkl,nlm->nkm", jj_inv, jg)  # (a, c, r)
    r = circles[:, 2]
    inside = r < radius * (1 - 1e-9)
    y = np.where(inside, np.sqrt(np.where(inside, radius**2 - r**2, 1.0)), np.inf)
    return np.einsum("nij,njm->nim", circle.centre_jacobian(r, y, side), dcirc)


def _hyper_circles(profiles):
    return np.array([[c.x, c.z, c.r] for c in (circle.hyper(p[:, 0], p[:, 1]) for p in profiles)])


def _spread(n, most):
    """Indices of at most ``most`` of ``n`` items spread evenly over them."""
    return np.arange(n) if n <= most else np.unique(np.linspace(0, n - 1, most).round().astype(int))


def estimate(profiles, radius, side=-1):
    """The :class:`Bend` of a dataset's (cleaned) profiles, or None with fewer than :data:`MIN_PROFILES` (or
    profiles no fit can be made of).

    Parameters
    ----------
    profiles : sequence of ndarray, shape (K_i, 2), or None
        Sensor x, z of each profile's points, mm (sensor frame, the laser plane y = 0); None for a row
        without one.
    radius : float
        The sphere's, mm.
    side : int
        Sign of the sensor-y of the sphere centre (the rebuilt centres' derivatives).

    Notes
    -----
    Above :data:`MAX_FIT_PROFILES` profiles the bend is fitted on that many spread over the rows, every
    profile thinned to :data:`MAX_POINTS` points; the passes run in blocks of :data:`BLOCK_POINTS` points.
    """
    rows = tuple(k for k, p in enumerate(profiles) if p is not None and len(p) >= 5)
    if len(rows) < MIN_PROFILES:
        return None
    every = [np.asarray(profiles[k], float) for k in rows]
    chosen = _spread(len(rows), MAX_FIT_PROFILES)
    try:
        with np.errstate(divide="raise", over="raise", invalid="raise"):
            return _estimated(every, chosen, rows, radius, side)
    except (circle.CircleFitError, np.linalg.LinAlgError, FloatingPointError, ValueError):
        return None  # degenerate profiles: no bend can be told (the circles are fitted as they are)


def _estimated(every, chosen, rows, radius, side):
    data = _blocks([every[k] for k in chosen])
    start = _hyper_circles([every[k] for k in chosen])
    m, ssrs, s0, pieces0 = _degree(data, start)
    dof = data.n_points - 3 * data.n - max(m, 1)
    seen = None if len(chosen) < len(every) else (  # what the profiles see of a bend of SEEN_DEGREE
        s0[:SEEN_DEGREE, :SEEN_DEGREE] / (ssrs[0] / (data.n_points - 3 * data.n)),
        _dcentre((pieces0[0], pieces0[1][:, :, :SEEN_DEGREE]), start, radius, side))
    if m == 0:
        f = float((ssrs[0] - ssrs[1]) / (ssrs[1] / dof))
        return Bend(0, np.zeros(0), np.zeros((0, 0)), data.depths, 0.0, f, f_survival(f, 1, dof), 0.0, False, rows,
                    seen=seen)
    beta, circles, s, pieces, ssr = _fit(data, start, m)
    f = float(((ssrs[0] - ssr) / m) / (ssr / dof))
    cov = _jackknife(s, pieces, beta)
    p_value = max(f_survival(f, m, dof), _hotelling(beta, cov, data.n))
    grid = np.linspace(*data.depths, 201)
    curve = _basis(grid, m, data.depths) @ beta
    bend_mm, slope = float(curve.max() - curve.min()), float(np.max(np.abs(np.gradient(curve, grid))))
    applied = bool(p_value < ALPHA and bend_mm >= MIN_BEND_MM and slope <= MAX_SLOPE)
    if len(chosen) < len(every) and applied:  # the derivatives of every row's centre, at its own circle
        data = _blocks(every, data.depths, data.mean_basis)
        circles = _circles_at(data, beta, _hyper_circles(every))
        pieces = _reduced(data, beta, circles)[3]
    return Bend(m, beta, cov, data.depths, float(data.mean_basis[:m] @ beta), f, p_value, bend_mm, applied, rows,
                _dcentre(pieces, circles, radius, side) if applied else None, slope=slope, mean_basis=data.mean_basis[:m],
                seen=seen)


def _hotelling(beta, cov, n):
    """P-value of Hotelling's T^2 of ``beta`` against its jackknife covariance over ``n`` profiles:
    ``T^2 (n - m) / (m (n - 1))`` is F(m, n - m)."""
    m = len(beta)
    if n <= m:
        return 1.0
    t2 = float(beta @ np.linalg.lstsq(cov, beta, rcond=None)[0])
    return f_survival(t2 * (n - m) / (m * (n - 1)), m, n - m)


def apply(profiles, centres, radius, side=-1, fit="hyper"):
    """A dataset's profiles and sphere centres with their :class:`Bend` applied: ``(profiles, centres, bend)``.

    Rows without a profile keep their centre; every row with one has its centre rebuilt from the
    corrected profile (a centre the file gives beside its profile came from the same bent points).
    Unchanged where the bend is None or not applied; a bend BIC chooses but the tests do not make clear
    keeps what its correction would move each centre by (:attr:`Bend.moved`).

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
    if bend is None or not bend.degree:
        return list(profiles), list(centres), bend
    corrected = [None if p is None else bend.corrected(p) for p in profiles]
    out, moved = [np.asarray(c, float) for c in centres], np.zeros((len(bend.rows), 3))
    for k, row in enumerate(bend.rows):
        try:
            before, after = (circle.sphere_centre_from_circle(circle.fit_circle(p[:, 0], p[:, 1], fit), radius, side)
                             for p in (profiles[row], corrected[row]))
        except circle.CircleFitError:
            continue  # a circle as wide as the sphere: its centre as it was (its y has no derivative there)
        moved[k] = after - before  # the bend's own change: a centre the file gives moves by it too
        out[row] = out[row] + moved[k]
    bend = dataclasses.replace(bend, moved=moved)
    if not bend.applied:  # suggested, not clear: the data as they are, and what the correction would do
        return list(profiles), list(centres), bend
    return corrected, [list(c) for c in out], bend
