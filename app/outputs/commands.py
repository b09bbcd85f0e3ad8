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

import numpy as np

from handeye.app.common import files, options
from handeye.app.common.choices import CLOUD_FORMATS, ROBOT_FORMATS  # noqa: F401 - the names, defined without numpy
from handeye.app.outputs import formats as exports
from handeye.app.outputs import verdict as verdicts
from handeye.app.outputs.request import CloudRequest, ExportRequest, ValidateRequest
from handeye.app.present.protocol import ResultProtocol
from handeye.app.present.result_parts import AsDict
from handeye.model.chain.mounts import FRAME


@dataclasses.dataclass(frozen=True)
class ExportResult(AsDict, ResultProtocol):
    """The text of ``handeye export`` and where it was written (None: not written)."""

    caption = 'handeye export'

    format: str
    text: str
    out: str | None


@options.COMMANDS["export"].documented
def export(calibration=None, *, format="json", parent=None, child="sensor", tool=None, register=99, out=None,
           sensor_pose=None, convention=None, force=False, base=None, sensor_mount=None, dataset=None):
    """The calibration in a robot's, ROS 2's or URDF's terms (:mod:`handeye.app.outputs.formats`).

    A sensor on the flange is written as a tool (number ``tool``, default 1), a sensor fixed in
    the cell (the calibration's ``sensor_mount`` "world") as a base / user frame (number
    ``base``, default 1); ``parent`` defaults to ``flange`` or ``base_link`` accordingly.
    ``sensor_mount`` ("flange" or "world"; default flange) is where a ``sensor_pose`` is given.
    Every format carries the calibration's verdict and its failed checks as comments (JSON: the
    key ``verdict``), recomputed from its dataset where one is at hand (``dataset``, else the
    file's ``dataset_path``; :mod:`handeye.app.outputs.verdict`); a calibration that did not
    converge is written only with ``force``, and its first comment line says so.

    Returns :class:`ExportResult`; with ``out`` the text is also written there (atomically).

    {parameters}
    """
    request = ExportRequest.from_options(options.COMMANDS["export"].given(locals()))
    if format in ROBOT_FORMATS:
        text = robot_text(*request.held, format, request.comments)
    else:
        text = exports.text(request.held, format, request.names, request.comments)
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


def robot_text(calibration, doc, format, comments=()):
    """The robot's nominal model corrected by the calibrated ``joint_offsets`` and ``link_lengths``
    of a saved calibration (the file ``calibration``, its JSON object ``doc``), as the model TOML
    (``robot-toml``) or a URDF (``robot-urdf``); :mod:`handeye.model.robot.robots`.
    ``joint_compliance`` depends on the pose: said in a comment; ``comments``: the verdict's lines
    (:func:`handeye.app.outputs.verdict.comment_lines`), the first one first."""
    from handeye.model.robot import robot_errors, robots

    nominal = robots.load(doc["robot_model"])
    values, said = _robot_values(doc, nominal)
    model = robot_errors.corrected_model(nominal, values)
    note = f"{model.name} corrected by the robot effects of {calibration} ({'; '.join(said) or 'none'})"
    if format == "robot-toml":
        return "".join(f"# {exports.one_line(c)}\n" for c in comments) + robots.to_toml(model, note)
    head, rest = robots.to_urdf(model, "".join(c if c.isalnum() else "_" for c in model.name).lower()).split("\n", 1)
    said = "".join(f"<!-- {exports.one_line(c).replace('--', '- -')} -->\n" for c in comments)
    return f"{head}\n{said}<!-- {note.replace('--', '- -')} -->\n{rest}"  # the XML declaration first


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
    notes: tuple = ()
    status: str | None = None

    def to_dict(self):
        lo, hi = (self.points.min(axis=0), self.points.max(axis=0)) if len(self.points) else (None, None)
        return {"n_points": int(len(self.points)), "n_poses": len(self.ids), "skipped": list(self.skipped),
                "out": self.out, "format": self.format, "calibration": self.calibration, "frame": self.frame,
                "verdict": self.status, "notes": list(self.notes),
                "bounds_mm": None if lo is None else {"min": lo.tolist(), "max": hi.tolist()},
                "sd_mm": None if self.sd is None or not len(self.sd) else {
                    "median": float(np.median(self.sd)), "max": float(self.sd.max())}}

    def summary(self):
        d = self.to_dict()
        lines = [f"{d['n_points']:,} points from {d['n_poses']} poses ({self.frame}, mm; calibration {self.calibration})"]
        lines += [f"calibration: {self.status}"] if self.status else []
        lines += [f"note: {n}" for n in self.notes]
        if d["skipped"]:
            lines.append(f"skipped {len(d['skipped'])} rows without a profile: {', '.join(d['skipped'][:10])}")
        if d["bounds_mm"]:
            lo, hi = d["bounds_mm"]["min"], d["bounds_mm"]["max"]
            lines.append("bounds: " + ", ".join(f"{a} {x:.2f}..{y:.2f}" for a, x, y in zip("xyz", lo, hi)))
        lines.append(f"1 sd from the calibration: median {d['sd_mm']['median']:.3f} mm, max {d['sd_mm']['max']:.3f} mm"
                     if d["sd_mm"] else "1 sd: unknown (the calibration has no covariance)")
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


def _bent(data, cal):
    """``(data, notes)``: a scan's profiles corrected by the depth bend its calibration corrected its own by (the
    sensor's linearity: :attr:`handeye.app.outputs.saved.Calibration.bend`), and a note saying so; unchanged
    without one."""
    bend = getattr(cal, "bend", None)
    if bend is None or not data.profiles:
        return data, []
    lo, hi = bend.depths
    depths = np.concatenate([p[:, 1] for p in data.profiles])
    outside = int(np.count_nonzero((depths < lo) | (depths > hi)))
    note = (f"profiles corrected by the calibration's depth bend ({bend.bend_mm:.3g} mm over {lo:.0f}-{hi:.0f} mm, "
            "the sensor's linearity error it measured)" + (f"; {outside:,} points lie outside that range, corrected "
                                                           "as at its nearer end" if outside else ""))
    return dataclasses.replace(data, profiles=[bend.corrected(p) for p in data.profiles]), [note]


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

    request = CloudRequest.from_options(options.COMMANDS["cloud"].given(locals()), scans.load(dataset))
    checked = verdicts.check(calibration, request.calibration, folder=dataset, folder_hash=request.data.content_hash())
    cal, (data, bent) = checked.calibration, _bent(request.data, checked.calibration)
    points, index = clouds.points_in_base(data.motions(), cal.sensor2flange, data.profiles)
    sd = None if cal.covariance is None else clouds.point_sd(np.concatenate(data.profiles, axis=0), cal.sensor2flange,
                                                              cal.covariance)
    result = CloudResult(points, index, sd, data.ids, data.skipped, None if out is None else str(out), request.format,
                         cal.source, FRAME[data.mounts.sphere], [*checked.notes, *bent], checked.status)
    if out is not None:
        _write_cloud(result, out, request.format)
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

    given = options.COMMANDS["validate"].given(locals())
    folder = datasets.resolve(dataset)
    table = tables.read_table(folder / "measurements.csv")
    header = [h.strip() for h in table[0]] if table else []
    with_profiles = "profile" in header and any(
        len(r) == len(header) and r[header.index("profile")].strip() for r in table[1:])
    request = ValidateRequest.from_options(given, scans.load(folder) if with_profiles else datasets.load(folder))
    sha = request.data.content_hash()
    checked = verdicts.check(calibration, request.calibration, folder=folder, folder_hash=sha)
    cal, data, bent = checked.calibration, request.data, []
    own = None if cal.dataset_sha256 is None else cal.dataset_sha256 == sha
    if with_profiles:
        data, bent = _bent(data, cal)
    result = (validation.validate_scan(data, cal, request.exclude, own) if with_profiles
              else validation.validate_centres(data, cal, own))
    result = dataclasses.replace(result, frame={"world": "base", "flange": "flange", "positioner": "table"}[
        data.mounts.sphere], notes=[*checked.notes, *bent, *result.notes], status=checked.status)
    if request.limits is not None:
        result = dataclasses.replace(result, acceptance=validation.accept(result, request.limits))
    if plot is not None:
        from handeye.app.present import report

        report.validation_figure(result, plot)
    return result
