"""The names the model's options take, defined once where nothing is imported.

:mod:`handeye.model.chain.symbolic` derives a function for each of them and the numeric modules
(:mod:`handeye.model.fit.calibration`, :mod:`handeye.model.chain.conventions`) validate requests against
them and re-export them; both import this leaf module, so neither imports the other (and
numpy-only code never imports sympy). The command line offers them as choices before it
imports anything heavy (``handeye --help`` does not pay for numpy).
"""
from __future__ import annotations

#: What a calibration estimates (:mod:`handeye.model.fit.calibration`).
UNKNOWNS = ("sensor", "sensor+sphere")
#: The parts ``--unknowns`` may join with ``+``, in their canonical order (:mod:`handeye.model.fit.cell`).
PARTS = ("sensor", "sphere", "positioner")
#: Where the sensor and the sphere may be mounted (:mod:`handeye.model.chain.mounts`).
SENSOR_MOUNTS = ("flange", "world")
SPHERE_MOUNTS = ("world", "flange", "positioner")
#: Names of the rotation parametrisations of the unknown sensor rotation.
ROTATIONS = ("euler", "matrix", "local")
#: Residual kinds and the rows of one residual.
KINDS = {"centre": 3, "measurement": 3, "points": 1}
#: Robot-brand rotation conventions and their parameters (units).
CONVENTIONS = {
    "kuka": ("a", "b", "c"),  # A, B, C in degrees: Rz(A) Ry(B) Rx(C), intrinsic Z-Y'-X''
    "fanuc": ("w", "p", "r"),  # W, P, R in degrees: fixed X-Y-Z, i.e. Rz(R) Ry(P) Rx(W)
    "abb": ("q1", "q2", "q3", "q4"),  # unit quaternion w, x, y, z
    "ur": ("rx", "ry", "rz"),  # rotation vector in radians: exp([r]x)
}
