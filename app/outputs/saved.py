"""A saved calibration read back: the sensor pose in its mount's frame and its covariance.

``handeye calibrate --out RESULT.json`` writes the whole :class:`handeye.CalibrationResult`;
what the uses of a calibration need from it (``handeye export``, ``cloud``, ``validate``) is
:class:`Calibration`: the 4x4 ``sensor_matrix`` (mm) and the 6x6 covariance of its local chart
``t + dt, R exp([dw]x)`` (``dt`` mm in the mount's frame, ``dw`` rad about the sensor's own axes).
A pose typed in by hand (``--sensor-pose``, e.g. a TCP already in the controller) is a
calibration without a covariance.

A calibration of a dataset whose profiles ``dataset new`` turned from the sensor's own frame
(``own_axes``) is written in that own frame with ``sensor_frame = "own"``; :class:`Calibration`
holds it in handeye's frame (what the chain uses) and writes it back in the own one. A file
with ``own_axes`` and ``sensor_frame`` "profiles" or none (written before) is of handeye's frame.

The file's ``sensor_mount`` says where the sensor is: ``"flange"`` (on the robot flange; the
matrix is sensor2flange; a file without the key is one) or ``"world"`` (fixed in the cell; the
matrix is sensor2base, the sensor frame in the robot base frame).

Every problem with the file raises :class:`CalibrationFileError` (an ``InputError``: exit 2),
naming the file and the key.
"""
from __future__ import annotations

import dataclasses
import json
import pathlib

import numpy as np

from handeye.app.common.arguments import typed_pose
from handeye.app.common.errors import RequestError
from handeye.model.chain import own_frame
from handeye.model.chain.names import SENSOR_MOUNTS
from handeye.model.common.rotation import pose_sd
from handeye.model.geometry import profile_bend
from handeye.model.readers.tables import PARSE_ERRORS, parse_problem

#: Largest |R^T R - I| entry accepted in a saved rotation (it was written with 17 digits).
ORTHONORMAL_TOLERANCE = 1e-6
#: A saved result larger than this is not a calibration result.
MAX_RESULT_BYTES = 256 * 1024**2
#: The frame the sensor matrix is given in, by mount (on the robot flange, or fixed in the cell:
#: the matrix in the robot base; the mounts' names: :data:`handeye.model.chain.names.SENSOR_MOUNTS`).
MOUNT_FRAME = {"flange": "flange", "world": "base"}


class CalibrationFileError(RequestError):
    """A saved calibration that cannot be used: missing, not JSON, or without a valid pose."""

    def __init__(self, file, problem, key=None):
        self.file, self.key, self.problem = str(file), key, problem
        super().__init__(f"{file}{f', key {key!r}' if key else ''}: {problem}")


@dataclasses.dataclass(frozen=True)
class Calibration:
    """The sensor pose in its mount's frame, with its uncertainty.

    Attributes
    ----------
    sensor2flange : ndarray, shape (4, 4)
        Sensor frame in the mount's frame, mm: the flange frame (``sensor_mount`` "flange"), or
        the robot base frame ("world": sensor2base). :attr:`sensor_matrix` is the same array.
    covariance : ndarray, shape (6, 6), or None
        Of the local chart ``(tx, ty, tz, wx, wy, wz)``: mm and rad, translation in the mount's
        frame, rotation about the sensor's axes; None when unknown.
    source : str
        Where it came from (a file, or ``--sensor-pose``).
    dataset, dataset_sha256 : str or None
        The calibration's dataset, when the file says.
    converged : bool
    sensor_mount : {'flange', 'world'}
        On the robot flange, or fixed in the cell.
    positioner_axes : tuple of handeye.model.chain.mounts.Axis
        The positioner's axes the calibration estimated (robot base, all angles zero); empty when
        it held them as set up (or has no positioner).
    bend : handeye.model.geometry.profile_bend.Bend or None
        The sensor's depth bend the calibration corrected its profiles by (``cleaning.bend``), which other
        scans of the same sensor are corrected by too (``cloud``, ``validate``); None where none was applied.
    """

    sensor2flange: np.ndarray
    covariance: np.ndarray | None
    source: str
    dataset: str | None = None
    dataset_sha256: str | None = None
    converged: bool = True
    sensor_mount: str = "flange"
    positioner_axes: tuple = ()
    own_axes: np.ndarray | None = None
    bend: object = None

    def user_frame(self):
        """The calibration of the frame the user's files are in, for writing it out: the sensor's
        own frame when the dataset's profiles were turned into handeye's (``own_axes`` R,
        ``p = R p_own``: the matrix ``S [R 0; 0 1]``, the covariance's rotation about the own axes;
        :mod:`handeye.model.chain.own_frame`), without ``own_axes`` then; itself without a turn."""
        if self.own_axes is None:
            return self
        return dataclasses.replace(self, sensor2flange=own_frame.to_own(self.sensor2flange, self.own_axes),
                                   covariance=own_frame.covariance_to_own(self.covariance, self.own_axes), own_axes=None)

    def from_user_frame(self, own_axes):
        """A calibration typed in the user's frame (``--sensor-pose``, a 4x4) of a dataset whose
        profiles were turned (``own_axes``; None: none), in handeye's frame, the inverse of
        :meth:`user_frame`."""
        if own_axes is None:
            return self
        return dataclasses.replace(self, sensor2flange=own_frame.to_internal(self.sensor2flange, own_axes),
                                   covariance=own_frame.covariance_to_own(self.covariance, own_axes, forward=False),
                                   own_axes=np.asarray(own_axes, float))

    def for_dataset(self, own_axes):
        """This calibration (a file read, in handeye's frame) for a dataset whose profiles were
        turned by ``own_axes`` (None: not turned): a file that names no sensor frame is of the user's
        own, as a 4x4 typed in is; a file of another sensor's own frame is refused."""
        if own_axes is None:
            return self
        if self.own_axes is None:
            return self.from_user_frame(own_axes)
        if not np.allclose(self.own_axes, own_axes, atol=1e-9):
            raise CalibrationFileError(self.source, "is of a sensor whose own frame is not this dataset's (its "
                                                    "own_axes differ from [profile] own_axes)", "own_axes")
        return self

    @property
    def sensor_matrix(self):
        """The 4x4 sensor frame in :attr:`frame` (mm): sensor2flange or sensor2base."""
        return self.sensor2flange

    @property
    def frame(self):
        """The frame the sensor matrix is in: ``"flange"`` or ``"base"``."""
        return MOUNT_FRAME[self.sensor_mount]

    def sd(self):
        """1-sd ``(translation (3,) mm, rotation (3,) deg)``, or None without a covariance."""
        return pose_sd(self.covariance)

    def to_dict(self):
        """The calibration as JSON-ready numbers of the user's frame (:meth:`user_frame`; ``own_axes`` and
        ``sensor_frame`` "own" say it is the sensor's own), a world mount says so."""
        user = self.user_frame()
        sd = user.sd()
        mount = {} if self.sensor_mount == "flange" else {"sensor_mount": self.sensor_mount}
        own = {} if self.own_axes is None else {"own_axes": np.asarray(self.own_axes).tolist(), "sensor_frame": "own"}
        return {**mount, **own, "source": self.source, "dataset": self.dataset, "dataset_sha256": self.dataset_sha256,
                "sensor_matrix": user.sensor2flange.tolist(),
                "sd_translation_mm": None if sd is None else sd[0].tolist(),
                "sd_rotation_deg": None if sd is None else sd[1].tolist(),
                "covariance": None if user.covariance is None else user.covariance.tolist()}


def _matrix(value, shape, file, key):
    try:
        m = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise CalibrationFileError(file, f"needs a {shape[0]}x{shape[1]} array of numbers", key) from None
    if m.shape != shape or not np.all(np.isfinite(m)):
        raise CalibrationFileError(file, f"needs a {shape[0]}x{shape[1]} array of finite numbers", key)
    return m


def check_transform(m, file, key="sensor_matrix"):
    """A 4x4 rigid transform, or :class:`CalibrationFileError`."""
    rot = m[:3, :3]
    err = float(np.max(np.abs(rot.T @ rot - np.eye(3))))
    if err > ORTHONORMAL_TOLERANCE or np.linalg.det(rot) < 0 or np.any(m[3] != (0, 0, 0, 1)):
        raise CalibrationFileError(file, f"not a rigid transform (|R^T R - I| = {err:.2g}, det R = "
                                         f"{np.linalg.det(rot):.6g}, last row {m[3].tolist()})", key)
    return m


def _covariance(doc, file):
    cov = doc.get("covariance")
    if isinstance(cov, dict) and cov.get("matrix") is not None:
        names = cov.get("names")
        if isinstance(names, list) and "tx" not in names:
            return None  # the sensor was held (--unknowns without sensor): no covariance of it here
        m = _named_matrix(names, cov["matrix"], file, "covariance")
    elif isinstance(doc.get("std"), dict) and isinstance(doc.get("correlation"), dict):
        std = doc["std"]  # an older result: rebuild it from sd and (rounded) correlations
        trans = _matrix([std.get("sensor_translation_mm")], (1, 3), file, "std")[0]
        rot = _matrix([std.get("sensor_rotation_deg")], (1, 3), file, "std")[0]
        sd = np.r_[trans, np.radians(rot)]
        corr = _named_matrix(doc["correlation"].get("names"), doc["correlation"].get("matrix"), file, "correlation")
        m = corr * np.outer(sd, sd)
    else:
        return None
    m = 0.5 * (m + m.T)
    if np.min(np.linalg.eigvalsh(m)) < -1e-9 * max(float(np.max(np.abs(m))), 1e-300):
        raise CalibrationFileError(file, "not a covariance (a negative eigenvalue)", "covariance")
    return m


def _named_matrix(names, matrix, file, key):
    """The sensor's 6x6 block of a matrix over ``names`` (which must begin with the sensor's six), or an error."""
    if not isinstance(names, list) or names[:6] != ["tx", "ty", "tz", "wx", "wy", "wz"]:
        raise CalibrationFileError(file, "names must begin tx, ty, tz, wx, wy, wz", key)
    return _matrix(matrix, (len(names), len(names)), file, key)[:6, :6]


def document(file):
    """The JSON object of a saved calibration file, or :class:`CalibrationFileError`."""
    try:
        if file.is_dir():
            raise CalibrationFileError(file, "is a folder; give the JSON file `handeye calibrate --out` wrote")
        if file.exists() and not file.is_file():  # a FIFO would block the read, /dev/zero never end it
            raise CalibrationFileError(file, "is not a regular file (a pipe or a device)")
        if file.stat().st_size > MAX_RESULT_BYTES:
            raise CalibrationFileError(file, "too large to be a calibration result")
        text = file.read_text(encoding="utf-8-sig")
    except FileNotFoundError:
        raise CalibrationFileError(file, "missing file (write one with handeye calibrate DATASET --out FILE)") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise CalibrationFileError(file, f"cannot be read: {getattr(exc, 'strerror', None) or exc}") from None
    try:
        return json.loads(text, parse_constant=lambda c: None)
    except PARSE_ERRORS as exc:
        raise CalibrationFileError(file, f"not JSON a calibration result can be ({parse_problem(exc)})") from None


def _mount(doc, file):
    """The file's ``sensor_mount``: "flange" when absent (files before the key), else checked."""
    mount = doc.get("sensor_mount", "flange")
    if mount not in SENSOR_MOUNTS:
        raise CalibrationFileError(file, f"needs \"flange\" or \"world\", got {_one_line(mount)!r}", "sensor_mount")
    return mount


def _one_line(value):
    """A value of the file shown in a one-line message: no control characters, at most 40."""
    return "".join(c if c.isprintable() else " " for c in str(value))[:40]


def load(path):
    """The :class:`Calibration` of a ``calibrate --out`` file (or of ``--json`` output saved)."""
    file = pathlib.Path(path)
    return from_document(document(file), file)


def from_document(doc, file):
    """The :class:`Calibration` of a calibration's JSON object ``doc`` (what :func:`load` reads from
    ``file``; ``file`` names it in messages)."""
    if not isinstance(doc, dict) or "sensor_matrix" not in doc:
        raise CalibrationFileError(file, "not a calibration result: no sensor_matrix (write one with handeye "
                                         "calibrate DATASET --out FILE)")
    if doc["sensor_matrix"] is None:
        raise CalibrationFileError(file, "the calibration has no result (it failed); see its message: "
                                         f"{str(doc.get('message'))[:200]}", "sensor_matrix")
    m = check_transform(_matrix(doc["sensor_matrix"], (4, 4), file, "sensor_matrix"), file)
    converged = doc.get("converged", True)  # a hand-made file with only the matrix: a calibration taken as given
    if not isinstance(converged, bool):
        raise CalibrationFileError(file, f"needs true or false, got {str(converged)[:40]!r}", "converged")
    sha = doc.get("dataset_sha256")
    own = _own_axes(doc, file)
    frame = doc.get("sensor_frame", "profiles")
    if frame not in ("own", "profiles") or (frame == "own" and own is None):
        raise CalibrationFileError(file, f"must be \"own\" (with own_axes) or \"profiles\", got {str(frame)[:40]!r}",
                                   "sensor_frame")
    source = str(file) + (" (handeye's turned frame, as files before sensor_frame \"own\" were written)"
                          if own is not None and frame == "profiles" else "")
    cal = Calibration(m, _covariance(doc, file), source, doc.get("dataset"), sha if isinstance(sha, str) else None,
                      converged, _mount(doc, file), _positioner(doc, file), bend=_bend(doc, file))
    return cal.from_user_frame(own) if frame == "own" else dataclasses.replace(cal, own_axes=own)


def _bend(doc, file):
    """The depth bend the file's calibration applied (``cleaning.bend``), or None."""
    cleaning = doc.get("cleaning")
    try:
        return profile_bend.from_saved(cleaning.get("bend") if isinstance(cleaning, dict) else None)
    except ValueError as exc:
        raise CalibrationFileError(file, str(exc), "cleaning.bend") from None


def _own_axes(doc, file):
    """``own_axes`` of the file (the turn from the sensor's own frame to its profiles'), or None."""
    if doc.get("own_axes") is None:
        return None
    rot = _matrix(doc["own_axes"], (3, 3), file, "own_axes")
    if not (np.allclose(rot @ rot.T, np.eye(3), atol=1e-6) and np.linalg.det(rot) > 0):
        raise CalibrationFileError(file, "is not a proper rotation", "own_axes")
    return rot


def _positioner(doc, file):
    """The calibrated positioner axes of the file (``positioner`` entries with ``calibrated``), or ()."""
    from handeye.model.chain.mounts import Axis
    from handeye.model.readers.tables import LIMIT_POSITION_MM

    entries = doc.get("positioner")
    if entries is None:
        return ()
    if not isinstance(entries, list) or not all(isinstance(e, dict) for e in entries):
        raise CalibrationFileError(file, "needs a list of axes {name, point, direction}", "positioner")
    flags = [e.get("calibrated") for e in entries]
    if not all(isinstance(f, bool) for f in flags):
        raise CalibrationFileError(file, "each axis needs calibrated = true or false", "positioner")
    if not any(flags):
        return ()  # held as set up: the dataset's own axes are the calibration's
    if not all(flags):
        raise CalibrationFileError(file, "some axes calibrated, some not: handeye writes all or none", "positioner")
    axes = []
    for k, e in enumerate(entries):
        point = _matrix([e.get("point")], (1, 3), file, f"positioner[{k}].point")[0]
        direction = _matrix([e.get("direction")], (1, 3), file, f"positioner[{k}].direction")[0]
        if not isinstance(e.get("name"), str) or not 0.5 < np.linalg.norm(direction) < 2.0:
            raise CalibrationFileError(file, "needs a name and a unit direction", f"positioner[{k}]")
        if np.any(np.abs(point) > LIMIT_POSITION_MM):
            raise CalibrationFileError(file, f"a point beyond +-{LIMIT_POSITION_MM:g} mm", f"positioner[{k}].point")
        axes.append(Axis(e["name"], point, direction / np.linalg.norm(direction)))
    return tuple(axes)


def from_matrix(matrix, source="a 4x4 matrix", sensor_mount="flange"):
    """A :class:`Calibration` without covariance from a 4x4 sensor2flange (or, ``sensor_mount``
    "world", sensor2base), mm, checked rigid."""
    return Calibration(check_transform(_matrix(matrix, (4, 4), source, None), source), None, source,
                       sensor_mount=sensor_mount)


def from_pose(pose, convention="kuka", sensor_mount="flange"):
    """A :class:`Calibration` without covariance from a pose typed in (``x, y, z`` mm and the
    convention's orientation columns; checked by :func:`handeye.app.common.arguments.typed_pose`),
    in the flange frame or (``sensor_mount`` "world") the robot base frame."""
    values, m = typed_pose(pose, convention, MOUNT_FRAME[sensor_mount])
    where = "" if sensor_mount == "flange" else ", in the robot base"
    return Calibration(m, None, f"--sensor-pose {','.join(f'{v:g}' for v in values)} ({convention}{where})",
                       sensor_mount=sensor_mount)
