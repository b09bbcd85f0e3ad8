"""The names the application's options take, with no numpy behind them.

The command line builds its parser from these before it imports anything heavy (``handeye
--help`` must not pay for numpy); the modules that implement them re-export them
(:data:`handeye.app.calibrate.METHODS`, :data:`handeye.app.classic.METHODS`,
:data:`handeye.app.robust.ALPHA`, :data:`handeye.app.export.FORMATS`,
:data:`handeye.app.use.CLOUD_FORMATS`).
"""
from __future__ import annotations

#: Least-squares methods of ``handeye calibrate`` (:mod:`handeye.app.calibrate`).
METHODS = ("ipopt", "gn", "lm", "tr", "dogleg", "newton")
#: Closed-form baselines (:mod:`handeye.app.classic`).
CLASSIC_METHODS = ("kim-cho", "li-two-step")
#: Family-wise significance level of the outlier tests (:mod:`handeye.app.robust`).
ALPHA = 0.01
#: What ``handeye export`` writes (:mod:`handeye.app.export`).
FORMATS = ("ur", "ros2", "urdf", "kuka", "abb", "fanuc", "matrix", "json")
#: What ``handeye cloud`` writes (:mod:`handeye.app.use`).
CLOUD_FORMATS = ("ply", "csv")
