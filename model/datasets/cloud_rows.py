"""Rows of ``measurements.csv`` whose sphere centre is fitted to the row's own point cloud (``cloud`` column).

A 3-D sensor (a structured-light camera, a 3-D scanner) gives a cloud of the sphere's surface per
pose: a CSV with header ``x,y,z`` (sensor frame, mm) named in the row's ``cloud`` column. On load
the sphere is fitted to it (:func:`handeye.model.geometry.sphere_cloud.fit_cloud`: cleaned as a
profile is, the radius held at ``[sphere] diameter`` / 2 when the setup gives one, else free), and
the row's centre is the fitted one, its covariance (sensor frame, mm^2) the fit's: the calibration
weighs the row by it (:func:`handeye.model.datasets.observations.profile_covariance`). A cloud that
is no sphere stops the load naming its file and row (:class:`~handeye.model.readers.tables.DatasetError`).

Clouds are kept apart from profiles: a profile is 2-D, ``x,z`` of the laser plane, its centre rebuilt
with ``[profile] side``; a cloud is 3-D and needs no side. A row names one of them, never both, and
gives no ``xs, ys, zs`` beside a cloud (the fit is the centre).
"""
from __future__ import annotations

import numpy as np

from handeye.model.geometry import sphere_cloud
from handeye.model.readers.tables import DatasetError, read_cloud


def row_cloud(reader, line, cells, rel):
    """``(centre [3 floats], CloudFit)`` of one row's cloud.

    Parameters
    ----------
    reader : handeye.model.datasets.dataset._RowReader
        The dataset's folder, ``measurements.csv``, setup and limits.
    line : int
        The row's line in ``measurements.csv``.
    cells : list of str
        The row's ``xs, ys, zs`` cells (must be empty).
    rel : str
        The ``cloud`` cell: the cloud's path, relative to the folder.
    """
    if any(cells):
        raise DatasetError(reader.file, "a row with a cloud gives no xs, ys, zs: its centre is the sphere fitted to the cloud",
                           line, "xs")
    if "profile" in reader.idx and "cloud" in reader.idx:
        raise DatasetError(reader.file, "a row names a profile or a cloud, not both", line, "cloud")
    points = read_cloud(reader.folder, rel, reader.file, line, reader.limits["sensor_mm"])
    diameter = reader.st.diameter
    try:
        fit = sphere_cloud.fit_cloud(points, None if diameter is None else diameter / 2)
    except sphere_cloud.CloudError as exc:
        raise DatasetError(reader.folder / rel, f"no sphere in the cloud of row {line} of measurements.csv: {exc}") from None
    return [float(v) for v in fit.centre], fit


def covariances(fits):
    """``(N, 3, 3)`` covariance of each row's centre from its cloud's fit (sensor frame, mm^2; zero where a
    row has no cloud), or None when no row has one."""
    if all(f is None for f in fits):
        return None
    out = np.zeros((len(fits), 3, 3))
    for k, f in enumerate(fits):
        if f is not None:
            out[k] = f.covariance
    out.setflags(write=False)
    return out


def needs_diameter(reader, line):
    """A DatasetError naming ``[sphere] diameter`` for a row with a profile (its centre is rebuilt from the
    sphere's radius, the profile cleaned against it) when the setup gives none: nothing else needs it on load."""
    if reader.st.diameter is None:
        raise DatasetError(reader.folder / "setup.toml", f"needed: row {line} of measurements.csv has a profile, whose "
                                                         "centre is rebuilt from the sphere's radius (a dataset of "
                                                         "centres or clouds needs none)", column="[sphere] diameter")
