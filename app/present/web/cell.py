"""The cell a report draws: every sample's frames and points in the robot base.

Built from what a calibration's JSON object holds (``sensor_matrix``, ``sphere_center``, the mounts,
the positioner's axes) and the dataset it was made from (flange poses, measured centres, profiles):
the chain of :mod:`handeye.model.chain.mounts`, ``M_i . X . xs_i = c``, read in the robot base.

==============  ==========================================  ==========================================
mount           sensor frame in the base, sample i          sphere centre in the base, sample i
==============  ==========================================  ==========================================
seed's cell     ``flange2base_i . sensor2flange``           ``c`` (fixed)
sensor fixed    ``sensor2base`` (one frame)                 ``flange2base_i . c_flange``
positioner      ``flange2base_i . sensor2flange``           ``table2base(th_i) . c_table``
==============  ==========================================  ==========================================

The residual drawn is the measured centre through the chain minus the sphere centre, both in the
base (mm): for the seed's cell the result's own residual vector; for the other mounts the same
vector rotated into the base (same length). With catalogue effects the result's residuals are of
corrected centres; the view draws the plain chain, and says so.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from handeye.model.chain import own_frame
from handeye.model.chain.mounts import Mounts, sphere_in_base

#: At most this many profile points per sample are drawn (evenly spaced): the view of a cell with
#: dense profiles stays light; every point still counts in the fit.
MAX_PROFILE_POINTS = 48


@dataclasses.dataclass(frozen=True)
class CellGeometry:
    """Every sample's frames and points in the robot base (mm).

    Attributes
    ----------
    ids : list of str, length N
    used : ndarray of bool, shape (N,)
        False for a sample the calibration excluded.
    flange2base, sensor2base : ndarray, shape (N, 4, 4)
        Flange and sensor frames in the robot base (mm).
    measured : ndarray, shape (N, 3)
        Each sample's measured sphere centre through the calibrated chain, robot base, mm.
    sphere : ndarray, shape (N, 3)
        The sphere centre at each sample (fixed, carried by the flange, or by the positioner), mm.
    residual_base : ndarray, shape (N, 3)
        ``measured - sphere``, robot base, mm.
    residual_sensor : ndarray, shape (N, 3)
        The same vector in each sample's sensor frame (x along the laser line, z the stand-off; the
        sensor's own frame, as ``sensor2base``, where the profiles were turned: ``own_axes``), mm.
    fans : ndarray, shape (N, 3, 3)
        The laser fan of each sample as a triangle: the sensor origin and the two ends of the arc
        it measured (or of the sphere's width at the measured centre), robot base, mm.
    profiles : list of ndarray, shape (K_i, 3)
        Each sample's (cleaned) profile points in the robot base, thinned to
        :data:`MAX_PROFILE_POINTS`; empty arrays without profiles.
    radius : float
        Sphere radius, mm.
    mounts : handeye.model.chain.mounts.Mounts
        The mounts, with the positioner's axes the result used.
    """

    ids: list
    used: np.ndarray
    flange2base: np.ndarray
    sensor2base: np.ndarray
    measured: np.ndarray
    sphere: np.ndarray
    residual_base: np.ndarray
    residual_sensor: np.ndarray
    fans: np.ndarray
    profiles: list
    radius: float
    mounts: Mounts

    @property
    def extent(self):
        """Size of the cell, mm: the largest side of the box around flanges, sensors and sphere."""
        pts = np.vstack([self.flange2base[:, :3, 3], self.sensor2base[:, :3, 3], self.sphere[self.used], np.zeros((1, 3))])
        return float(np.ptp(pts, axis=0).max()) or 1.0

    def to_dict(self):
        """JSON-ready numbers (rounded to 1 um / 1e-6): what the page's script draws and links."""
        def r(a):
            return np.round(np.asarray(a, float), 6).tolist()

        return {"ids": list(self.ids), "used": [bool(u) for u in self.used], "radius_mm": float(self.radius),
                "flange2base": r(self.flange2base), "sensor2base": r(self.sensor2base), "measured": r(self.measured),
                "sphere": r(self.sphere), "residual_base": r(self.residual_base),
                "residual_sensor": r(self.residual_sensor),
                "sensor_mount": self.mounts.sensor, "sphere_mount": self.mounts.sphere,
                "axes": [a.to_dict() for a in self.mounts.axes]}


def result_mounts(result, dataset):
    """The dataset's mounts at the positioner axes the result calibrated (its JSON ``positioner``
    entries with ``calibrated``), else as set up."""
    mounts = dataset.mounts
    entries = result.get("positioner") or []
    if mounts.axes and entries and all(e.get("calibrated") for e in entries):
        mounts = mounts.with_axes([e["point"] for e in entries], [e["direction"] for e in entries])
    return mounts


def cell_geometry(result, dataset):
    """The cell of ``result`` (a calibration's JSON object) on ``dataset``, as :class:`CellGeometry`.

    Parameters
    ----------
    result : dict
        ``handeye calibrate --json``'s object: ``sensor_matrix`` (4x4, mm, the sensor in its mount's
        frame), ``sphere_center`` (mm, in its mount's frame), ``residuals`` (``used`` per sample).
    dataset : handeye.model.datasets.dataset.Dataset
        The dataset the result was made from (same ids, in order).
    """
    mounts = result_mounts(result, dataset)
    f2b = np.asarray(dataset.flange2base(), float)
    x = np.asarray(result["sensor_matrix"], float)
    if result.get("sensor_frame") == "own":  # the sensor's own frame, as the user reads it: the chain is handeye's
        x = own_frame.to_internal(x, result["own_axes"])
    s2b = np.broadcast_to(x, f2b.shape).copy() if mounts.sensor == "world" else f2b @ x
    xs = np.asarray(dataset.centre_in_sensor, float)
    measured = np.einsum("nij,nj->ni", s2b[:, :3, :3], xs) + s2b[:, :3, 3]
    sphere = sphere_in_base(mounts, result["sphere_center"], f2b, dataset.axis_angles)
    e_base = measured - sphere
    e_sensor = np.einsum("nji,nj->ni", s2b[:, :3, :3], e_base)
    radius = _drawn_radius(dataset)
    local = [_thinned(p) for p in dataset.profiles or (None,) * len(xs)]
    profiles = [_to_base(s2b[i], p) for i, p in enumerate(local)]
    fans = np.stack([_fan(s2b[i], local[i], xs[i], radius) for i in range(len(xs))])
    if result.get("sensor_frame") == "own":  # drawn and tabled in the frame the user reads: the sensor's own
        rot = np.asarray(result["own_axes"], float)
        s2b, e_sensor = s2b @ own_frame.to_own(np.eye(4), rot), e_sensor @ rot
    return CellGeometry(list(dataset.ids), _used(result, dataset), f2b, s2b, measured, sphere, e_base, e_sensor, fans,
                        profiles, radius, mounts)


def _drawn_radius(dataset):
    """The sphere's radius drawn, mm: the stated one; without ``[sphere] diameter`` the mean of the radii fitted to the
    clouds, or 0 (a dataset of reported centres: the sphere drawn as its centre, no radius made up)."""
    if dataset.sphere_diameter is not None:
        return dataset.sphere_diameter / 2.0
    radii = [c.radius for c in getattr(dataset, "clouds", None) or () if c is not None]
    return float(np.mean(radii)) if radii else 0.0


def _used(result, dataset):
    rows = result.get("residuals") or []
    by_id = {r["id"]: bool(r["used"]) for r in rows if isinstance(r, dict) and "id" in r}
    return np.array([by_id.get(i, True) for i in dataset.ids], bool)


def _thinned(prof):
    """A sample's profile points in its sensor frame (K, 3), thinned; empty without a profile."""
    if prof is None or len(prof) == 0:
        return np.zeros((0, 3))
    prof = np.asarray(prof, float)
    keep = np.unique(np.linspace(0, len(prof) - 1, min(len(prof), MAX_PROFILE_POINTS)).round().astype(int))
    return np.column_stack([prof[keep, 0], np.zeros(len(keep)), prof[keep, 1]])


def _to_base(s2b, points):
    return points @ s2b[:3, :3].T + s2b[:3, 3] if len(points) else np.zeros((0, 3))


def _fan(s2b, points, xs, radius):
    """The laser fan of one sample: sensor origin and the arc's two ends (or the sphere's width)."""
    if len(points) >= 2:
        ends = points[[np.argmin(points[:, 0]), np.argmax(points[:, 0])]]
    else:  # the chord the laser plane (y = 0) cuts from the sphere, |y| = |ys| from its centre
        half = np.sqrt(max(radius**2 - xs[1] ** 2, 0.0))
        ends = np.array([[xs[0] - half, 0.0, xs[2]], [xs[0] + half, 0.0, xs[2]]])
    return _to_base(s2b, np.vstack([np.zeros(3), ends]))
