"""Profile points into handeye's sensor frame: NaN rows dropped, the laser plane's axes found.

handeye's sensor frame has the laser plane at y = 0, x along the line, z the measuring direction
(away from the sensor), y = z x x; a profile is (x, z) points. Two-column profiles are (x, z).
Three-column profiles must lie in a coordinate plane through the origin: the axis with (near)
zero spread is the plane's normal. When it is y the points are kept as they are; when it is
another axis (a LaserScan's points lie in z = 0) the points are turned by a proper rotation
``R`` (``p_handeye = R p_file``) that makes the normal handeye's y and the in-plane axis with the
larger mean distance from zero (the measuring direction) handeye's z, pointing away from the
sensor; ``--profile-axes X,Z`` names the two in-plane axes instead (``y,-x``). The calibrated
sensor frame is then the rotated one: the file's frame on the flange is ``T_flange_sensor R``.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from handeye.app.errors import RequestError
from handeye.model.tables import DatasetError

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

    @property
    def identity(self):
        return bool(np.allclose(self.rotation, np.eye(3)))

    def describe(self):
        if self.identity:
            return "laser plane y = 0: points kept as (x, z)"
        return (f"laser plane {self.normal} = 0: handeye x = file {self.x_from}, z = file {self.z_from} "
                f"(rotation R = {self.rotation.astype(int).tolist()}, p_handeye = R p_file)")


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
    centred = points - points.mean(axis=0)
    sv = np.linalg.svd(centred, compute_uv=False) if len(points) >= 3 else np.ones(3)
    spreads = ", ".join(f"{a} {s:.3g}" for a, s in zip(AXES, spread))
    if sv[-1] <= PLANAR_TOLERANCE * sv[0]:
        raise DatasetError(file, f"the profile is planar but its plane is not a coordinate plane (spreads {spreads} mm): "
                                 "give the points in the sensor's own frame, laser plane y = 0")
    raise DatasetError(file, f"not a planar profile: no coordinate is constant (spreads {spreads} mm); a laser-line "
                             "profile lies in the laser plane")


def _signed_axis(text):
    t = text.strip().lower()
    sign = -1.0 if t.startswith("-") else 1.0
    name = t.lstrip("+-")
    if name not in AXES:
        raise RequestError(f"--profile-axes: {text!r} is not x, y or z (with an optional sign)")
    return AXES.index(name), sign


def parse_axes(axes):
    """``--profile-axes 'y,-x'`` -> ((1, 1.0), (0, -1.0)): the file's axes (index, sign) that are
    handeye's x and z."""
    parts = str(axes).split(",")
    if len(parts) != 2:
        raise RequestError(f"--profile-axes takes two axes (handeye's x, z), got {axes!r}")
    (ax, sx), (az, sz) = (_signed_axis(p) for p in parts)
    if ax == az:
        raise RequestError(f"--profile-axes {axes}: two different axes")
    return (ax, sx), (az, sz)


def decide(profiles3, axes=None):
    """The :class:`PlaneMapping` of a set of 3-column profiles ``[(file, points)]``: one normal for
    all (else a DatasetError naming the first profile that differs). ``axes``: ``--profile-axes``."""
    normals = [(file, normal_axis(pts, file)) for file, pts in profiles3]
    normal = normals[0][1]
    for file, n in normals:
        if n != normal:
            raise DatasetError(file, f"its laser plane is {AXES[n]} = 0, {normals[0][0]}'s is {AXES[normal]} = 0")
    if axes is not None:
        (ax, sx), (az, sz) = parse_axes(axes)
        if len({ax, az, normal}) != 3:
            raise RequestError(f"--profile-axes {axes}: the two axes must be the in-plane ones (the normal is "
                               f"{AXES[normal]})")
    elif normal == 1:
        (ax, sx), (az, sz) = (0, 1.0), (2, 1.0)
    else:
        inplane = [a for a in range(3) if a != normal]
        allpts = np.concatenate([p for _, p in profiles3])
        means = np.mean(allpts[:, inplane], axis=0)
        az = inplane[int(np.argmax(np.abs(means)))]
        ax = inplane[0] if az == inplane[1] else inplane[1]
        sz, sx = (1.0 if means[inplane.index(az)] >= 0 else -1.0), 1.0
    rot = np.zeros((3, 3))
    rot[0, ax], rot[2, az] = sx, sz
    rot[1] = np.cross(rot[2], rot[0])
    name = {1.0: "", -1.0: "-"}
    return PlaneMapping(rot, AXES[normal], name[sx] + AXES[ax], name[sz] + AXES[az])


def to_xz(points, mapping):
    """(K, 2) handeye (x, z) of (K, 2) points (as they are) or (K, 3) points (through ``mapping``)."""
    if points.shape[1] == 2:
        return points
    turned = points @ mapping.rotation.T
    return turned[:, [0, 2]]


def check_scale(xz, diameter, file, units_option="--profile-units"):
    """Profile coordinates in mm plausible against the sphere's diameter (mm)."""
    if not len(xz):
        return
    top = float(np.max(np.abs(xz)))
    if diameter is not None and diameter > 5 and top < 1.0:
        raise DatasetError(file, f"every coordinate is within +-{top:.3g}: metres, not mm? give {units_option} m")
