"""One error hierarchy for bad input.

Every error that means "the input cannot be used as given" -- a malformed dataset, a bad
option, observations that lack what a model needs, a simulation that cannot be made, a
value invalid in its robot convention, motions a method needs but the data lack, poses that
do not determine the unknowns -- derives from :class:`InputError`. The command line maps
exactly this class to exit code 2 and anything else to exit code 3 (a bug), so a bug can never
pass as bad input. ``InputError`` is a ``ValueError``, so code that catches ``ValueError``
keeps working.

The classes, and where each is raised:

- ``DatasetError`` (:mod:`handeye.model.readers.tables`, raised by the dataset and scan readers): a file,
  row or column of a dataset;
- ``ConventionError`` (:mod:`handeye.model.chain.conventions`): a pose invalid in its robot convention;
- ``ObservationError`` (:mod:`handeye.model.datasets.observations`): a residual model needs what the
  data lack (profiles);
- ``SimulationError`` (:mod:`handeye.model.simulation.simulate`): a simulation that cannot be made;
- ``CircleFitError`` (:mod:`handeye.model.geometry.circle`): degenerate profile points;
- ``ClosedFormError`` (:mod:`handeye.model.fit.closed_form`): poses that do not fix the linear system;
- ``MissingMotions`` (:mod:`handeye.model.fit.classics`): motions a closed-form method needs;
- ``PlanningError`` (:mod:`handeye.model.design.planning`): a pose plan that cannot be made;
- ``RequestError`` (:mod:`handeye.app.common.errors`): an option or argument that cannot work, and its
  subclass ``CalibrationInputError``: a calibration request (too few or degenerate poses).
"""
from __future__ import annotations


class InputError(ValueError):
    """Bad input: the message names the file, row and column, or the option, and the problem."""
