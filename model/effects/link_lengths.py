"""``link_lengths``: errors (mm) of the robot's nominal lengths and offsets -- the data sheet's
link lengths the controller's model uses, which a real arm misses by a few tenths of a
millimetre (machining, assembly, thermal growth).

The translation of each joint's fixed transform (a chain model's joint origin, a DH model's
``(a, 0, d)``) moved in its nonzero components (:mod:`handeye.model.robot.robot_errors`); parameters
``j<k>_<x|y|z>`` (chain) or ``a<k>``, ``d<k>`` (DH), in mm. The flange the robot really reached
is ``F_rep T(q)^-1 T*(q)``, exact derivatives by the chain's product rule. Not every length is
measurable from one fixed sphere: a length before the first joint's rotation moves the whole arm
(the sphere centre absorbs it), a length along the last joint's axis moves the flange in its own
frame (the sensor translation absorbs it); only the lengths this pose set separates are
estimated, the others reported as absorbed.
"""
from handeye.model.effects.joint_offsets import available  # noqa: F401 (the same data make it visible)
from handeye.model.robot import robot_errors

KIND = "robot"
NAME = "link_lengths"
#: Parameters depend on the robot model (:func:`params`): these are the KR 60 HA's.
PARAMS = ("j2_x", "j2_z", "j3_x", "j4_x", "j4_z", "j5_x", "j6_x")
#: Unit of the parameters (:mod:`handeye.model.fit.power` states sizes in it; "" dimensionless).
UNIT = "mm"
DOC = "errors of the robot's nominal link lengths and offsets (mm)"


def params(model):
    """The parameter names on ``model`` (its nonzero nominal lengths)."""
    return robot_errors.param_names(model, NAME)
