"""``sensor_scale``: the sensor's coordinates are scaled by 1 + s (a triangulation scale error).

The profile's points, so the fitted circle's centre (xc, zc) and radius r, come out (1 + s)
times too large, while y is reconstructed from r as ``sqrt(R^2 - r^2)``. The correction:
``x = xm / (1 + s)``, ``z = zm / (1 + s)``, ``r = rm / (1 + s)`` with ``rm^2 = R^2 - ym^2``, and
``y = sign(ym) sqrt(R^2 - r^2)``.
"""
KIND = "data"
NAME = "sensor_scale"
PARAMS = ("s",)
#: its correction rebuilds y from the sphere's radius: it needs [sphere] diameter (handeye.model.effects.needs_diameter)
NEEDS_DIAMETER = True
#: Unit of the parameters (:mod:`handeye.model.fit.power` states sizes in it; "" dimensionless).
UNIT = ""
DOC = "scale error of the sensor's coordinates (dimensionless; 0.001 = 0.1 %)"


def correction(xm, ym, zm, radius, params):
    import sympy as sp  # only when the correction is derived (a cache miss), never on a warm start

    (s,) = params
    r2 = (radius**2 - ym**2) / (1 + s) ** 2
    return [xm / (1 + s), sp.sign(ym) * sp.sqrt(radius**2 - r2), zm / (1 + s)]
