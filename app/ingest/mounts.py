"""Every cell in ``handeye dataset new``: the mounts and the positioner's axes (issue 40).

The options ``--sensor-mount``, ``--sphere-mount`` and ``--positioner-axes`` say which of the three
cells of :mod:`handeye.model.chain.mounts` the files are of (the sensor on the flange and the sphere
fixed, the default; the sensor fixed in the cell and the sphere on the flange; the sphere on a
positioner's table); :func:`checked` validates them before anything is read, :func:`axis_angles`
takes each pose's axis angles from the pose file's columns named as the axes (``e1,e2``, degrees),
and :func:`setup_lines` writes them into ``setup.toml`` as :mod:`handeye.model.readers.mount_setup`
reads them.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from handeye.app.common.errors import RequestError
from handeye.app.engine.making_request import _axes as parse_axes
from handeye.app.ingest.tables import read_table
from handeye.model.chain.mounts import CELLS
from handeye.model.readers.tables import DatasetError


@dataclasses.dataclass(frozen=True)
class Cell:
    """The cell the files are of.

    Attributes
    ----------
    sensor, sphere : str
        ``[sensor] mount`` (flange, world) and ``[sphere] mount`` (world, flange, positioner).
    axes : tuple of Axis
        The positioner's nominal axes (robot base at zero angles, mm), base first; empty without one.
    """

    sensor: str = "flange"
    sphere: str = "world"
    axes: tuple = ()

    @property
    def names(self):
        """The axis columns (``('e1', 'e2')``)."""
        return tuple(a.name for a in self.axes)


def checked(sensor, sphere, axes_text, bag=False):
    """The :class:`Cell` of the options (None: the default); a pair that is no cell, axes without a
    positioner or a positioner without axes is a RequestError naming the option."""
    sensor, sphere = sensor or "flange", sphere or "world"
    if (sensor, sphere) not in CELLS:
        pairs = ", ".join(f"{a}/{b}" for a, b in CELLS)
        raise RequestError(f"--sensor-mount {sensor} with --sphere-mount {sphere} is no cell (nothing moves the sensor "
                           f"against the sphere); use one of {pairs}")
    if axes_text is not None and sphere != "positioner":
        raise RequestError("--positioner-axes needs --sphere-mount positioner")
    if sphere != "positioner":
        return Cell(sensor, sphere)
    if axes_text is None:
        raise RequestError("--sphere-mount positioner needs --positioner-axes 'NAME:px,py,pz:dx,dy,dz;...' (the nominal "
                           "axes from the controller, base first; the pose file's columns named as the axes)")
    if bag:
        raise RequestError("--sphere-mount positioner with --bag: a bag's axis angles are not read; give --poses with "
                           "the axis columns")
    return Cell(sensor, sphere, parse_axes(axes_text))


def axis_angles(file, cell, n_poses):
    """Each pose's axis angles (N, k), degrees, from the columns of the pose file ``file`` named as
    ``cell``'s axes (case-insensitive; a header or JSON keys needed); None without a positioner."""
    if not cell.axes:
        return None
    table = read_table(file)
    header = [h.strip().lower() for h in table.header or ()]
    missing = [n for n in cell.names if n.lower() not in header]
    if missing:
        shown = ", ".join(table.header or ()) or "none: no header"
        raise DatasetError(file, f"no column {missing[0]!r} (the axis angles of --positioner-axes, degrees; the "
                                 f"columns: {shown[:80]})", 1)
    out = np.empty((len(table.rows), len(cell.axes)))
    for c, name in enumerate(cell.names):
        j = header.index(name.lower())
        for r, (row, line) in enumerate(zip(table.rows, table.lines)):
            out[r, c] = _angle(file, row[j] if j < len(row) else "", line, table.header[j])
    if len(out) != n_poses:
        raise DatasetError(file, f"{len(out)} rows of axis angles for {n_poses} poses")
    return out


def _angle(file, text, line, column):
    try:
        value = float(text) if "_" not in text else math.nan
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise DatasetError(file, f"not a finite angle: {text[:30]!r}", line, column)
    return value


def setup_lines(cell):
    """``{section: lines}`` of ``setup.toml`` for ``cell``: the mounts (left out where the default)
    and the ``[positioner] axes``."""
    out = {"sensor": [], "sphere": [], "positioner": []}
    if cell.sensor != "flange":
        out["sensor"].append(f'mount = "{cell.sensor}"')
    if cell.sphere != "world":
        out["sphere"].append(f'mount = "{cell.sphere}"')
    if cell.axes:
        rows = [f'  {{ name = "{a.name}", point = {_vec(a.point)}, direction = {_vec(a.direction)} }}' for a in cell.axes]
        out["positioner"] += ["axes = ["] + [r + "," for r in rows] + ["]"]
    return out


def _vec(v):
    return "[" + ", ".join(f"{float(a)!r}" for a in v) + "]"


def notes(made, cell):
    """The pose reader's notes ``made`` with the axis columns said to be kept, not ignored."""
    if not cell.axes:
        return list(made)
    names, out = {n.lower() for n in cell.names}, []
    for note in made:
        if note.startswith("columns ignored: "):
            rest = [c for c in note[len("columns ignored: "):].split(", ") if c.strip().lower() not in names]
            note = f"columns ignored: {', '.join(rest)}" if rest else None
        if note:
            out.append(note)
    return out + [f"positioner axis columns {', '.join(cell.names)} kept (degrees)"]


def axes_text(axes):
    """``[positioner] axes`` of a setup.toml (a list of ``{ name, point, direction }``) as
    ``--positioner-axes`` text; None for anything else."""
    def vector(v):
        return (isinstance(v, list) and len(v) == 3
                and all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v))

    if not isinstance(axes, list) or not axes:
        return None
    if not all(isinstance(a, dict) and isinstance(a.get("name"), str) and vector(a.get("point"))
               and vector(a.get("direction")) for a in axes):
        return None
    return ";".join(f"{a['name']}:{','.join(map(repr, a['point']))}:{','.join(map(repr, a['direction']))}" for a in axes)
