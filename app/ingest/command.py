"""``handeye dataset new OUT``: :func:`new_dataset` and its result, :class:`NewDatasetResult`."""
from __future__ import annotations

import dataclasses
import datetime
import pathlib
import re

import numpy as np

from handeye.app.common import options
from handeye.app.common.files import tool_version, write_folder_atomically
from handeye.app.ingest import mounts, sources, writer
from handeye.app.ingest.pairing import pair
from handeye.app.ingest.poses import read_centres, read_joints, read_poses
from handeye.app.ingest.request import MODEL_FILE, NewDatasetRequest
from handeye.app.present.protocol import ResultProtocol
from handeye.model.chain import conventions
from handeye.model.datasets.dataset import load
from handeye.model.geometry import sphere_cloud
from handeye.model.readers.tables import DatasetError


@dataclasses.dataclass(frozen=True)
class NewDatasetResult(ResultProtocol):
    """A dataset folder assembled by :func:`new_dataset`.

    Attributes
    ----------
    path : pathlib.Path
        The dataset folder written.
    ids : tuple of str
        One measurement per pose with a profile, in the poses' order.
    convention : str
        The dataset's robot convention (``[robot] convention``).
    inputs : dict
        What was read: ``poses`` (file, format, columns, convention of the columns) or ``bag``
        (path, topics, types, counts), ``profiles`` (files per format), ``joints``.
    conversions : tuple of str
        Units, angles, quaternion order and convention changes made.
    plane : str
        How the profiles' laser plane was mapped to handeye's y = 0 (:mod:`handeye.app.ingest.plane`).
    rotation : ndarray (3, 3) or None
        ``R`` (handeye sensor = R @ file coordinates) when 3-column profiles were turned.
    dropped : dict
        Measurement id -> NaN/inf rows dropped from its profile (only ids with some).
    pairing : str
        How poses and profiles were paired.
    next_command : str
        The calibration to run next.
    side : int
        ``[profile] side`` written: ``side`` given in the profiles' frame, in handeye's.
    measured : {'profiles', 'clouds', 'centres'}
        What the sensor gave per pose (``--profiles``, ``--clouds``, ``--centres``).
    clouds : dict or None
        With ``--clouds``, what their sphere fits say: ``radius`` (held or free), ``diameter_mm`` (``mean``, ``sd``,
        ``min``, ``max`` of the fitted diameters, radius free), ``centre_sd_mm`` (the median over poses of a
        centre's largest sd from its fit), ``points_dropped`` (id -> points cleaned off the sphere).
    """

    caption = "handeye dataset new"

    def _measured_lines(self):
        """The summary's lines of what the sensor gave: profiles or clouds (formats, rows dropped, the clouds' fits), or
        the centres' table."""
        if self.measured == "centres":
            return [f"  centres   {self.inputs['centres']['file']} ({self.inputs['centres']['rows']} rows, sensor frame)"]
        fmts = ", ".join(f"{n} {f}" for f, n in self.inputs[self.measured].items())
        lines = [f"  {self.measured:<9} {fmts}; {sum(self.dropped.values())} NaN/inf rows dropped in {len(self.dropped)} "
                 f"{self.measured}"]
        if self.clouds:
            c, cut = self.clouds, self.clouds["points_dropped"]
            d = c.get("diameter_mm")
            size = (f"fitted diameters {d['mean']:.4f} mm, sd {d['sd']:.2g} mm (range {d['min']:.4f}-{d['max']:.4f})" if d
                    else "radius held at the stated diameter's")
            lines.append(f"  spheres   {size}; centre sd {c['centre_sd_mm']:.2g} mm (median); {sum(cut.values()):,} points "
                         f"cleaned off the sphere in {len(cut)} clouds")
        return lines

    path: pathlib.Path
    ids: tuple
    convention: str
    inputs: dict
    conversions: tuple
    plane: str
    rotation: np.ndarray | None
    dropped: dict
    pairing: str
    next_command: str
    side: int = -1
    measured: str = "profiles"
    clouds: dict | None = None

    def to_dict(self):
        return {"path": str(self.path), "measurements": len(self.ids), "ids": list(self.ids),
                "convention": self.convention, "inputs": self.inputs, "conversions": list(self.conversions),
                "plane": self.plane, "rotation": None if self.rotation is None else np.asarray(self.rotation).tolist(),
                "dropped_nonfinite": dict(self.dropped), "pairing": self.pairing, "side": self.side,
                "measured": self.measured, "clouds": self.clouds, "next": self.next_command}

    def summary(self):
        src = self.inputs.get("poses") or self.inputs.get("bag")
        lines = [f"handeye dataset new: wrote {self.path} ({len(self.ids)} measurements, convention {self.convention})"]
        if "poses" in self.inputs:
            lines.append(f"  poses     {src['file']} ({src['format']}; columns {','.join(src['columns'])}; "
                         f"{src['source_convention']})")
        else:
            c = src["counts"]
            lines.append(f"  bag       {src['path']}: {c['poses']} poses ({src['types'][0]}), {c['profiles']} profiles "
                         f"({src['types'][1]}), {c['unmatched']} without a pose within {c['max_dt_s']:g} s")
        lines += self._measured_lines()
        if self.inputs.get("skipped"):
            n = len(self.inputs["skipped"])
            lines.append(f"  skipped   {n} file{'s' if n > 1 else ''} of the folders that {'are' if n > 1 else 'is'} no profile: "
                         + ", ".join(pathlib.Path(f).name for f in list(self.inputs["skipped"])[:4])
                         + (", ..." if len(self.inputs["skipped"]) > 4 else "") + " (PROVENANCE.toml says why)")
        lines.append(f"  plane     {self.plane}")
        if self.rotation is not None:
            lines.append("            kept as [profile] own_axes: every sensor pose (--start, calibrate's, export's) is of "
                         "your sensor's own frame")
        lines.append(f"  pairing   {self.pairing}")
        if self.conversions:
            lines.append(f"  converted {'; '.join(self.conversions)}")
        lines.append(f"  next      {self.next_command}")
        return "\n".join(lines)


@dataclasses.dataclass(frozen=True)
class _Read:
    """What the inputs gave, paired: one measurement per pose with a profile.

    Attributes
    ----------
    ids : list of str
    values : ndarray (N, 3 + k)
        The flange poses in ``convention``.
    convention : str
    profiles : list of Profile
        Each measurement's (:class:`handeye.app.ingest.sources.Profile`).
    inputs, notes, pairing
        What was read, the conversions made, how poses and profiles were paired
        (:class:`NewDatasetResult`'s ``inputs``, ``conversions``, ``pairing``).
    roles : list of (str, path-like, str)
        Role, file and format of each source file.
    joints : ndarray (N, 6) or None
        The joint angles of each pose (``--joints``; never with a bag).
    lines : tuple of int or None
        The line (or JSON item) of each pose in the pose file (None: a bag).
    angles : ndarray (N, k) or None
        The positioner's axis angles of each pose, degrees (``--sphere-mount positioner``).
    centres : ndarray (N, 3) or None
        The sphere centre the sensor reported at each pose (``--centres``), sensor frame, mm; then
        ``profiles`` is None.
    configuration : ndarray of int (N,) or None
        The arm configuration of each pose as ABB's ``cfx`` (a pose table's ``cfx`` column, a FANUC
        program's ``CONFIG``): written as the dataset's ``cfx`` column.
    """

    ids: list
    values: np.ndarray
    convention: str
    profiles: list
    inputs: dict
    notes: list
    pairing: str
    roles: list
    joints: np.ndarray | None
    lines: tuple | None = None
    angles: np.ndarray | None = None
    centres: np.ndarray | None = None
    configuration: np.ndarray | None = None


def _from_files(req):
    """Poses and profiles (or clouds, or reported centres) from loose files, paired."""
    table = read_poses(req.poses, req.convention, req.columns, req.units, req.angles,
                       {"accept_frames": req.accept_frames, "still": req.still})
    if req.measured == "centres":
        return _with_centres(req, table)
    profiles, skipped = sources.read_profiles(req.profiles, req.profile_units)
    if req.measured == "clouds":
        sources.check_clouds(profiles)
    try:
        index, ids, how = pair([p.label for p in profiles], [p.name for p in profiles], table.ids, len(table.values),
                               str(table.file), req.pairing)
    except DatasetError as exc:
        exc = _stops_said(exc, table)
        if not skipped:
            raise exc from None
        raise DatasetError(exc.file, f"{exc.problem}; skipped as no profile: {skipped[0][0]} ({skipped[0][1]})"
                           + (f" and {len(skipped) - 1} more" if len(skipped) > 1 else ""), exc.row, exc.column) from None
    per_pose = [None] * len(ids)  # pair gave every pose one profile
    for p, k in zip(profiles, index):
        per_pose[k] = p
    inputs = _inputs(req, table)
    if skipped:
        inputs["skipped"] = {f: why for f, why in skipped}
    roles = [("poses", f, table.format) for f in (table.file, *table.companions)]
    roles += [("profile", p.file, p.format) for p in profiles]
    notes = list(table.notes)
    if req.joints is None and table.joints is not None and req.robot is None:
        notes.append("joint angles not written: give --robot MODEL to keep them (the loader checks them)")
    return _Read(ids, table.values, table.convention, per_pose, inputs, mounts.notes(notes, req.cell), how, roles,
                 _joints(req.joints, table) if req.joints is not None or req.robot is None else table.joints,
                 table.lines, mounts.axis_angles(table.file, req.cell, len(table.values)), configuration=table.configuration)


def _stops_said(exc, table):
    """A pairing error of a streamed RTDE log's poses said to be its stops."""
    if "stops of a stream" not in table.format:
        return exc
    return DatasetError(exc.file, f"{exc.problem}; the poses are the {len(table.values)} stops found in the log "
                                  "(--still MM,DEG,S says what a stop is)", exc.row, exc.column)


def _inputs(req, table):
    """What ``--poses`` was read as (:class:`NewDatasetResult`'s ``inputs['poses']``)."""
    return {"poses": {"file": str(table.file), "format": table.format, "columns": list(table.columns),
                      "source_convention": table.source, "units": req.units, "angles": req.angles or "the convention's"}}


def _with_centres(req, table):
    """The poses with the centre the sensor reported at each (``--centres``: by id where both files have ids, else
    by order), as :class:`_Read`."""
    ids_c, values, lines = read_centres(req.centres)
    centres = _by_pose(req.centres, (ids_c, values, lines), table, "sphere centre") * (1000.0 if req.profile_units == "m"
                                                                                    else 1.0)
    ids = list(table.ids) if table.ids is not None else [str(k) for k in range(1, len(table.values) + 1)]
    how = "by id" if ids_c is not None and table.ids is not None else "by order"
    inputs = {**_inputs(req, table), "centres": {"file": str(req.centres), "rows": len(values)}}
    roles = [("poses", f, table.format) for f in (table.file, *table.companions)] + [("centres", req.centres, "table")]
    notes = list(table.notes) + (["centres m -> mm"] if req.profile_units == "m" else [])
    return _Read(ids, table.values, table.convention, None, inputs, mounts.notes(notes, req.cell), how, roles,
                 _joints(req.joints, table) if req.joints is not None or req.robot is None else table.joints,
                 table.lines, mounts.axis_angles(table.file, req.cell, len(table.values)), centres, table.configuration)


def _from_bag(req):
    """The same from a ROS 2 bag (:mod:`handeye.app.ingest.rosbag`)."""
    from handeye.app.ingest.rosbag import read_bag

    data = read_bag(req.bag, req.pose_topic, req.profile_topic, req.base_frame, req.flange_frame, req.max_dt)
    convention = req.convention or "abb"
    profiles = sources.bag_profiles(data.profiles, req.profile_topic)
    inputs = {"bag": {"path": str(req.bag), "pose_topic": req.pose_topic, "profile_topic": req.profile_topic,
                      "types": list(data.types), "counts": data.counts}}
    notes = ["ROS positions m -> mm", "ROS quaternions (x, y, z, w)" + (" -> abb (w, x, y, z)" if convention == "abb"
                                                                          else f" -> {convention}")]
    how = f"by time: each profile with the nearest pose within {req.max_dt:g} s"
    roles = [("bag", f, "ROS 2 bag") for f in writer.source_files(req.bag)]
    return _Read([p.name for p in profiles], conventions.pose_from(convention, data.flange2base), convention, profiles, inputs,
                 notes, how, roles, None)


def _joints(file, table):
    """Joint angles (n, 6) in the order of the poses of ``table`` (by id when both files have ids,
    else by order)."""
    if file is None:
        return None
    return _by_pose(file, read_joints(file), table, "joint angles")


def _by_pose(file, found, table, what):
    """The rows ``found`` (``(ids or None, values (n, k), lines)`` of ``file``) in the order of the poses of ``table``:
    by id when both files have ids, else by order; a pose without a row, or counts that differ, named."""
    ids, values, _ = found
    if ids is not None and table.ids is not None:
        where = {i: k for k, i in enumerate(ids)}
        missing = [i for i in table.ids if i not in where]
        if missing:
            raise DatasetError(file, f"no {what} for pose {missing[0]!r}")
        return values[[where[i] for i in table.ids]]
    if len(values) != len(table.lines):
        raise DatasetError(file, f"{len(values)} rows of {what} for {len(table.lines)} poses")
    return values


@options.COMMANDS["dataset new"].documented
def new_dataset(out, *, poses=None, profiles=(), clouds=(), centres=None, convention=None, columns=None, units="mm",
                angles=None,
                profile_units=None, profile_axes=None, diameter=None, side=None, center=None, start=None, sensor_mount=None,
                sphere_mount=None, positioner_axes=None, joints=None,
                robot=None, pair="auto", match=None, bag=None, pose_topic=None, profile_topic=None, base_frame=None,
                flange_frame=None, max_dt=0.05, setup=None, accept_frames=False, still=None):
    """Assemble a handeye dataset folder from loose files or a ROS 2 bag (``handeye dataset new``).

    {parameters}

    Returns
    -------
    NewDatasetResult

    Raises
    ------
    handeye.InputError
        Bad input (:class:`~handeye.model.readers.tables.DatasetError` naming file, row, column;
        :class:`~handeye.app.common.errors.RequestError` naming the option).
    """
    req = NewDatasetRequest.from_options(options.COMMANDS["dataset new"].given(locals()))
    read = _from_files(req) if req.bag is None else _from_bag(req)
    plane, rotation, side = _plane(req, read)
    start_pose = req.start_pose(read.convention, rotation)
    result = NewDatasetResult(
        path=pathlib.Path(out), ids=tuple(read.ids), convention=read.convention, inputs=read.inputs,
        conversions=tuple(read.notes), plane=plane, rotation=rotation,
        dropped={i: p.dropped for i, p in zip(read.ids, read.profiles or ()) if p.dropped}, pairing=read.pairing,
        next_command=f"handeye calibrate {out}" + (" --unknowns sensor+sphere" if req.center is None else ""), side=side,
        measured=req.measured)
    files, rels = _files(result, read, req, start_pose)
    poses = None if read.lines is None else (read.roles[0][1], read.lines)
    loaded = _write_checked(out, files, {rel: (p.label, i) for rel, p, i in zip(rels, read.profiles or (), result.ids)},
                            poses)
    return dataclasses.replace(result, clouds=_cloud_fits(loaded)) if req.measured == "clouds" else result


def _plane(req, read):
    """``(plane, rotation, side)``: how the profiles' laser plane was mapped (:mod:`handeye.app.ingest.plane`), the
    turn ``R`` (None: none) and ``[profile] side`` in handeye's frame; clouds and centres are 3-D, kept as they are."""
    if read.profiles is None or req.measured == "clouds":
        if read.profiles is not None:
            read.inputs["clouds"] = sources.formats(read.profiles)
        return f"{req.measured}: 3-D, in the sensor frame as given (no laser plane)", None, req.side
    mapping = sources.map_to_plane(read.profiles, req.diameter, req.profile_axes,
                                   "--profile-units" if req.bag is None else "the bag's profile topic")
    read.inputs["profiles"] = sources.formats(read.profiles)
    side = req.side if req.side_from == "setup" else mapping.side(req.side)
    if side != req.side:
        given = "the default --side" if req.side_from == "default" else "--side"
        read.notes.append(f"{given} {req.side:+d} (the profiles' {mapping.normal}) is side {side:+d} in handeye's y")
    return mapping.describe(), None if mapping.identity else mapping.rotation, side


def _cloud_fits(dataset):
    """What the sphere fits of a loaded dataset's clouds say (:class:`NewDatasetResult`'s ``clouds``)."""
    fits = dataset.clouds or ()
    spread = sphere_cloud.diameter_spread(fits)
    out = {"radius": "held at the stated diameter's" if dataset.sphere_diameter is not None else "free (fitted)",
           "centre_sd_mm": float(np.median([np.sqrt(np.max(np.diag(f.covariance))) for f in fits])),
           "points_dropped": {i: f.n_dropped for i, f in zip(dataset.ids, fits) if f.n_dropped}}
    if spread is not None:
        out["diameter_mm"] = dict(zip(("mean", "sd", "min", "max"), spread))
    return out


def _files(result, read, req, start_pose):
    """``(files, rels)``: relative path -> text of every file of the dataset, and each measurement's
    profile (or cloud) path; none with reported centres."""
    taken, folder = set(), "clouds" if req.measured == "clouds" else "profiles"
    rels = [f"{folder}/{writer.safe_name(ident, taken)}.csv" for ident in result.ids] if read.profiles else []
    files = {rel: writer.points_text(p.points if req.measured == "clouds" else p.xz) for rel, p in zip(rels, read.profiles or ())}
    head = {"tool": "handeye dataset new", "version": tool_version(),
            "created_utc": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")}
    sections = {"options": req.options, "inputs": dict(result.inputs), "conversions": {"made": list(result.conversions)},
                "plane": {"mapping": result.plane, "rotation_handeye_from_file": None if result.rotation is None
                          else np.asarray(result.rotation).tolist()},
                "pairing": {"method": result.pairing, "pairs": {i: p.label for i, p in zip(result.ids, read.profiles or ())}},
                "dropped_nonfinite": dict(result.dropped)}
    extra = [(r, getattr(req, r), "table" if r == "joints" else "TOML") for r in ("joints", "setup")
             if getattr(req, r) is not None]
    if req.robot_file is not None:
        files[MODEL_FILE] = req.robot_file[1]
        extra.append(("robot model", req.robot_file[0], "TOML"))
    srcs = [{"role": role, "path": str(pathlib.Path(f).resolve()), "format": fmt, "sha256": writer.sha256(f)}
            for role, f, fmt in _unique(read.roles + extra)]
    measured = (req.measured, read.centres if req.measured == "centres" else rels)
    files["measurements.csv"] = writer.measurements_text(result.ids, read.values, result.convention, measured,
                                                         (read.joints, read.configuration), (req.cell.names, read.angles))
    files["setup.toml"] = writer.setup_text(result, req, start_pose)
    files["PROVENANCE.toml"] = writer.provenance_text(head, sections, srcs)
    return files, rels


def _unique(roles):
    """The ``(role, file, format)`` of each file once (its first role), None left out."""
    first = {}
    for role, f, fmt in roles:
        first.setdefault(str(f), (role, f, fmt))
    return [entry for entry in first.values() if entry[1] is not None]


def _write_checked(out, files, sources, poses=None):
    """Write the files into a temporary folder, load it as a dataset (every check of
    :func:`handeye.model.datasets.dataset.load`), then rename it to ``out``: never a half-written folder.
    A check that fails names the source (``sources``: profile path -> the file it was read from and
    its pose id; ``poses``: the pose file and each measurement's line in it), never a file of the
    folder, which is not written."""

    loaded = []

    def write(tmp):
        for sub in {pathlib.Path(rel).parent for rel in files} - {pathlib.Path(".")}:
            (tmp / sub).mkdir()
        for rel, text in files.items():
            (tmp / rel).write_text(text)
        try:
            loaded.append(load(tmp))
        except DatasetError as exc:
            raise _named(exc, tmp, out, sources, poses) from None

    write_folder_atomically(out, write, option="OUT")
    return loaded[0]


def _source(match, sources):
    """``profiles/7.csv (row 8`` of a load error as ``scans/p7.yml (pose '7'``."""
    if match.group(1) not in sources:
        return match.group(0)
    label, ident = sources[match.group(1)]
    return label + (f" (pose {ident!r}" if match.group(2) else "")


def _named(exc, tmp, out, sources, poses):
    """The load error ``exc`` of the temporary folder ``tmp`` told of the source files."""
    where = pathlib.Path(exc.file).resolve()
    rel = where.relative_to(tmp.resolve()).as_posix() if where.is_relative_to(tmp.resolve()) else None
    problem = exc.problem.replace(" in setup.toml", " (--diameter)")  # the setup is the options' here
    named = [sources[m] for m in re.findall(r"(?:profiles|clouds)/[^\s:;()]+\.csv", problem) if m in sources]
    problem = re.sub(r"((?:profiles|clouds)/[^\s:;()]+\.csv)( \(row \d+)?", lambda m: _source(m, sources), problem)
    problem = f"the assembled dataset does not load: {problem}"
    if rel in sources:
        what = "cloud" if rel.startswith("clouds/") else "profile"
        return DatasetError(sources[rel][0], f"{problem} (its {what}, as handeye wrote it)", None, exc.column)
    if rel == "measurements.csv" and named:
        return DatasetError(named[0][0], problem, None, None)
    if rel == "measurements.csv" and poses is not None:
        k = exc.row - 2 if exc.row else -1  # measurements.csv: a header, then one row per pose in order
        return DatasetError(poses[0], problem, poses[1][k] if 0 <= k < len(poses[1]) else None, None)
    return DatasetError(pathlib.Path(out) / (rel or where), problem, exc.row, exc.column)
