"""The checks every command's arguments share: a dataset named or given, numbers in their ranges,
poses as text or numbers, a sensor pose typed in (:mod:`handeye.app.public.api`, :mod:`handeye.app.public.making`
and the requests use them; one place, one message for each slip)."""
from __future__ import annotations

import os

import numpy as np

from handeye.app.common.errors import RequestError
from handeye.model.chain import conventions


def load_dataset(name_or_folder, clean=True):
    """Read and check a dataset.

    Parameters
    ----------
    name_or_folder : str, pathlib.Path or Dataset
        An embedded dataset (``'thesis-real'``, ``'thesis-sim'``; see
        :func:`handeye.model.datasets.dataset.embedded_names`) or a folder holding ``measurements.csv``
        and ``setup.toml``. A Dataset is returned as it is (cleaned or not as it was loaded).
    clean : bool
        Clean every profile (:mod:`handeye.model.geometry.profile_clean`: speckle and background points
        dropped, what was dropped recorded in ``cleaning``); False keeps every point (``--no-clean``).

    Returns
    -------
    handeye.model.datasets.dataset.Dataset

    Raises
    ------
    handeye.InputError
        A :class:`handeye.model.datasets.dataset.DatasetError` naming file, row and column of the first
        problem found.
    """
    from handeye.model.datasets.dataset import Dataset, load

    return name_or_folder if isinstance(name_or_folder, Dataset) else load(_path_argument(name_or_folder), clean=bool(clean))


def _path_argument(value):
    if not isinstance(value, (str, os.PathLike)):
        raise RequestError(f"dataset: give an embedded dataset's name or a folder, got {value!r}")
    return value


def _pose_text(pose, option):
    """A pose given as text or numbers, as text (numbers that are not numbers are bad input)."""
    if isinstance(pose, str):
        return pose
    try:
        return ",".join(repr(float(v)) for v in np.ravel(np.asarray(pose, dtype=object)))
    except (TypeError, ValueError):
        raise RequestError(f"{option}: needs numbers, got {pose!r}") from None


def numbers(value, option, count=None, form="not a number (give numbers separated by commas)"):
    """An option's numbers, ``'1,2,3'`` or a sequence, as a list of floats (None stays None); with
    ``count``, exactly that many and finite. RequestError naming ``option`` and the expected
    ``form`` otherwise (the one parser of the requests' number lists)."""
    if value is None:
        return None
    parts = value.split(",") if isinstance(value, str) else np.ravel(np.asarray(value, dtype=object)).tolist()
    try:
        out = [float(v) for v in parts]
    except (TypeError, ValueError):
        raise RequestError(f"{option} {value!r}: {form}") from None
    if count is not None and (len(out) != count or not np.all(np.isfinite(out))):
        raise RequestError(f"{option} {value!r}: needs {count} finite numbers")
    return out


def _number(value, option, low, high, low_open=False):
    ok = not isinstance(value, bool) and isinstance(value, (int, float, np.floating)) and np.isfinite(value)
    if not ok or value > high or value < low or (low_open and value == low):
        raise RequestError(f"{option} must lie in {'(' if low_open else '['}{low:g}, {high:g}], got {value!r}")
    return float(value)


def _integer(value, option, low, high=None):
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low or (
            high is not None and value > high):
        bound = f"at least {low}" if high is None else f"at least {low} and at most {high}"
        raise RequestError(f"{option} must be an integer {bound}, got {value!r}")
    return int(value)


#: A sensor origin nearer its mount's frame's than this (mm) is a pose typed in metres (UR's units).
MIN_OFFSET_MM = 1.0


def typed_pose(pose, convention, frame="flange"):
    """A sensor pose typed in (``--sensor-pose``: ``x, y, z`` mm and ``convention``'s orientation
    columns, in the ``frame`` of its mount) checked: ``(its numbers, its 4x4)``."""
    cols = conventions.columns(convention)
    values = np.asarray(pose, dtype=float)
    if values.shape != (len(cols),) or not np.all(np.isfinite(values)):
        raise RequestError(f"--sensor-pose needs {len(cols)} finite numbers ({','.join(cols)}, {convention})")
    try:
        matrix = conventions.transform_from(convention, values)
    except conventions.ConventionError as exc:
        raise RequestError(f"--sensor-pose: {exc}") from None
    offset = float(np.linalg.norm(values[:3]))
    if 0 < offset < MIN_OFFSET_MM:
        raise RequestError(f"--sensor-pose: the sensor origin {offset:.3g} mm from the {frame}'s: metres? handeye "
                           "positions are mm (UR: multiply x, y, z by 1000)")
    return values, matrix
