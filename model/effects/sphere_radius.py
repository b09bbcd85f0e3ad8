"""``sphere_radius``: the true radius exceeds the setup's by dr mm.

The centre's y was reconstructed as ``sqrt(R^2 - r^2)`` with the setup's R; with the true
radius ``R + dr`` it is ``y = sign(ym) sqrt((R + dr)^2 - R^2 + ym^2)`` -- wrong by about
``(R / |y|) dr``, most where the laser plane passes near the centre.
"""
KIND = "data"
NAME = "sphere_radius"
PARAMS = ("dr",)
DOC = "true radius minus the setup's, mm"


def correction(xm, ym, zm, radius, params):
    import sympy as sp  # only when the correction is derived (a cache miss), never on a warm start

    (dr,) = params
    return [xm, sp.sign(ym) * sp.sqrt((radius + dr) ** 2 - radius**2 + ym**2), zm]
