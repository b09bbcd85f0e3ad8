"""``sphere_center``: the sphere centre differs from the setup's by (dx, dy, dz) mm, base frame.

The residual ``e = R1 (R2 xs + t2) + t1 - (c + d)`` has columns ``-I`` for d. Estimated by
making the centre an unknown (``--unknowns sensor+sphere``); reported as ``c_est - c_setup``.
"""
KIND = "centre"
NAME = "sphere_center"
PARAMS = ("dx", "dy", "dz")
#: Unit of the parameters (:mod:`handeye.model.fit.power` states sizes in it; "" dimensionless).
UNIT = "mm"
DOC = "sphere centre offset from the setup's, mm (in its mount's frame: the robot base, the flange or the table)"
