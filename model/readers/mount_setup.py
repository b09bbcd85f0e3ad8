"""The mounts of a cell as ``setup.toml`` states them, read and checked (:mod:`handeye.model.chain.mounts`).

``setup.toml``::

    [sensor]
    mount = "flange"        # default; "world": fixed in the robot's base frame
    pose = [x, y, z, ...]   # optional: the sensor pose known (dataset's convention, its mount's frame)
    [sphere]
    mount = "world"         # default; "flange": carried by the robot; "positioner": on the table
    center = [x, y, z]      # mm, in its mount's frame (positioner: the table frame = base at zero angles)
    [positioner]            # with sphere mount = "positioner": nominal revolute axes, base first,
    axes = [ { name = "e1", point = [x, y, z], direction = [dx, dy, dz] },   # robot base frame,
             { name = "e2", point = [x, y, z], direction = [dx, dy, dz] } ]  # all angles zero

``measurements.csv`` then has one column per axis, named as in ``axes`` (degrees). Every problem
raises :class:`handeye.model.readers.tables.DatasetError` naming the file and the key.
"""
from __future__ import annotations

import re

import numpy as np

from handeye.model.chain.mounts import CELLS, SENSOR_MOUNTS, SPHERE_MOUNTS, Axis, Mounts
from handeye.model.readers.tables import DatasetError

#: An axis name: a CSV column that is not one of the dataset's own.
_AXIS_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]{0,31}$")
#: Columns an axis may not be named after.
RESERVED = {"id", "x", "y", "z", "a", "b", "c", "w", "p", "r", "q1", "q2", "q3", "q4", "rx", "ry", "rz",
            "xs", "ys", "zs", "profile", "j1", "j2", "j3", "j4", "j5", "j6"}
#: Most axes a positioner may have.
MAX_AXES = 3


def _mount(doc, section, choices, default, file):
    value = doc.get(section, {}).get("mount", default)
    if not isinstance(value, str) or value not in choices:
        raise DatasetError(file, f"must be one of {', '.join(repr(c) for c in choices)}, got {value!r}",
                           column=f"[{section}] mount")
    return value


def _axis_vector(entry, key, file, k, bound):
    col = f"[positioner] axes[{k}] {key}"
    value = entry.get(key)
    if not isinstance(value, list) or len(value) != 3:
        raise DatasetError(file, f"needs a list of 3 numbers, got {str(value)[:40]!r}", column=col)
    out = []
    for v in value:
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(float(v)):
            raise DatasetError(file, f"needs finite numbers, got {str(v)[:40]!r}", column=col)
        out.append(float(v))
    out = np.array(out)
    if key == "point" and np.any(np.abs(out) > bound):
        raise DatasetError(file, f"a position beyond +-{bound:g} mm: a unit or a misprint?", column=col)
    if key == "direction":
        big = np.abs(out).max()
        if big < 1e-9:
            raise DatasetError(file, "a zero direction: an axis needs a direction", column=col)
        out = out / big  # first to the largest component: no overflow of the norm for 1e300
        out = out / np.linalg.norm(out)
    return out


def read_axes(table, file, bound, section="positioner"):
    """The ``axes`` list of a ``[positioner]`` (or ``[truth]``) table: a tuple of :class:`Axis`."""
    axes = table.get("axes")
    if not isinstance(axes, list) or not 1 <= len(axes) <= MAX_AXES:
        raise DatasetError(file, f"needs a list of 1 to {MAX_AXES} axes {{ name, point, direction }}, "
                                 f"got {str(axes)[:60]!r}", column=f"[{section}] axes")
    out, names = [], set()
    for k, entry in enumerate(axes):
        col = f"[{section}] axes[{k}]"
        if not isinstance(entry, dict) or set(entry) - {"name", "point", "direction"}:
            raise DatasetError(file, "needs exactly the keys name, point, direction", column=col)
        name = entry.get("name")
        if not isinstance(name, str) or not _AXIS_NAME.match(name) or name.lower() in RESERVED:
            raise DatasetError(file, f"needs a column name (letters, digits, _; not one of the pose or centre "
                                     f"columns), got {name!r}", column=f"{col} name")
        if name in names:
            raise DatasetError(file, f"two axes named {name!r}", column=f"{col} name")
        names.add(name)
        out.append(Axis(name, _axis_vector(entry, "point", file, k, bound),
                        _axis_vector(entry, "direction", file, k, bound)))
    return tuple(out)


def read_mounts(doc, file, bound):
    """The :class:`Mounts` of a parsed ``setup.toml`` (module docstring).

    Parameters
    ----------
    doc : dict
        The parsed TOML.
    file : pathlib.Path
        For messages.
    bound : float
        Plausible robot position, mm (``[limits] position_mm``).
    """
    sensor = _mount(doc, "sensor", SENSOR_MOUNTS, "flange", file)
    sphere = _mount(doc, "sphere", SPHERE_MOUNTS, "world", file)
    if (sensor, sphere) not in CELLS:
        moving = "nothing moves the sensor against the sphere" if sensor != "flange" or sphere != "flange" else \
            "the sensor and the sphere both ride on the flange: no motion between them"
        raise DatasetError(file, f"sensor mount {sensor!r} with sphere mount {sphere!r}: {moving}; observable "
                                 "cells: " + "; ".join(f"{a}/{b}" for a, b in CELLS), column="[sphere] mount")
    axes = ()
    if sphere == "positioner":
        if "positioner" not in doc:
            raise DatasetError(file, "sphere mount 'positioner' needs a [positioner] section with its axes",
                               column="[positioner]")
        axes = read_axes(doc["positioner"], file, bound)
    elif "positioner" in doc:
        raise DatasetError(file, "a [positioner] needs [sphere] mount = \"positioner\"", column="[positioner]")
    return Mounts(sensor, sphere, axes)
