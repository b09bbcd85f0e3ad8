"""Scans: flange poses and laser profiles, with or without a sphere.

A scan is what ``handeye cloud`` and ``handeye validate`` read: a folder with
``measurements.csv`` and, optionally, ``setup.toml``.

``measurements.csv``
    ``id``, the flange pose in the robot's convention (``x,y,z,a,b,c`` KUKA, ``x,y,z,w,p,r``
    FANUC, ``x,y,z,q1,q2,q3,q4`` ABB, ``x,y,z,rx,ry,rz`` UR; :mod:`handeye.model.chain.conventions`)
    and ``profile``: the path, inside the folder, of a CSV with header ``x,z`` (laser-line points
    in the sensor's y = 0 plane, mm). Columns ``xs, ys, zs`` may be present (a calibration
    dataset is a scan too) and are not read. A row with an empty ``profile`` is skipped (and
    counted).
``setup.toml`` (optional)
    As for a dataset (:mod:`handeye.model.datasets.dataset`): ``[robot] convention`` (without the file,
    the header tells the convention), ``[limits]``, ``[noise] robot_mm``, and for validation
    ``[sphere]`` and an optional second sphere ``[sphere2]`` (diameter, centre).

Profiles are read by :func:`handeye.model.readers.tables.read_points`: a C parser for clean files, the
row-by-row reader (which names the bad row) otherwise.
"""
from __future__ import annotations

import dataclasses
import pathlib

import numpy as np

from handeye.model.chain import conventions
from handeye.model.chain.mounts import Mounts
from handeye.model.datasets import dataset
from handeye.model.readers import tables
from handeye.model.readers.tables import DatasetError


@dataclasses.dataclass(frozen=True)
class Sphere:
    """A sphere of the setup: diameter (mm) and centre in its mount's frame (mm) or None."""

    diameter: float
    centre: np.ndarray | None


@dataclasses.dataclass(frozen=True)
class Scan(dataset.FlangePoses):
    """Poses and profiles read by :func:`load`.

    Attributes
    ----------
    name : str
    path : pathlib.Path
    ids : tuple of str
    rows : tuple of int
        Line of each pose in ``measurements.csv``.
    flange_poses : ndarray, shape (N, 6)
        Flange in robot base, KUKA (mm, deg).
    profiles : tuple of ndarray
        Per pose the profile points (K_i, 2): sensor x, z, mm.
    spheres : tuple of Sphere
        ``[sphere]`` and ``[sphere2]`` of setup.toml, those given.
    convention : str
    robot_sigma_mm : float
        Robot repeatability per axis (``[noise] robot_mm``), mm.
    skipped : tuple of str
        Ids of rows without a profile.
    profile_files : tuple of pathlib.Path
    mounts : handeye.model.chain.mounts.Mounts
        The cell's mounts (``setup.toml``; the seed's cell without one): :meth:`motions` carries
        the profiles into the sphere mount's frame.
    axis_angles : ndarray, shape (N, k), or None
        Positioner axis angles of the poses with a profile, degrees.
    """

    name: str
    path: pathlib.Path
    ids: tuple
    rows: tuple
    flange_poses: np.ndarray
    profiles: tuple
    spheres: tuple = ()
    convention: str = "kuka"
    robot_sigma_mm: float = dataset.NOISE_ROBOT_MM
    skipped: tuple = ()
    profile_files: tuple = ()
    mounts: Mounts = Mounts()
    axis_angles: np.ndarray | None = None
    own_axes: np.ndarray | None = None  # [profile] own_axes: the profiles turned from the sensor's own frame

    @property
    def n_points(self):
        return int(sum(len(p) for p in self.profiles))

    def content_hash(self):
        """SHA-256 of the scan's files, as :meth:`handeye.model.datasets.dataset.Dataset.content_hash`
        (equal when the scan is a calibration's own dataset)."""
        return dataset.folder_hash(self.path, self.profile_files)


def _convention_from_header(header, file):
    found = tables.pose_list_convention([c for c in header if c not in ("profile", "xs", "ys", "zs")])
    if found is None:
        known = "; ".join(",".join(["id", *conventions.columns(c)]) + f" ({c})" for c in conventions.CONVENTIONS)
        raise DatasetError(file, f"header must hold id, a convention's pose columns and profile: {known}", 1)
    return found


def load(name_or_path):
    """Read and check a scan (module docstring); raises :class:`DatasetError` naming file, row
    and column."""
    folder = dataset.resolve(name_or_path)
    file = folder / "measurements.csv"
    table = tables.read_table(file)
    if not table:
        raise DatasetError(file, "empty file; needs a header such as id,x,y,z,a,b,c,profile", 1)
    header = [h.strip() for h in table[0]]
    for col in header:
        if header.count(col) > 1:
            raise DatasetError(file, "duplicate column", 1, col)
    if (folder / "setup.toml").exists():
        st = dataset.read_setup(folder, require_sphere=False)
        convention, limits, noise = st.convention, st.noise["limits"], st.noise
        if st.sphere2 is not None and st.diameter is None:
            raise DatasetError(folder / "setup.toml", "[sphere2] without [sphere]: name the first sphere [sphere]",
                               column="[sphere2]")
        spheres = [Sphere(st.diameter, st.centre)] if st.diameter is not None else []
        mounts, own_axes = st.mounts, st.own_axes
        if st.sphere2 is not None:
            spheres.append(Sphere(st.sphere2[0], st.sphere2[1]))
    else:
        convention = _convention_from_header(header, file)
        limits = {"position_mm": tables.LIMIT_POSITION_MM, "sensor_mm": dataset.LIMIT_SENSOR_MM}
        noise, spheres, mounts, own_axes = {}, [], Mounts(), None
    pose_columns = conventions.columns(convention)
    axes = mounts.axis_names
    for col in ("id",) + pose_columns + ("profile",) + axes:
        if col not in header:
            raise DatasetError(file, f"missing column (a scan needs id,{','.join(pose_columns)},profile for the "
                                     f"{convention} convention)", 1, col)
    for col in header:
        if col not in ("id",) + pose_columns + ("profile", "xs", "ys", "zs") + axes:
            raise DatasetError(file, f"unknown column (expected id,{','.join(pose_columns + axes)},profile)", 1, col)
    idx = {c: header.index(c) for c in header}
    ids, rows, poses, profiles, skipped, files, seen, angles = [], [], [], [], [], [], {}, []
    for line, fields in enumerate(table[1:], start=2):
        if not any(f.strip() for f in fields):
            continue
        if len(fields) != len(header):
            raise DatasetError(file, f"expected {len(header)} fields, got {len(fields)}", line)
        ident = tables.row_id(fields, idx["id"], seen, file, line)
        rel = fields[idx["profile"]].strip()
        if not rel:
            skipped.append(ident)
            continue
        pose = tables.read_pose(fields, idx, convention, file, line, limits["position_mm"])
        points = tables.read_points(folder, rel, file, line, limits["sensor_mm"], minimum=1)
        angles.append([dataset.axis_angle(fields[idx[a]], file, line, a) for a in axes])
        files.append((folder / rel).resolve())
        ids.append(ident)
        rows.append(line)
        poses.append(pose)
        profiles.append(points)
    if not ids:
        raise DatasetError(file, "no pose with a profile (the profile column names each pose's x,z file)", 2)
    return Scan(folder.name, folder, tuple(ids), tuple(rows), np.array(poses), tuple(profiles), tuple(spheres),
                convention, float(noise.get("robot_mm", dataset.NOISE_ROBOT_MM)), tuple(skipped),
                tuple(sorted(set(files))), mounts, np.array(angles, float).reshape(len(ids), len(axes)) if axes else None,
                own_axes)
