"""Is a profile an arc of the stated sphere? The test, per (cleaned) profile.

A plane cuts a sphere of radius R in a circle of radius ``r <= R``; a laser-line sensor sees an
arc of it, its points scattered about the circle by the sensor's noise. The circle fit that
reconstructs the sphere centre (:mod:`handeye.model.geometry.circle`) assumes exactly this, and
returns a circle for almost any points: a flat face, an edge target's two faces (a corner), two
pieces with a step between them. Those give centres millimetres off (a real edge target declared
as a sphere calibrated at RMS 5 mm and exit 0). Two checks, each against the noise model the
circle fit already has (independent points about one circle, their scatter estimated from the
profile itself):

0. **Scatter.** Its points scatter about their circle by more than :data:`MAX_SCATTER_MM` RMS:
   no sensor's noise on a sphere does (speckle or background an uncleaned profile kept).
1. **Wider than the sphere.** The fitted circle's radius exceeds R by more than its tolerance
   (:data:`RADIUS_TOL`, :data:`RADIUS_BAND_MM`, the cleaning's, :mod:`handeye.model.geometry.profile_clean`):
   no plane cuts this sphere so (a straight line is a circle of radius ~infinity).
2. **Not one circle.** The alternative with more parameters: each half of the arc (split at its
   median angle about the fitted circle) its own circle. On an arc both halves are the same circle
   and the sum of squares falls by noise alone, ``F = ((S1 - S2) / 3) / (S2 / (K - 6)) ~ F(3, K - 6)``;
   on a corner or a step each half is straight (or its own piece) and ``S1`` is all structure. The
   profile is no arc when ``F`` is improbable at :data:`ALPHA` (Bonferroni over the dataset's
   profiles), the structure the one circle misses is physical (its RMS ``sqrt((S1 - S2) / K)``
   exceeds :data:`MIN_FORM_MM`), **and** that structure is a flat piece: a half's own circle is
   wider than :data:`HALF_WIDER` R, flatter than any cut of the sphere.

Why all three: a real sensor's profile departs from a circle by more than its noise (the
sphere's form, the sensor's linearity, speckle correlated along the line), so with thousands of
points the F test alone is significant on good real profiles. The RobCalibrator scans (the real
profiles in tests/data) show F up to 1,300 and a missed structure up to 0.009 mm RMS (R 40 mm
sensor) and 0.097 mm (the 1-in ball's sensor), but their halves stay circles of the sphere: the
flatter half at most 1.03 R. An edge target's faces or a step's pieces are straight: of 40
independent corner profiles (tests/indep_arcs.py) after cleaning, 7 are circles wider than the
sphere, 8 scatter over 1 mm, and the other 25 have a flatter half of at least 65 R and a
structure of at least 0.18 mm. HALF_WIDER = 1.5 lies between, with room on both sides; the
structure floor MIN_FORM_MM = 0.02 mm is the cleaning's scale floor
(:data:`profile_clean.SCALE_FLOOR_MM`: a laser-line sensor's point noise is not below it), so that
noise alone never names a profile.

Why ``ALPHA = 1e-3`` with Bonferroni: a profile judged no arc is excluded (and a set of them
refused), so the test is strict, as the row-consistency check (:mod:`handeye.model.datasets.consistency`)
is for the same reason.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from handeye.model.common.statistics import f_survival
from handeye.model.geometry import circle, profile_clean

#: Family-wise level of the one-circle test over a dataset's profiles (module docstring).
ALPHA = 1e-3
#: The structure a circle misses must exceed this RMS (mm) to call a profile no arc (module docstring).
MIN_FORM_MM = 0.02
#: A circle is wider than the sphere when ``r > R (1 + RADIUS_TOL) + RADIUS_BAND_MM`` (the cleaning's rule).
RADIUS_TOL = profile_clean.RADIUS_TOL
RADIUS_BAND_MM = profile_clean.BAND_MM
#: A profile whose points scatter more than this RMS about their circle (mm) is no arc: the
#: cleaning's window (:data:`profile_clean.WINDOW_MM`, the distances it takes for an arc's scale);
#: real profiles scatter 0.01 mm (RobCalibrator's R 40 mm scanner) to 0.17 mm (its 1-in ball's).
MAX_SCATTER_MM = profile_clean.WINDOW_MM
#: A half of the arc is flatter than any cut of the sphere when its own circle's radius exceeds
#: HALF_WIDER R (module docstring).
HALF_WIDER = 1.5
#: Fewer points per half cannot tell a corner from noise: the test needs at least this many.
MIN_HALF_POINTS = 8


@dataclasses.dataclass(frozen=True)
class ArcVerdict:
    """One profile judged (sensor x-z plane, mm).

    Attributes
    ----------
    arc : bool
        An arc of the stated sphere.
    reason : str
        Why not, in words (empty for an arc).
    radius_mm : float
        The fitted circle's radius (inf when no circle fits).
    form_mm : float
        RMS of the structure one circle misses against one per half, mm (NaN when not tested).
    f_stat : float
        Its F statistic on (3, K - 6) degrees of freedom (NaN when not tested).
    p_value : float
        Its tail probability, Bonferroni-adjusted (NaN when not needed: the structure is no flat
        piece, or too small).
    """

    arc: bool
    reason: str
    radius_mm: float
    form_mm: float = float("nan")
    f_stat: float = float("nan")
    p_value: float = float("nan")


def _ssr(x, z):
    """Sum of squared orthogonal distances from the points' circle, and the circle: the Hyper fit
    (:func:`handeye.model.geometry.circle.hyper`, the one that reconstructs the centre; one SVD, where
    the geometric fit's iterations would cost a load a second), whose sum exceeds the geometric
    minimum only to second order in the noise."""
    c = circle.fit_circle(x, z, "hyper")
    d, _ = circle.distance_jacobian(x, z, c)
    return float(d @ d), c


def halves(x, z, whole, s1):
    """One circle per half of the arc against ``whole`` (module docstring, 2).

    Parameters
    ----------
    x, z : ndarray, shape (K,)
        The points, sensor x and z, mm.
    whole : handeye.model.geometry.circle.Circle
        Their one circle.
    s1 : float
        Its sum of squared distances, mm^2.

    Returns
    -------
    (form_mm, f_stat, half_mm) : (float, float, float)
        The RMS of the structure one circle misses (mm), F on (3, K - 6) degrees of freedom and the
        larger of the halves' radii (mm); NaN when a half has fewer than :data:`MIN_HALF_POINTS` points.
    """
    k = len(x)
    angle = np.arctan2(z - whole.z, x - whole.x)
    order = np.argsort(angle)
    theta = angle[order]
    gaps = np.diff(np.r_[theta, theta[0] + 2 * np.pi])
    along = np.roll(order, -((int(np.argmax(gaps)) + 1) % k))  # the arc begins after its largest empty stretch
    first, second = along[: k // 2], along[k // 2:]
    if min(len(first), len(second)) < MIN_HALF_POINTS:
        return float("nan"), float("nan"), float("nan")
    (sa, ca), (sb, cb) = _ssr(x[first], z[first]), _ssr(x[second], z[second])
    drop = max(s1 - sa - sb, 0.0)
    return float(np.sqrt(drop / k)), float((drop / 3.0) / max((sa + sb) / (k - 6), 1e-300)), max(ca.r, cb.r)


def check(points, radius, n_tests=1, alpha=ALPHA, min_form_mm=MIN_FORM_MM):
    """Judge one profile (module docstring).

    Parameters
    ----------
    points : array_like, shape (K, 2)
        The (cleaned) profile: sensor x, z, mm.
    radius : float
        The stated sphere's radius R, mm.
    n_tests : int
        Profiles judged in the dataset (Bonferroni).
    alpha : float
    min_form_mm : float

    Returns
    -------
    ArcVerdict
    """
    pts = np.asarray(points, float).reshape(-1, 2)
    x, z = pts[:, 0], pts[:, 1]
    try:
        s1, fitted = _ssr(x, z)
    except circle.CircleFitError as exc:
        return ArcVerdict(False, f"no circle fits its {len(pts)} points ({exc})", float("inf"))
    scatter = float(np.sqrt(s1 / len(x)))
    if scatter > MAX_SCATTER_MM:
        return ArcVerdict(False, f"its points scatter {scatter:.3g} mm RMS about their circle, more than "
                                 f"{MAX_SCATTER_MM:g} mm: not one arc (speckle, background, another object)", fitted.r)
    if fitted.r > radius * (1 + RADIUS_TOL) + RADIUS_BAND_MM:
        return ArcVerdict(False, f"fitted circle radius {fitted.r:.3f} mm exceeds the sphere radius {radius:.3f} mm "
                                 "(no plane cuts the sphere so: a flat or wider surface)", fitted.r)
    if scatter <= min_form_mm:  # the structure a circle misses is at most its scatter: an arc
        return ArcVerdict(True, "", fitted.r)
    form, f_stat, half = halves(x, z, fitted, s1)
    if not (form > min_form_mm and half > HALF_WIDER * radius):
        return ArcVerdict(True, "", fitted.r, form, f_stat)
    p = min(f_survival(f_stat, 3, len(x) - 6) * n_tests, 1.0)
    if p >= alpha:
        return ArcVerdict(True, "", fitted.r, form, f_stat, p)
    return ArcVerdict(False, f"its halves are not one circle: a half is flatter than any cut of the sphere (radius "
                             f"{half:.3g} mm), one circle misses {form:.3f} mm RMS (F = {f_stat:.3g}, Bonferroni p = "
                             f"{p:.2g} < {alpha:g}): a corner, an edge or a step", fitted.r, form, f_stat, p)
