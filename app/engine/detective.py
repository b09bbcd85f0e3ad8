"""The convention detective: robot poses read the way the user may have meant them.

A flange pose is six or seven numbers, and every controller writes them differently: KUKA's
A, B, C are Z-Y'-X'' angles, FANUC's W, P, R the same rotation with the angles in the other
order, ABB's quaternion is w first while ROS writes it w last, UR's rotation vector is in
radians, and a tf lookup of "base in flange" gives the inverse of the flange in the base. A
dataset written in one convention and declared as another calibrates to an official-looking
answer with a residual of hundreds of millimetres.

When the plain fit is far worse than the stated noise (:func:`handeye.app.engine.slips.check`
decides that), :func:`candidates` re-reads the file's numbers (``Dataset.raw_poses``) in
every interpretation a user may have meant: the orientation columns as Euler angles of each
of the 12 axis sequences (intrinsic; the values in the file's order or reversed, which is the
extrinsic reading of the same sequence), in degrees or radians, or as a rotation vector
(radians or degrees); four columns as a quaternion w-first or w-last; each with the poses
as written or inverted, and the positions in mm or m. :func:`closed_form_rms` scores each by
the exact global minimum of the centre model (with the sphere centre known, one SVD per
candidate, all candidates at once: :mod:`handeye.model.fit.global_fit`), or by the linear closed
form with the centre free (the best few then by the reduced-form search). The caller names
the best when it fits clearly and significantly better than the data as declared.
"""
from __future__ import annotations

import dataclasses
import itertools

import numpy as np

from handeye.model.chain import conventions, mounts
from handeye.model.common.rotation import matrix_from_rotvec, nearest_rotation
from handeye.model.fit import global_fit

#: Position scales tried (mm per unit) and what they look like.
UNITS = conventions.LENGTH_UNITS  # the lengths a pose file is wrongly written in, by their factor to mm
#: Axis sequences of Euler angles (6 Tait-Bryan, 6 proper Euler).
SEQUENCES = ("xyz", "xzy", "yxz", "yzx", "zxy", "zyx", "xyx", "xzx", "yxy", "yzy", "zxz", "zyz")
#: With the centre free, this many of the best linear closed-form candidates are re-scored by
#: the global search of the centre model.
REFINE = 2



@dataclasses.dataclass(frozen=True)
class Reading:
    """One way of reading the file's pose numbers.

    Attributes
    ----------
    name : str
        What the numbers are under this reading, e.g. ``"FANUC W,P,R"``.
    convention : str or None
        The handeye convention that reads them so (then the fix is to declare it), else None.
    rotation : callable
        Orientation columns (N, k) -> rotation matrices (N, 3, 3).
    """

    name: str
    convention: str | None
    rotation: object


def _axis(axis, angles):
    """Rotations (N, 3, 3) by ``angles`` (N,, rad) about the basis vector ``axis`` ('x', 'y' or 'z')."""
    angles = np.asarray(angles, float)
    i = "xyz".index(axis)
    j, k = (i + 1) % 3, (i + 2) % 3
    out = np.zeros((len(angles), 3, 3))
    c, s = np.cos(angles), np.sin(angles)
    out[:, i, i] = 1.0
    out[:, j, j] = out[:, k, k] = c
    out[:, k, j], out[:, j, k] = s, -s
    return out


def _euler(sequence, reverse, radians):
    def rotation(values):
        v = values[:, ::-1] if reverse else values
        v = v if radians else np.radians(v)
        return _axis(sequence[0], v[:, 0]) @ _axis(sequence[1], v[:, 1]) @ _axis(sequence[2], v[:, 2])

    return rotation


def _known(sequence, reverse, radians):
    return ("fanuc" if reverse else "kuka") if sequence == "zyx" and not radians else None


def _euler_name(sequence, reverse, radians, columns):
    known = {"kuka": "KUKA A,B,C", "fanuc": "FANUC W,P,R"}.get(_known(sequence, reverse, radians))
    if known:  # (only in degrees)
        return known
    c = columns[::-1] if reverse else columns
    return (f"Euler angles {'-'.join(sequence.upper())} (intrinsic, R = R{sequence[0]}({c[0]}) R{sequence[1]}({c[1]}) "
            f"R{sequence[2]}({c[2]}), {'rad' if radians else 'deg'})")


def readings(k, columns):
    """Every reading of ``k`` orientation columns named ``columns`` (module docstring)."""
    if k == 4:
        return [Reading("a quaternion w,x,y,z (ABB)", "abb", lambda v: conventions.matrix_from("abb", v)),
                Reading("a quaternion x,y,z,w (w last, as ROS writes it)", None,
                        lambda v: conventions.matrix_from("abb", v[:, [3, 0, 1, 2]]))]
    out = [Reading("a UR rotation vector (rad)", "ur", lambda v: matrix_from_rotvec(v)),
           Reading("a rotation vector in degrees", None, lambda v: matrix_from_rotvec(np.radians(v)))]
    for sequence, reverse, radians in itertools.product(SEQUENCES, (False, True), (False, True)):
        out.append(Reading(_euler_name(sequence, reverse, radians, columns), _known(sequence, reverse, radians),
                           _euler(sequence, reverse, radians)))
    return out


@dataclasses.dataclass(frozen=True)
class Candidate:
    """The flange poses under one reading, inverted or not, in mm or m. ``flange2base`` holds the
    chain's carrier motions of those poses (:meth:`handeye.model.datasets.dataset.Dataset.motions`): the
    poses themselves for the seed's cell, through the mount otherwise, so every mount is scored by
    the same centre model."""

    reading: Reading
    inverted: bool
    scale: float
    flange2base: np.ndarray
    centre_scaled: bool = False
    robot_poses: np.ndarray | None = None  # the flange poses of this reading (N, 4, 4), robot base

    @property
    def unit(self):
        """The length unit the positions look written in (None: mm)."""
        return UNITS.get(self.scale)

    def describe(self):
        parts = [f"the orientation columns read as {self.reading.name}"]
        if self.inverted:
            parts.append("the poses inverted (the file holds the base in the flange)")
        if self.unit:
            parts.append(f"the positions in {self.unit}" + (" (the sphere centre too)" if self.centre_scaled else ""))
        return ", ".join(parts)


def _transforms(rot, pos, inverted):
    out = np.zeros((len(rot), 4, 4))
    out[:, 3, 3] = 1.0
    if inverted:
        rt = np.swapaxes(rot, 1, 2)
        out[:, :3, :3], out[:, :3, 3] = rt, -np.einsum("nab,nb->na", rt, pos)
    else:
        out[:, :3, :3], out[:, :3, 3] = rot, pos
    return out


def _chain(dataset, flange2base):
    """The carrier motions of a reading's flange poses in the dataset's cell (:mod:`handeye.model.chain.mounts`)."""
    if dataset.mounts.default:
        return flange2base
    with np.errstate(all="ignore"):
        return mounts.motions(flange2base, dataset.mounts, dataset.axis_angles)


def raw_poses(dataset):
    """The file's pose numbers (N, 3 + k) in the dataset's convention."""
    return (np.asarray(dataset.raw_poses, float) if dataset.raw_poses is not None
            else conventions.pose_from(dataset.convention, dataset.flange2base()))


def candidates(dataset):
    """Every other reading of the dataset's flange poses (the declared one left out)."""
    raw = raw_poses(dataset)
    columns = conventions.columns(dataset.convention)[3:]
    out = []
    for reading in readings(raw.shape[1] - 3, columns):
        with np.errstate(all="ignore"):
            rot = reading.rotation(raw[:, 3:])
        if not np.all(np.isfinite(rot)):
            continue
        for inverted, scale in itertools.product((False, True), (1.0, *UNITS)):
            if reading.convention == dataset.convention and not inverted and scale in (1.0, 1000.0):
                continue  # as declared (metres alone is handeye.app.engine.slips' own candidate)
            robot = _transforms(rot, raw[:, :3] * scale, inverted)
            poses = _chain(dataset, robot)
            out.append(Candidate(reading, inverted, scale, poses, robot_poses=robot))
            if scale != 1.0 and dataset.sphere_centre is not None:
                out.append(Candidate(reading, inverted, scale, poses, centre_scaled=True, robot_poses=robot))
    return out


def closed_form_rms(flange2base, centre_in_sensor, sphere_centre=None):
    """RMS (mm, of |e_i|) of the centre model's closed-form fit of stacks of flange poses.

    Parameters
    ----------
    flange2base : ndarray, shape (C, N, 4, 4)
        C candidate readings of N flange poses (flange in base, mm).
    centre_in_sensor : ndarray, shape (N, 3)
        mm, sensor frame.
    sphere_centre : ndarray, shape (3,) or (C, 3), optional
        Base, mm (one for all candidates or one each). Given: the exact global minimum (one
        SVD per candidate). None: the linear
        closed form's fit (an upper bound of the minimum; inf where it is undetermined).
    """
    f2b = np.asarray(flange2base, float)
    p = np.asarray(centre_in_sensor, float)
    n = p.shape[0]
    if sphere_centre is None:
        return _linear_rms(f2b, p)
    c = np.asarray(sphere_centre, float).reshape(-1, 1, 3)  # one centre, or one per candidate
    q = np.einsum("cnba,cnb->cna", f2b[..., :3, :3], c - f2b[..., :3, 3])
    pc, qc = p - p.mean(axis=0), q - q.mean(axis=1, keepdims=True)
    h = np.einsum("cni,nj->cij", qc, pc)
    u, s, vt = np.linalg.svd(h)
    d = np.sign(np.linalg.det(u @ vt))
    trace = s[:, 0] + s[:, 1] + d * s[:, 2]
    ssr = np.sum(pc * pc) + np.sum(qc * qc, axis=(1, 2)) - 2 * trace
    return np.sqrt(np.maximum(ssr, 0.0) / n)


def _linear_rms(f2b, p):
    """RMS (mm) of the linear closed form (:mod:`handeye.model.fit.closed_form`) with the centre
    free, for every candidate at once: normal equations of ``(vec R, t, c)``, the rotation
    block projected onto SO(3), ``(t, c)`` re-solved; inf where the system is singular."""
    c_n, n = f2b.shape[0], p.shape[0]
    rot, t = f2b[..., :3, :3], f2b[..., :3, 3]
    eye = np.broadcast_to(-np.eye(3), (c_n, n, 3, 3))
    a = np.concatenate([(rot[..., None] * p[None, :, None, None, :]).reshape(c_n, n, 3, 9), rot, eye], axis=3)
    a = a.reshape(c_n, 3 * n, 15)
    at = np.swapaxes(a, 1, 2)
    ata = at @ a
    atb = (at @ -t.reshape(c_n, 3 * n, 1))[..., 0]
    sv = np.linalg.svd(ata, compute_uv=False)
    ok = sv[:, -1] > 1e-12 * sv[:, 0]
    sol = np.linalg.solve(np.where(ok[:, None, None], ata, np.eye(15)), atb[..., None])[..., 0]
    r_x = nearest_rotation(sol[:, :9].reshape(c_n, 3, 3))
    lhs = np.concatenate([rot, eye], axis=3).reshape(c_n, 3 * n, 6)
    in_flange = p @ np.swapaxes(r_x, 1, 2)  # (C, N, 3): R_X p_i
    rhs = (-t - (rot @ in_flange[..., None])[..., 0]).reshape(c_n, 3 * n, 1)
    lt = np.swapaxes(lhs, 1, 2)
    normal = lt @ lhs  # singular when every rotation turns about one axis (t, c free along it)
    sv = np.linalg.svd(normal, compute_uv=False)
    ok &= sv[:, -1] > 1e-12 * sv[:, 0]
    tc = np.linalg.solve(np.where(ok[:, None, None], normal, np.eye(6)), lt @ rhs)
    e = lhs @ tc - rhs
    rms = np.sqrt(np.sum(e[..., 0] ** 2, axis=1) / n)
    return np.where(ok, rms, np.inf)


#: Above this many measurements the readings are compared on this many rows, evenly spread
#: (a convention slip moves every row; every reading's poses at once would need 700 copies of
#: the flange poses: 18 GB at 200,000 rows), and the best one is scored again on every row.
SCREEN_ROWS = 2000


def best(dataset, unknowns):
    """The best other reading and its RMS (mm) over every row, or None: ``(Candidate, rms)``."""
    if len(dataset) <= SCREEN_ROWS:
        return _best(dataset, unknowns)
    keep = np.zeros(len(dataset), bool)
    keep[np.linspace(0, len(dataset) - 1, SCREEN_ROWS).round().astype(int)] = True
    found = _best(dataset.subset(keep), unknowns)
    if found is None:
        return None
    cand = found[0]
    raw = raw_poses(dataset)
    with np.errstate(all="ignore"):
        robot = _transforms(cand.reading.rotation(raw[:, 3:]), raw[:, :3] * cand.scale, cand.inverted)
    poses = _chain(dataset, robot)
    cand = dataclasses.replace(cand, flange2base=poses, robot_poses=robot)
    centre = None if unknowns == "sensor+sphere" else dataset.sphere_centre * (cand.scale if cand.centre_scaled else 1.0)
    if centre is None:
        try:
            minima = global_fit.centre_minima(poses, dataset.centre_in_sensor, None)
        except global_fit.GlobalFitError:
            return None
        return cand, float(np.sqrt(2 * minima.best.cost / len(dataset)))
    return cand, float(closed_form_rms(poses[None], dataset.centre_in_sensor, centre[None])[0])


def _best(dataset, unknowns):
    found = candidates(dataset)
    if not found:
        return None
    centre = None if unknowns == "sensor+sphere" else dataset.sphere_centre
    if centre is None and unknowns == "sensor":
        return None
    stack = np.array([c.flange2base for c in found])
    if centre is not None:
        centre = np.array([centre * (c.scale if c.centre_scaled else 1.0) for c in found])
    rms = closed_form_rms(stack, dataset.centre_in_sensor, centre)
    if centre is None:  # the linear closed form is an upper bound: the best few searched exactly
        for k in np.argsort(rms)[:REFINE]:
            if np.isfinite(rms[k]):
                try:
                    minima = global_fit.centre_minima(found[k].flange2base, dataset.centre_in_sensor, None)
                except global_fit.GlobalFitError:
                    continue
                rms[k] = min(rms[k], np.sqrt(2 * minima.best.cost / len(dataset)))
    k = int(np.argmin(rms))
    ties = [j for j in range(len(found)) if rms[j] <= rms[k] * 1.01 + 1e-12]
    known = [j for j in ties if found[j].reading.convention is not None]  # a convention before an Euler order
    k = min(known or ties, key=lambda j: (found[j].inverted + (found[j].scale != 1.0), rms[j]))
    return found[k], float(rms[k])


def fix(candidate, dataset):
    """What the user should change, in words."""
    setup, measurements = dataset.path / "setup.toml", dataset.path / "measurements.csv"
    steps = []
    conv = candidate.reading.convention
    if conv is not None and conv != dataset.convention:
        cols = ",".join(conventions.columns(conv)[3:])
        steps.append(f'set convention = "{conv}" in {setup} and name the orientation columns of {measurements} '
                     f"{cols} (their values stay as they are; the poses in {setup.name} -- start_pose, base_pose, "
                     f"[truth] -- are then read as {conv} too: write them so)")
    elif conv is None:
        cols = ",".join(conventions.columns(dataset.convention)[3:])
        steps.append(f"convert the orientation columns of {measurements} from {candidate.reading.name} to "
                     f"{dataset.convention} {cols} (handeye reads kuka, fanuc, abb and ur; see model/chain/conventions.py)")
    if candidate.inverted:
        steps.append("write the flange in the robot base (the inverse of each pose: the file holds the base in the "
                     "flange, as a tf lookup of base in flange gives it)" + (
                         " -- unless the sensor is fixed in the cell and the robot carries the sphere: then the poses "
                         f'are right, and {setup} needs [sensor] mount = "world" and [sphere] mount = "flange" (the same '
                         "data fit either way: only you know which cell it is)" if dataset.mounts.default else ""))
    if candidate.unit:
        steps.append(f"write the positions{' and the [sphere] center' if candidate.centre_scaled else ''} in "
                     f"millimetres (x {candidate.scale:g}: they look like {candidate.unit})")
    return "; ".join(steps)
