"""The options of ``handeye export``, ``cloud`` and ``validate``, validated in one place.

Each command reads its dataset (export has none), turns its options into a request here, runs,
then writes: ``load -> *Request.from_options(given, data) -> run -> write``, the options as the
public function was given them (``COMMANDS[name].given``). Resolved here, once: the calibration
held (a saved file, a :class:`handeye.CalibrationResult`, a 4x4, or ``--sensor-pose`` typed in
``--convention``'s columns; of the user's frame, turned into handeye's where the dataset's
profiles were turned) and checked against the dataset's sensor mount and positioner axes;
export's names and numbers for its format; the outputs, before the work. What only a file's
content can tell is that file's error, naming it and its key (:mod:`handeye.app.outputs.saved`).
"""
from __future__ import annotations

import dataclasses
import pathlib
import re

import numpy as np

from handeye.app.common import files
from handeye.app.common.arguments import _path_argument, numbers
from handeye.app.common.choices import CLOUD_FORMATS, FORMATS, ROBOT_FORMATS
from handeye.app.common.errors import RequestError
from handeye.app.outputs import saved
from handeye.app.outputs import verdict as verdicts
from handeye.app.outputs.formats import Names
from handeye.model.chain.names import SENSOR_MOUNTS

#: Frame names: what ROS, URDF and the controllers accept as an identifier.
_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_/.-]{0,63}$")
_RAPID_NAME = re.compile(r"[^A-Za-z0-9_]")
_IDENTIFIER = re.compile(r"^[A-Za-z_][A-Za-z0-9_]{0,31}$")
#: format -> (largest number, what it numbers) of a tool (sensor on the flange) and of a base / user frame (world)
_NUMBERS = {"kuka": ((16, "a KUKA tool number"), (32, "a KUKA base number")),
            "fanuc": ((10, "a FANUC tool frame number"), (9, "a FANUC user frame number"))}


def given_calibration(calibration, sensor_mount=None, own_axes=None):
    """A calibration given as a file, a 4x4 (in ``sensor_mount``'s frame; of the sensor's own frame
    for a dataset whose profiles were turned, ``own_axes``), a :class:`saved.Calibration` or a
    CalibrationResult."""
    if calibration is None:
        raise RequestError("a calibration is needed: --calibration RESULT.json (from handeye calibrate --out) or "
                           "--sensor-pose X,Y,Z,...")
    if isinstance(calibration, saved.Calibration):
        return calibration
    if isinstance(calibration, (np.ndarray, list, tuple)):
        return saved.from_matrix(calibration, sensor_mount=sensor_mount or "flange").from_user_frame(own_axes)
    if not (hasattr(calibration, "sensor2flange") and hasattr(calibration, "covariance")):
        return saved.load(calibration).for_dataset(own_axes)
    if calibration.sensor2flange is None:  # a CalibrationResult
        raise RequestError(f"the calibration failed ({calibration.message}); nothing to use")
    cov = None if calibration.covariance is None else np.asarray(calibration.covariance)[:6, :6]
    cal = saved.Calibration(np.asarray(calibration.sensor2flange, float), cov, f"calibration of {calibration.dataset}",
                            calibration.dataset, calibration.dataset_sha256, bool(calibration.converged),
                            getattr(calibration, "sensor_mount", "flange"),
                            own_axes=getattr(calibration, "own_axes", None))
    if getattr(calibration, "pose_frame", "handeye") == "own":  # a result turned for the user: back to handeye's
        cal = dataclasses.replace(cal, own_axes=None).from_user_frame(cal.own_axes)
    return cal


def held(v, data=None, name="--calibration"):
    """The :class:`saved.Calibration` the options ``v`` give (``calibration``, ``sensor_pose``,
    ``convention``, ``force``; export's ``sensor_mount``: where a typed pose or 4x4 is, checked
    against a saved one's), for ``data`` (its convention and own frame; None: export's, which has
    no dataset)."""
    mount, own_axes = v.get("sensor_mount"), getattr(data, "own_axes", None)
    if mount is not None and mount not in SENSOR_MOUNTS:
        raise RequestError(f"--sensor-mount {mount!r}: choose one of {', '.join(SENSOR_MOUNTS)}")
    if v["sensor_pose"] is not None:
        if v["calibration"] is not None:
            raise RequestError(f"give {name} or --sensor-pose, not both")
        convention = v["convention"] or getattr(data, "convention", None)
        if convention is None:
            raise RequestError("--sensor-pose needs --convention (kuka, fanuc, abb, ur): there is no dataset to take "
                               "it from")
        values = numbers(v["sensor_pose"], "--sensor-pose")
        return saved.from_pose(values, convention, mount or "flange").from_user_frame(own_axes)
    cal = given_calibration(v["calibration"], mount, own_axes)
    if mount is not None and mount != cal.sensor_mount:
        raise RequestError(f"--sensor-mount {mount}: {cal.source} is a sensor_mount {cal.sensor_mount} "
                           "calibration (the option is for --sensor-pose or a 4x4)")
    if not cal.converged and not v["force"]:
        raise RequestError(f"{cal.source}: the calibration did not converge; handeye will not use it (rerun "
                           "calibrate, or pass --force to use it anyway)")
    return cal


def same_mount(cal, data, command):
    """``cal``, if its sensor is mounted where the dataset's is (a sensor2flange read as a
    sensor2base, or the other way round, would give wrong numbers without a warning)."""
    mounts = getattr(data, "mounts", None)
    mount = "flange" if mounts is None else mounts.sensor
    if cal.sensor_mount != mount:
        raise RequestError(f"{cal.source}: a calibration of a sensor mounted on the {cal.sensor_mount} "
                           f"(sensor_mount); {data.path / 'setup.toml'} mounts the sensor on the {mount} "
                           f"([sensor] mount): handeye {command} needs the two to agree")
    return cal


def given_sensor(calibration, sensor_pose, convention, data, scoring=False):
    """The sensor pose given (4x4, the mount's frame) and where it came from: a saved calibration
    (``--calibration``) or a pose typed in (``--sensor-pose``, in ``convention``), checked against
    the dataset's sensor mount; ``(None, None)`` when neither is given. A calibration that did not
    converge is held only to be scored."""
    if calibration is None and sensor_pose is None:
        return None, None
    if sensor_pose is not None:
        values = numbers(sensor_pose, "--sensor-pose")
        text = sensor_pose if isinstance(sensor_pose, str) else ",".join(map(repr, np.ravel(sensor_pose).tolist()))
        cal, source = saved.from_pose(values, convention, data.mounts.sensor), f"--sensor-pose {text}"
        if data.own_axes is not None:  # typed in: the sensor's own frame, as export writes it (p = R p_own)
            cal = cal.from_user_frame(data.own_axes)
            source += " (the sensor's own frame, turned by [profile] own_axes)"
    else:
        cal, source = saved.load(_path_argument(calibration)).for_dataset(data.own_axes), str(calibration)
        source += "" if cal.converged else " (a calibration that did not converge)"
        if not cal.converged and not scoring:
            raise RequestError(f"--calibration: {calibration} did not converge; handeye will not hold its sensor pose "
                               "(calibrate again)")
    mount = getattr(cal, "sensor_mount", "flange")
    if mount != data.mounts.sensor:
        raise RequestError(f"{'--calibration' if calibration is not None else '--sensor-pose'}: {source} is of a sensor "
                           f"mounted on the {mount}, the dataset's sensor is mounted on the {data.mounts.sensor} "
                           "([sensor] mount)")
    return np.asarray(cal.sensor2flange, float), source


def _held_on(v, data, command):
    """:func:`held` for ``data``, checked against its sensor mount, and ``data`` at the positioner
    axes the calibration holds (as set up when it holds none)."""
    cal = same_mount(held(v, data), data, command)
    axes, mounts = cal.positioner_axes, getattr(data, "mounts", None)
    if not axes or mounts is None or mounts.sphere != "positioner":
        return cal, data
    if tuple(a.name for a in axes) != mounts.axis_names:
        raise RequestError(f"{cal.source}: its positioner axes ({', '.join(a.name for a in axes)}) are not the "
                           f"dataset's ({', '.join(mounts.axis_names)})")
    return cal, dataclasses.replace(data, mounts=mounts.at(axes))


def _inputs(data, *more):
    """The files of ``data``'s folder a command reads (never written over), and ``more``."""
    return [data.path / "measurements.csv", data.path / "setup.toml", *more]


def _file(calibration):
    """``[calibration]`` when it is a file's name (an input, never written over), else ``[]``."""
    return [calibration] if isinstance(calibration, (str, pathlib.Path)) else []


@dataclasses.dataclass(frozen=True)
class ExportRequest:
    """``handeye export``'s options, checked: the calibration (a robot format: the saved file's name
    and JSON object), the names and numbers written (:class:`Names`) and the verdict's comment
    lines (:func:`handeye.app.outputs.verdict.comment_lines`)."""

    held: object
    names: Names
    comments: tuple = ()

    @classmethod
    def from_options(cls, v):
        """The request of the options ``v`` (the public function's keywords)."""
        fmt, calibration = v["format"], v["calibration"]
        if calibration is None and v["sensor_pose"] is None:
            raise RequestError("give the saved calibration (handeye export RESULT.json --format ...) or --sensor-pose")
        if v["out"] is not None:
            files.check_output_path(v["out"], "--out", _file(calibration))
        if fmt in ROBOT_FORMATS:
            name, doc = _robot_file(calibration, fmt, v["force"])
            checked = verdicts.check(calibration, saved.from_document(doc, name), dataset=v["dataset"])
            forced = None if doc.get("converged") is True else _why(doc)
            return cls((name, doc), Names(), tuple(verdicts.comment_lines(checked, forced)))
        cal = held(v, name="the saved calibration")
        if fmt not in FORMATS:
            raise RequestError(f"--format {fmt!r}: choose one of {', '.join(FORMATS)}")
        checked = verdicts.check(calibration, cal, dataset=v["dataset"])
        forced = None if cal.converged else _why(saved.document(pathlib.Path(calibration)) if _file(calibration) else {})
        return cls(checked.calibration, _names(v, cal.sensor_mount == "world"),
                   tuple(verdicts.comment_lines(checked, forced)))


def _why(doc):
    """Why a saved calibration is no calibration (its ``converged`` false), in words."""
    message = doc.get("message") if isinstance(doc, dict) else None
    return "the calibration did not converge" + (f": {message}" if isinstance(message, str) and message else "")


def _robot_file(calibration, fmt, force):
    """``(name, JSON object)`` of the saved calibration a robot format corrects the robot's model by."""
    if not isinstance(calibration, (str, pathlib.Path)):
        raise RequestError(f"--format {fmt}: give a saved calibration file (calibrate --effects joint_offsets --out)")
    doc = saved.document(pathlib.Path(calibration))
    if not isinstance(doc, dict) or not isinstance(doc.get("robot_model"), str):
        raise RequestError(f"{calibration}: no robot_model (calibrate a dataset with j1..j6 and [robot] model)")
    if doc.get("converged") is not True and not force:
        raise RequestError(f"{calibration}: the calibration did not converge; handeye will not use it (--force)")
    return str(calibration), doc


def _names(v, world):
    """Export's names and numbers (``--parent``, ``--child``, ``--tool`` or ``--base``, ``--register``)
    checked for ``v["format"]`` and the sensor's mount (``world``: fixed in the cell)."""
    fmt, child, parent = v["format"], v["child"], v["parent"]
    for option, name in (("--parent", parent), ("--child", child)):
        if name is not None and not _NAME.match(name):
            raise RequestError(f"{option} {name!r}: a frame name is letters, digits and _ / . - (at most 64), "
                               "starting with a letter or _")
    if world and v["tool"] is not None:
        raise RequestError(f"--tool {v['tool']}: the sensor is fixed in the cell (sensor_mount world), written as a "
                           "base / user frame: give its number with --base")
    if not world and v["base"] is not None:
        raise RequestError(f"--base {v['base']}: the sensor is on the flange, written as a tool: give its number with "
                           "--tool")
    number = v["base" if world else "tool"]
    number = 1 if number is None else number
    if fmt in _NUMBERS and not 1 <= number <= _NUMBERS[fmt][world][0]:
        most, what = _NUMBERS[fmt][world]
        raise RequestError(f"{'--base' if world else '--tool'} {number}: {what} is 1..{most}")
    if fmt == "kuka" and (len(child) > 24 or '"' in child):  # the name of what the format writes
        raise RequestError(f"--child {child!r}: KUKA's {'BASE' if world else 'TOOL'}_NAME holds at most 24 characters")
    rapid = f"wobj_{child}" if world else "t" + child
    if fmt == "abb" and (_RAPID_NAME.search(child) or len(rapid) > 32):
        raise RequestError(f"--child {child!r}: the ABB {'wobjdata' if world else 'tooldata'} is named {rapid}, a "
                           "RAPID identifier: letters, digits and _, at most 32 characters")
    if fmt == "fanuc" and not 1 <= v["register"] <= 100:
        raise RequestError(f"--register {v['register']}: a FANUC position register is 1..100")
    if fmt == "ur" and world and not _IDENTIFIER.match(f"{child}_frame"):
        raise RequestError(f"--child {child!r}: the URScript variable is {child}_frame, an identifier: letters, "
                           "digits and _, at most 32 characters")
    return Names(parent, child, number, v["register"])


@dataclasses.dataclass(frozen=True)
class CloudRequest:
    """``handeye cloud``'s options on a scan: the calibration, the scan at its positioner axes and the
    format written."""

    calibration: saved.Calibration
    data: object
    format: str

    @classmethod
    def from_options(cls, v, data):
        """The request of the options ``v`` (the public function's keywords) on the scan ``data``."""
        out, fmt = v["out"], v["format"]
        suffix = "" if out is None else pathlib.Path(out).suffix.lower().lstrip(".")
        fmt = ("csv" if suffix == "csv" else "ply") if fmt is None else fmt
        if fmt not in CLOUD_FORMATS:
            raise RequestError(f"--format {fmt!r}: choose one of {', '.join(CLOUD_FORMATS)}")
        if suffix in CLOUD_FORMATS and suffix != fmt:
            raise RequestError(f"--out {out}: a .{suffix} file, but --format {fmt}; name it .{fmt} or drop --format")
        if out is not None:
            files.check_output_path(out, "--out", _inputs(data, *data.profile_files, *_file(v["calibration"])))
        return cls(*_held_on(v, data, "cloud"), fmt)


@dataclasses.dataclass(frozen=True)
class ValidateRequest:
    """``handeye validate``'s options on a scan or a dataset of centres: the calibration, the data at
    its positioner axes, the fraction of points left out and the maximum permissible errors (None:
    no verdict)."""

    calibration: saved.Calibration
    data: object
    exclude: float
    limits: list | None

    @classmethod
    def from_options(cls, v, data):
        """The request of the options ``v`` (the public function's keywords) on ``data`` (a scan, or a
        dataset without profiles)."""
        limits, exclude = _mpe(v["mpe"]), _exclude(v["exclude"])
        if v["plot"] is not None:
            files.check_output_path(v["plot"], "--plot", _inputs(data), plot=True)
        cal, data = _held_on(v, data, "validate")
        spheres = getattr(data, "spheres", None)  # a scan's; a dataset of centres has none
        if limits is not None and spheres is None:
            raise RequestError("--mpe judges PF, PS and SD of a sphere scan; a validation of centres has none")
        if limits is not None and len(limits) == 3 and len(spheres) == 1:
            raise RequestError("--mpe gives an SD limit, but the setup has one sphere ([sphere2] gives the second)")
        return cls(cal, data, exclude, limits)


def _exclude(value):
    try:
        value = float(value)
    except (TypeError, ValueError):
        raise RequestError(f"--exclude {value!r}: a fraction of points in [0, 0.05]") from None
    if not 0.0 <= value <= 0.05:
        raise RequestError(f"--exclude {value}: a fraction of points in [0, 0.05] (VDI/VDE 2634-2 allows 0.003)")
    return value


def _mpe(mpe):
    """``"PF,PS[,SD]"`` (mm) or a sequence, checked; None stays None."""
    if mpe is None:
        return None
    values = numbers(mpe, "--mpe", form="PF,PS[,SD] in mm, e.g. 0.05,0.03")
    if len(values) not in (2, 3) or not all(np.isfinite(v) and v > 0 for v in values):
        raise RequestError(f"--mpe {mpe!r}: two or three positive numbers (PF, PS[, SD] in mm)")
    return values
