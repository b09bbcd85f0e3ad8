"""The files of an assembled dataset: ``measurements.csv``, ``setup.toml``, ``profiles/*.csv`` and
``PROVENANCE.toml`` (every source file with its SHA-256, the options, the conversions made)."""
from __future__ import annotations

import csv
import hashlib
import io
import json
import pathlib
import re

import numpy as np

from handeye.app.ingest import mounts
from handeye.model.chain import conventions
from handeye.model.robot.robots import JOINTS


def safe_name(ident, taken):
    """A file name of an id (``profiles/<name>.csv``), unique among ``taken`` (updated)."""
    base = re.sub(r"[^A-Za-z0-9_.-]", "_", str(ident)).strip(".") or "pose"
    name, k = base, 1
    while name.lower() in taken:
        k += 1
        name = f"{base}_{k}"
    taken.add(name.lower())
    return name


def measurements_text(ids, values, convention, measured, robot=(None, None), axes=((), None)):
    """``measurements.csv``: id, the convention's pose columns, ``xs,ys,zs`` (the centres reported, or empty),
    [the positioner's axis columns,] [j1..j6,] [cfx,] [profile or cloud]; ``measured``: ``(what, rels)``, ``what``
    ``'profiles'`` or ``'clouds'`` (the column ``profile`` or ``cloud`` of the files ``rels``), or ``('centres',
    (N, 3) mm)``; ``robot``: the joint angles (N, 6), degrees, and the arm configurations (N,), ABB's ``cfx``
    (either None: no such columns); ``axes``: the axis names and their angles (N, k), degrees."""
    names, angles = axes
    joints, cfx = robot
    what, rels = measured
    centres = rels if what == "centres" else None
    column = [] if centres is not None else ["cloud" if what == "clouds" else "profile"]
    buffer = io.StringIO()
    out = csv.writer(buffer, lineterminator="\n")  # an id holding a comma or a quote is quoted
    out.writerow(["id", *conventions.columns(convention), "xs", "ys", "zs", *names,
                  *(JOINTS if joints is not None else ()), *(("cfx",) if cfx is not None else ()), *column])
    for k, (ident, pose) in enumerate(zip(ids, values)):
        row = [str(ident), *(f"{v:.10g}" for v in pose)]
        row += [f"{v:.10g}" for v in centres[k]] if centres is not None else ["", "", ""]
        row += [f"{v:.10g}" for v in angles[k]] if angles is not None else []
        row += [f"{v:.6f}" for v in joints[k]] if joints is not None else []
        row += [str(int(cfx[k]))] if cfx is not None else []
        out.writerow(row + ([rels[k]] if column else []))
    return buffer.getvalue()


def points_text(points):
    """A profile CSV (header ``x,z``: sensor x and z) of points (K, 2), or a cloud's (header ``x,y,z``) of (K, 3); mm."""
    pts = np.asarray(points, float)  # one format over every number at once: 4x the speed of a line per point
    head = "x,z\n" if pts.shape[1] == 2 else "x,y,z\n"
    return head + ((",".join(["%.6f"] * pts.shape[1]) + "\n") * len(pts)) % tuple(pts.ravel().tolist())



def _vec(v):
    return "[" + ", ".join(f"{float(a)!r}" for a in v) + "]"


def setup_text(result, request, start=None):
    """``setup.toml`` of the dataset ``result`` (a :class:`~handeye.app.ingest.command.NewDatasetResult`:
    convention, side, and ``rotation``, the turn R, ``p_handeye = R p_file``, of profiles not given
    in handeye's frame, kept as ``own_axes`` with ``poses = "own"``: ``start`` and every pose a
    calibration reports are of the sensor's own frame) assembled for ``request`` (a
    :class:`~handeye.app.ingest.request.NewDatasetRequest`: diameter, centre, robot model);
    :mod:`handeye.model.datasets.dataset` has the format."""
    text = "# assembled by `handeye dataset new`; PROVENANCE.toml says from what\n"
    model = f"model = {json.dumps(request.robot)}\n" if request.robot else ""
    text += f"[robot]\nconvention = \"{result.convention}\"\n{model}\n"
    cell = mounts.setup_lines(request.cell)
    sensor = cell["sensor"] + ([f"start_pose = {_vec(start)}"] if start is not None else [])
    text += "[sensor]\n" + "".join(line + "\n" for line in sensor) + "\n" if sensor else ""
    diameter = f"diameter = {float(request.diameter)!r}\n" if request.diameter is not None else ""
    text += "[sphere]\n" + "".join(line + "\n" for line in cell["sphere"]) + diameter
    text += f"center = {_vec(request.center)}\n" if request.center is not None else ""
    text += "\n[positioner]\n" + "".join(line + "\n" for line in cell["positioner"]) if cell["positioner"] else ""
    text += f"\n[profile]\nside = {int(result.side)}\n" if result.measured == "profiles" else ""
    if result.rotation is not None:
        rows = ", ".join(_vec(np.round(np.asarray(r, float), 12) + 0.0) for r in result.rotation)
        text += ("# the profiles were turned from the sensor's own frame: p = R p_own (rows of R); every sensor\n"
                 "# pose (start_pose here, calibrate's, export's) is of the sensor's own frame\n"
                 f"own_axes = [{rows}]\nposes = \"own\"\n")
    return text


def sha256(path):
    """SHA-256 of a file (streamed)."""
    with open(path, "rb") as fh:
        return hashlib.file_digest(fh, "sha256").hexdigest()


def source_files(path):
    """The files of an input (a bag folder: each of its files)."""
    p = pathlib.Path(path)
    return sorted(f for f in p.rglob("*") if f.is_file()) if p.is_dir() else [p]


def _toml_value(v):
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        return repr(float(v))
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{json.dumps(str(k))} = {_toml_value(x)}" for k, x in v.items()) + " }"
    if isinstance(v, (list, tuple, np.ndarray)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    return json.dumps(str(v))


def provenance_text(head, sections, sources):
    """``PROVENANCE.toml``: ``head`` (key -> value), ``sections`` (name -> dict) and one
    ``[[source]]`` table per input file (role, path, format, sha256)."""
    lines = [f"{k} = {_toml_value(v)}" for k, v in head.items() if v is not None]
    for name, table in sections.items():
        lines += ["", f"[{name}]"] + [f"{json.dumps(str(k))} = {_toml_value(v)}" for k, v in table.items() if v is not None]
    for src in sources:
        lines += ["", "[[source]]"] + [f"{k} = {_toml_value(v)}" for k, v in src.items()]
    return "\n".join(lines) + "\n"

