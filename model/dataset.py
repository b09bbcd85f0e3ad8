"""Datasets: a folder with ``measurements.csv`` and ``setup.toml``.

``measurements.csv``
    Header ``id,x,y,z,a,b,c,xs,ys,zs`` (any order) and an optional ``profile`` column; with
    ``[robot] convention`` other than ``kuka`` the pose columns are those of that convention
    (``x,y,z,q1,q2,q3,q4`` for abb, ``x,y,z,rx,ry,rz`` for ur, ``x,y,z,w,p,r`` for fanuc;
    :mod:`handeye.model.conventions`), and so is ``start_pose``.
    ``id`` is unique text; ``x..c`` the flange pose in the robot base (KUKA: mm, degrees,
    ``A, C`` in [-180, 180], ``B`` in [-90, 90], the controller's ranges; a start pose may
    hold any angle in [-360, 360]); ``xs, ys, zs`` the sphere centre in the sensor
    frame (mm). ``profile``, when present, is the path (relative to the folder) of a CSV with
    header ``x,z``: laser-line points in the sensor's y = 0 plane, mm; then ``xs, ys, zs`` may
    be empty and the centre is reconstructed as in the seed (C15, C16, 6-26, 6-27), but with
    the Hyper circle fit instead of the seed's biased Kasa fit (:mod:`handeye.model.circle`): centre
    ``(x_c, z_c)`` and radius r, then ``y = side * sqrt(R^2 - r^2)`` with R the sphere's radius.
``setup.toml``
    ``[sensor] start_pose`` (p2: six numbers; optional -- without it the calibration starts from
    the closed-form estimate); ``[sphere] diameter`` (mm) and either
    ``center`` (three numbers, robot base) or ``base_pose`` (p3) with ``center_in_plate``
    (x_p'), or neither when the centre is to be estimated (``--unknowns sensor+sphere``);
    ``[profile] side`` (+1 or -1, default -1 as in the seed); optional ``[noise] centre_mm``
    (per-component sd of a sphere centre through the chain, default 0.05) and ``robot_mm``
    (robot repeatability per axis, default 0.025), the noise model a calibration tests its
    fit against; optional ``[truth]`` with
    ``sensor_pose`` (in the dataset's convention) and optionally ``sphere_center`` -- for
    simulated data, never read by a calibration.

Every problem found raises :class:`DatasetError`, whose text names file, row and column.
"""
from __future__ import annotations

import dataclasses
import functools
import math
import pathlib
import tomllib

import numpy as np

from handeye.model import conventions, mount_setup
from handeye.model.mounts import Mounts, motions
from handeye.model.pose import transform_from_pose
from handeye.model.tables import (  # noqa: F401  (read_pose_list, pose_list_text: public here too)
    GUESS_LIMITS,
    LIMIT_POSITION_MM,
    MAX_LINE_BYTES,
    DatasetError,
    check_angles,
    number,
    pose_list_text,
    read_plain_rows,
    read_points,
    read_pose,
    read_pose_list,
    read_table,
    row_id,
    to_kuka,
)

REQUIRED_COLUMNS = ("id", "x", "y", "z", "a", "b", "c", "xs", "ys", "zs")
OPTIONAL_COLUMNS = ("profile",)
DATA_DIR = pathlib.Path(__file__).parent / "data"


class FlangePoses:
    """What a dataset and a scan share: ``ids`` and ``flange_poses`` (N, 6, KUKA)."""

    def flange2base(self):
        """Flange poses as homogeneous transforms, shape (N, 4, 4), mm; computed once per
        dataset and read-only (copy it to change it)."""
        return self._flange2base

    @functools.cached_property
    def _flange2base(self):
        out = transform_from_pose(self.flange_poses)
        out.setflags(write=False)
        return out

    def motions(self):
        """The carrier motions ``M_i`` of the chain ``M_i X xs_i = c`` (:mod:`handeye.model.mounts`),
        shape (N, 4, 4), mm: the flange poses for the seed's cell (the same array), their inverses
        for a sensor fixed in the cell, the flange in the table frame for a sphere on a positioner
        (nominal axes). Read-only; every calibration stage works on these."""
        return self._motions

    @functools.cached_property
    def _motions(self):
        mounts = getattr(self, "mounts", None)
        if mounts is None or mounts.default:
            return self.flange2base()
        out = motions(self.flange2base(), mounts, getattr(self, "axis_angles", None))
        out.setflags(write=False)
        return out

    def __len__(self):
        return len(self.ids)


@dataclasses.dataclass(frozen=True)
class Dataset(FlangePoses):
    """A dataset read and checked by :func:`load`.

    Attributes
    ----------
    name : str
    path : pathlib.Path
    ids : tuple of str
    rows : tuple of int
        Line of each measurement in ``measurements.csv``.
    flange_poses : ndarray, shape (N, 6)
        Flange in robot base, KUKA (mm, deg).
    centre_in_sensor : ndarray, shape (N, 3)
        Sphere centre in the sensor frame, mm.
    start_pose : ndarray, shape (6,), or None
        Start value of the sensor pose on the flange (p2), KUKA; None when the setup has none.
    sphere_diameter : float
        mm.
    sphere_centre : ndarray, shape (3,), or None
        Sphere centre in the robot base, mm (from ``center`` or ``T(p3) x_p'``); None when the
        setup gives neither (then only ``unknowns='sensor+sphere'`` can calibrate: the closed
        form estimates the centre).
    plate_pose, centre_in_plate : ndarray or None
        p3 (6,) and x_p' (3,) when the setup gives them.
    side : int
        Sign of the sensor-y coordinate of the centre for profile reconstruction.
    truth : dict or None
        ``sensor_pose`` (6,) and maybe ``sphere_center`` (3,); simulated data only.
    profiles : tuple or None
        Per measurement the profile points (K, 2: sensor x, z in mm) or None; None when the
        dataset has no profiles at all.
    convention : str
        The robot-brand convention of the files (:mod:`handeye.model.conventions`); poses here are
        always KUKA.
    raw_poses : ndarray, shape (N, 3 + k), or None
        The flange poses as the file wrote them, in ``convention`` (what a convention slip is
        read back from); None for a dataset not read from a file.
    reconstructed : tuple of bool or None
        Per measurement: True when its centre was reconstructed from its profile (so
        ``side`` decided the sign of its y).
    mounts : handeye.model.mounts.Mounts
        Where the sensor and the sphere are mounted (``[sensor] mount``, ``[sphere] mount``,
        ``[positioner] axes``); the default is the seed's cell. ``start_pose``, ``sensor_pose``
        and ``sphere_centre`` are in their mounts' frames.
    axis_angles : ndarray, shape (N, k), or None
        Positioner axis angles, degrees (sphere on a positioner).
    sensor_pose : ndarray, shape (6,), or None
        ``[sensor] pose``: the sensor pose known (KUKA), for calibrations that do not estimate it.
    noise_centre_mm, noise_robot_mm : float
        The stated noise model (``[noise]``, defaults :data:`NOISE_CENTRE_MM`,
        :data:`NOISE_ROBOT_MM`): per-component sd of a sphere centre through the chain, and the
        robot's repeatability per axis, mm.
    """

    name: str
    path: pathlib.Path
    ids: tuple
    rows: tuple
    flange_poses: np.ndarray
    centre_in_sensor: np.ndarray
    start_pose: np.ndarray
    sphere_diameter: float
    sphere_centre: np.ndarray
    plate_pose: np.ndarray | None = None
    centre_in_plate: np.ndarray | None = None
    side: int = -1
    truth: dict | None = None
    profiles: tuple | None = None
    convention: str = "kuka"
    noise_centre_mm: float = 0.05
    noise_robot_mm: float = 0.025
    reconstructed: tuple | None = None
    profile_files: tuple = ()
    raw_poses: np.ndarray | None = None
    mounts: Mounts = Mounts()
    axis_angles: np.ndarray | None = None
    sensor_pose: np.ndarray | None = None

    def subset(self, mask):
        """The dataset restricted to the measurements where ``mask`` is true."""
        mask = np.asarray(mask, bool)
        if len(mask) == len(self) and mask.all():
            return self  # immutable: every measurement is this dataset
        out = dataclasses.replace(
            self,
            ids=tuple(i for i, k in zip(self.ids, mask) if k),
            rows=tuple(r for r, k in zip(self.rows, mask) if k),
            flange_poses=self.flange_poses[mask],
            centre_in_sensor=self.centre_in_sensor[mask],
            profiles=None if self.profiles is None else tuple(p for p, k in zip(self.profiles, mask) if k),
            reconstructed=None if self.reconstructed is None else tuple(r for r, k in zip(self.reconstructed, mask) if k),
            raw_poses=None if self.raw_poses is None else self.raw_poses[mask],
            axis_angles=None if self.axis_angles is None else self.axis_angles[mask],
        )
        for key in ("_flange2base", "_motions"):  # computed already: its rows, not a million poses again
            if key in self.__dict__ and not (key == "_motions" and self.mounts.default):
                rows = self.__dict__[key][mask]
                rows.setflags(write=False)
                out.__dict__[key] = rows
        return out

    def content_hash(self):
        """SHA-256 of the files that make the dataset (setup, measurements, profiles)."""
        return folder_hash(self.path, self.profile_files)


def folder_hash(path, profile_files=()):
    """SHA-256 of a dataset folder's ``.csv`` and ``.toml`` files and of the profile files read
    (whatever their names), by relative path: equal for the same data wherever it lies."""
    import hashlib

    path = pathlib.Path(path)
    h = hashlib.sha256()
    files = {str(p.relative_to(path)): p for p in path.rglob("*") if p.is_file() and p.suffix in (".csv", ".toml")}
    base = path.resolve()
    for p in profile_files:  # whatever their names: what was read (inside the folder, checked)
        files.setdefault(str(pathlib.Path(p).relative_to(base)), pathlib.Path(p))
    for name in sorted(files):
        h.update(name.encode())
        h.update(files[name].read_bytes())
    return h.hexdigest()


def embedded_names():
    """Names of the datasets shipped with the package."""
    return sorted(p.name for p in DATA_DIR.iterdir() if (p / "setup.toml").is_file())


def resolve(name_or_path):
    """Folder of a dataset given by an embedded name or a path."""
    p = pathlib.Path(name_or_path)
    if p.is_dir():
        return p
    if (DATA_DIR / str(name_or_path) / "setup.toml").is_file():
        return DATA_DIR / str(name_or_path)
    raise DatasetError(
        name_or_path, f"no dataset folder or embedded dataset of that name (embedded: {', '.join(embedded_names())})"
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
    "robot": {"convention"},
    "sensor": {"start_pose", "mount", "pose"},
    "sphere": {"diameter", "center", "base_pose", "center_in_plate", "mount"},
    "positioner": {"axes"},
    "sphere2": {"diameter", "center", "base_pose", "center_in_plate"},
    "profile": {"side"},
    "truth": {"sensor_pose", "sphere_center", "axes"},
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


def read_setup(path, require_sphere=True):
    """Read and check ``setup.toml`` of a dataset folder (module docstring): a ``_SetupFile``.
    ``require_sphere=False`` (a scan) accepts a setup without ``[sphere]``."""
    file = path / "setup.toml"
    try:
        if file.exists() and not file.is_file():
            raise DatasetError(file, "is not a regular file (a device, a pipe or a folder?)")
        if file.exists() and file.stat().st_size > MAX_LINE_BYTES:
            raise DatasetError(file, "more than 1 MB: not a setup file")
        text = file.read_text(encoding="utf-8-sig")  # a byte-order mark is accepted, as in the CSV files
    except FileNotFoundError:
        raise DatasetError(file, "missing file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise DatasetError(file, f"cannot be read: {exc}") from None
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise DatasetError(file, f"not valid TOML: {exc}") from None
    for section, table in doc.items():
        if section not in _ALLOWED or not isinstance(table, dict):
            raise DatasetError(file, f"unknown section (known: {', '.join(sorted(_ALLOWED))})", column=f"[{section}]")
        for key in table:
            if key not in _ALLOWED[section]:
                raise DatasetError(file, f"unknown key (known: {', '.join(sorted(_ALLOWED[section]))})",
                                   column=f"[{section}] {key}")
    convention = doc.get("robot", {}).get("convention", "kuka")
    if not isinstance(convention, str) or convention not in conventions.CONVENTIONS:
        raise DatasetError(file, f"unknown convention {convention!r} (known: {', '.join(conventions.CONVENTIONS)})",
                           column="[robot] convention")
    start = None
    if "start_pose" in doc.get("sensor", {}):
        start = _vector(doc["sensor"], "start_pose", len(conventions.columns(convention)), file, "sensor")
        if convention == "kuka":
            check_angles(start, file, column_prefix="[sensor] start_pose ", limits=GUESS_LIMITS)
        else:
            start = to_kuka(start, convention, file, None, "[sensor] start_pose")
    known = None
    if "pose" in doc.get("sensor", {}):
        known = _vector(doc["sensor"], "pose", len(conventions.columns(convention)), file, "sensor")
        known = to_kuka(known, convention, file, None, "[sensor] pose") if convention != "kuka" else known
        if convention == "kuka":
            check_angles(known, file, column_prefix="[sensor] pose ", limits=GUESS_LIMITS)
    diam, centre, plate_pose, centre_in_plate = _read_sphere(doc, "sphere", file, convention, require_sphere)
    sphere2 = _read_sphere(doc, "sphere2", file, convention, True) if "sphere2" in doc else None
    side = doc.get("profile", {}).get("side", -1)
    if side not in (1, -1) or isinstance(side, bool):
        raise DatasetError(file, f"must be 1 or -1, got {side!r}", column="[profile] side")
    truth = None
    if "truth" in doc:
        truth_pose = _vector(doc["truth"], "sensor_pose", len(conventions.columns(convention)), file, "truth")
        if convention != "kuka":  # in the dataset's convention, as every pose of the dataset
            truth_pose = to_kuka(truth_pose, convention, file, None, "[truth] sensor_pose")
        truth = {"sensor_pose": truth_pose}
        if "sphere_center" in doc["truth"]:
            truth["sphere_center"] = _vector(doc["truth"], "sphere_center", 3, file, "truth")
        if "axes" in doc["truth"]:
            truth["axes"] = mount_setup.read_axes(doc["truth"], file, LIMIT_RANGE_MM[1], "truth")
    noise = {}
    for key in ("centre_mm", "robot_mm"):
        if doc.get("noise", {}).get(key) is None:
            continue
        noise[key] = _bounded(doc["noise"][key], NOISE_RANGE_MM, file, f"[noise] {key}")
    limits = {"position_mm": LIMIT_POSITION_MM, "sensor_mm": LIMIT_SENSOR_MM}
    for key in limits:
        if doc.get("limits", {}).get(key) is None:
            continue
        limits[key] = _bounded(doc["limits"][key], LIMIT_RANGE_MM, file, f"[limits] {key}")
    noise["limits"] = limits
    bound = limits["position_mm"]
    vectors = [("[sensor] start_pose", start), ("[sphere] center", centre), ("[sphere] base_pose", plate_pose)]
    if sphere2 is not None:
        vectors += [("[sphere2] center", sphere2[1]), ("[sphere2] base_pose", sphere2[2])]
    for what, vector in vectors:
        if vector is not None and np.any(np.abs(vector[:3]) > bound):
            raise DatasetError(file, f"a position beyond +-{bound:g} mm ({', '.join(f'{v:g}' for v in vector[:3])}): "
                                     "a unit or a misprint? ([limits] position_mm sets the bound)", column=what)
    for name, d in (("sphere", diam), ("sphere2", sphere2[0] if sphere2 else None)):
        if d is not None and not d <= 2 * limits["sensor_mm"]:
            raise DatasetError(file, f"{d:g} mm is not a sphere a laser-line sensor measures", column=f"[{name}] diameter")
    mounts = mount_setup.read_mounts(doc, file, bound)
    if known is not None and np.any(np.abs(known[:3]) > bound):
        raise DatasetError(file, f"a position beyond +-{bound:g} mm: a unit or a misprint?", column="[sensor] pose")
    return _SetupFile(start, diam, centre, plate_pose, centre_in_plate, int(side), truth, convention, noise, sphere2,
                      mounts, known)


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


def _read_sphere(doc, section, file, convention, required):
    """``(diameter, centre, plate_pose, centre_in_plate)`` of a ``[sphere]``-like section; the
    diameter is None only when the section is absent and not ``required``."""
    sphere = doc.get(section, {})
    if not sphere and not required:
        return None, None, None, None
    diam = toml_number(sphere.get("diameter"))
    if diam is None or diam <= 0:
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
    return float(diam), centre, plate_pose, centre_in_plate


def _centre_from_profile(points, radius, side, pfile):
    from handeye.model import circle

    try:
        return circle.sphere_centre_from_circle(circle.fit_circle(points[:, 0], points[:, 1], PROFILE_FIT), radius, side)
    except circle.CircleFitError as exc:
        hint = (f"; a profile cannot be wider than the sphere: check [sphere] diameter = {2 * radius:g} mm in setup.toml "
                "(a radius given for the diameter? inches?)" if "exceeds" in str(exc) else "")
        raise DatasetError(pfile, str(exc) + hint) from None


#: Circle fit used to reconstruct a centre from a profile when xs, ys, zs are empty.
PROFILE_FIT = "hyper"


@dataclasses.dataclass(frozen=True)
class CellSetup:
    """What ``setup.toml`` says of a cell, without measurements (for planning before measuring).

    Attributes
    ----------
    path : pathlib.Path
    start_pose : ndarray, shape (6,), or None
        Nominal sensor pose on the flange, KUKA (mm, deg).
    sphere_diameter : float
    sphere_centre : ndarray, shape (3,), or None
    side : int
    convention : str
    mounts : handeye.model.mounts.Mounts
        With the nominal positioner axes; ``start_pose`` and ``sphere_centre`` are in their
        mounts' frames.
    """

    path: pathlib.Path
    start_pose: np.ndarray | None
    sphere_diameter: float
    sphere_centre: np.ndarray | None
    side: int
    convention: str
    mounts: Mounts = Mounts()


def load_setup(name_or_path):
    """Read and check only ``setup.toml`` of a dataset folder (``measurements.csv`` may not exist
    yet: a cell being planned); raises :class:`DatasetError`."""
    folder = resolve(name_or_path)
    st = read_setup(folder)
    return CellSetup(folder, st.start, st.diameter, st.centre, st.side, st.convention, st.mounts)


def _read_rows(folder, file, convention, limits, diam, side, axes=()):
    """The rows of ``measurements.csv`` read and checked one by one (any file: profiles, blank
    lines, quoting); ``(ids, rows, poses, centres, profiles, reconstructed, profile_files, raw,
    angles)`` as lists (``angles``: the positioner axis columns ``axes``, degrees). Raises
    DatasetError naming file, row and column."""
    pose_columns = conventions.columns(convention)
    required = ("id",) + pose_columns + ("xs", "ys", "zs") + tuple(axes)
    table = read_table(file)
    if not table:
        raise DatasetError(file, "empty file; needs the header " + ",".join(required), 1)
    header = [h.strip() for h in table[0]]
    for col in header:
        if col not in required + OPTIONAL_COLUMNS:
            raise DatasetError(file, f"unknown column (expected {','.join(required)}[,profile] for the "
                                     f"{convention} convention)", 1, col)
        if header.count(col) > 1:
            raise DatasetError(file, "duplicate column", 1, col)
    for col in required:
        if col not in header:
            raise DatasetError(file, "missing column", 1, col)
    idx = {c: header.index(c) for c in header}
    ids, rows, poses, centres, profiles, reconstructed, profile_files, raw = [], [], [], [], [], [], [], []
    angles = []
    seen = {}
    for line, fields in enumerate(table[1:], start=2):
        if not any(f.strip() for f in fields):
            continue
        if len(fields) != len(header):
            raise DatasetError(file, f"expected {len(header)} fields, got {len(fields)}", line)
        ident = row_id(fields, idx["id"], seen, file, line)
        pose = read_pose(fields, idx, convention, file, line, limits["position_mm"])
        raw.append([float(fields[idx[c]]) for c in pose_columns])  # read_pose checked them
        cells = [fields[idx[c]].strip() for c in ("xs", "ys", "zs")]
        profile = fields[idx["profile"]].strip() if "profile" in idx else ""
        points = read_points(folder, profile, file, line, limits["sensor_mm"]) if profile else None
        if profile:
            profile_files.append((folder / profile).resolve())
        if all(cells) or not profile:
            xs = [number(v, file, line, c) for v, c in zip(cells, ("xs", "ys", "zs"))]
            for v, c in zip(xs, ("xs", "ys", "zs")):
                if abs(v) > limits["sensor_mm"]:
                    raise DatasetError(file, f"{v:g} mm is beyond the sensor's plausible range +-{limits['sensor_mm']:g} mm "
                                             "([limits] sensor_mm in setup.toml sets it)", line, c)
        elif any(cells):
            raise DatasetError(file, "give all of xs, ys, zs or none (with a profile)", line, "xs")
        else:
            xs = _centre_from_profile(points, diam / 2, side, folder / profile)
        angles.append([axis_angle(fields[idx[a]], file, line, a) for a in axes])
        reconstructed.append(bool(profile) and not all(cells))
        profiles.append(points)
        ids.append(ident)
        rows.append(line)
        poses.append(pose)
        centres.append(xs)
    return ids, rows, poses, centres, profiles, reconstructed, profile_files, raw, angles


#: Largest positioner axis angle a row may hold (degrees): beyond it, radians or a misprint are not
#: the question -- two turns is.
AXIS_ANGLE_LIMIT_DEG = 720.0


def axis_angle(text, file, line, column):
    """A positioner axis angle of a row (degrees), checked."""
    value = number(text, file, line, column)
    if abs(value) > AXIS_ANGLE_LIMIT_DEG:
        raise DatasetError(file, f"{value:g} deg is beyond +-{AXIS_ANGLE_LIMIT_DEG:g} deg for a positioner axis", line,
                           column)
    return value


def load(name_or_path):
    """Read and check a dataset (module docstring); raises :class:`DatasetError`."""
    folder = resolve(name_or_path)
    st = read_setup(folder)
    if st.sphere2 is not None:
        raise DatasetError(folder / "setup.toml", "two spheres: a calibration uses one; [sphere2] is for handeye "
                                                  "validate and cloud (remove it to calibrate)", column="[sphere2]")
    start, diam, centre, side, truth, convention = st.start, st.diameter, st.centre, st.side, st.truth, st.convention
    plate_pose, centre_in_plate, noise = st.plate_pose, st.centre_in_plate, dict(st.noise)
    limits = noise.pop("limits")
    pose_columns = conventions.columns(convention)
    file = folder / "measurements.csv"
    axes = st.mounts.axis_names
    plain = read_plain_rows(file, pose_columns, convention, limits, axes)  # a large plain file: column-wise
    if plain is None:
        ids, rows, poses, centres, profiles, reconstructed, profile_files, raw, angles = _read_rows(
            folder, file, convention, limits, diam, side, axes)
    else:
        ids, rows, poses, centres, raw, angles = (plain[k] for k in ("ids", "rows", "poses", "centres", "raw", "extra"))
        profiles, reconstructed, profile_files = (None,) * len(ids), (False,) * len(ids), []
    if not ids:
        raise DatasetError(file, "no measurements", 2)
    return Dataset(
        name=folder.name,
        path=folder,
        ids=tuple(ids),
        rows=tuple(rows),
        flange_poses=np.array(poses),
        centre_in_sensor=np.array(centres, dtype=float),
        start_pose=start,
        sphere_diameter=diam,
        sphere_centre=centre,
        plate_pose=plate_pose,
        centre_in_plate=centre_in_plate,
        side=side,
        truth=truth,
        profiles=tuple(profiles) if any(p is not None for p in profiles) else None,
        reconstructed=tuple(reconstructed),
        profile_files=tuple(sorted(set(profile_files))),
        raw_poses=np.array(raw, dtype=float),
        convention=convention,
        noise_centre_mm=noise.get("centre_mm", NOISE_CENTRE_MM),
        noise_robot_mm=noise.get("robot_mm", NOISE_ROBOT_MM),
        mounts=st.mounts,
        axis_angles=np.array(angles, float).reshape(len(ids), len(axes)) if axes else None,
        sensor_pose=st.sensor_pose,
    )
