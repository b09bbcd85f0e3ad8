"""Bad requests to the application: options and arguments that cannot be honoured.

Both derive from :class:`handeye.model.common.errors.InputError` (the one class the CLI maps to
exit code 2); see that module for the whole hierarchy.
"""
from __future__ import annotations

from handeye.model.common.errors import InputError


class RequestError(InputError):
    """An option or argument that cannot work (out of range, a missing folder, options that
    do not fit together)."""


class CalibrationInputError(RequestError):
    """The request cannot be calibrated as asked (bad option, too few or degenerate poses)."""
