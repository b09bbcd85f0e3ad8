"""Datasets: a folder with ``measurements.csv`` and ``setup.toml``.

``measurements.csv``
    Header ``id,x,y,z,a,b,c,xs,ys,zs`` (any order) and an optional ``profile`` column (with it,
    ``xs,ys,zs`` may be left out altogether when every row has a profile); with
    ``[robot] convention`` other than ``kuka`` the pose columns are those of that convention
    (``x,y,z,q1,q2,q3,q4`` for abb, ``x,y,z,rx,ry,rz`` for ur, ``x,y,z,w,p,r`` for fanuc;
    :mod:`handeye.model.chain.conventions`), and so is ``start_pose``.
    ``id`` is unique text; ``x..c`` the flange pose in the robot base (KUKA: mm, degrees,
    ``A, C`` in [-180, 180], ``B`` in [-90, 90], the controller's ranges; a start pose may
    hold any angle in [-360, 360]); ``xs, ys, zs`` the sphere centre in the sensor
    frame (mm). ``profile``, when present, is the path (relative to the folder) of a CSV with
    header ``x,z``: laser-line points in the sensor's y = 0 plane, mm; then ``xs, ys, zs`` may
    be empty and the centre is reconstructed as in the seed (C15, C16, 6-26, 6-27), but with
    the Hyper circle fit instead of the seed's biased Kasa fit (:mod:`handeye.model.geometry.circle`): centre
    ``(x_c, z_c)`` and radius r, then ``y = side * sqrt(R^2 - r^2)`` with R the sphere's radius.
    ``cloud`` instead (a 3-D sensor): a CSV with header ``x,y,z``, the sphere's surface seen from
    that pose (sensor frame, mm); ``xs, ys, zs`` are then empty, the centre is the sphere fitted to
    it and carries the fit's covariance (:mod:`handeye.model.datasets.cloud_rows`).
``setup.toml``
    ``[sensor] start_pose`` (p2: six numbers; optional -- without it the calibration starts from
    the closed-form estimate); ``[sphere] diameter`` (mm; needed only where a row has a profile: a
    dataset of centres or clouds may leave it out, a cloud's radius is then fitted) and either
    ``center`` (three numbers, robot base) or ``base_pose`` (p3) with ``center_in_plate``
    (x_p'), or neither when the centre is to be estimated (``--unknowns sensor+sphere``);
    ``[profile] side`` (+1 or -1, default -1 as in the seed); optional ``[noise] centre_mm``
    (per-component sd of a sphere centre through the chain, default 0.05) and ``robot_mm``
    (robot repeatability per axis, default 0.025), the noise model a calibration tests its
    fit against; optional ``[truth]`` with
    ``sensor_pose`` (in the dataset's convention) and optionally ``sphere_center`` -- for
    simulated data, never read by a calibration. ``[profile] own_axes`` (R, ``p = R p_own``) and
    ``poses = "own"``: the profiles were turned from the sensor's own frame by ``dataset new``,
    and the ``[sensor]`` poses are of that own frame (:mod:`handeye.model.chain.own_frame`); they are
    turned into handeye's frame here, on load.

Every problem found raises :class:`DatasetError`, whose text names file, row and column.
"""
from __future__ import annotations

import dataclasses
import functools
import hashlib
import pathlib

import numpy as np

from handeye.model.chain import conventions
from handeye.model.chain.mounts import Mounts, motions
from handeye.model.chain.pose import transform_from_pose
from handeye.model.datasets import cloud_rows
from handeye.model.geometry import profile_bend
from handeye.model.readers.setup_file import (  # noqa: F401  (the setup's names: public here too)
    LIMIT_SENSOR_MM,
    NOISE_CENTRE_MM,
    NOISE_ROBOT_MM,
    read_setup,
)
from handeye.model.readers.tables import (  # noqa: F401  (read_pose_list, pose_list_text: public here too)
    DatasetError,
    number,
    pose_list_text,
    read_plain_rows,
    read_points,
    read_pose,
    read_pose_list,
    read_table,
    row_id,
)
from handeye.model.robot import configuration, robots
from handeye.model.robot.robots import JOINTS

OPTIONAL_COLUMNS = ("profile", "cloud", "cfx")
DATA_DIR = pathlib.Path(__file__).parent.parent / "data"


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
        """The carrier motions ``M_i`` of the chain ``M_i X xs_i = c`` (:mod:`handeye.model.chain.mounts`),
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
    sphere_diameter : float or None
        mm; None where the setup gives none (a dataset of centres or clouds: nothing on load needs
        it; what does says so).
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
        dataset has no profiles at all. Cleaned (the points on the sphere's arc) unless loaded
        with ``clean=False``; every fit and check uses these.
    raw_profiles : tuple or None
        The same profiles as read, every point (what ``handeye validate`` and ``cloud`` see).
    cleaning : tuple or None
        Per measurement its :class:`handeye.model.geometry.profile_clean.Cleaning` (kept mask, points
        dropped and why) or None without a profile; None when the dataset was loaded with
        ``clean=False`` or has no profiles.
    convention : str
        The robot-brand convention of the files (:mod:`handeye.model.chain.conventions`); poses here are
        always KUKA.
    raw_poses : ndarray, shape (N, 3 + k), or None
        The flange poses as the file wrote them, in ``convention`` (what a convention slip is
        read back from); None for a dataset not read from a file.
    reconstructed : tuple of bool or None
        Per measurement: True when its centre was reconstructed from its profile (so
        ``side`` decided the sign of its y).
    mounts : handeye.model.chain.mounts.Mounts
        Where the sensor and the sphere are mounted (``[sensor] mount``, ``[sphere] mount``,
        ``[positioner] axes``); the default is the seed's cell. ``start_pose``, ``sensor_pose``
        and ``sphere_centre`` are in their mounts' frames.
    axis_angles : ndarray, shape (N, k), or None
        Positioner axis angles, degrees (sphere on a positioner).
    sensor_pose : ndarray, shape (6,), or None
        ``[sensor] pose``: the sensor pose known (KUKA), for calibrations that do not estimate it.
    joints : ndarray, shape (N, 6), or None
        Joint angles ``j1..j6`` of each pose, degrees (optional columns; they need ``[robot] model``).
    configuration : ndarray of int, shape (N,), or None
        ABB's ``cfx`` of each pose (an optional column, 0-7: the arm's configuration, named when the
        excluded samples are one of its groups, :mod:`handeye.model.robot.configuration`).
    robot_model : handeye.model.robot.robots.RobotModel or None
        ``[robot] model``: the nominal kinematics (checked on load to reproduce the reported poses).
    own_axes : ndarray, shape (3, 3), or None
        ``[profile] own_axes``: R with ``p = R p_own``, the sensor's own frame (its driver's points)
        in the frame of the profiles (laser plane y = 0) that the calibration is of; None: the same.
        ``start_pose`` and ``sensor_pose`` are of handeye's frame (turned on load); the results
        turn the calibrated pose back to the own frame (:mod:`handeye.model.chain.own_frame`).
    profile_of : tuple or None
        Per measurement the profile file it names (a resolved path) or None; None when no row
        names one. What a message about a profile names.
    not_arcs : tuple of handeye.model.datasets.arcs.NotArc
        The rows set aside because their profile is no arc of the stated sphere (not among the
        measurements; :mod:`handeye.model.datasets.arcs`).
    bend : handeye.model.geometry.profile_bend.Bend or None
        The profiles' depth bend (a sensor linearity error, :mod:`handeye.model.geometry.profile_bend`), where
        ``profiles`` are enough to estimate it; where it is applied, ``profiles`` and
        the centres of their rows are corrected by it (``raw_profiles`` are not).
    poses_read : str or None
        How ``[sensor]`` poses were read when the setup does not say their frame (an older setup
        with ``own_axes`` and no ``poses = "own"``: in handeye's turned frame), else None.
    noise_centre_mm, noise_robot_mm : float
        The stated noise model (``[noise]``, defaults :data:`NOISE_CENTRE_MM`,
        :data:`NOISE_ROBOT_MM`): per-component sd of a sphere centre through the chain, and the
        robot's repeatability per axis, mm.
    noise_stated : tuple of str
        The keys ``[noise]`` gives (``centre_mm``, ``robot_mm``): residuals far above a stated noise are
        structure the model lacks, not noise (:func:`handeye.app.engine.search.unexplained`).
    clouds : tuple or None
        Per measurement the :class:`handeye.model.geometry.sphere_cloud.CloudFit` of its point cloud (the
        ``cloud`` column) or None; None when no row has a cloud.
    centre_cov : ndarray, shape (N, 3, 3), or None
        The covariance of each centre fitted to a cloud (sensor frame, mm^2; zero for other rows), what
        weighs it (:func:`handeye.model.datasets.observations.profile_covariance`); None without clouds.
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
    joints: np.ndarray | None = None
    configuration: np.ndarray | None = None
    robot_model: object | None = None
    raw_profiles: tuple | None = None
    cleaning: tuple | None = None
    own_axes: np.ndarray | None = None
    poses_read: str | None = None
    profile_of: tuple | None = None
    not_arcs: tuple = ()
    bend: object = None
    noise_stated: tuple = ()
    clouds: tuple | None = None
    centre_cov: np.ndarray | None = None

    @property
    def sphere_radius_mm(self):
        """``sphere_diameter / 2``, mm; NaN without a diameter (a dataset of centres or clouds: what needs the
        radius -- a profile, an effect that rebuilds y from it -- is refused before, naming ``[sphere] diameter``)."""
        return float("nan") if self.sphere_diameter is None else self.sphere_diameter / 2

    @functools.cached_property
    def _once(self):
        return {}

    def once(self, key, compute):
        """``compute()``, computed once for this dataset under ``key`` (a dataset is frozen: a
        function of it alone is the same each time it is asked; calibrate's stages, its search
        and diagnose ask some of them several times)."""
        if key not in self._once:
            self._once[key] = compute()
        return self._once[key]

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
            raw_profiles=None if self.raw_profiles is None else tuple(p for p, k in zip(self.raw_profiles, mask) if k),
            cleaning=None if self.cleaning is None else tuple(c for c, k in zip(self.cleaning, mask) if k),
            profile_of=None if self.profile_of is None else tuple(f for f, k in zip(self.profile_of, mask) if k),
            reconstructed=None if self.reconstructed is None else tuple(r for r, k in zip(self.reconstructed, mask) if k),
            raw_poses=None if self.raw_poses is None else self.raw_poses[mask],
            axis_angles=None if self.axis_angles is None else self.axis_angles[mask],
            joints=None if self.joints is None else self.joints[mask],
            configuration=None if self.configuration is None else self.configuration[mask],
            bend=None if self.bend is None else self.bend.subset(mask),
            clouds=None if self.clouds is None else tuple(c for c, k in zip(self.clouds, mask) if k),
            centre_cov=None if self.centre_cov is None else self.centre_cov[mask],
        )
        for key in ("_flange2base", "_motions"):  # computed already: its rows, not a million poses again
            if key in self.__dict__ and not (key == "_motions" and self.mounts.default):
                rows = self.__dict__[key][mask]
                rows.setflags(write=False)
                out.__dict__[key] = rows
        return out

    def paired(self, step):
        """The dataset with each row's pose paired with the measurement ``step`` rows below it
        (``step`` = +1: row i's pose with row i+1's measurement; -1: with row i-1's), one sample
        per pose that has such a row (``len(self) - |step|``).

        The pose side -- ``flange_poses``, ``raw_poses``, ``axis_angles``, ``joints`` (what the
        robot and the positioner report) and ``ids``, ``rows`` (a row's id names its pose, as
        ``dataset new --pair id`` matches profile names to pose ids; its line is the pose's) --
        stays; the measurement side -- ``centre_in_sensor``, ``profiles``, ``raw_profiles``,
        ``cleaning``, ``reconstructed``, ``bend``, ``clouds``, ``centre_cov`` (what the sensor reports) -- moves.
        """
        n, step = len(self), int(step)
        if step == 0 or abs(step) >= n:
            raise ValueError(f"a pairing step of {step} rows on {n} rows")
        poses = np.arange(max(0, -step), n - max(0, step))
        mask = np.zeros(n, bool)
        mask[poses] = True
        measured = np.zeros(n, bool)
        measured[poses + step] = True
        posed, m = self.subset(mask), self.subset(measured)
        out = dataclasses.replace(posed, centre_in_sensor=m.centre_in_sensor, profiles=m.profiles,
                                  raw_profiles=m.raw_profiles, cleaning=m.cleaning, reconstructed=m.reconstructed,
                                  bend=m.bend, clouds=m.clouds, centre_cov=m.centre_cov)
        for key in ("_flange2base", "_motions"):  # the pose side's, computed already: kept
            if key in posed.__dict__:
                out.__dict__[key] = posed.__dict__[key]
        return out

    def content_hash(self):
        """SHA-256 of the files that make the dataset (setup, measurements, profiles)."""
        return folder_hash(self.path, self.profile_files)


def folder_hash(path, profile_files=()):
    """SHA-256 of a dataset folder's ``.csv`` and ``.toml`` files and of the profile files read
    (whatever their names), by relative path: equal for the same data wherever it lies."""
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


def _clean_profile(points, radius):
    """The profile's points on the sphere's arc, the :class:`~handeye.model.geometry.profile_clean.Cleaning`
    record (:mod:`handeye.model.geometry.profile_clean`) and, for a profile without an arc, why (else
    None): its row is set aside (:mod:`handeye.model.datasets.arcs`)."""
    from handeye.model.geometry import profile_clean

    record = profile_clean.clean(points, radius)
    if record.status == "no arc":
        return points, record, profile_clean.no_arc_message(record, radius)
    return (points if record.kept.all() else points[record.kept]), record, None


class NoCentre(DatasetError):
    """A profile that gives no sphere centre (no circle, or one wider than the sphere): its row is
    set aside as no arc (:mod:`handeye.model.datasets.arcs`)."""


def _centre_from_profile(points, radius, side, pfile):
    from handeye.model.geometry import circle

    try:
        return circle.sphere_centre_from_circle(circle.fit_circle(points[:, 0], points[:, 1], PROFILE_FIT), radius, side)
    except circle.CircleFitError as exc:
        raise NoCentre(pfile, str(exc)) from None


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
    mounts : handeye.model.chain.mounts.Mounts
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


def _read_rows(folder, st, limits, clean=True):
    """The rows of ``measurements.csv`` read and checked one by one (any file: profiles, blank
    lines, quoting); ``(ids, rows, poses, centres, profiles, reconstructed, profile_files, raw,
    angles, raw_profiles, cleaning, clouds, problems)`` as lists (``angles``: the positioner axis columns of the setup
    ``st``, degrees; ``profiles`` cleaned when ``clean``, ``raw_profiles`` as read). Raises DatasetError
    naming file, row and column."""
    file = folder / "measurements.csv"
    table = read_table(file)
    reader = _RowReader(folder, file, st, limits, clean, *_header(table, file, st.convention, st.mounts.axis_names))
    out = tuple([] for _ in range(13))
    seen = {}
    for line, fields in enumerate(table[1:], start=2):
        if any(f.strip() for f in fields):
            for column, value in zip(out, reader.row(line, fields, seen)):
                column.append(value)
    return out


def _header(table, file, convention, axes):
    """The header of ``measurements.csv`` checked: ``(column index by name, whether the rows have centre
    columns, the joint columns)``."""
    required = ("id",) + conventions.columns(convention) + ("xs", "ys", "zs") + tuple(axes)
    if not table:
        raise DatasetError(file, "empty file; needs the header " + ",".join(required), 1)
    header = [h.strip() for h in table[0]]
    centre_columns = not (("profile" in header or "cloud" in header) and not any(c in header for c in ("xs", "ys", "zs")))
    if not centre_columns:  # every row's centre from its profile or cloud: the columns may be left out
        required = tuple(c for c in required if c not in ("xs", "ys", "zs"))
    joints = JOINTS if any(h in JOINTS for h in header) else ()
    required += joints  # all six or none
    for col in header:
        if col not in required + OPTIONAL_COLUMNS:
            raise DatasetError(file, f"unknown column (expected {','.join(required)}[,profile|cloud] for the "
                                     f"{convention} convention)", 1, col)
        if header.count(col) > 1:
            raise DatasetError(file, "duplicate column", 1, col)
    for col in required:
        if col not in header:
            raise DatasetError(file, "missing column", 1, col)
    return {c: header.index(c) for c in header}, centre_columns, joints


@dataclasses.dataclass(frozen=True)
class _RowReader:
    """What reading one row of ``measurements.csv`` needs: the dataset's folder, the file, its setup and
    limits, whether profiles are cleaned, and its checked header (:func:`_header`)."""

    folder: pathlib.Path
    file: pathlib.Path
    st: object
    limits: dict
    clean: bool
    idx: dict
    centre_columns: bool
    joints: tuple

    def row(self, line, fields, seen):
        """One row: ``(id, line, pose, centre, profile, reconstructed, profile file or None, raw pose, angles,
        raw profile, cleaning record, cloud fit or None, why the profile is no arc or None)``."""
        file, idx, limits, convention = self.file, self.idx, self.limits, self.st.convention
        if len(fields) != len(idx):
            raise DatasetError(file, f"expected {len(idx)} fields, got {len(fields)}", line)
        ident = row_id(fields, idx["id"], seen, file, line)
        pose = read_pose(fields, idx, convention, file, line, limits["position_mm"])
        raw = [float(fields[idx[c]]) for c in conventions.columns(convention)]  # read_pose checked them
        cells = [fields[idx[c]].strip() for c in ("xs", "ys", "zs")] if self.centre_columns else ["", "", ""]
        profile = fields[idx["profile"]].strip() if "profile" in idx else ""
        cloud = fields[idx["cloud"]].strip() if "cloud" in idx else ""
        if cloud:  # the sphere fitted to the row's cloud (cloud_rows)
            xs, fit = cloud_rows.row_cloud(self, line, cells, cloud)
            return (ident, line, pose, xs, None, False, (self.folder / cloud).resolve(), raw, self._angles(fields, line),
                    None, None, fit, None)
        if not profile and not self.centre_columns:
            raise DatasetError(file, "no profile or cloud: without xs,ys,zs columns every row needs one", line,
                               "profile" if "profile" in idx else "cloud")
        if profile:
            cloud_rows.needs_diameter(self, line)
        points = read_points(self.folder, profile, file, line, limits["sensor_mm"]) if profile else None
        raw_points, record, problem = points, None, None
        if profile and self.clean:
            points, record, problem = _clean_profile(points, self.st.diameter / 2)
        xs = [np.nan] * 3  # a profile that is no arc gives no centre: the row is set aside (arcs.py)
        if problem is None:
            try:
                xs = self._centre(cells, profile, points, line)
            except NoCentre as exc:
                problem = exc.problem
        return (ident, line, pose, xs, points, bool(profile) and not all(cells),
                (self.folder / profile).resolve() if profile else None, raw, self._angles(fields, line), raw_points, record,
                None, problem)

    def _angles(self, fields, line):
        """The row's positioner axis angles, joint angles and ``cfx`` (the optional numeric columns)."""
        file, idx = self.file, self.idx
        return ([axis_angle(fields[idx[a]], file, line, a) for a in self.st.mounts.axis_names]
                + [axis_angle(fields[idx[j]], file, line, j, JOINT_ANGLE_LIMIT_DEG, "a robot joint") for j in self.joints]
                + ([configuration.cfx_field(fields[idx["cfx"]], file, line)] if "cfx" in idx else []))

    def _centre(self, cells, profile, points, line):
        """The row's sphere centre in the sensor frame: its columns, else from its profile."""
        file, limit = self.file, self.limits["sensor_mm"]
        if all(cells) or not profile:
            xs = [number(v, file, line, c) for v, c in zip(cells, ("xs", "ys", "zs"))]
            for v, c in zip(xs, ("xs", "ys", "zs")):
                if abs(v) > limit:
                    raise DatasetError(file, f"{v:g} mm is beyond the sensor's plausible range +-{limit:g} mm "
                                             "([limits] sensor_mm in setup.toml sets it)", line, c)
            return xs
        if any(cells):
            raise DatasetError(file, "give all of xs, ys, zs or none (with a profile)", line, "xs")
        return _centre_from_profile(points, self.st.diameter / 2, self.st.side, self.folder / profile)


#: Largest positioner axis angle a row may hold (degrees): beyond it, radians or a misprint are not
#: the question -- two turns is.
AXIS_ANGLE_LIMIT_DEG = 720.0


#: Largest joint angle a row may hold (degrees).
JOINT_ANGLE_LIMIT_DEG = 400.0


def axis_angle(text, file, line, column, limit=AXIS_ANGLE_LIMIT_DEG, what="a positioner axis"):
    """An angle cell of a row (degrees: a positioner axis, or a robot joint with ``limit`` and
    ``what``), checked against ``limit``."""
    value = number(text, file, line, column)
    if abs(value) > limit:
        raise DatasetError(file, f"{value:g} deg is beyond +-{limit:g} deg for {what}", line, column)
    return value


def _robot_model(st, folder, joints, poses, file):
    """The ``[robot] model`` (None without one), checked against the joint angles when the file has them."""
    if st.robot_model is None:
        if joints is not None:
            raise DatasetError(folder / "setup.toml", "measurements.csv has joint angles j1..j6: name the robot's "
                                                      f"nominal model (built in: {', '.join(robots.builtin_names())}, "
                                                      "or a model file)", column="[robot] model")
        return None
    model = robots.load(st.robot_model if st.robot_model in robots.builtin_names() else folder / st.robot_model)
    if joints is not None and len(joints):
        model = robots.check_reported(model, joints, transform_from_pose(poses), file)
    return model


def _check_truth_params(truth, model, file):
    """``[truth] link_lengths`` / ``joint_compliance`` name parameters of the robot model."""
    from handeye.model.robot import robot_errors

    for name in ("link_lengths", "joint_compliance"):
        given = (truth or {}).get(name)
        if not given:
            continue
        if model is None:
            raise DatasetError(file, f"[truth] {name} needs [robot] model", column=f"[truth] {name}")
        unknown = sorted(set(given) - set(robot_errors.param_names(model, name)))
        if unknown:
            raise DatasetError(file, f"{unknown[0]} is not a parameter of the {model.name} (it has "
                                     f"{', '.join(robot_errors.param_names(model, name))})", column=f"[truth] {name}")


def _set_aside(columns, folder, diameter):
    """The columns of :func:`_read_rows` without the rows whose profile is no arc of the sphere, and
    their records (:mod:`handeye.model.datasets.arcs`); raises DatasetError when they are most of the
    rows with a profile."""
    from handeye.model.datasets import arcs

    *kept, problems = columns
    ids, rows, profiles, files = kept[0], kept[1], kept[4], kept[6]
    if all(p is None for p in profiles):  # nothing to judge (and no diameter needed)
        return kept, ()
    verdicts = arcs.judge(profiles, problems, diameter / 2)
    base = pathlib.Path(folder).resolve()
    bad = [arcs.NotArc(ids[k], int(rows[k]), relative_name(files[k], base), why, f_stat, p)
           for k, (why, f_stat, p) in enumerate(verdicts) if why is not None]
    if not bad:
        return kept, ()
    if len(bad) > sum(p is not None for p in profiles) // 2:
        raise DatasetError(pathlib.Path(folder) / "measurements.csv", arcs.refusal(bad, diameter))
    keep = arcs.keep_mask([b.row for b in bad], rows)
    return [[v for v, k in zip(column, keep) if k] for column in kept], tuple(bad)


def _rows(folder, st, limits, clean):
    """``(columns, not_arcs)``: the columns of :func:`_read_rows` (a large plain file read column-wise,
    :func:`handeye.model.readers.tables.read_plain_rows`), without the rows set aside as no arc, and their records."""
    convention, file = st.convention, folder / "measurements.csv"
    plain = read_plain_rows(file, conventions.columns(convention), convention, limits, st.mounts.axis_names)
    if plain is None:
        return _set_aside(_read_rows(folder, st, limits, clean), folder, st.diameter)
    n = len(plain["ids"])
    return [plain["ids"], plain["rows"], plain["poses"], plain["centres"], (None,) * n, (False,) * n, [], plain["raw"],
            plain["extra"], (None,) * n, (None,) * n, (None,) * n], ()


def _corrected_bend(profiles, centres, st):
    """``(profiles, centres, bend)``: the profiles' depth bend measured (cleaned or, loaded without cleaning,
    every point), and applied where it is clear (:func:`handeye.model.geometry.profile_bend.apply`); unchanged (bend
    None) without profiles."""
    if all(p is None for p in profiles):
        return profiles, centres, None
    return profile_bend.apply(profiles, centres, st.diameter / 2, st.side, PROFILE_FIT)


def relative_name(file, base):
    """``file`` relative to the folder ``base`` when inside it, else as it is (str)."""
    try:
        return str(pathlib.Path(file).relative_to(pathlib.Path(base).resolve()))
    except ValueError:
        return str(file)


def load(name_or_path, clean=True):
    """Read and check a dataset (module docstring); raises :class:`DatasetError`.

    With ``clean`` (the default) every profile is cleaned (:mod:`handeye.model.geometry.profile_clean`:
    speckle and background dropped) before anything is fitted to it: ``profiles`` holds the
    points on the arc, ``raw_profiles`` the points as read and ``cleaning`` what was dropped."""
    folder = resolve(name_or_path)
    st = read_setup(folder)
    if st.sphere2 is not None:
        raise DatasetError(folder / "setup.toml", "two spheres: a calibration uses one; [sphere2] is for handeye "
                                                  "validate and cloud (remove it to calibrate)", column="[sphere2]")
    start, diam, centre, side, truth, convention = st.start, st.diameter, st.centre, st.side, st.truth, st.convention
    plate_pose, centre_in_plate, noise = st.plate_pose, st.centre_in_plate, dict(st.noise)
    limits = noise.pop("limits")
    file, axes = folder / "measurements.csv", st.mounts.axis_names
    (ids, rows, poses, centres, profiles, reconstructed, profile_files, raw, angles, raw_profiles, cleaning,
     clouds), not_arcs = _rows(folder, st, limits, clean)
    if not ids:
        raise DatasetError(file, "no measurements", 2)
    profiles, centres, bend = _corrected_bend(profiles, centres, st)
    angles, cfx = configuration.split_cfx(np.array(angles, float).reshape(len(ids), -1), len(axes))
    joints = angles[:, len(axes):] if angles.shape[1] > len(axes) else None
    model = _robot_model(st, folder, joints, np.asarray(poses, float), file)
    _check_truth_params(st.truth, model, folder / "setup.toml")
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
        raw_profiles=tuple(raw_profiles) if any(p is not None for p in profiles) else None,
        cleaning=tuple(cleaning) if clean and any(p is not None for p in profiles) else None,
        reconstructed=tuple(reconstructed),
        profile_files=tuple(sorted({f for f in profile_files if f is not None})),
        profile_of=tuple(profile_files) if any(f is not None for f in profile_files) else None,
        raw_poses=np.array(raw, dtype=float),
        convention=convention,
        noise_centre_mm=noise.get("centre_mm", NOISE_CENTRE_MM), noise_robot_mm=noise.get("robot_mm", NOISE_ROBOT_MM),
        noise_stated=tuple(sorted(noise)),
        mounts=st.mounts,
        axis_angles=angles[:, :len(axes)] if axes else None,
        sensor_pose=st.sensor_pose,
        joints=joints,
        configuration=cfx,
        robot_model=model,
        own_axes=st.own_axes,
        poses_read=st.poses_read,
        not_arcs=not_arcs,
        bend=bend,
        clouds=tuple(clouds) if any(c is not None for c in clouds) else None,
        centre_cov=cloud_rows.covariances(clouds),
    )
