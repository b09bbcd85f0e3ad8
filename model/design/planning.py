"""Which poses to measure: D-optimal selection from a candidate set.

Each candidate flange pose i contributes a Fisher information F_i (:func:`handeye.model.design.bounds.information`,
for the nominal setup and the simulator's noise model). A set S of poses gives the covariance
bound ``(sum_{i in S} F_i)^-1``; D-optimality maximises ``log det sum_{i in S} F_i``, i.e. shrinks
the volume of the confidence ellipsoid. The selection is greedy (each step adds the pose
that raises log det most; by the matrix determinant lemma that is the pose with the largest
``log det(I + F_i M^-1)``) followed by Fedorov exchanges (swap a chosen and an unchosen pose
while log det rises).

For a sphere on a positioner the set must also determine the positioner's axes: there F_i is the
information of the whole cell (sensor, sphere centre, four parameters per axis:
:func:`cell_information`, the centre model with the stated centre noise), so the plan chooses
poses *and* axis angles that separate the axes from the sensor and the centre.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from handeye.model.chain.mounts import motions, table2base
from handeye.model.chain.pose import pose_from_transform, transform_from_pose
from handeye.model.common.errors import InputError
from handeye.model.design import bounds
from handeye.model.simulation import simulate


class PlanningError(InputError):
    """A pose plan that cannot be made (fewer usable candidates than poses asked for)."""


def logdet(m):
    """log det of a symmetric matrix (..., p, p); -inf where it is not positive definite."""
    sign, value = np.linalg.slogdet(m)
    return np.where(sign > 0, value, -np.inf) if np.ndim(value) else (value if sign > 0 else -np.inf)


def select(info, n, exchange=True, ridge=1e-9):
    """Indices of ``n`` candidates maximising ``log det sum F_i``.

    Parameters
    ----------
    info : ndarray, shape (N, p, p)
    n : int
    """
    info = np.asarray(info, float)
    total = len(info)
    if not 1 <= n <= total:
        raise PlanningError(f"cannot choose {n} poses from {total} candidates")
    p = info.shape[1]
    scale = np.trace(info.sum(axis=0)) / p
    base = ridge * scale * np.eye(p)
    chosen = []
    m = base.copy()
    for _ in range(n):
        gains = logdet(m + info)  # every candidate at once; the chosen ones left out
        gains[chosen] = -np.inf
        best = int(np.argmax(gains))
        chosen.append(best)
        m = m + info[best]
    improved = exchange
    while improved:
        improved = False
        current = logdet(m)
        for a in list(chosen):
            others = np.setdiff1d(np.arange(total), chosen)
            trials = (m - info[a]) + info[others]
            better = np.flatnonzero(logdet(trials) > current + 1e-12)
            if len(better):  # the first unchosen candidate that raises log det replaces a
                chosen[chosen.index(a)] = int(others[better[0]])
                m = trials[better[0]]
                current, improved = logdet(m), True
    return sorted(chosen), float(logdet(m - base))


def predicted_sd(info):
    """Bound on the standard deviations (mm, deg) of a set with total information ``info`` (p, p)."""
    sd = np.sqrt(np.diag(np.linalg.inv(info)))
    sd[3:6] = np.degrees(sd[3:6])
    return sd


#: Cut distances of the candidates (|y| of the sphere centre in the laser plane) as fractions of
#: the sphere radius: the thesis's 5, 15 and 25 mm of a 30 mm radius.
CUT_FRACTIONS = (1 / 6, 1 / 2, 5 / 6)


def view_window(setup, margin_mm=0.0, margin_deg=0.0):
    """Where the sphere centre may be put in the sensor frame so that it is still seen when the
    nominal sensor pose is off by up to ``margin_mm`` and ``margin_deg``.

    Such an error moves the centre, in the sensor frame, by at most
    ``shift = margin_mm + radians(margin_deg) * z_max`` (mm). The window keeps the laser plane
    cutting the sphere between 0.1 R and 0.9 R from its centre, the sphere within the laser
    line, and its centre at least max(25 mm, 0.8 R) inside the measuring range (so that most of
    the profile is measured), each with ``shift`` to spare.

    Returns
    -------
    dict
        ``cuts`` (|y| values, mm, the :data:`CUT_FRACTIONS` of R clipped into the window), ``x``
        and ``z`` (ranges, mm), ``shift`` (mm).

    Raises
    ------
    PlanningError
        When the margin leaves no room on this sphere.
    """
    radius = setup.diameter / 2
    z_lo, z_hi = setup.z_range
    shift = float(margin_mm + np.radians(margin_deg) * z_hi)
    y_lo, y_hi = 0.1 * radius + shift, 0.9 * radius - shift
    x_half = min(10.0, setup.line_length / 2 - radius - shift)
    z_window = (max(z_lo + 25.0, z_lo + 0.8 * radius) + shift, z_hi - 25.0 - shift)
    if y_lo > y_hi or x_half < 0 or z_window[0] > z_window[1]:
        raise PlanningError(
            f"a margin of {margin_mm:g} mm and {margin_deg:g} deg moves the sphere by up to {shift:.1f} mm in the sensor "
            f"frame: more than a {setup.diameter:g} mm sphere and the {z_lo:g}-{z_hi:g} mm range leave room for")
    cuts = np.clip(np.array(CUT_FRACTIONS) * radius, y_lo, y_hi)
    return {"cuts": np.unique(np.round(cuts, 9)), "x": (-x_half, x_half), "z": z_window, "shift": shift}


def thesis_candidates(setup, sphere_centre, seed=0, margin_mm=0.0, margin_deg=0.0, cuts=None):
    """Candidate flange poses: the thesis strategy's 36 orientations (tilted up to
    ``setup.max_tilt_deg``) x sphere placements whose laser plane cuts the sphere at the cut
    distances of :func:`view_window` (scaled to the sphere, kept inside the margin), or at
    ``cuts`` (mm) when given."""
    rng = np.random.default_rng(seed)
    window = view_window(setup, margin_mm, margin_deg)
    if cuts is not None:
        window["cuts"] = np.asarray(cuts, float)
    t_x = transform_from_pose(setup.sensor_pose)
    ids, poses = [], []
    for name, rot, seen_at in _placements(setup, window, rng):
        sensor = np.eye(4)
        sensor[:3, :3] = rot
        sensor[:3, 3] = np.asarray(sphere_centre, float) - rot @ seen_at
        ids.append(name if name not in ids else f"{name}#{sum(i.startswith(name) for i in ids) + 1}")
        poses.append(pose_from_transform(sensor @ np.linalg.inv(t_x)))
    return ids, np.array(poses)


def _placements(setup, window, rng):
    """``(id, sensor rotation, sphere centre in the sensor frame)`` of each thesis orientation (tilted up to
    ``setup.max_tilt_deg``) x cut of the :func:`view_window` ``window``; x and z drawn from ``rng`` in turn."""
    for ident, rot in simulate.thesis_orientations(36, setup.max_tilt_deg):
        for cut in window["cuts"]:
            yield f"{ident}@{cut:.3g}", rot, np.array([rng.uniform(*window["x"]), setup.side * cut, rng.uniform(*window["z"])])


def cell_candidates(setup, mounts, sphere_centre, seed=0, margin_mm=0.0, margin_deg=0.0):
    """Candidates of a cell other than the seed's (:mod:`handeye.model.chain.mounts`), made as the
    simulator makes its poses (:func:`handeye.model.simulation.simulate_mounts.flanges_for_cell`): the thesis
    orientations (the sensor's, or the flange's for a sensor fixed in the cell) x the cuts of
    :func:`view_window`; on a positioner each with axis angles drawn as the simulator draws them.

    Parameters
    ----------
    setup : handeye.model.simulation.simulate.Setup
        Nominal sensor pose in its mount's frame.
    mounts : handeye.model.chain.mounts.Mounts
        With the nominal axes.
    sphere_centre : array_like, shape (3,)
        Nominal centre in its mount's frame, mm.

    Returns
    -------
    ids : list of str
    poses : ndarray, shape (N, 6)
        Flange poses, KUKA (mm, degrees).
    angles : ndarray, shape (N, k), or None
        Positioner axis angles, degrees.
    """
    from handeye.model.simulation import simulate_mounts

    rng = np.random.default_rng(seed)
    ids, rots, seen = (list(column) for column in zip(*_placements(setup, view_window(setup, margin_mm, margin_deg), rng)))
    angles = None
    if mounts.sphere == "positioner":
        angles = simulate_mounts.draw_axis_angles(len(ids), len(mounts.axes), rng)
    flanges = simulate_mounts.flanges_for_cell(mounts, setup, np.array(rots), np.array(seen), sphere_centre, angles)
    return ids, pose_from_transform(flanges), angles


def carrier_poses(flange_poses, mounts=None, angles=None):
    """KUKA poses (N, 6) of the carrier motions ``M_i`` (:func:`handeye.model.chain.mounts.motions`): what
    :func:`handeye.model.design.bounds.information` takes as flange poses, for any mount."""
    if mounts is None or mounts.default:
        return np.asarray(flange_poses, float)

    return pose_from_transform(motions(transform_from_pose(np.asarray(flange_poses, float)), mounts, angles))


def few_angles(angles, names, least=3):
    """Warnings for positioner axes that take fewer than ``least`` distinct angles in a plan."""
    if angles is None:
        return []
    return [f"axis {name} takes only {len(np.unique(np.round(col, 6)))} distinct angle(s) in these poses: "
            f"calibrating the positioner needs at least {least}" for name, col in zip(names, np.asarray(angles).T)
            if len(np.unique(np.round(col, 6))) < least]


def in_workspace(flange_poses, workspace):
    """Which flange positions lie in ``workspace`` = (xmin, xmax, ymin, ymax, zmin, zmax), mm, base."""
    w = np.asarray(workspace, float).reshape(3, 2)
    pos = np.asarray(flange_poses, float)[:, :3]
    return np.all((pos >= w[:, 0]) & (pos <= w[:, 1]), axis=1)


#: Per-component sd of a sphere centre (mm) of the positioner cell's information (the default
#: ``[noise] centre_mm``).
CELL_SIGMA_MM = 0.05


def cell_information(flange_poses, angles, setup, sphere_centre, mounts, sigma=CELL_SIGMA_MM):
    """Fisher information (N, 9 + 4k, 9 + 4k) of each pose of a positioner cell on the chart of
    :class:`handeye.model.fit.cell.CellModel` (sensor mm and rad, centre mm, per axis two tilts (rad)
    and two shifts (mm)): the centre residual at the nominal cell, isotropic sd ``sigma`` (mm).

    Parameters
    ----------
    flange_poses : array_like, shape (N, 6)
        KUKA, robot base.
    angles : array_like, shape (N, k)
        Axis angles, degrees.
    setup : handeye.model.simulation.simulate.Setup
        Its ``sensor_pose`` is the nominal sensor on the flange.
    sphere_centre : array_like, shape (3,)
        Table frame (= base at zero angles), mm.
    mounts : handeye.model.chain.mounts.Mounts
        With the nominal axes.
    """
    from handeye.model.fit.cell import CellModel, pack

    f2b = transform_from_pose(np.asarray(flange_poses, float))
    sensor = transform_from_pose(setup.sensor_pose)
    centre = np.asarray(sphere_centre, float)
    in_base = table2base(mounts.axes, angles) @ np.append(centre, 1.0)
    xs = np.linalg.solve(f2b @ sensor, in_base[..., None])[:, :3, 0]
    model = CellModel(f2b, xs, np.asarray(angles, float).reshape(len(f2b), -1), mounts.axis_names)
    _, jac = model.evaluate(pack(sensor, centre, mounts.axes))
    return np.einsum("ikn,ikm->inm", jac, jac) / sigma**2


def _informations(flange_poses, setup, sphere_centre, mounts, angles):
    """Per-pose information: the sensor's (measurement model), or the whole positioner cell's."""
    carriers = carrier_poses(flange_poses, mounts, angles)
    sensor_info = bounds.information(carriers, setup, sphere_centre)  # also: each pose sees the sphere
    if mounts is None or mounts.sphere != "positioner":
        return sensor_info
    return cell_information(flange_poses, angles, setup, sphere_centre, mounts)


def score(flange_poses, setup, sphere_centre, mounts=None, angles=None):
    """Predicted 1-sd bounds (Cramer-Rao; mm, deg) of a given pose list, and its log det
    (``mounts`` and the axis ``angles``, degrees: :func:`carrier_poses`; on a positioner the
    whole cell's, :func:`cell_information`)."""
    info = _informations(flange_poses, setup, sphere_centre, mounts, angles).sum(axis=0)
    try:
        return predicted_sd(info), float(logdet(info))
    except np.linalg.LinAlgError:
        raise PlanningError("these poses do not determine the sensor pose (identical or only translated poses?)") \
            from None


@dataclasses.dataclass(frozen=True)
class Candidates:
    """Candidate flange poses: ``ids``; ``flange_poses`` (N, 6), KUKA (mm, degrees), robot base; the
    positioner's axis ``angles`` (N, k), degrees, or None; the robot's ``joints`` (N, 6), degrees, to use
    instead of the inverse kinematics' (a robot plan), or None."""

    ids: list
    flange_poses: object
    angles: object = None
    joints: object = None


@dataclasses.dataclass
class Plan:
    """A planned pose set with its predicted accuracy."""

    ids: list
    poses: np.ndarray
    logdet: float
    predicted_sd: np.ndarray
    skipped: list
    angles: np.ndarray | None = None


def plan(candidates, n, setup, sphere_centre, mounts=None):
    """Choose ``n`` of the :class:`Candidates` (D-optimal); candidates that cannot see the sphere are skipped.

    ``mounts`` (:class:`handeye.model.chain.mounts.Mounts`, nominal axes) and the candidates' axis
    angles (N, k), degrees, make the information of any mount (:func:`carrier_poses`);
    ``sphere_centre`` is then in its mount's frame.
    """
    candidate_ids, candidate_poses, angles = candidates.ids, candidates.flange_poses, candidates.angles
    infos, keep, skipped = [], [], []
    carriers = carrier_poses(candidate_poses, mounts, angles)
    for k, (ident, pose) in enumerate(zip(candidate_ids, carriers)):
        try:
            infos.append(bounds.information(pose[None], setup, sphere_centre)[0])
            keep.append(k)
        except simulate.SimulationError as exc:
            skipped.append((ident, str(exc)))
    if len(keep) < n:
        raise PlanningError(f"only {len(keep)} candidate poses see the sphere; cannot choose {n}")
    info = np.array(infos)
    if mounts is not None and mounts.sphere == "positioner":
        unknowns = 9 + 4 * len(mounts.axes)
        if 3 * n <= unknowns:
            raise PlanningError(f"a positioner cell has {unknowns} unknowns (sensor, sphere, axes): plan at least "
                                f"{unknowns // 3 + 1} poses")
        info = cell_information(np.asarray(candidate_poses)[keep], np.asarray(angles)[keep], setup, sphere_centre,
                                mounts)
    chosen, value = select(info, n)
    try:
        sd = predicted_sd(info[chosen].sum(axis=0))
    except np.linalg.LinAlgError:
        raise PlanningError(f"the {n} poses chosen do not determine the sensor pose (the candidates are too alike: "
                            "identical or only translated poses?)") from None
    idx = [keep[c] for c in chosen]
    return Plan([candidate_ids[i] for i in idx], np.asarray(candidate_poses)[idx], value, sd, skipped,
                None if angles is None else np.asarray(angles)[idx])
