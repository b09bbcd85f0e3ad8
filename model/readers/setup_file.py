"""``setup.toml`` of a dataset folder, read and checked (:mod:`handeye.model.datasets.dataset` has the format).

Every problem raises :class:`handeye.model.readers.tables.DatasetError` naming the file and the key.
"""
from __future__ import annotations

import dataclasses
import math
import tomllib

import numpy as np

from handeye.model.chain import conventions, own_frame
from handeye.model.chain.mounts import Mounts
from handeye.model.chain.pose import transform_from_pose
from handeye.model.readers import mount_setup
from handeye.model.readers.tables import (
    GUESS_LIMITS,
    LIMIT_POSITION_MM,
    MAX_LINE_BYTES,
    PARSE_ERRORS,
    DatasetError,
    check_angles,
    parse_problem,
    to_kuka,
)


def _vector(table, key, n, file, section):
    value = table.get(key)
    col = f"[{section}] {key}"
    if value is None:
        raise DatasetError(file, "missing", column=col)
    if not isinstance(value, list) or len(value) != n:
        raise DatasetError(file, f"needs a list of {n} numbers, got {value!r}", column=col)
    out = []
    for v in value:
        number = toml_number(v)
        if number is None:
            raise DatasetError(file, f"needs finite numbers, got {str(v)[:40]!r}", column=col)
        out.append(number)
    return np.array(out)


def _bounded(value, bounds, file, column):
    number = toml_number(value)
    if number is None or not bounds[0] <= number <= bounds[1]:
        raise DatasetError(file, f"needs a number of mm in [{bounds[0]:g}, {bounds[1]:g}], got {str(value)[:40]!r}",
                           column=column)
    return number


def toml_number(v):
    """A TOML value as a finite float, or None (a bool, text, NaN, or an integer too big for a float)."""
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return None
    try:
        number = float(v)
    except OverflowError:
        return None
    return number if math.isfinite(number) else None


_ALLOWED = {
    "robot": {"convention", "model"},
    "sensor": {"start_pose", "mount", "pose"},
    "sphere": {"diameter", "center", "base_pose", "center_in_plate", "mount"},
    "positioner": {"axes"},
    "sphere2": {"diameter", "center", "base_pose", "center_in_plate"},
    "profile": {"side", "own_axes", "poses"},
    "truth": {"sensor_pose", "sphere_center", "axes", "joint_offsets", "link_lengths", "joint_compliance"},
    "noise": {"centre_mm", "robot_mm"},
    "limits": {"position_mm", "sensor_mm"},
}

#: Plausible magnitudes (mm): a robot position (flange, sphere centre, start pose offset) and a
#: coordinate the sensor reports. Beyond them a value is a slip (a unit, a misprint, 1e300), named
#: with its row and column; ``[limits] position_mm`` and ``sensor_mm`` in setup.toml change them.
#: What [noise] and [limits] values may be (mm): beyond these no arithmetic on them is meaningful.
NOISE_RANGE_MM = (1e-6, 1e3)
LIMIT_RANGE_MM = (1.0, 1e7)
LIMIT_SENSOR_MM = 5_000.0  # loose: thesis-real misprints one zs as 2237 mm, which screening names

#: Default noise model: per-component sd of a sphere centre through the chain (robot
#: repeatability and the sensor's centre reconstruction together), and robot repeatability
#: per axis (mm). ``[noise] centre_mm`` and ``robot_mm`` in setup.toml override them.
NOISE_CENTRE_MM = 0.05
NOISE_ROBOT_MM = 0.025


def _document(file):
    """The parsed TOML of ``file``, its sections and keys checked against :data:`_ALLOWED`."""
    try:
        if file.exists() and not file.is_file():
            raise DatasetError(file, "is not a regular file (a device, a pipe or a folder?)")
        if file.exists() and file.stat().st_size > MAX_LINE_BYTES:
            raise DatasetError(file, "more than 1 MB: not a setup file")
        raw = file.read_bytes()  # a byte-order mark is accepted, as in the CSV files (Python's utf-8-sig decodes a
        text = raw.removeprefix(b"\xef\xbb\xbf").decode("utf-8")  # lone 0xEF to nothing: not a setup)
    except FileNotFoundError:
        raise DatasetError(file, "missing file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise DatasetError(file, f"cannot be read: {exc}") from None
    try:
        doc = tomllib.loads(text)
    except PARSE_ERRORS as exc:
        raise DatasetError(file, f"not valid TOML: {parse_problem(exc)}") from None
    for section, table in doc.items():
        if section not in _ALLOWED or not isinstance(table, dict):
            raise DatasetError(file, f"unknown section (known: {', '.join(sorted(_ALLOWED))})", column=f"[{section}]")
        for key in table:
            if key not in _ALLOWED[section]:
                raise DatasetError(file, f"unknown key (known: {', '.join(sorted(_ALLOWED[section]))})",
                                   column=f"[{section}] {key}")
    return doc


def _sensor_pose(doc, key, file, convention):
    """``[sensor] <key>`` (``start_pose`` or ``pose``) as KUKA, or None."""
    if key not in doc.get("sensor", {}):
        return None
    pose = _vector(doc["sensor"], key, len(conventions.columns(convention)), file, "sensor")
    if convention == "kuka":
        check_angles(pose, file, column_prefix=f"[sensor] {key} ", limits=GUESS_LIMITS)
        return pose
    return to_kuka(pose, convention, file, None, f"[sensor] {key}")


def _truth(doc, file, convention):
    """``[truth]``: ``sensor_pose`` (KUKA), optional ``sphere_center``, ``axes``, ``joint_offsets``
    (degrees), ``link_lengths`` and ``joint_compliance`` (tables parameter -> mm or degrees per
    metre); None without it."""
    if "truth" not in doc:
        return None
    pose = _vector(doc["truth"], "sensor_pose", len(conventions.columns(convention)), file, "truth")
    if convention != "kuka":  # in the dataset's convention, as every pose of the dataset
        pose = to_kuka(pose, convention, file, None, "[truth] sensor_pose")
    truth = {"sensor_pose": pose}
    if "sphere_center" in doc["truth"]:
        truth["sphere_center"] = _vector(doc["truth"], "sphere_center", 3, file, "truth")
    if "axes" in doc["truth"]:
        truth["axes"] = mount_setup.read_axes(doc["truth"], file, LIMIT_RANGE_MM[1], "truth")
    if "joint_offsets" in doc["truth"]:  # the robot's hidden joint offsets j1..j6, degrees
        truth["joint_offsets"] = _vector(doc["truth"], "joint_offsets", 6, file, "truth")
    for key in ("link_lengths", "joint_compliance"):  # { parameter = value }: mm, degrees per metre
        if key in doc["truth"]:
            table = doc["truth"][key]
            if not isinstance(table, dict) or not all(isinstance(v, (int, float)) and not isinstance(v, bool)
                                                      and np.isfinite(v) for v in table.values()):
                raise DatasetError(file, "needs { parameter = number, ... }", column=f"[truth] {key}")
            truth[key] = {str(k): float(v) for k, v in table.items()}
    return truth


def _noise_and_limits(doc, file):
    """``[noise]`` values given and ``[limits]`` (with defaults) as ``{..., "limits": {...}}``."""
    noise = {}
    for key in ("centre_mm", "robot_mm"):
        if doc.get("noise", {}).get(key) is not None:
            noise[key] = _bounded(doc["noise"][key], NOISE_RANGE_MM, file, f"[noise] {key}")
    limits = {"position_mm": LIMIT_POSITION_MM, "sensor_mm": LIMIT_SENSOR_MM}
    for key in limits:
        if doc.get("limits", {}).get(key) is not None:
            limits[key] = _bounded(doc["limits"][key], LIMIT_RANGE_MM, file, f"[limits] {key}")
    noise["limits"] = limits
    return noise


def _check_bounds(file, limits, vectors, diameters):
    """Positions within ``[limits] position_mm``, diameters a sensor can measure."""
    bound = limits["position_mm"]
    for what, vector in vectors:
        if vector is not None and np.any(np.abs(vector[:3]) > bound):
            raise DatasetError(file, f"a position beyond +-{bound:g} mm ({', '.join(f'{v:g}' for v in vector[:3])}): "
                                     "a unit or a misprint? ([limits] position_mm sets the bound)", column=what)
    for name, d in diameters:
        if d is not None and not d <= 2 * limits["sensor_mm"]:
            raise DatasetError(file, f"{d:g} mm is not a sphere a laser-line sensor measures", column=f"[{name}] diameter")


def read_setup(path, require_sphere=True):
    """Read and check ``setup.toml`` of a dataset folder (module docstring): a ``_SetupFile``.
    ``require_sphere=False`` (a scan) accepts a setup without ``[sphere]``."""
    file = path / "setup.toml"
    doc = _document(file)
    convention = doc.get("robot", {}).get("convention", "kuka")
    if not isinstance(convention, str) or convention not in conventions.CONVENTIONS:
        raise DatasetError(file, f"unknown convention {convention!r} (known: {', '.join(conventions.CONVENTIONS)})",
                           column="[robot] convention")
    start, known = _sensor_pose(doc, "start_pose", file, convention), _sensor_pose(doc, "pose", file, convention)
    diam, centre, plate_pose, centre_in_plate = _read_sphere(doc, "sphere", file, convention, require_sphere)
    sphere2 = _read_sphere(doc, "sphere2", file, convention, True) if "sphere2" in doc else None
    side = doc.get("profile", {}).get("side", -1)
    if side not in (1, -1) or isinstance(side, bool):
        raise DatasetError(file, f"must be 1 or -1, got {side!r}", column="[profile] side")
    own_axes = _own_axes(doc.get("profile", {}).get("own_axes"), file)
    start, known, poses_read = _poses_frame(doc, file, own_axes, start, known)
    noise = _noise_and_limits(doc, file)
    vectors = [("[sensor] start_pose", start), ("[sensor] pose", known), ("[sphere] center", centre),
               ("[sphere] base_pose", plate_pose)]
    if sphere2 is not None:
        vectors += [("[sphere2] center", sphere2[1]), ("[sphere2] base_pose", sphere2[2])]
    _check_bounds(file, noise["limits"], vectors, (("sphere", diam), ("sphere2", sphere2[0] if sphere2 else None)))
    mounts = mount_setup.read_mounts(doc, file, noise["limits"]["position_mm"])
    model = doc.get("robot", {}).get("model")
    if model is not None and (not isinstance(model, str) or not model.strip()):
        raise DatasetError(file, f"needs a built-in model's name or a model file, got {model!r}", column="[robot] model")
    return _SetupFile(start, diam, centre, plate_pose, centre_in_plate, int(side), _truth(doc, file, convention),
                      convention, noise, sphere2, mounts, known, model, own_axes, poses_read)


def _own_axes(value, file):
    """``[profile] own_axes``: the rotation R (3 x 3, rows) with ``p = R p_own`` from the sensor's own
    frame (its driver's points) to the frame of the profiles (laser plane y = 0); None when absent.
    Written by ``handeye dataset new`` when it turned the files' points; a proper rotation."""
    if value is None:
        return None
    try:
        rot = np.array(value, dtype=float)
    except (TypeError, ValueError):
        rot = None
    if rot is None or rot.shape != (3, 3) or not np.all(np.isfinite(rot)):
        raise DatasetError(file, "needs three rows of three numbers (a rotation)", column="[profile] own_axes")
    if not (np.allclose(rot @ rot.T, np.eye(3), atol=1e-6) and np.linalg.det(rot) > 0):
        raise DatasetError(file, "is not a proper rotation (R R^T = I, det R = +1)", column="[profile] own_axes")
    return rot


def _poses_frame(doc, file, own_axes, start, known):
    """``[sensor] start_pose`` and ``pose`` in handeye's frame, and how they were read (a note, or
    None). With ``own_axes`` they are of the sensor's own frame when ``[profile] poses = "own"``
    (what ``dataset new`` writes), turned here once; a setup with ``own_axes`` and no ``poses``
    (written before the key) gave them in handeye's turned frame, read as such and said."""
    poses = doc.get("profile", {}).get("poses")
    if poses is not None and (poses != "own" or own_axes is None):
        raise DatasetError(file, f"must be \"own\" (the sensor poses of the sensor's own frame, with own_axes), got "
                                 f"{str(poses)[:40]!r}", column="[profile] poses")
    if own_axes is None or (start is None and known is None):
        return start, known, None
    if poses == "own":
        return own_frame.kuka_to_internal(start, own_axes), own_frame.kuka_to_internal(known, own_axes), None
    return start, known, (f"{file}: [profile] own_axes without poses = \"own\" (a setup written before the key): its "
                          "[sensor] poses read in handeye's turned frame, as it was written")


@dataclasses.dataclass(frozen=True)
class _SetupFile:
    """What setup.toml holds, checked; poses KUKA, mm (see the module docstring)."""

    start: np.ndarray | None
    diameter: float | None
    centre: np.ndarray | None
    plate_pose: np.ndarray | None
    centre_in_plate: np.ndarray | None
    side: int
    truth: dict | None
    convention: str
    noise: dict
    sphere2: tuple | None  # (diameter, centre, plate_pose, centre_in_plate) of a second sphere
    mounts: Mounts = Mounts()
    sensor_pose: np.ndarray | None = None  # [sensor] pose: the sensor pose known, KUKA
    robot_model: str | None = None  # [robot] model: a built-in name or a file (relative to the folder)
    own_axes: np.ndarray | None = None  # [profile] own_axes: p = R p_own (the sensor's own frame)
    poses_read: str | None = None  # how [sensor] poses were read, when not as the key says (an older setup)


def _read_sphere(doc, section, file, convention, required):
    """``(diameter, centre, plate_pose, centre_in_plate)`` of a ``[sphere]``-like section; the
    diameter is None when the section is absent and not ``required``, or ``[sphere]`` gives none (a
    dataset of centres or clouds: :func:`handeye.model.datasets.dataset.load` asks for it where a row
    has a profile)."""
    sphere = doc.get(section, {})
    if not sphere and not required:
        return None, None, None, None
    diam = toml_number(sphere.get("diameter"))
    if section == "sphere" and "diameter" not in sphere:
        diam = None  # a dataset of centres or clouds needs none (the load asks for it where a row has a profile)
    elif diam is None or diam <= 0:
        raise DatasetError(file, f"needs a positive number (mm), got {str(sphere.get('diameter'))[:40]!r}",
                           column=f"[{section}] diameter")
    plate_pose = centre_in_plate = None
    if "center" in sphere:
        if "base_pose" in sphere or "center_in_plate" in sphere:
            raise DatasetError(file, "give either center or base_pose with center_in_plate, not both", column=f"[{section}]")
        centre = _vector(sphere, "center", 3, file, section)
    elif "base_pose" not in sphere and "center_in_plate" not in sphere:
        centre = None  # unknown: estimated with the sensor pose (--unknowns sensor+sphere)
    else:
        if "base_pose" not in sphere:
            raise DatasetError(file, "needs center, or base_pose with center_in_plate", column=f"[{section}]")
        plate_pose = _vector(sphere, "base_pose", len(conventions.columns(convention)), file, section)
        if convention == "kuka":
            check_angles(plate_pose, file, column_prefix=f"[{section}] base_pose ")
        else:  # in the dataset's convention, as every pose of the dataset
            plate_pose = to_kuka(plate_pose, convention, file, None, f"[{section}] base_pose")
        centre_in_plate = _vector(sphere, "center_in_plate", 3, file, section)
        centre = (transform_from_pose(plate_pose) @ np.append(centre_in_plate, 1.0))[:3]
    return None if diam is None else float(diam), centre, plate_pose, centre_in_plate
