"""Profile points into handeye's sensor frame: NaN rows dropped, the laser plane's axes found.

handeye's sensor frame has the laser plane at y = 0, x along the line, z the measuring direction
(away from the sensor), y = z x x; a profile is (x, z) points. Three-column profiles must lie in a
coordinate plane through the origin: the axis with (near) zero spread is the plane's normal, and
becomes handeye's y; of the two in-plane axes the one with the larger mean distance from zero (the
stand-off) becomes z (for the plane y = 0: z), and x the other. z is then signed by the sphere:
the sensor sees the cap that faces it, so when most profiles' points lie on the +z side of their
circle's centre, z grows towards the sensor and is flipped (a half turn about x). Two-column
profiles are (x, z) of the plane y = 0, signed the same way. The result is a proper rotation
``R`` (``p_handeye = R p_file``); ``--profile-axes X,Z`` names the files' axes that are handeye's
x and z instead (``y,-x``), used as they are. The calibrated sensor frame is the turned one: the
file's frame on the flange is ``T_flange_sensor R``. ``--side`` is given in the files' frame (the
sign along their normal) and written in handeye's (:meth:`PlaneMapping.side`).
"""
from __future__ import annotations

import dataclasses

import numpy as np

from handeye.model.readers.tables import DatasetError

AXES = "xyz"
#: the normal's spread may be at most this fraction of the profile's size (plus 1e-9 mm)
PLANAR_TOLERANCE = 1e-4


@dataclasses.dataclass(frozen=True)
class PlaneMapping:
    """How 3-column profiles were mapped to handeye's (x, z).

    Attributes
    ----------
    rotation : ndarray, shape (3, 3)
        ``R``: handeye sensor coordinates = ``R`` @ file coordinates (a proper rotation).
    normal : str
        The file's axis normal to the laser plane (``'y'`` needs no rotation).
    x_from, z_from : str
        The file's (signed) axes that became handeye's x and z.
    """

    rotation: np.ndarray
    normal: str
    x_from: str
    z_from: str
    votes: tuple | None = None

    @property
    def identity(self):
        return bool(np.allclose(self.rotation, np.eye(3)))

    def side(self, side_in_file):
        """``[profile] side`` in handeye's frame of a side given in the files' frame (the sign of the
        sphere centre's coordinate along the laser plane's normal)."""
        return int(np.sign(self.rotation[1, AXES.index(self.normal)])) * int(side_in_file)

    def describe(self):
        why = (f" (the profiles' cap faced +{self.z_from.lstrip('-')} in {self.votes[0]} of {sum(self.votes)}: "
               "handeye's z runs away from the sensor)" if self.votes and self.z_from.startswith("-") else "")
        if self.identity:
            return "laser plane y = 0: points kept as (x, z)"
        return (f"laser plane {self.normal} = 0: handeye x = file {self.x_from}, y = file "
                f"{'-' if self.rotation[1, AXES.index(self.normal)] < 0 else ''}{self.normal}, z = file {self.z_from}"
                f"{why} (R = {self.rotation.astype(int).tolist()}, p_handeye = R p_file)")


def finite_rows(points):
    """``(points without a NaN or infinite coordinate, how many rows were dropped)``."""
    keep = np.all(np.isfinite(points), axis=1)
    return points[keep], int(np.count_nonzero(~keep))


def normal_axis(points, file):
    """The coordinate axis (0, 1, 2) with (near) zero spread and (near) zero mean; a profile
    that is not planar, or planar but tilted or off the origin, is a DatasetError naming the file."""
    spread = np.ptp(points, axis=0)
    size = float(np.max(spread)) if points.size else 0.0
    tol = PLANAR_TOLERANCE * size + 1e-9
    axis = int(np.argmin(spread))
    if spread[axis] <= tol:
        offset = float(np.mean(points[:, axis]))
        if abs(offset) > max(tol, 1e-6 * np.max(np.abs(points))):
            raise DatasetError(file, f"the profile lies in the plane {AXES[axis]} = {offset:.6g}, not {AXES[axis]} = 0: "
                                     "the laser plane must pass through the sensor frame's origin")
        return axis
    sv = np.linalg.svd(points - points.mean(axis=0), compute_uv=False) if len(points) >= 3 else np.ones(3)
    spreads = ", ".join(f"{a} {s:.3g}" for a, s in zip(AXES, spread))
    if sv[-1] <= PLANAR_TOLERANCE * sv[0]:
        raise DatasetError(file, f"the profile is planar but its plane is not a coordinate plane (spreads {spreads} mm): "
                                 "give the points in the sensor's own frame, laser plane y = 0")
    raise DatasetError(file, f"not a planar profile: no coordinate is constant (spreads {spreads} mm); a laser-line "
                             "profile lies in the laser plane")


def _normal(profiles):
    """The laser plane's normal (0, 1, 2) of 3-column profiles, one for all; y for 2-column ones."""
    normals = [(file, normal_axis(pts, file)) for file, pts in profiles if pts.shape[1] == 3]
    if not normals:
        return 1
    normal = normals[0][1]
    for file, n in normals:
        if n != normal:
            raise DatasetError(file, f"its laser plane is {AXES[n]} = 0, {normals[0][0]}'s is {AXES[normal]} = 0")
    return normal


def _in_plane(profiles, normal):
    """(x axis, depth axis) among the in-plane ones: x, z for the plane y = 0; otherwise the axis
    with the larger mean distance from zero is the depth (the sensor's stand-off)."""
    if normal == 1:
        return 0, 2
    inplane = [a for a in range(3) if a != normal]
    means = np.mean(np.concatenate([p for _, p in profiles if p.shape[1] == 3])[:, inplane], axis=0)
    az = inplane[int(np.argmax(np.abs(means)))]
    return (inplane[0] if az == inplane[1] else inplane[1]), az


def _rotation(ax, sx, az, sz):
    rot = np.zeros((3, 3))
    rot[0, ax], rot[2, az] = sx, sz
    rot[1] = np.cross(rot[2], rot[0])
    return rot


def cap_votes(xz_profiles):
    """(profiles whose points lie on the +z side of their circle's centre, on the -z side): the
    sensor sees the cap of the sphere that faces it, so a cap at larger z means that z grows
    towards the sensor. Circles by the algebraic (Kasa) fit; the median point decides (speckle
    aside); profiles that do not fit are not counted."""
    up = down = 0
    for xz in xz_profiles:
        if len(xz) < 3:
            continue
        x, z = xz[:, 0], xz[:, 1]
        a = np.column_stack([x, z, np.ones_like(x)])
        sol, _, rank, _ = np.linalg.lstsq(a, -(x**2 + z**2), rcond=None)
        if rank < 3:
            continue
        above = np.median(z) > -sol[1] / 2
        up, down = up + int(above), down + int(not above)
    return up, down


def decide(profiles, axes=None):
    """The :class:`PlaneMapping` of profiles ``[(label, points (K, 2) or (K, 3))]`` (module
    docstring): the plane's normal becomes handeye's y, the depth axis z, signed so that z runs
    away from the sensor (:func:`cap_votes`; 2-column profiles are (x, z) of the plane y = 0).
    ``axes`` (``--profile-axes``, as the files' ``((axis, sign), (axis, sign))`` of handeye's x and z)
    names them instead, as they are."""
    normal = _normal(profiles)
    votes = None
    if axes is not None:
        (ax, sx), (az, sz) = axes
        if len({ax, az, normal}) != 3:
            raise DatasetError(profiles[0][0], f"its laser plane is {AXES[normal]} = 0: --profile-axes must name the "
                                               "two in-plane axes")
    else:
        (ax, az), sx = _in_plane(profiles, normal), 1.0
        trial = _rotation(ax, sx, az, 1.0)
        votes = cap_votes([_turned(p, trial)[:, [0, 2]] for _, p in profiles])
        sz = -1.0 if votes[0] > votes[1] else 1.0
    name = {1.0: "", -1.0: "-"}
    return PlaneMapping(_rotation(ax, sx, az, sz), AXES[normal], name[sx] + AXES[ax], name[sz] + AXES[az], votes)


def _turned(points, rotation):
    """Points (K, 2: x, z of the plane y = 0, or K, 3) in handeye's frame."""
    p3 = points if points.shape[1] == 3 else np.column_stack([points[:, 0], np.zeros(len(points)), points[:, 1]])
    return p3 @ rotation.T


def to_xz(points, mapping):
    """(K, 2) handeye (x, z) of (K, 2) points (x, z of the plane y = 0) or (K, 3) points, through
    ``mapping``."""
    return _turned(points, mapping.rotation)[:, [0, 2]]


def check_scale(xz, diameter, file, units_option="--profile-units"):
    """Profile coordinates in mm plausible against the sphere's diameter (mm); ``xz`` has points
    (:func:`handeye.app.ingest.sources.map_to_plane` refuses fewer than 3)."""
    top = float(np.max(np.abs(xz)))
    if diameter is not None and diameter > 5 and top < 1.0:
        raise DatasetError(file, f"every coordinate is within +-{top:.3g}: metres, not mm? give {units_option} m")
