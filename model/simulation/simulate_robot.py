"""A simulated robot with joints: inverse kinematics of a nominal model and hidden joint offsets.

``handeye simulate --robot MODEL`` (:mod:`handeye.model.robot.robots`) makes the simulator's flange
poses (those that see the sphere, :mod:`handeye.model.simulation.simulate`) into joint angles: the
controller is commanded the angles ``q`` that the NOMINAL model's inverse kinematics gives for
each wanted flange pose, and the dataset gets ``j1..j6`` (degrees) and ``[robot] model``.

Inverse kinematics
------------------
Damped least squares (Levenberg-Marquardt) on the 6-vector pose error -- position (mm) and the
rotation vector of ``R_wanted R(q)^T`` (degrees) -- with the chain's exact Jacobian
(:func:`handeye.model.robot.robots.offset_derivatives`), started from a per-robot seed that is elbow-up
with the flange looking down and the wrist not flipped (:data:`SEEDS`; joint 1 first turned
towards the target); only a pose that fails from there is tried again from the seed with joints 4
and 6, then joint 4 alone, half a turn round (the other wrist). A solution
counts when it reproduces the pose within :data:`TOL_MM` and :data:`TOL_DEG`; a pose none
reaches is dropped (``simulation.json``'s ``dropped``), as a real cell cannot go there either.
Angles are returned wrapped to (-180, 180] degrees. The models carry no joint limits, so none are
applied.

Hidden joint offsets
--------------------
``--effect joint_offsets=j2:0.05,j3:-0.03`` (degrees): the robot really goes to the nominal
``T(q + delta)`` (the sensor sees the sphere from there) while the controller reports ``T(q)``
and ``q`` -- the mastering error ``handeye diagnose`` names ``joint_offsets``
(:mod:`handeye.model.effects.joint_offsets`).

Workspace (documented defaults)
-------------------------------
The thesis's sphere centre lies too far out even for its KR 60 HA (a third of the 90-degree tilts
are beyond reach); with ``--robot`` and no ``--center`` the sphere is placed at :data:`CENTRES`
(robot base, mm), chosen on a grid so that the thesis strategy's 36 poses (sensor 210-270 mm from
the sphere, the thesis's sensor pose on the flange) are reached for every seed tried: in front of
the robot and to its right. The UR5e (850 mm reach) with the thesis's sensor 250 mm off its
flange still misses one or two of the 36 poses (dropped, as any unreachable pose).
"""
from __future__ import annotations

import dataclasses

import numpy as np

from handeye.model.common.rotation import rotvec_from_matrix, transform_distance
from handeye.model.robot import robot_errors, robots

#: Convergence of the inverse kinematics: position (mm) and rotation (degrees).
TOL_MM, TOL_DEG = 1e-6, 1e-6
#: Elbow-up seeds with the flange looking down and the wrist not flipped (degrees, reported angles).
SEEDS = {
    "kr60ha": (0.0, -90.0, 90.0, 0.0, 90.0, 0.0),
    "irb4600": (0.0, 0.0, 0.0, 0.0, 90.0, 0.0),
    "m20ia": (0.0, 0.0, 0.0, 0.0, -90.0, 0.0),
    "ur5e": (0.0, -90.0, 90.0, -90.0, -90.0, 0.0),
    "ur10e": (0.0, -90.0, 90.0, -90.0, -90.0, 0.0),
}
#: Default sphere centres with ``--robot`` (robot base, mm; module docstring).
CENTRES = {
    "kr60ha": (1300.0, -450.0, 900.0),
    "irb4600": (1300.0, -300.0, 800.0),
    "m20ia": (1100.0, -300.0, 300.0),
    "ur5e": (250.0, -200.0, 50.0),
    "ur10e": (600.0, -300.0, 100.0),
}


def _jacobian(model, q):
    """Flange poses (N, 4, 4) and the pose error's Jacobian (N, 6, 6): d(position mm, rotation deg)
    per degree of the reported joint angles ``q`` (N, 6)."""
    fk, dfk = robots.offset_derivatives(model, q, np.zeros(6))  # per degree of the chain's angles
    omega = dfk[:, :, :3, :3] @ np.swapaxes(fk[:, :3, :3], 1, 2)[:, None]  # [w]x per degree, base frame
    w = np.stack([omega[..., 2, 1], omega[..., 0, 2], omega[..., 1, 0]], -1)
    jac = np.concatenate([dfk[:, :, :3, 3], np.degrees(w)], -1)  # (N, chain joint, 6)
    return fk, np.swapaxes(jac, 1, 2) @ model.coupling


def pose_error(target, fk):
    """6-vector errors (N, 6): ``target - fk`` position (mm) and ``rotvec(R_t R^T)`` (degrees)."""
    rot = target[:, :3, :3] @ np.swapaxes(fk[:, :3, :3], 1, 2)
    return np.concatenate([target[:, :3, 3] - fk[:, :3, 3], np.degrees(rotvec_from_matrix(rot))], -1)


def _levenberg_marquardt(model, target, q, iterations=200):
    """Refine joint angles ``q`` (N, 6, degrees) towards flange poses ``target`` (N, 4, 4, mm);
    returns the angles and the final position (mm) and rotation (deg) errors (N,)."""
    lam = np.full(len(q), 1e-2)
    fk, jac = _jacobian(model, q)
    err = pose_error(target, fk)
    cost = np.einsum("ni,ni->n", err, err)
    for _ in range(iterations):
        jtj = np.swapaxes(jac, 1, 2) @ jac
        step = np.linalg.solve(jtj + lam[:, None, None] * np.eye(6), np.swapaxes(jac, 1, 2) @ err[..., None])[..., 0]
        step = np.clip(step, -20.0, 20.0)
        fk_new, jac_new = _jacobian(model, q + step)
        err_new = pose_error(target, fk_new)
        cost_new = np.einsum("ni,ni->n", err_new, err_new)
        better = cost_new < cost
        q = np.where(better[:, None], q + step, q)
        fk = np.where(better[:, None, None], fk_new, fk)
        jac = np.where(better[:, None, None], jac_new, jac)
        err = np.where(better[:, None], err_new, err)
        cost = np.where(better, cost_new, cost)
        lam = np.clip(np.where(better, lam / 3.0, lam * 4.0), 1e-12, 1e8)
        if np.all(cost < 1e-16):
            break
    return q, np.linalg.norm(err[:, :3], axis=1), np.linalg.norm(err[:, 3:], axis=1)


def _wrap(q):
    """Angles wrapped to (-180, 180] degrees."""
    return 180.0 - np.mod(180.0 - q, 360.0)


def seed_for(model_name, model, target):
    """Seeds (N, 6) of the inverse kinematics: the robot's :data:`SEEDS` entry (zeros but for a
    wrist turned down if unknown) with joint 1 turned towards each target's position (degrees)."""
    seed = np.array(SEEDS.get(model_name, (0.0,) * 6), float)
    home = model.flange2base(seed[None])[0, :3, 3]
    axis1 = (model.base[:3, :3] @ model.origins[0][:3, :3] @ model.axes[0])[2]
    turn = np.degrees(np.arctan2(target[:, 1, 3], target[:, 0, 3]) - np.arctan2(home[1], home[0]))
    out = np.tile(seed, (len(target), 1))
    out[:, 0] += _wrap(turn) * np.sign(axis1) / max(abs(model.coupling[0, 0]), 1e-12)
    return out


def inverse_kinematics(model, target, model_name=None):
    """Joint angles of flange poses by the nominal model (module docstring).

    Parameters
    ----------
    model : handeye.model.robot.robots.RobotModel
    target : ndarray, shape (N, 4, 4)
        Wanted flange poses in the robot base (mm).
    model_name : str, optional
        Key of :data:`SEEDS` (a built-in name); a user's model starts from zeros with joint 1 turned.

    Returns
    -------
    joints : ndarray, shape (N, 6)
        Reported joint angles, degrees in (-180, 180]; NaN where no solution was found.
    ok : ndarray of bool, shape (N,)
        Whether ``FK(joints)`` reproduces the pose within :data:`TOL_MM` and :data:`TOL_DEG`.
    """
    target = np.asarray(target, float).reshape(-1, 4, 4)
    best = np.full((len(target), 6), np.nan)
    ok = np.zeros(len(target), bool)
    seed = seed_for(model_name, model, target)
    flips = [np.zeros(6), np.array([0, 0, 0, 180.0, 0, 180.0]), np.array([0, 0, 0, 180.0, 0, 0])]
    for flip in flips:
        todo = ~ok
        if not todo.any():
            break
        q, dpos, drot = _levenberg_marquardt(model, target[todo], seed[todo] + flip)
        q = _wrap(q)
        err = pose_error(target[todo], model.flange2base(q))
        good = (np.linalg.norm(err[:, :3], axis=1) < TOL_MM) & (np.linalg.norm(err[:, 3:], axis=1) < TOL_DEG)
        idx = np.flatnonzero(todo)[good]
        best[idx], ok[idx] = q[good], True
    return best, ok


#: Given joint angles must reach the wanted flange pose within these (mm, degrees): a pose list
#: written with 4 decimals carries 1e-4 mm.
GIVEN_MM, GIVEN_DEG = 0.01, 0.01


@dataclasses.dataclass(frozen=True)
class Robot:
    """A simulated robot with joints: its nominal model and the name setup.toml gives it.

    Attributes
    ----------
    model_key : str
        ``[robot] model`` of the written dataset (a built-in name or a model file).
    model : handeye.model.robot.robots.RobotModel
    """

    model_key: str
    model: robots.RobotModel

    @classmethod
    def load(cls, name):
        """The robot of a built-in name or model file (DatasetError when there is none)."""
        return cls(str(name), robots.load(name))

    def joints_given(self, wanted, joints):
        """Given joint angles checked against the wanted flange poses (N, 4, 4): ``(joints, all reached)``;
        ValueError naming the first whose nominal flange is off by more than :data:`GIVEN_MM` or
        :data:`GIVEN_DEG`."""
        joints = np.asarray(joints, float).reshape(len(wanted), 6)
        dpos, dang = transform_distance(self.model.flange2base(joints), wanted)
        bad = np.flatnonzero((dpos > GIVEN_MM) | (dang > GIVEN_DEG))
        if len(bad):
            k = int(bad[0])
            raise ValueError(f"pose {k + 1}: its joint angles put the {self.model.name}'s flange {dpos[k]:.3g} mm / "
                             f"{dang[k]:.3g} deg from the pose (more than {GIVEN_MM:g} mm / {GIVEN_DEG:g} deg)")
        return joints, np.ones(len(wanted), bool)

    def describe(self):
        """``simulation.json``'s ``robot``."""
        return {"model": self.model_key, "name": self.model.name, "source": self.model.source,
                "ik_tolerance": {"mm": TOL_MM, "deg": TOL_DEG}}

    def reach(self, wanted, errors=None, joints=None):
        """Joint angles for the wanted flange poses and the flanges reported and really reached.

        Parameters
        ----------
        wanted : ndarray, shape (N, 4, 4)
            Flange poses in the robot base that see the sphere (mm).
        errors : dict or array_like, optional
            The robot's hidden errors: robot effect name -> its full parameter vector
            (:func:`handeye.model.robot.robot_errors.perturbed`), or six joint offsets (degrees); none
            when None.
        joints : array_like, shape (N, 6), optional
            The joint angles to use (degrees; a planned pose list's ``j1..j6``) instead of the
            inverse kinematics: their nominal flange must be the wanted one within
            :data:`GIVEN_MM` and :data:`GIVEN_DEG` (ValueError naming the first that is not).

        Returns
        -------
        joints : ndarray, shape (N, 6)
            Commanded (and reported) angles ``q``, degrees; NaN where unreachable.
        reported : ndarray, shape (N, 4, 4)
            ``T(q)`` by the nominal model, the controller's flange pose (mm).
        true : ndarray, shape (N, 4, 4)
            ``T*(q)`` with the errors: where the flange really is (mm).
        unreached : dict
            Index -> reason of the poses the inverse kinematics cannot reach.
        """
        wanted = np.asarray(wanted, float)
        if joints is None:
            joints, ok = inverse_kinematics(self.model, wanted, self.model_key)
        else:
            joints, ok = self.joints_given(wanted, joints)
        q = np.where(ok[:, None], joints, 0.0)
        values = {} if errors is None else errors if isinstance(errors, dict) else {"joint_offsets": errors}
        reported = np.where(ok[:, None, None], self.model.flange2base(q), wanted)
        true = np.where(ok[:, None, None], robot_errors.perturbed(self.model, q, values)[0], wanted)
        unreached = {int(k): f"the {self.model.name} cannot reach this flange pose (no inverse kinematics "
                             f"solution within {TOL_MM:g} mm / {TOL_DEG:g} deg)" for k in np.flatnonzero(~ok)}
        return joints, reported, true, unreached
