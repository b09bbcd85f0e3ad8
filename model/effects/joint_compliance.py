"""``joint_compliance``: gravity deflection of the shoulder and the elbow (joints 2 and 3),
proportional to the load torque -- the error that makes a heavy arm's absolute accuracy depend on
how far it reaches out.

Each joint turns by ``k_j l_j(q)`` degrees with ``l_j`` the flange's horizontal lever about the
joint's axis in metres (:mod:`handeye.model.robot.robot_errors`: gravity along the robot base's -z, a
floor-mounted robot); parameters ``j2``, ``j3`` in degrees per metre (compliance times the load's
weight; positive sags the load). Unlike a zero offset, which turns the joint by the same angle
everywhere, the deflection grows with the reach: poses at one reach cannot tell the two apart
(the identifiability gate then masks it and says so).
"""
from handeye.model.effects.joint_offsets import available  # noqa: F401 (the same data make it visible)
from handeye.model.robot import robot_errors

KIND = "robot"
NAME = "joint_compliance"
PARAMS = ("j2", "j3")
#: Unit of the parameters (:mod:`handeye.model.fit.power` states sizes in it; "" dimensionless).
UNIT = "deg/m"
DOC = "gravity deflection of shoulder and elbow (degrees per metre of lever)"


def params(model):
    """The parameter names on ``model``."""
    return robot_errors.param_names(model, NAME)
