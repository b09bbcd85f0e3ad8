"""One error hierarchy for bad input.

Every error that means "the input cannot be used as given" -- a malformed dataset, a bad
option, observations that lack what a model needs, a simulation that cannot be made, a
value invalid in its robot convention, motions a method needs but the data lack, poses that
do not determine the unknowns -- derives from :class:`InputError`. The command line maps
exactly this class to exit code 2 and anything else to exit code 3 (a bug), so a bug can never
pass as bad input. ``InputError`` is a ``ValueError``, so code that catches ``ValueError``
keeps working.

=========================================  =====================================  =====
class                                       raised for                             where
=========================================  =====================================  =====
``DatasetError``                            a file, row or column of a dataset      model.dataset
``ConventionError``                         a pose invalid in its robot convention  model.conventions
``ObservationError``                        the residual model needs what is absent model.observations
``SimulationError``                         a simulation that cannot be made        model.simulate
``CircleFitError``                          degenerate profile points               model.circle
``ClosedFormError``                         poses that do not fix the linear system model.closed_form
``MissingMotions``                          motions a closed-form method needs      model.classics
``PlanningError``                           a pose plan that cannot be made         model.planning
``RequestError``                            an option or argument that cannot work  handeye.app
``CalibrationInputError``                   a calibration request (too few poses..) handeye.app.calibrate
=========================================  =====================================  =====
"""
from __future__ import annotations


class InputError(ValueError):
    """Bad input: the message names the file, row and column, or the option, and the problem."""
