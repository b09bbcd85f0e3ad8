"""``centre_scale``: the measured centre is scaled by 1 + s in all three coordinates.

A 3-D sensor's scale error, or that of a file of centres computed elsewhere: every coordinate
of the centre the sensor reports comes out (1 + s) times too large. A line scanner's scale acts
otherwise (``sensor_scale``: x and z scale, y is rebuilt from the scaled circle's radius); both
are in the catalogue, and the search names the one the data show. The correction:
``(x, y, z) = (xm, ym, zm) / (1 + s)``.

Measured before it was added: a 0.5 % scale of this kind, on every cell of an independent
generator (sensor on the flange, fixed in the cell, sphere on a positioner), calibrated with
exit 0 at 1.0-1.2 mm and 20-53 reported sd from the truth (the line scanner's ``sensor_scale``
does not describe it, and nothing else did).
"""
KIND = "data"
NAME = "centre_scale"
PARAMS = ("s",)
DOC = "scale error of the measured centre's three coordinates (dimensionless; 0.001 = 0.1 %)"


def correction(xm, ym, zm, radius, params):
    (s,) = params
    return [xm / (1 + s), ym / (1 + s), zm / (1 + s)]
