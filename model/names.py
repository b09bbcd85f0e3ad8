"""The names the model's options take, with no numpy behind them.

The command line offers these as choices before it imports anything heavy (``handeye
--help`` must not pay for numpy); :mod:`handeye.model.calibration` and
:mod:`handeye.model.conventions` define their behaviour and re-export them.
"""
from __future__ import annotations

#: What a calibration estimates (:mod:`handeye.model.calibration`).
UNKNOWNS = ("sensor", "sensor+sphere")
#: Names of the rotation parametrisations of the unknown sensor rotation (handeye.model.symbolic uses these).
ROTATIONS = ("euler", "matrix", "local")
#: Residual kinds and the rows of one residual (handeye.model.symbolic uses these).
KINDS = {"centre": 3, "measurement": 3, "points": 1}
#: Robot-brand rotation conventions and their parameters (units); handeye.model.symbolic derives each.
CONVENTIONS = {
    "kuka": ("a", "b", "c"),  # A, B, C in degrees: Rz(A) Ry(B) Rx(C), intrinsic Z-Y'-X''
    "fanuc": ("w", "p", "r"),  # W, P, R in degrees: fixed X-Y-Z, i.e. Rz(R) Ry(P) Rx(W)
    "abb": ("q1", "q2", "q3", "q4"),  # unit quaternion w, x, y, z
    "ur": ("rx", "ry", "rz"),  # rotation vector in radians: exp([r]x)
}
