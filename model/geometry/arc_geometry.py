"""What a profile's arc says about how well it determines the sphere centre.

A laser profile is an arc of the circle where the laser plane (the sensor's y = 0) cuts the
sphere (radius R). The circle's centre ``(xc, zc)`` and radius r give the sphere centre in the
sensor frame, ``(xc, side sqrt(R^2 - r^2), zc)``; how well depends on the arc:

* its **span** (the angle it subtends at the circle's centre): a short arc leaves the centre
  and the radius poorly determined (their sd grow like the inverse square and cube of the span);
* whether it is **one-sided**: all its points on one side of the circle's centre (x), so that
  it misses the point nearest the sensor -- the measuring window cut it -- and the centre slides
  along the arc's chord with the radius;
* its **distance from the equator**, ``|y| = sqrt(R^2 - r^2)``: the sphere centre's y moves by
  ``dy = -(r / |y|) dr``, so near the equator (small |y|) a radius error of microns is a y
  error of a millimetre;
* its number of **points**.

:func:`describe` measures these and the centre's sd (:func:`handeye.model.geometry.circle.circle_covariance`
with the profile's own scatter, propagated by :func:`handeye.model.geometry.circle.centre_covariance`);
:func:`cause` names them for one profile against the others, only when the numbers support it:

* the centre's sd along some axis exceeds :data:`SD_RATIO` times the median of the other
  profiles' along that axis (on clean simulated datasets -- 5 seeds, 180 profiles of the
  thesis's design -- the largest such ratio is 4.1, the 99th percentile 4.0: a ratio of 5 is a
  badly determined centre, not the spread of a good design);
* and, given the sample's prediction error, the profile's own uncertainty accounts for it: the
  error is at most :data:`EXPLAINS` times the centre's total sd (a robot pose 2 mm off on a good
  profile is not explained by a 0.01 mm sd).

The features named are those past their thresholds (:data:`SHORT_DEG`, :data:`NEAR_EQUATOR`,
:data:`FEW_POINTS`; one-sidedness is a fact).
"""
from __future__ import annotations

import dataclasses

import numpy as np

from handeye.model.geometry import circle

#: A profile's centre is badly determined when its sd along an axis exceeds this many times the
#: median of the other profiles' sd along that axis.
SD_RATIO = 5.0
#: The profile explains an error up to this many times its centre's total sd.
EXPLAINS = 5.0
#: An arc spanning less than this (degrees) is short: the centre's sd grows like span^-2 below
#: about 90 degrees.
SHORT_DEG = 60.0
#: The plane is near the equator when |y| < NEAR_EQUATOR R: there r/|y| > 3.2, so y's error is
#: more than three times the radius's.
NEAR_EQUATOR = 0.3
#: Few points: fewer than this fraction of the other profiles' median number.
FEW_POINTS = 0.25
AXES = ("x", "y", "z")


@dataclasses.dataclass(frozen=True)
class ArcGeometry:
    """One profile's arc (sensor frame, mm and degrees).

    Attributes
    ----------
    n_points : int
    span_deg : float
        Angle the arc subtends at its circle's centre.
    one_sided : bool
        Every point on one side of the circle's centre in x (the arc misses the point nearest
        the sensor).
    equator_mm : float
        Distance of the laser plane from the sphere's centre, ``sqrt(max(R^2 - r^2, 0))``.
    radius_mm : float
        The fitted circle's radius r.
    centre_sd : ndarray, shape (3,)
        1-sd of the sphere centre reconstructed from the arc, along the sensor's x, y, z.
    """

    n_points: int
    span_deg: float
    one_sided: bool
    equator_mm: float
    radius_mm: float
    centre_sd: np.ndarray


def describe(points, radius, side=-1):
    """The :class:`ArcGeometry` of a profile.

    Parameters
    ----------
    points : array_like, shape (K, 2)
        Sensor x, z, mm (the cleaned profile).
    radius : float
        The sphere's radius R, mm.
    side : {-1, 1}
        ``[profile] side`` (the sign of the centre's y; the sd does not depend on it).

    Returns
    -------
    ArcGeometry or None
        None when no circle fits the points.
    """
    pts = np.asarray(points, float).reshape(-1, 2)
    try:
        fitted = circle.fit_circle(pts[:, 0], pts[:, 1], "geometric")
        cov = circle.circle_covariance(pts[:, 0], pts[:, 1], fitted)
    except (circle.CircleFitError, np.linalg.LinAlgError):
        return None
    theta = np.sort(np.arctan2(pts[:, 1] - fitted.z, pts[:, 0] - fitted.x))
    gaps = np.diff(np.r_[theta, theta[0] + 2 * np.pi])
    span = 360.0 - np.degrees(gaps.max())  # the circle less its largest empty stretch
    dx = pts[:, 0] - fitted.x
    sd = np.sqrt(np.clip(np.diag(circle.centre_covariance(fitted, cov, radius, side)), 0.0, None))
    return ArcGeometry(len(pts), float(span), bool(np.all(dx > 0) or np.all(dx < 0)),
                       float(np.sqrt(max(radius**2 - fitted.r**2, 0.0))), float(fitted.r), sd)


def cause(geometry, others, radius, error_mm=None):
    """The geometric cause of a badly determined centre, in words, or None.

    Parameters
    ----------
    geometry : ArcGeometry
        The profile in question.
    others : sequence of ArcGeometry
        The dataset's other profiles (their medians are the reference).
    radius : float
        The sphere's radius R, mm.
    error_mm : float, optional
        The sample's prediction error (mm): named only when at most :data:`EXPLAINS` times the
        centre's total sd (NaN: never named).

    Returns
    -------
    str or None
        E.g. ``'short (38 deg), one-sided arc 5.5 mm from the equator: the centre's sd along y is
        0.9 mm (21x the other profiles' median 0.042 mm)'``; None when no axis's sd exceeds
        :data:`SD_RATIO` times the others' median (or there are no others), or when the sd does
        not account for ``error_mm``.
    """
    others = [g for g in others if g is not None]
    if geometry is None or not others:
        return None
    median = np.median([g.centre_sd for g in others], axis=0)
    ratio = geometry.centre_sd / np.maximum(median, 1e-12)
    axis = int(np.argmax(ratio))
    if not ratio[axis] > SD_RATIO:
        return None
    if error_mm is not None and not error_mm <= EXPLAINS * float(np.linalg.norm(geometry.centre_sd)):
        return None
    words = []
    if geometry.span_deg < SHORT_DEG:
        words.append(f"short ({geometry.span_deg:.0f} deg)")
    if geometry.one_sided:
        words.append("one-sided")
    if geometry.n_points < FEW_POINTS * np.median([g.n_points for g in others]):
        words.append(f"few-point ({geometry.n_points})")
    where = (f" {geometry.equator_mm:.1f} mm from the equator" if geometry.equator_mm < NEAR_EQUATOR * radius else "")
    arc = (", ".join(words) + " arc" + where) if words or where else "its arc"
    return (f"{arc}: the centre's sd along {AXES[axis]} is {geometry.centre_sd[axis]:.2g} mm "
            f"({ratio[axis]:.0f}x the other profiles' median {median[axis]:.2g} mm)")


def causes(profiles, radius, side, which, errors=None):
    """:func:`cause` of the profiles ``which`` (indices) against all the others.

    Parameters
    ----------
    profiles : sequence of ndarray (K_i, 2) or None
        A dataset's (cleaned) profiles; None where a sample has none.
    radius : float
    side : {-1, 1}
    which : sequence of int
    errors : sequence of float, optional
        The prediction errors (mm) of ``which``, in order (:func:`cause`'s ``error_mm``).

    Returns
    -------
    dict
        Index -> sentence, for those of ``which`` with a cause.
    """
    geoms = [None if p is None else describe(p, radius, side) for p in profiles]
    out = {}
    for k, error in zip(which, [None] * len(which) if errors is None else errors):
        text = cause(geoms[k], [g for j, g in enumerate(geoms) if j != k], radius, error)
        if text is not None:
            out[k] = text
    return out
