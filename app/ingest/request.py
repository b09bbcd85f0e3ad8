"""The options of ``handeye dataset new``, validated in one place: :class:`NewDatasetRequest`.

:func:`handeye.app.ingest.command.new_dataset` reads as request -> read -> pair -> write. The
request is made before anything is read: the option table's checks
(:attr:`handeye.app.common.option_record.Opt.check`) and what only this command knows (poses from
files or a bag, not both; ``--joints`` with ``--robot``), with ``--setup``'s values filling the
options not given, ``--profiles`` expanded into files, ``--robot`` resolved. What only the data
tell (a column the file lacks, a topic the bag lacks, a pairing that fails) is a data error naming
file, row and column, raised where the file is read; the one check of an option that waits for
the data, the start pose's length (the dataset's convention), is :meth:`NewDatasetRequest.start_pose`.
"""
from __future__ import annotations

import dataclasses
import glob
import importlib.util
import os
import pathlib
import re
import tomllib

from handeye.app.common.arguments import numbers
from handeye.app.common.errors import RequestError
from handeye.app.common.files import check_output_folder
from handeye.app.engine.command_request import checked_values
from handeye.app.ingest import mounts
from handeye.app.ingest.controller_rtde import Still
from handeye.app.ingest.pairing import Pairing, natural_key
from handeye.app.ingest.plane import AXES
from handeye.app.ingest.poses import canonical
from handeye.app.ingest.tables import decode, read_bytes
from handeye.model.chain import conventions, own_frame
from handeye.model.readers.setup_file import _own_axes
from handeye.model.readers.tables import MAX_LINE_BYTES, PARSE_ERRORS, DatasetError, parse_problem
from handeye.model.robot import robots

#: The name a robot model file gets in the dataset (as ``handeye simulate --robot FILE`` names it).
MODEL_FILE = "robot_model.toml"
#: what ``--columns`` writes for a column to skip
_SKIP = ("-", "_", "skip", "")


def _is_number(v):
    return isinstance(v, (int, float)) and not isinstance(v, bool)


#: option -> (section, key) of setup.toml that fills it, and what its value must be
_SETUP = {"diameter": ("sphere", "diameter", _is_number),
          "side": ("profile", "side", lambda v: v in (1, -1) and not isinstance(v, bool)),
          "center": ("sphere", "center", lambda v: isinstance(v, list) and len(v) == 3 and all(map(_is_number, v))),
          "start": ("sensor", "start_pose", lambda v: isinstance(v, list) and all(map(_is_number, v))),
          "convention": ("robot", "convention", lambda v: isinstance(v, str)),
          "robot": ("robot", "model", lambda v: isinstance(v, str) and v.strip()),
          "sensor_mount": ("sensor", "mount", lambda v: isinstance(v, str)),
          "sphere_mount": ("sphere", "mount", lambda v: isinstance(v, str)),
          "positioner_axes": ("positioner", "axes", lambda v: mounts.axes_text(v) is not None)}


@dataclasses.dataclass(frozen=True)
class NewDatasetRequest:
    """``handeye dataset new``'s options, checked and resolved.

    Attributes
    ----------
    poses, joints, setup : path-like or None
        The pose file (None: a bag), the joint angles, the ``--setup`` file.
    profiles : tuple of (pathlib.Path, bool)
        The ``--profiles`` (or ``--clouds``) files in pairing order, each with whether it was named or
        matched (False: a folder's, which may hold files that are no profile).
    measured : {'profiles', 'clouds', 'centres'}
        What the sensor gave per pose: laser profiles, point clouds of the sphere (``--clouds``) or
        its centre (``--centres``).
    centres : path-like or None
        The ``--centres`` table.
    convention, angles : str or None
    columns : tuple or None
        ``--columns`` as canonical names (None for a column skipped).
    units, profile_units : str
    profile_axes : tuple or None
        ``--profile-axes`` as the files' ``(axis, sign)`` of handeye's x and of its z.
    diameter : float or None
        None only without profiles (``--clouds``: their radius fitted; ``--centres``).
    side : int
        ``--side`` in the profiles' frame (default -1), or the setup's, in handeye's frame already.
    side_from : {'option', 'default', 'setup'}
    center : list of 3 floats or None
    start : str, sequence or None
        The start pose as given (checked against the dataset's convention by :meth:`start_pose`).
    start_axes : ndarray (3, 3), None or False
        False: ``--start`` given, in the frame of the profile files; else the start pose is the
        setup's, in the setup's own frame (``[profile] own_axes``) or in handeye's (None).
    robot : str or None
        ``[robot] model``: a built-in name, or :data:`MODEL_FILE`.
    robot_file : (path-like, str) or None
        A model file and its text, copied into the dataset.
    pairing : Pairing
    bag, pose_topic, profile_topic, base_frame, flange_frame, max_dt
        A ROS 2 bag and what to read of it (:func:`handeye.app.ingest.rosbag.read_bag`).
    accept_frames : bool
        ``--accept-frames``: a controller file's tool and frame taken as the flange and the base.
    still : controller_rtde.Still or None
        ``--still MM,DEG,S``: what a stop of a streamed RTDE log is (None: the default).
    options : dict
        The options as PROVENANCE.toml keeps them (the setup's values filled in; None left out).
    cell : mounts.Cell
        ``--sensor-mount``, ``--sphere-mount``, ``--positioner-axes`` (:mod:`handeye.app.ingest.mounts`).
    """

    poses: object
    profiles: tuple
    convention: str | None
    columns: tuple | None
    units: str
    angles: str | None
    profile_units: str
    profile_axes: tuple | None
    diameter: float | None
    side: int
    side_from: str
    center: list | None
    start: object
    start_axes: object
    joints: object
    setup: object
    robot: str | None
    robot_file: tuple | None
    pairing: Pairing
    bag: object
    pose_topic: str | None
    profile_topic: str | None
    base_frame: str | None
    flange_frame: str | None
    max_dt: float
    accept_frames: bool
    options: dict
    still: Still | None = None
    cell: mounts.Cell = mounts.Cell()
    measured: str = "profiles"
    centres: object = None

    @classmethod
    def from_options(cls, given):
        """The request of ``given``, the keywords :func:`~handeye.app.ingest.command.new_dataset`
        was called with; raises :class:`~handeye.app.common.errors.RequestError` naming the option (a
        bad value of the ``--setup`` file: :class:`~handeye.model.readers.tables.DatasetError`)."""
        v = {**given, **{k: _listed(given.get(k)) for k in ("profiles", "clouds")}}
        check_output_folder(v["out"], "OUT", empty=True)
        found, start_axes = _from_setup(v["setup"], start_given=v["start"] is not None)
        side_from = "option" if v["side"] is not None else "setup" if found.get("side") is not None else "default"
        v.update({key: value for key, value in found.items() if v[key] is None and value is not None})
        v["side"] = -1 if v["side"] is None else v["side"]
        _together(v)
        v = checked_values("dataset new", v)  # diameter and --max-dt in range, the choices among theirs
        if v["bag"] is not None:
            _bag_checked(v["bag"])
        robot, robot_file = _robot(v["robot"])
        measured = "clouds" if v["clouds"] else "centres" if v["centres"] is not None else "profiles"
        resolved = {
            "profiles": tuple(expand(v["clouds"] or v["profiles"], [v[k] for k in ("poses", "joints", "setup", "centres")],
                                     "--clouds" if v["clouds"] else "--profiles")), "measured": measured,
            "columns": None if v["columns"] is None else _columns(v["columns"]), "profile_units": v["profile_units"] or "mm",
            "profile_axes": None if v["profile_axes"] is None else _profile_axes(v["profile_axes"]),
            "center": numbers(v["center"], "--center", 3), "robot": robot, "robot_file": robot_file,
            "pairing": Pairing(v["pair"], _match(v["match"])), "side_from": side_from, "start_axes": start_axes,
            "still": _still(v["still"]),
            "cell": mounts.checked(v["sensor_mount"], v["sphere_mount"], v["positioner_axes"], v["bag"] is not None),
            "options": {k: x for k, x in v.items() if k != "out" and x is not None and not (isinstance(x, list) and not x)}}
        return cls(**{**{field.name: v.get(field.name) for field in dataclasses.fields(cls)}, **resolved})

    def start_pose(self, convention, rotation):
        """``[sensor] start_pose`` of a dataset in ``convention`` whose profiles were turned by
        ``rotation`` (``p_handeye = R p_file``; None: not turned): the columns of the convention,
        in the frame of the profile files; None without a start pose."""
        pose = numbers(self.start, "--start", len(conventions.columns(convention)))
        if pose is None or self.start_axes is False:
            return pose
        matrix = own_frame.to_internal(conventions.transform_from(convention, pose), self.start_axes)
        return conventions.pose_from(convention, own_frame.to_own(matrix, rotation))


def _still(value):
    """``--still MM,DEG,S`` as a :class:`~handeye.app.ingest.controller_rtde.Still` (None: not given)."""
    got = numbers(value, "--still", 3)
    if got is None:
        return None
    if not all(v > 0 for v in got):
        raise RequestError(f"--still {value!r}: MM, DEG and S must be positive (a stop's tolerances and its shortest time)")
    return Still(*got)


def _listed(value):
    """``--profiles`` / ``--clouds`` as a list (one path given as a string: a list of it)."""
    return [value] if isinstance(value, (str, pathlib.Path)) else list(value or ())


def _together(v):
    """Options that do not go together, and options that others need."""
    poses, bag, joints, robot = (v[key] is not None for key in ("poses", "bag", "joints", "robot"))
    given = [flag for flag, key in (("--profiles", "profiles"), ("--clouds", "clouds"), ("--centres", "centres"))
             if v[key] not in (None, [])]
    for refused, text in (
            (poses and bag, "--poses and --bag: give one of them (the bag's --pose-topic has the poses)"),
            (not poses and not bag, "give the poses: --poses FILE, or --bag PATH with --pose-topic and --profile-topic"),
            (len(given) > 1, f"{' and '.join(given)}: give one of them (what the sensor measured per pose)"),
            (poses and not given, "--poses needs --profiles FILES|GLOB|DIR (the laser profile of each pose), --clouds (a "
                                  "3-D sensor's point cloud of the sphere) or --centres FILE (the centres it reported)"),
            (bag and given, f"{given[0] if given else ''} and --bag: the bag's --profile-topic gives the profiles; give one of "
                            "them"),
            (v["diameter"] is None and (bag or "--profiles" in given),
             "--diameter MM is required with profiles: the sphere's diameter from its certificate, mm (their centres are "
             "rebuilt from it)"),
            (joints and bag, "--joints with --bag: a bag's joint states are not read; give --poses and --profiles files"),
            (joints and not robot, "--joints needs --robot MODEL (the nominal kinematics the loader checks them against)"),
            (bag and not (v["pose_topic"] and v["profile_topic"]), "--bag needs --pose-topic and --profile-topic")):
        if refused:
            raise RequestError(text)


def _bag_checked(bag):
    """A bag that can be read: the ``rosbags`` package there, the bag there."""
    if importlib.util.find_spec("rosbags") is None or importlib.util.find_spec("rosbags.highlevel") is None:
        raise RequestError("--bag needs the rosbags package: pip install 'handeye[ros]'")
    if not pathlib.Path(bag).exists():
        raise RequestError(f"--bag {bag}: no such file or folder")


def _columns(text):
    """``--columns`` as canonical names of the file's columns (None: one skipped)."""
    names = [c.strip() for c in str(text).split(",")]
    for name in names:
        if name not in _SKIP and canonical(name) is None:
            raise RequestError(f"--columns: unknown column name {name!r} (x,y,z, a,b,c | w,p,r | rx,ry,rz | "
                               "qw,qx,qy,qz, id; '-' skips a column)")
    return tuple(None if name in _SKIP else canonical(name) for name in names)


def _profile_axes(text):
    """``--profile-axes 'y,-x'`` -> ((1, 1.0), (0, -1.0)): the files' axes (index, sign) that are
    handeye's x and z."""
    parts = str(text).split(",")
    if len(parts) != 2:
        raise RequestError(f"--profile-axes takes two axes (handeye's x, z), got {text!r}")
    axes = []
    for part in parts:
        name = part.strip().lower()
        if name.lstrip("+-") not in AXES:
            raise RequestError(f"--profile-axes: {part!r} is not x, y or z (with an optional sign)")
        axes.append((AXES.index(name.lstrip("+-")), -1.0 if name.startswith("-") else 1.0))
    if axes[0][0] == axes[1][0]:
        raise RequestError(f"--profile-axes {text}: two different axes")
    return tuple(axes)


def _match(pattern):
    """``--match``: a regular expression with exactly one group (None stays None)."""
    if pattern is None:
        return None
    try:
        groups = re.compile(pattern).groups
    except re.error as exc:
        raise RequestError(f"--match {pattern!r}: not a regular expression ({exc})") from None
    if groups != 1:
        raise RequestError(f"--match {pattern!r} needs exactly one group (...), it has {groups}")
    return pattern


def _real(path):
    """The path with its symlinks resolved, never an error (a symlink loop stays as it is: the reader names it)."""
    return pathlib.Path(os.path.realpath(path))


def expand(specs, exclude=(), option="--profiles"):
    """The profile files of ``--profiles`` arguments (files, globs, folders) as ``(file, listed)``
    pairs, natural order within each argument, argument order kept; ``listed`` is False for a
    folder's files (which may hold other files too). A folder's hidden files and subfolders, and
    the files in ``exclude`` (the pose file, ...), are left out; errors name ``option``."""
    skip = {_real(f) for f in exclude if f is not None}
    out = []
    for spec in specs:
        p = pathlib.Path(spec)
        try:
            files, where = _files_of(spec, p, skip, option)
        except OSError as exc:  # a folder that cannot be listed (permissions): bad input, named
            raise RequestError(f"{option} {spec}: cannot be read: {exc.strerror or exc}") from None
        if not files:
            raise RequestError(f"{option}: {where} has no files")
        out += [(f, not p.is_dir()) for f in sorted(files, key=lambda f: natural_key(f.name))]
    return out


def _files_of(spec, p, skip, option="--profiles"):
    """``(files, where)`` of one ``--profiles`` argument (unsorted); OSError where a folder cannot be
    listed."""
    if p.is_dir():
        files = [f for f in p.iterdir() if f.is_file() and not f.name.startswith(".") and _real(f) not in skip]
        return files, f"folder {spec}"
    if any(c in str(spec) for c in "*?["):
        return [pathlib.Path(f) for f in glob.glob(str(spec)) if pathlib.Path(f).is_file()], f"pattern {spec!r}"
    if p.is_file():
        return [p], spec
    raise RequestError(f"{option} {spec}: no such file or folder")


def _robot(robot):
    """``([robot] model, (model file, its text) or None)``: a built-in name as it is; a model file
    copied into the dataset as :data:`MODEL_FILE` (a path in setup.toml is the dataset folder's)."""
    if robot is None or str(robot) in robots.builtin_names():
        return robot, None
    path = pathlib.Path(robot)
    if not path.is_file():
        raise RequestError(f"--robot {robot}: not a built-in model ({', '.join(robots.builtin_names())}) nor a file")
    return MODEL_FILE, (robot, decode(path, read_bytes(path, MAX_LINE_BYTES, "a robot model file"), "a robot model file"))


def _from_setup(file, start_given):
    """``--setup FILE``: ``(values, start axes)``, the values an existing setup.toml gives for the
    options (diameter, center, side, start pose, convention, robot model, the mounts and the
    positioner's axes; a model file's path made the setup folder's) and
    :attr:`NewDatasetRequest.start_axes` (the frame of the setup's start pose when it gives the one
    used: its ``own_axes`` when its poses are of the sensor's own frame, else None, handeye's). No
    file: ``({}, False)``."""
    if file is None:
        return {}, False
    try:
        doc = tomllib.loads(decode(file, read_bytes(file, MAX_LINE_BYTES, "a setup file"), "a setup file"))
    except PARSE_ERRORS as exc:
        raise DatasetError(file, f"not valid TOML: {parse_problem(exc)}") from None
    for section in ("sphere", "sensor", "robot", "profile", "positioner"):
        if not isinstance(doc.get(section, {}), dict):
            raise DatasetError(file, "must be a [section] of keys (the --setup file)", column=f"[{section}]")
    found = {option: doc.get(section, {}).get(key) for option, (section, key, _) in _SETUP.items()}
    for option, (section, key, ok) in _SETUP.items():
        if found[option] is not None and not ok(found[option]):
            raise DatasetError(file, f"{str(found[option])[:40]!r} is not a value of this key (the --setup file)",
                               column=f"[{section}] {key}")
    if found["positioner_axes"] is not None:  # the option's text, checked as --positioner-axes is
        found["positioner_axes"] = mounts.axes_text(found["positioner_axes"])
    model = found["robot"]
    if isinstance(model, str) and (pathlib.Path(file).parent / model).is_file():  # a model file: the setup's folder's
        found["robot"] = str(pathlib.Path(file).parent / model)
    if start_given or found["start"] is None:
        return found, False
    profile = doc.get("profile", {})
    return found, _own_axes(profile.get("own_axes"), file) if profile.get("poses") == "own" else None
