"""The names the application's options take, with no numpy behind them.

The command line builds its parser from these before it imports anything heavy (``handeye
--help`` must not pay for numpy); the modules that implement them re-export them
(:data:`handeye.app.engine.calibrate.METHODS`, :data:`handeye.app.engine.classic.METHODS`,
:data:`handeye.app.engine.robust.ALPHA`, :data:`handeye.app.outputs.formats.FORMATS`,
:data:`handeye.app.outputs.commands.CLOUD_FORMATS`).
"""
from __future__ import annotations

#: Least-squares methods of ``handeye calibrate`` (:mod:`handeye.app.engine.calibrate`).
METHODS = ("ipopt", "gn", "lm", "tr", "dogleg", "newton")
#: Closed-form baselines (:mod:`handeye.app.engine.classic`).
CLASSIC_METHODS = ("kim-cho", "li-two-step")
#: Family-wise significance level of the outlier tests (:mod:`handeye.app.engine.robust`).
ALPHA = 0.01
#: What ``handeye export`` writes (:mod:`handeye.app.outputs.formats`).
FORMATS = ("ur", "ros2", "urdf", "kuka", "abb", "fanuc", "matrix", "json")
#: The robot's nominal model corrected by a calibration's joint offsets (export --format).
ROBOT_FORMATS = ("robot-toml", "robot-urdf")
#: What ``handeye cloud`` writes (:mod:`handeye.app.outputs.commands`).
CLOUD_FORMATS = ("ply", "csv")
