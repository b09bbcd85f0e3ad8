"""``sphere_radius``: the true radius exceeds the setup's by dr mm.

The centre's y was reconstructed as ``sqrt(R^2 - r^2)`` with the setup's R; with the true
radius ``R + dr`` it is ``y = sign(ym) sqrt((R + dr)^2 - R^2 + ym^2)`` -- wrong by about
``(R / |y|) dr``, most where the laser plane passes near the centre.

A physical bound: a plane cuts a sphere in a circle no larger than the sphere, so ``R + dr``
cannot be smaller than a circle measured on it (:func:`contradicted_by`). The same gain
``(R + dr) / |y|`` that makes dr visible near the equator makes its 1-sd small there. The
linearised sd is right while the fit is a regular minimum: within about 10 % of a Monte Carlo
on simulated data with the planes 1 mm or more from the equator (tests/test_effect_sd.py);
1.4 x too small at 0.5 mm, where y's own noise, growing like r/|y|, is not in the model. Where
the fit runs into the bound (a corrected y of 0, an infinite derivative) it is no minimum, and
calibrate says so instead of reporting it.
"""
import numpy as np

KIND = "data"
NAME = "sphere_radius"
PARAMS = ("dr",)
#: its correction rebuilds y from the sphere's radius: it needs [sphere] diameter (handeye.model.effects.needs_diameter)
NEEDS_DIAMETER = True
#: Unit of the parameters (:mod:`handeye.model.fit.power` states sizes in it; "" dimensionless).
UNIT = "mm"
DOC = "true radius minus the setup's, mm"
#: A radius this many of a circle's 1-sd below the circle's fitted radius contradicts the profile.
CIRCLE_SD = 3.0


def correction(xm, ym, zm, radius, params):
    import sympy as sp  # only when the correction is derived (a cache miss), never on a warm start

    (dr,) = params
    return [xm, sp.sign(ym) * sp.sqrt((radius + dr) ** 2 - radius**2 + ym**2), zm]


def contradicted_by(params, radius, circles):
    """Why the radius ``radius + dr`` is smaller than what the measured circles show (text),
    or None.

    Parameters
    ----------
    params : array_like, shape (1,)
        ``dr``, mm.
    radius : float
        The setup's sphere radius, mm.
    circles : tuple (ids, r, sd)
        Per sample its id, the radius of the circle the laser plane cut (mm: a profile's fitted
        circle, or ``sqrt(R^2 - ys^2)`` of a centre given without one) and that radius's 1 sd
        (0 when not known).
    """
    ids, r, sd = circles
    r, sd = np.asarray(r, float), np.asarray(sd, float)
    if not len(r):
        return None
    fitted = radius + float(np.ravel(params)[0])
    excess = (r - CIRCLE_SD * sd) - fitted
    k = int(np.nanargmax(excess))
    if not excess[k] > 0:
        return None
    shown = f"{r[k]:.4f}" + (f" +- {sd[k]:.4f}" if sd[k] > 0 else "")
    return (f"sphere_radius would need dr = {float(np.ravel(params)[0]):.4g} mm, a sphere radius of {fitted:.4f} mm, "
            f"below the {shown} mm circle that sample {ids[k]!r} measured on it (by {excess[k] + CIRCLE_SD * sd[k]:.4f} "
            "mm): a plane cuts a sphere in a circle no larger than the sphere, so the fitted radius absorbs something "
            "else (a sphere centre offset, a wrong [profile] side or a gross error?); it is not named")
