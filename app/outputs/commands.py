"""Using a calibration: ``handeye export``, ``cloud`` and ``validate`` as Python functions.

Each takes the calibration as a saved result (``calibrate --out`` file), a
:class:`handeye.CalibrationResult`, or ``sensor_pose=`` (a pose typed in, e.g. a TCP already in
the controller; then no uncertainty is known), and the CLI's options as keyword arguments::

    import handeye
    text = handeye.export("result.json", format="ur").text
    c = handeye.cloud("my-scan", "result.json", out="scan.ply")     # c.points (M, 3), c.sd (M,)
    v = handeye.validate("sphere-scan", "result.json")              # v.spheres[0].form_error_mm
"""
from __future__ import annotations

import csv
import dataclasses
import io
import pathlib

import numpy as np

from handeye.app.common import files, options
from handeye.app.common.choices import CLOUD_FORMATS  # noqa: F401 - the names, defined without numpy
from handeye.app.common.errors import RequestError
from handeye.app.outputs import formats as exports
from handeye.app.outputs import saved
from handeye.app.present.protocol import ResultProtocol
from handeye.model.chain.mounts import FRAME


def _calibration(calibration, sensor_pose=None, convention=None, force=False, dataset_convention="kuka",
                 name="--calibration", sensor_mount=None, own_axes=None):
    """The :class:`saved.Calibration` to use; ``sensor_mount`` (None: flange, or the file's) is
    that of ``--sensor-pose``, or checked against the calibration's; ``own_axes`` (a dataset whose
    profiles ``dataset new`` turned): a typed pose or 4x4 is of the sensor's own frame, turned back."""
    if sensor_pose is not None:
        if calibration is not None:
            raise RequestError(f"give {name} or --sensor-pose, not both")
        if convention is None and dataset_convention is None:
            raise RequestError("--sensor-pose needs --convention (kuka, fanuc, abb, ur): there is no dataset to take "
                               "it from")
        values = numbers(sensor_pose, "--sensor-pose", "numbers separated by commas")
        cal = saved.from_pose(values, convention or dataset_convention, sensor_mount or "flange")
        return cal.from_user_frame(own_axes)
    cal = given_calibration(calibration, sensor_mount, own_axes)
    if sensor_mount is not None and saved.check_mount(sensor_mount) != cal.sensor_mount:
        raise RequestError(f"--sensor-mount {sensor_mount}: {cal.source} is a sensor_mount {cal.sensor_mount} "
                           "calibration (the option is for --sensor-pose or a 4x4)")
    if not cal.converged and not force:
        raise RequestError(f"{cal.source}: the calibration did not converge; handeye will not use it (rerun "
                           "calibrate, or pass --force to use it anyway)")
    return cal


def given_calibration(calibration, sensor_mount=None, own_axes=None):
    """A calibration given as a file, a 4x4 (in ``sensor_mount``'s frame; of the sensor's own frame
    for a dataset whose profiles were turned, ``own_axes``), a :class:`saved.Calibration` or a
    CalibrationResult."""
    if calibration is None:
        raise RequestError("a calibration is needed: --calibration RESULT.json (from handeye calibrate --out) or "
                           "--sensor-pose X,Y,Z,...")
    if isinstance(calibration, saved.Calibration):
        cal = calibration
    elif isinstance(calibration, np.ndarray) or isinstance(calibration, (list, tuple)):
        cal = saved.from_matrix(calibration, sensor_mount=sensor_mount or "flange").from_user_frame(own_axes)
    elif hasattr(calibration, "sensor2flange") and hasattr(calibration, "covariance"):  # a CalibrationResult
        if calibration.sensor2flange is None:
            raise RequestError(f"the calibration failed ({calibration.message}); nothing to use")
        cov = None if calibration.covariance is None else np.asarray(calibration.covariance)[:6, :6]
        cal = saved.Calibration(np.asarray(calibration.sensor2flange, float), cov,
                                f"calibration of {calibration.dataset}", calibration.dataset,
                                calibration.dataset_sha256, bool(calibration.converged),
                                saved.check_mount(getattr(calibration, "sensor_mount", "flange"), "sensor_mount"),
                                own_axes=getattr(calibration, "own_axes", None))
        if getattr(calibration, "pose_frame", "handeye") == "own":  # a result turned for the user: back to handeye's
            cal = dataclasses.replace(cal, own_axes=None).from_user_frame(cal.own_axes)
    else:
        cal = saved.load(calibration).for_dataset(own_axes)
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


def _at_calibrated_axes(data, cal):
    """The dataset at the positioner axes the calibration holds (as set up when it holds none)."""
    axes = getattr(cal, "positioner_axes", None)
    mounts = getattr(data, "mounts", None)
    if not axes or mounts is None or mounts.sphere != "positioner":
        return data
    if tuple(a.name for a in axes) != mounts.axis_names:
        raise RequestError(f"{cal.source}: its positioner axes ({', '.join(a.name for a in axes)}) are not the "
                           f"dataset's ({', '.join(mounts.axis_names)})")
    return dataclasses.replace(data, mounts=mounts.at(axes))


@dataclasses.dataclass(frozen=True)
class ExportResult(ResultProtocol):
    """The text of ``handeye export`` and where it was written (None: not written)."""

    caption = 'handeye export'

    format: str
    text: str
    out: str | None

    def to_dict(self):
        return dataclasses.asdict(self)


@options.COMMANDS["export"].documented
def export(calibration=None, *, format="json", parent=None, child="sensor", tool=None, register=99, out=None,
           sensor_pose=None, convention=None, force=False, base=None, sensor_mount=None):
    """The calibration in a robot's, ROS 2's or URDF's terms (:mod:`handeye.app.outputs.formats`).

    A sensor on the flange is written as a tool (number ``tool``, default 1), a sensor fixed in
    the cell (the calibration's ``sensor_mount`` "world") as a base / user frame (number
    ``base``, default 1); ``parent`` defaults to ``flange`` or ``base_link`` accordingly.
    ``sensor_mount`` ("flange" or "world"; default flange) is where a ``sensor_pose`` is given.

    Returns :class:`ExportResult`; with ``out`` the text is also written there (atomically).

    {parameters}
    """
    if calibration is None and sensor_pose is None:
        raise RequestError("give the saved calibration (handeye export RESULT.json --format ...) or --sensor-pose")
    if out is not None:
        inputs = [calibration] if isinstance(calibration, (str, pathlib.Path)) else []
        files.check_output_path(out, "--out", inputs)
    if format in ("robot-toml", "robot-urdf"):
        text = robot_text(calibration, format, force)
    else:
        cal = _calibration(calibration, sensor_pose, convention, force, None, "the saved calibration", sensor_mount)
        text = exports.text(cal, format, parent, child, tool, register, base)
    if out is not None:
        files.write_text_atomically(out, text)
    return ExportResult(format, text, None if out is None else str(out))


def _robot_values(doc, model):
    """The calibrated robot effects of a saved calibration ``doc`` as full parameter vectors of
    ``model`` (:func:`handeye.model.robot.robot_errors.corrected_model`), and what they are, said (the
    gravity gains, which no kinematic model holds, as a note)."""
    from handeye.model.robot import robot_errors

    values, said = {}, []
    for effect in doc.get("effects") or []:
        name = effect.get("name") if isinstance(effect, dict) else None
        if name not in robot_errors.NAMES:
            continue
        names, unit = robot_errors.param_names(model, name), {"joint_offsets": "deg", "link_lengths": "mm"}.get(name)
        full = np.zeros(len(names))
        for param, value in (effect.get("parameters") or {}).items():
            if param in names and isinstance(value, (int, float)) and np.isfinite(value):
                full[names.index(param)] = float(value)
        if name == "joint_compliance":
            said.append("gravity deflection not in the model (it depends on the pose): "
                        + ", ".join(f"{p} {v:+.5f} deg/m" for p, v in zip(names, full) if v))
            continue
        values[name] = full
        said.append(f"{name} " + ", ".join(f"{p} {v:+.5f} {unit}" for p, v in zip(names, full) if v))
    return values, said


def robot_text(calibration, format, force=False):
    """The robot's nominal model corrected by the calibrated ``joint_offsets`` and ``link_lengths``
    of a saved calibration, as the model TOML (``robot-toml``) or a URDF (``robot-urdf``);
    :mod:`handeye.model.robot.robots`. ``joint_compliance`` depends on the pose: said in a comment."""
    from handeye.model.robot import robot_errors, robots

    if not isinstance(calibration, (str, pathlib.Path)):
        raise RequestError(f"--format {format}: give a saved calibration file (calibrate --effects joint_offsets --out)")
    doc = saved.document(pathlib.Path(calibration))
    spec = doc.get("robot_model") if isinstance(doc, dict) else None
    if not isinstance(spec, str):
        raise RequestError(f"{calibration}: no robot_model (calibrate a dataset with j1..j6 and [robot] model)")
    if doc.get("converged") is not True and not force:
        raise RequestError(f"{calibration}: the calibration did not converge; handeye will not use it (--force)")
    nominal = robots.load(spec)
    values, said = _robot_values(doc, nominal)
    model = robot_errors.corrected_model(nominal, values)
    note = f"{model.name} corrected by the robot effects of {calibration} ({'; '.join(said) or 'none'})"
    if format == "robot-toml":
        return robots.to_toml(model, note)
    head, rest = robots.to_urdf(model, "".join(c if c.isalnum() else "_" for c in model.name).lower()).split("\n", 1)
    return f"{head}\n<!-- {note.replace('--', '- -')} -->\n{rest}"  # the XML declaration first


@dataclasses.dataclass(frozen=True)
class CloudResult(ResultProtocol):
    """The point cloud of ``handeye cloud``.

    Attributes
    ----------
    points : ndarray, shape (M, 3)
        mm, in ``frame``: the sphere mount's (the robot base, the flange, the positioner table),
        where the measured object is fixed.
    pose_index : ndarray, shape (M,)
        Index into ``ids`` of each point's pose.
    sd : ndarray, shape (M,), or None
        3-D 1-sd of each point from the calibration's covariance, mm (:mod:`handeye.model.geometry.cloud`).
    ids : tuple of str
    skipped : tuple of str
        Poses without a profile.
    out, format : str or None
    calibration : str
    frame : str
    """

    caption = 'handeye cloud'

    points: np.ndarray
    pose_index: np.ndarray
    sd: np.ndarray | None
    ids: tuple
    skipped: tuple
    out: str | None
    format: str
    calibration: str
    frame: str = "robot base"

    def to_dict(self):
        lo, hi = (self.points.min(axis=0), self.points.max(axis=0)) if len(self.points) else (None, None)
        return {"n_points": int(len(self.points)), "n_poses": len(self.ids), "skipped": list(self.skipped),
                "out": self.out, "format": self.format, "calibration": self.calibration, "frame": self.frame,
                "bounds_mm": None if lo is None else {"min": lo.tolist(), "max": hi.tolist()},
                "sd_mm": None if self.sd is None or not len(self.sd) else {
                    "median": float(np.median(self.sd)), "max": float(self.sd.max())}}

    def summary(self):
        d = self.to_dict()
        lines = [f"{d['n_points']:,} points from {d['n_poses']} poses ({self.frame}, mm; calibration {self.calibration})"]
        if d["skipped"]:
            lines.append(f"skipped {len(d['skipped'])} rows without a profile: {', '.join(d['skipped'][:10])}")
        if d["bounds_mm"]:
            lo, hi = d["bounds_mm"]["min"], d["bounds_mm"]["max"]
            lines.append("bounds: " + ", ".join(f"{a} {x:.2f}..{y:.2f}" for a, x, y in zip("xyz", lo, hi)))
        if d["sd_mm"]:
            lines.append(f"1 sd from the calibration: median {d['sd_mm']['median']:.3f} mm, max {d['sd_mm']['max']:.3f} mm")
        else:
            lines.append("1 sd: unknown (the calibration has no covariance)")
        if self.out:
            lines.append(f"written: {self.out} ({self.format})")
        return "\n".join(lines)


def ply_bytes(result):
    """Binary little-endian PLY: ``x y z`` double (mm, robot base), ``pose`` int, ``sd`` float."""
    with_sd = result.sd is not None
    fields = [("x", "<f8"), ("y", "<f8"), ("z", "<f8"), ("pose", "<i4")] + ([("sd", "<f4")] if with_sd else [])
    arr = np.empty(len(result.points), dtype=fields)
    arr["x"], arr["y"], arr["z"] = result.points.T
    arr["pose"] = result.pose_index
    if with_sd:
        arr["sd"] = result.sd
    header = ["ply", "format binary_little_endian 1.0", "comment handeye point cloud: robot base frame, mm",
              f"comment calibration {result.calibration}",
              "comment sd: 3-D 1-sd of each point from the calibration's covariance, mm" if with_sd
              else "comment no sd: the calibration has no covariance"]
    header += [f"comment pose {k} {ident}" for k, ident in enumerate(result.ids)]
    header += [f"element vertex {len(arr)}", "property double x", "property double y", "property double z",
               "property int pose"] + (["property float sd"] if with_sd else []) + ["end_header"]
    return ("\n".join(header) + "\n").encode("ascii", "replace"), arr


def _write_cloud(result, out, fmt):
    if fmt == "ply":
        head, arr = ply_bytes(result)

        def write(fh):
            fh.write(head)
            arr.tofile(fh)

        files.write_stream_atomically(out, write)
        return

    ids = np.asarray(result.ids, dtype=object)[result.pose_index]
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")  # an id with a comma or a quote is quoted, not split
    writer.writerow(["x", "y", "z", "pose", "id"] + (["sd"] if result.sd is not None else []))
    sd = result.sd if result.sd is not None else [None] * len(ids)
    for p, k, ident, s in zip(result.points, result.pose_index, ids, sd):
        row = [f"{p[0]:.6f}", f"{p[1]:.6f}", f"{p[2]:.6f}", int(k), ident]
        writer.writerow(row if s is None else row + [f"{s:.6f}"])
    files.write_text_atomically(out, buf.getvalue())


def _scan_inputs(path):
    from handeye.model.datasets import dataset

    folder = dataset.resolve(path)
    return [folder / "measurements.csv", folder / "setup.toml"]


@options.COMMANDS["cloud"].documented
def cloud(dataset, calibration=None, *, out=None, format=None, sensor_pose=None, convention=None, force=False):
    """Every profile point of every pose in the robot base (:mod:`handeye.model.geometry.cloud`).

    {parameters}

    Returns
    -------
    CloudResult
    """
    from handeye.model.datasets import scan as scans
    from handeye.model.geometry import cloud as clouds

    suffix = "" if out is None else pathlib.Path(out).suffix.lower().lstrip(".")
    if format is None:
        format = "csv" if suffix == "csv" else "ply"
    if format not in CLOUD_FORMATS:
        raise RequestError(f"--format {format!r}: choose one of {', '.join(CLOUD_FORMATS)}")
    if suffix in CLOUD_FORMATS and suffix != format:
        raise RequestError(f"--out {out}: a .{suffix} file, but --format {format}; name it .{format} or drop --format")
    if out is not None:
        inputs = _scan_inputs(dataset) + ([calibration] if isinstance(calibration, (str, pathlib.Path)) else [])
        files.check_output_path(out, "--out", inputs)
    data = scans.load(dataset)
    if out is not None:
        files.check_output_path(out, "--out", list(data.profile_files))
    cal = same_mount(_calibration(calibration, sensor_pose, convention, force, data.convention,
                                  own_axes=getattr(data, "own_axes", None)), data, "cloud")
    data = _at_calibrated_axes(data, cal)
    points, index = clouds.points_in_base(data.motions(), cal.sensor2flange, data.profiles)
    sd = None
    if cal.covariance is not None:
        sd = clouds.point_sd(np.concatenate(data.profiles, axis=0), cal.sensor2flange, cal.covariance)
    result = CloudResult(points, index, sd, data.ids, data.skipped, None if out is None else str(out), format,
                         cal.source, FRAME[data.mounts.sphere])
    if out is not None:
        _write_cloud(result, out, format)
    return result


@options.COMMANDS["validate"].documented
def validate(dataset, calibration=None, *, plot=None, exclude=0.0, sensor_pose=None, convention=None, force=False,
             mpe=None):
    """Measure the setup's sphere(s) through the calibration (:mod:`handeye.app.outputs.validate`).

    With profiles: the cloud, a geometric sphere fit, PF, PS, the centre's offset and (two
    spheres) SD, each with its 1-sd; without: each pose's centre against the setup's.
    ``exclude``: fraction of points with the largest deviations left out (VDI/VDE 2634-2
    allows up to 0.003). ``mpe``: maximum permissible errors ``"PF,PS[,SD]"`` (mm) for a
    verdict (``result.passed``; the CLI exits 1 when one is exceeded). Returns
    :class:`handeye.app.outputs.validate.ValidationResult`.

    {parameters}
    """
    from handeye.app.outputs import validate as validation
    from handeye.model.datasets import dataset as datasets
    from handeye.model.datasets import scan as scans
    from handeye.model.readers import tables

    limits = _mpe(mpe)
    try:
        exclude = float(exclude)
    except (TypeError, ValueError):
        raise RequestError(f"--exclude {exclude!r}: a fraction of points in [0, 0.05]") from None
    if not 0.0 <= exclude <= 0.05:
        raise RequestError(f"--exclude {exclude}: a fraction of points in [0, 0.05] (VDI/VDE 2634-2 allows 0.003)")
    if plot is not None:
        files.check_output_path(plot, "--plot", _scan_inputs(dataset), plot=True)
    folder = datasets.resolve(dataset)
    table = tables.read_table(folder / "measurements.csv")
    header = [h.strip() for h in table[0]] if table else []
    with_profiles = "profile" in header and any(
        len(r) == len(header) and r[header.index("profile")].strip() for r in table[1:])
    data = scans.load(folder) if with_profiles else datasets.load(folder)
    cal = same_mount(_calibration(calibration, sensor_pose, convention, force, data.convention,
                                  own_axes=getattr(data, "own_axes", None)), data, "validate")
    data = _at_calibrated_axes(data, cal)
    own = None if cal.dataset_sha256 is None else cal.dataset_sha256 == data.content_hash()
    if with_profiles:
        result = validation.validate_scan(data, cal, float(exclude), own)
    else:
        result = validation.validate_centres(data, cal, own)
    result = dataclasses.replace(result, frame={"world": "base", "flange": "flange", "positioner": "table"}[
        data.mounts.sphere])
    if limits is not None:
        result = dataclasses.replace(result, acceptance=validation.accept(result, limits))
    if plot is not None:
        from handeye.app.present import report

        report.validation_figure(result, plot)
    return result


def _mpe(mpe):
    """``"PF,PS[,SD]"`` (mm) or a sequence, checked; None stays None."""
    if mpe is None:
        return None
    values = list(numbers(mpe, "--mpe", "PF,PS[,SD] in mm, e.g. 0.05,0.03"))
    if len(values) not in (2, 3) or not all(np.isfinite(v) and v > 0 for v in values):
        raise RequestError(f"--mpe {mpe!r}: two or three positive numbers (PF, PS[, SD] in mm)")
    return values


def numbers(value, option, form):
    """Comma-separated numbers of an option (a sequence passes as it is); RequestError naming
    ``option`` and the expected ``form`` otherwise."""
    if not isinstance(value, str):
        return value
    try:
        return [float(v) for v in value.split(",")]
    except ValueError:
        raise RequestError(f"{option} {value!r}: {form}") from None
