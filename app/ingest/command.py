"""``handeye dataset new OUT``: :func:`new_dataset` and its result, :class:`NewDatasetResult`."""
from __future__ import annotations

import dataclasses
import datetime
import pathlib
import tomllib

import numpy as np

from handeye.app.common import options
from handeye.app.common.errors import RequestError
from handeye.app.ingest import sources, writer
from handeye.app.ingest.pairing import pair
from handeye.app.ingest.plane import parse_axes
from handeye.app.ingest.poses import read_joints, read_poses
from handeye.app.present.protocol import ResultProtocol
from handeye.model.chain import conventions, own_frame
from handeye.model.readers.tables import DatasetError
from handeye.model.robot import robots


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
    """

    caption = "handeye dataset new"

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

    def to_dict(self):
        return {"path": str(self.path), "measurements": len(self.ids), "ids": list(self.ids),
                "convention": self.convention, "inputs": self.inputs, "conversions": list(self.conversions),
                "plane": self.plane, "rotation": None if self.rotation is None else np.asarray(self.rotation).tolist(),
                "dropped_nonfinite": dict(self.dropped), "pairing": self.pairing, "side": self.side,
                "next": self.next_command}

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
        fmts = ", ".join(f"{n} {f}" for f, n in self.inputs["profiles"].items())
        lines.append(f"  profiles  {fmts}; {sum(self.dropped.values())} NaN/inf rows dropped in {len(self.dropped)} "
                     "profiles")
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


def _vector(value, n, option):
    """``'1,2,3'`` or a sequence as n floats; None stays None."""
    if value is None:
        return None
    parts = str(value).split(",") if isinstance(value, str) else list(np.ravel(value))
    try:
        out = np.array([float(v) for v in parts])
    except (TypeError, ValueError):
        raise RequestError(f"{option}: needs {n} comma-separated numbers, got {value!r}") from None
    if len(out) not in (n if isinstance(n, tuple) else (n,)) or not np.all(np.isfinite(out)):
        raise RequestError(f"{option}: needs {n} finite numbers, got {value!r}")
    return out


_SETUP_KEYS = {"diameter": "[sphere] diameter", "center": "[sphere] center", "side": "[profile] side",
               "start": "[sensor] start_pose", "convention": "[robot] convention", "robot": "[robot] model"}


def _check_setup_values(found, file):
    """The --setup file's values of the right kinds, named with the file and key (DatasetError)."""
    def number(v):
        return isinstance(v, (int, float)) and not isinstance(v, bool)

    checks = {"diameter": number, "side": lambda v: v in (1, -1) and not isinstance(v, bool),
              "center": lambda v: isinstance(v, list) and len(v) == 3 and all(map(number, v)),
              "start": lambda v: isinstance(v, list) and all(map(number, v)),
              "convention": lambda v: isinstance(v, str), "robot": lambda v: isinstance(v, str) and v.strip()}
    for key, ok in checks.items():
        if found[key] is not None and not ok(found[key]):
            raise DatasetError(file, f"{str(found[key])[:40]!r} is not a value of this key (the --setup file)",
                               column=_SETUP_KEYS[key])


def _from_setup(opts):
    """``--setup FILE``: an existing setup.toml fills the options not given (diameter, center, side,
    start pose, convention, robot model)."""
    file = opts["setup"]
    if file is None:
        return
    try:
        doc = tomllib.loads(pathlib.Path(file).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError) as exc:
        raise RequestError(f"--setup {file}: cannot be read: {getattr(exc, 'strerror', None) or exc}") from None
    except tomllib.TOMLDecodeError as exc:
        raise DatasetError(file, f"not valid TOML: {exc}") from None
    for section in ("sphere", "sensor", "robot", "profile"):
        if not isinstance(doc.get(section, {}), dict):
            raise DatasetError(file, "must be a [section] of keys (the --setup file)", column=f"[{section}]")
    sphere, sensor, robot = doc.get("sphere", {}), doc.get("sensor", {}), doc.get("robot", {})
    found = {"diameter": sphere.get("diameter"), "center": sphere.get("center"),
             "side": doc.get("profile", {}).get("side"), "start": sensor.get("start_pose"),
             "convention": robot.get("convention"), "robot": robot.get("model")}
    _check_setup_values(found, file)
    if opts["side"] is None and found["side"] is not None:
        opts["_side_from_setup"] = True  # a setup's side is in handeye's frame already
    if opts["start"] is None and found["start"] is not None:  # of the setup's own frame when it says so, else handeye's
        from handeye.model.readers.setup_file import _own_axes

        profile = doc.get("profile", {})
        opts["_start_axes"] = _own_axes(profile.get("own_axes"), file) if profile.get("poses") == "own" else None
    model = found["robot"]
    if isinstance(model, str) and (pathlib.Path(file).parent / model).is_file():  # a model file: the setup's folder's
        found["robot"] = str(pathlib.Path(file).parent / model)
    for key, value in found.items():
        if opts[key] is None and value is not None:
            opts[key] = value


def _check_options(out, opts):
    """Options checked before anything is read; raises RequestError naming the option."""
    from handeye.app.common.files import check_output_folder
    from handeye.app.engine.command_request import checked_values

    check_output_folder(out, "OUT", empty=True)
    _from_setup(opts)
    opts["_side_default"] = opts["side"] is None
    opts["side"] = -1 if opts["side"] is None else opts["side"]
    if opts["poses"] is not None and opts["bag"] is not None:
        raise RequestError("--poses and --bag: give one of them (the bag's --pose-topic has the poses)")
    if opts["poses"] is None and opts["bag"] is None:
        raise RequestError("give the poses: --poses FILE, or --bag PATH with --pose-topic and --profile-topic")
    if opts["poses"] is not None and not opts["profiles"]:
        raise RequestError("--poses needs --profiles FILES|GLOB|DIR (the laser profile of each pose)")
    if opts["bag"] is not None and opts["profiles"]:
        raise RequestError("--profiles and --bag: the bag's --profile-topic gives the profiles; give one of them")
    diameter = opts["diameter"]
    if diameter is None:
        raise RequestError("--diameter MM is required: the sphere's diameter from its certificate, mm")
    try:
        ok = not isinstance(diameter, (bool, str)) and 0 < float(diameter) < 10_000
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise RequestError(f"--diameter must be a number of mm in (0, 10000), got {diameter!r}")
    opts["diameter"] = float(diameter)
    checked_values("dataset new", opts)  # units, angles, side, pairing and convention among their choices
    if opts["profile_axes"] is not None:
        parse_axes(opts["profile_axes"])
    if opts["joints"] is not None and opts["bag"] is not None:
        raise RequestError("--joints with --bag: a bag's joint states are not read; give --poses and --profiles files")
    if opts["joints"] is not None and opts["robot"] is None:
        raise RequestError("--joints needs --robot MODEL (the nominal kinematics the loader checks them against)")
    if not isinstance(opts["max_dt"], (int, float)) or not opts["max_dt"] > 0:
        raise RequestError(f"--max-dt must be a positive number of seconds, got {opts['max_dt']!r}")


def _from_files(opts):
    """Poses and profiles from loose files: ``(ids, values (N, 3 + k) in the convention, convention, Profile per
    pose, inputs, notes, pairing, source roles [(role, file, format)], (the pose file's ids or None, its lines))``."""
    table = read_poses(opts["poses"], opts["convention"], opts["columns"], opts["units"], opts["angles"])
    profiles, skipped = sources.read_profiles(opts["profiles"], opts["profile_units"] or "mm",
                                              exclude=[opts[k] for k in ("poses", "joints", "setup")])
    try:
        index, ids, how = pair([p.label for p in profiles], [p.name for p in profiles], table.ids, len(table.values),
                               str(table.file), opts["pair"], opts["match"])
    except DatasetError as exc:
        if not skipped:
            raise
        raise DatasetError(exc.file, f"{exc.problem}; skipped as no profile: {skipped[0][0]} ({skipped[0][1]})"
                           + (f" and {len(skipped) - 1} more" if len(skipped) > 1 else ""), exc.row, exc.column) from None
    per_pose = [None] * len(ids)
    for p, k in zip(profiles, index):
        per_pose[k] = p
    keep = [k for k in range(len(ids)) if per_pose[k] is not None]
    inputs = {"poses": {"file": str(table.file), "format": table.format, "columns": list(table.columns),
                        "source_convention": table.source, "units": opts["units"],
                        "angles": opts["angles"] or "the convention's"}}
    if skipped:
        inputs["skipped"] = {f: why for f, why in skipped}
    roles = [("poses", table.file, table.format)] + [("profile", p.file, p.format) for p in profiles]
    return ([ids[k] for k in keep], table.values[keep], table.convention, [per_pose[k] for k in keep], inputs,
            list(table.notes), how, roles, (table.ids, table.lines))


def _from_bag(opts):
    """The same from a ROS 2 bag (:mod:`handeye.app.ingest.rosbag`)."""
    from handeye.app.ingest.rosbag import read_bag

    data = read_bag(opts["bag"], opts["pose_topic"], opts["profile_topic"], opts["base_frame"], opts["flange_frame"],
                    opts["max_dt"])
    convention = opts["convention"] or "abb"
    values = conventions.pose_from(convention, data.flange2base)
    profiles = sources.bag_profiles(data.profiles, opts["profile_topic"])
    ids = [p.name for p in profiles]
    inputs = {"bag": {"path": str(opts["bag"]), "pose_topic": opts["pose_topic"], "profile_topic": opts["profile_topic"],
                      "types": list(data.types), "counts": data.counts}}
    notes = ["ROS positions m -> mm", "ROS quaternions (x, y, z, w)" + (" -> abb (w, x, y, z)" if convention == "abb"
                                                                          else f" -> {convention}")]
    how = f"by time: each profile with the nearest pose within {opts['max_dt']:g} s"
    roles = [("bag", f, "ROS 2 bag") for f in writer.source_files(opts["bag"])]
    return ids, values, convention, profiles, inputs, notes, how, roles, (tuple(ids), tuple(range(1, len(ids) + 1)))


def _joints(opts, pose_ids, n):
    """Joint angles (n, 6) in the poses' order (by id when both files have ids, else by order)."""
    if opts["joints"] is None:
        return None
    ids, values, lines = read_joints(opts["joints"])
    if ids is not None and pose_ids[0] is not None:
        where = {i: k for k, i in enumerate(ids)}
        missing = [i for i in pose_ids[0] if i not in where]
        if missing:
            raise DatasetError(opts["joints"], f"no joint angles for pose {missing[0]!r}")
        return values[[where[i] for i in pose_ids[0]]]
    if len(values) != len(pose_ids[1]):
        raise DatasetError(opts["joints"], f"{len(values)} rows of joint angles for {len(pose_ids[1])} poses")
    return values


@options.COMMANDS["dataset new"].documented
def new_dataset(out, *, poses=None, profiles=(), convention=None, columns=None, units="mm", angles=None,
                profile_units=None, profile_axes=None, diameter=None, side=None, center=None, start=None, joints=None,
                robot=None, pair="auto", match=None, bag=None, pose_topic=None, profile_topic=None, base_frame=None,
                flange_frame=None, max_dt=0.05, setup=None):
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
    opts = {**{k: v for k, v in options.COMMANDS["dataset new"].given(locals()).items() if k != "out"},
            "profiles": [profiles] if isinstance(profiles, (str, pathlib.Path)) else list(profiles or ())}
    _check_options(out, opts)
    centre = _vector(opts["center"], 3, "--center")
    ids, values, conv, per_pose, inputs, notes, how, roles, pose_ids = (_from_files if bag is None else _from_bag)(opts)
    mapping = sources.map_to_plane(per_pose, opts["diameter"], profile_axes,
                                   "--profile-units" if bag is None else "the bag's profile topic")
    start_pose = _vector(opts["start"], len(conventions.columns(conv)), "--start")
    if start_pose is not None and "_start_axes" in opts:  # a --setup's start: of this dataset's frame (the own one)
        matrix = own_frame.to_internal(conventions.transform_from(conv, start_pose), opts["_start_axes"])
        start_pose = conventions.pose_from(conv, own_frame.to_own(matrix, None if mapping.identity else mapping.rotation))
    joint_values = _joints(opts, pose_ids, len(ids))
    inputs["profiles"] = sources.formats(per_pose)
    side = opts["side"] if opts.get("_side_from_setup") else mapping.side(opts["side"])
    if side != opts["side"]:
        given = "the default --side" if opts.get("_side_default") else "--side"
        notes.append(f"{given} {opts['side']:+d} (the profiles' {mapping.normal}) is side {side:+d} in handeye's y")
    result = NewDatasetResult(
        path=pathlib.Path(out), ids=tuple(ids), convention=conv, inputs=inputs, conversions=tuple(notes),
        plane=mapping.describe(), rotation=None if mapping.identity else mapping.rotation,
        dropped={i: p.dropped for i, p in zip(ids, per_pose) if p.dropped}, pairing=how,
        next_command=f"handeye calibrate {out}" + (" --unknowns sensor+sphere" if centre is None else ""), side=side)
    files = _files(result, values, per_pose, joint_values, opts, centre, start_pose, roles)
    _write_checked(out, files)
    return result


def _files(result, values, per_pose, joints, opts, centre, start_pose, roles):
    """Relative path -> text of every file of the dataset."""
    from handeye.app.common.files import tool_version

    taken, profile_files, rels = set(), {}, []
    for ident, p in zip(result.ids, per_pose):
        rel = f"profiles/{writer.safe_name(ident, taken)}.csv"
        profile_files[rel] = writer.profile_text(p.xz)
        rels.append(rel)
    head = {"tool": "handeye dataset new", "version": tool_version(),
            "created_utc": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")}
    options = {k: _option_value(v) for k, v in opts.items()
               if v is not None and not k.startswith("_") and not (isinstance(v, list) and not v)}  # _: internal marks
    sections = {"options": options, "inputs": dict(result.inputs), "conversions": {"made": list(result.conversions)},
                "plane": {"mapping": result.plane, "rotation_handeye_from_file": None if result.rotation is None
                          else np.asarray(result.rotation).tolist()},
                "pairing": {"method": result.pairing, "pairs": {i: p.label for i, p in zip(result.ids, per_pose)}},
                "dropped_nonfinite": dict(result.dropped)}
    files = dict(profile_files)
    model = _robot_model(opts["robot"], files)
    extra = [(r, opts[r], "table" if r == "joints" else "TOML") for r in ("joints", "setup") if opts[r] is not None]
    extra += [("robot model", opts["robot"], "TOML")] if model == MODEL_FILE else []
    srcs = [{"role": role, "path": str(pathlib.Path(f).resolve()), "format": fmt, "sha256": writer.sha256(f)}
            for role, f, fmt in _unique(roles + extra)]
    files["measurements.csv"] = writer.measurements_text(result.ids, values, result.convention, rels, joints)
    files["setup.toml"] = writer.setup_text(result.convention, opts["diameter"], result.side, centre, start_pose, model,
                                            result.rotation)
    files["PROVENANCE.toml"] = writer.provenance_text(head, sections, srcs)
    return files


#: The name a robot model file gets in the dataset (as ``handeye simulate --robot FILE`` names it).
MODEL_FILE = "robot_model.toml"


def _robot_model(robot, files):
    """``[robot] model``: a built-in name as it is; a model file copied into the dataset as
    :data:`MODEL_FILE` (a path in setup.toml is the dataset folder's)."""
    if robot is None or str(robot) in robots.builtin_names():
        return robot
    path = pathlib.Path(robot)
    if not path.is_file():
        raise RequestError(f"--robot {robot}: not a built-in model ({', '.join(robots.builtin_names())}) nor a file")
    try:
        files[MODEL_FILE] = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise RequestError(f"--robot {robot}: cannot be read: {getattr(exc, 'strerror', None) or exc}") from None
    return MODEL_FILE


def _option_value(v):
    """An option's value for PROVENANCE.toml: numbers as numbers, sequences as lists, else text."""
    if isinstance(v, (bool, int, float)):
        return v
    if isinstance(v, (list, tuple, np.ndarray)):
        return [x if isinstance(x, (int, float)) else str(x) for x in np.asarray(v, object).ravel().tolist()]
    return str(v)


def _unique(roles):
    seen, out = set(), []
    for role, f, fmt in roles:
        if f is not None and str(f) not in seen:
            seen.add(str(f))
            out.append((role, f, fmt))
    return out


def _write_checked(out, files):
    """Write the files into a temporary folder, load it as a dataset (every check of
    :func:`handeye.model.datasets.dataset.load`), then rename it to ``out``: never a half-written folder."""
    from handeye.app.common.files import write_folder_atomically
    from handeye.model.datasets.dataset import load

    def write(tmp):
        (tmp / "profiles").mkdir()
        for rel, text in files.items():
            (tmp / rel).write_text(text)
        try:
            load(tmp)
        except DatasetError as exc:
            rel = pathlib.Path(exc.file).resolve()
            name = rel.relative_to(tmp.resolve()) if rel.is_relative_to(tmp.resolve()) else rel
            problem = exc.problem.replace(" in setup.toml", " (--diameter)")  # the setup is the options' here
            raise DatasetError(pathlib.Path(out) / name, f"the assembled dataset does not load: {problem}", exc.row,
                               exc.column) from None

    write_folder_atomically(out, write, option="OUT")
