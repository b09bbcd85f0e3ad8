"""The inputs of ``handeye dataset new`` read into poses and (x, z) profiles, before pairing.

:func:`read_profiles` reads ``--profiles`` files (every format of :mod:`handeye.app.ingest.clouds`),
drops NaN/inf rows, scales metres to mm and maps 3-column profiles into the laser plane
(:mod:`handeye.app.ingest.plane`); :func:`bag_profiles` does the same for a bag's clouds.
"""
from __future__ import annotations

import collections
import dataclasses

import numpy as np

from handeye.app.ingest import clouds, plane
from handeye.model.readers.tables import DatasetError


@dataclasses.dataclass
class Profile:
    """One profile before pairing.

    Attributes
    ----------
    label : str
        Its file (and key when the file holds several), for messages and provenance.
    name : str
        The text a pose id is searched in: the file's stem, or the key.
    file : pathlib.Path or None
    format : str
    points : ndarray, shape (K, 2 or 3)
        Finite points, mm, as the file has them (before the plane mapping).
    dropped : int
        Rows dropped for a NaN or infinite coordinate.
    xz : ndarray, shape (K, 2), or None
        handeye sensor (x, z), mm, after :func:`map_to_plane`.
    """

    label: str
    name: str
    file: object
    format: str
    points: np.ndarray
    dropped: int
    xz: np.ndarray | None = None


def read_profiles(files, units="mm"):
    """``(profiles, skipped)``: every profile of ``files``, the ``(file, listed)`` pairs of the
    ``--profiles`` arguments (:func:`handeye.app.ingest.request.expand`) in pairing order, and the
    files of a folder that are no profile (``[(file, why)]``: a folder may hold the pose file or a
    calibration report too; a file named or matched, ``listed``, is read or is an error)."""
    out, skipped = [], []
    for f, listed in files:
        try:
            fmt, matrices = clouds.read_profile_file(f)
            if not listed:
                for key, pts in matrices:
                    _profile(str(f), key, f, fmt, pts, units)  # a shape that is no profile: skipped too
        except DatasetError as exc:
            if listed:
                raise
            skipped.append((str(f), exc.problem))
            continue
        for key, pts in matrices:
            label, name = (f"{f}[{key}]", key) if len(matrices) > 1 else (str(f), f.stem)
            out.append(_profile(label, name, f, fmt, pts, units))
    if not out:  # named: a file that looked like a profile (a format read), not the first stray file
        file, why = next((s for s in skipped if not s[1].startswith(("unknown format", "not UTF-8"))), skipped[0])
        raise DatasetError(file, f"no profile in the --profiles folders ({len(skipped)} files skipped; this one: {why})")
    return out, skipped


def _profile(label, name, file, fmt, pts, units):
    pts = np.asarray(pts, float)
    if pts.ndim != 2 or pts.shape[1] not in (2, 3):
        raise DatasetError(label, f"shape {pts.shape}: a profile is K x 2 (x, z) or K x 3 (x, y, z)")
    finite, dropped = plane.finite_rows(pts)
    return Profile(label, name, file, fmt, finite * (1000.0 if units == "m" else 1.0), dropped)


def check_clouds(clouds):
    """Every file of ``--clouds`` holds a 3-D cloud: a 2-column file is a laser profile (x, z), named."""
    for c in clouds:
        if c.points.shape[1] != 3:
            raise DatasetError(c.label, "2 columns (x, z): a laser profile, not a point cloud of the sphere (x, y, z); give "
                                        "profiles with --profiles")


def bag_profiles(clouds_mm, topic):
    """Profiles of a bag's clouds (K, 3), mm, named by their order on the topic."""
    return [_profile(f"{topic}[{k}]", str(k), None, "ROS 2 bag", pts, "mm") for k, pts in enumerate(clouds_mm, 1)]


def map_to_plane(profiles, diameter, axes=None, units_option="--profile-units"):
    """Fill each profile's ``xz``; the :class:`~handeye.app.ingest.plane.PlaneMapping` of them all
    (:func:`handeye.app.ingest.plane.decide`). Fewer than 3 finite points is an error."""
    for p in profiles:
        if len(p.points) < 3:
            raise DatasetError(p.label, f"{len(p.points)} finite points (after {p.dropped} NaN/inf rows dropped): a "
                                        "circle needs at least 3")
    three = [p for p in profiles if p.points.shape[1] == 3]
    mapping = plane.decide([(p.label, p.points) for p in profiles], axes)
    if mapping.normal != "y" and len(three) != len(profiles):
        two = next(p for p in profiles if p.points.shape[1] == 2)
        raise DatasetError(two.label, f"2 columns (x, z), where {three[0].label}'s 3 columns lie in the plane "
                                      f"{mapping.normal} = 0: give all profiles alike")
    for p in profiles:
        p.xz = plane.to_xz(p.points, mapping)
        plane.check_scale(p.xz, diameter, p.label, units_option)
    return mapping


def formats(profiles):
    """Files per format found (a file holding several profiles counted once)."""
    seen = {}
    for p in profiles:
        seen.setdefault(p.file or p.label, p.format)
    return dict(collections.Counter(seen.values()))
