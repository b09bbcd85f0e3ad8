"""Which poses to measure: D-optimal selection from a candidate set.

Each candidate flange pose i contributes a Fisher information F_i (:func:`handeye.model.bounds.information`,
for the nominal setup and the simulator's noise model). A set S of poses gives the covariance
bound ``(sum_{i in S} F_i)^-1``; D-optimality maximises ``log det sum_{i in S} F_i``, i.e. shrinks
the volume of the confidence ellipsoid. The selection is greedy (each step adds the pose
that raises log det most; by the matrix determinant lemma that is the pose with the largest
``log det(I + F_i M^-1)``) followed by Fedorov exchanges (swap a chosen and an unchosen pose
while log det rises).
"""
from __future__ import annotations

import dataclasses

import numpy as np

from handeye.model import bounds, simulate
from handeye.model.errors import InputError
from handeye.model.pose import pose_from_transform, transform_from_pose


class PlanningError(InputError):
    """A pose plan that cannot be made (fewer usable candidates than poses asked for)."""


def logdet(m):
    sign, value = np.linalg.slogdet(m)
    return value if sign > 0 else -np.inf


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
        gains = [logdet(m + info[i]) if i not in chosen else -np.inf for i in range(total)]
        best = int(np.argmax(gains))
        chosen.append(best)
        m = m + info[best]
    if exchange:
        improved = True
        while improved:
            improved = False
            current = logdet(m)
            for a in list(chosen):
                for b in range(total):
                    if b in chosen:
                        continue
                    trial = m - info[a] + info[b]
                    if logdet(trial) > current + 1e-12:
                        chosen[chosen.index(a)] = b
                        m, current, improved = trial, logdet(trial), True
                        break
    return sorted(chosen), float(logdet(m - base))


def predicted_sd(info):
    """Bound on the standard deviations (mm, deg) of a set with total information ``info`` (p, p)."""
    sd = np.sqrt(np.diag(np.linalg.inv(info)))
    sd[3:6] = np.degrees(sd[3:6])
    return sd


def thesis_candidates(setup, sphere_centre, cut_distances=(5.0, 15.0, 25.0), seed=0):
    """Candidate flange poses: the thesis strategy's 36 orientations x sphere placements whose
    laser plane cuts the sphere at each of ``cut_distances`` mm from its centre."""
    rng = np.random.default_rng(seed)
    t_x = transform_from_pose(setup.sensor_pose)
    ids, poses = [], []
    for ident, rot in simulate.thesis_orientations(36):
        for cut in cut_distances:
            seen_at = np.array([rng.uniform(-10, 10), setup.side * cut, rng.uniform(215, 265)])
            sensor = np.eye(4)
            sensor[:3, :3] = rot
            sensor[:3, 3] = np.asarray(sphere_centre, float) - rot @ seen_at
            ids.append(f"{ident}@{cut:g}")
            poses.append(pose_from_transform(sensor @ np.linalg.inv(t_x)))
    return ids, np.array(poses)


@dataclasses.dataclass
class Plan:
    """A planned pose set with its predicted accuracy."""

    ids: list
    poses: np.ndarray
    logdet: float
    predicted_sd: np.ndarray
    skipped: list


def plan(candidate_ids, candidate_poses, n, setup, sphere_centre):
    """Choose ``n`` of the candidates (D-optimal); candidates that cannot see the sphere are skipped."""
    infos, keep, skipped = [], [], []
    for k, (ident, pose) in enumerate(zip(candidate_ids, candidate_poses)):
        try:
            infos.append(bounds.information(pose[None], setup, sphere_centre)[0])
            keep.append(k)
        except simulate.SimulationError as exc:
            skipped.append((ident, str(exc)))
    if len(keep) < n:
        raise PlanningError(f"only {len(keep)} candidate poses see the sphere; cannot choose {n}")
    info = np.array(infos)
    chosen, value = select(info, n)
    idx = [keep[c] for c in chosen]
    return Plan([candidate_ids[i] for i in idx], np.asarray(candidate_poses)[idx], value,
                predicted_sd(info[chosen].sum(axis=0)), skipped)
