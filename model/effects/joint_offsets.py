"""``joint_offsets``: a zero offset of each robot joint (degrees), the most common systematic error
of an industrial arm (its encoders' zero positions, mastering).

The flange the robot really reached is ``F_rep T(q)^-1 T(q + delta)``: the reported pose moved by
the nominal model's (:mod:`handeye.model.robot.robots`) change for the offsets ``delta``, so what the
controller's own, calibrated model knows stays in. Its derivative is the chain's, exact
(:func:`handeye.model.robot.robots.offset_derivatives`). Needs the joint angles ``j1..j6`` and
``[robot] model``. Not every joint is measurable: a first-joint offset turns the whole robot
about the base axis (the sphere centre absorbs it), a last-joint offset turns the flange about
its axis (the sensor's rotation absorbs it); only the joints this pose set separates from the
sensor pose and the sphere centre are estimated, the others are reported as absorbed.
"""
KIND = "robot"
NAME = "joint_offsets"
PARAMS = ("j1", "j2", "j3", "j4", "j5", "j6")
#: Unit of the parameters (:mod:`handeye.model.fit.power` states sizes in it; "" dimensionless).
UNIT = "deg"
DOC = "zero offsets of the robot's joints (degrees)"


def params(model):
    """The parameter names on ``model`` (every model has six joints)."""
    return PARAMS


def available(dataset):
    """Whether a dataset can show this effect: joint angles and a robot model, the sensor or the
    sphere fixed in the cell (the corrected flange poses enter the cell's carrier motions). Not
    with the sphere on a positioner: there the turning axes, refined first, absorb the robot's
    errors in part, and what remains is not attributable (tried: a named centre offset that is
    not there beside the robot effects)."""
    return (getattr(dataset, "joints", None) is not None and getattr(dataset, "robot_model", None) is not None
            and dataset.mounts.sphere != "positioner")
