"""The Cramer-Rao bound of the simulator's noise model.

For the circles measured in the laser plane (what the sensor delivers after a circle fit),
the noise of sample i has covariance

    C_i = sigma_point^2 (J_c^T J_c)^-1  +  sigma_robot^2 diag(1, 1, y_i^2 / r_i^2),

the first term the geometric circle fit's (J_c: derivatives of the orthogonal distances of the
noise-free profile points), the second the robot's repeatability moving the predicted centre.
With the measurement residual's Jacobian J_i at the truth (local chart: mm, rad), the Fisher
information is ``F = sum_i J_i^T C_i^-1 J_i`` and no unbiased estimator has a covariance below
``F^-1``. Profile-point noise and robot noise are taken as Gaussian and independent; the
linearity error is not noise (it is a bias) and is not in the bound.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from handeye.model.chain.pose import transform_from_pose
from handeye.model.datasets import observations
from handeye.model.fit.calibration import CalibrationModel
from handeye.model.geometry import circle


def information(flange_poses, setup, sphere_centre, unknowns="sensor"):
    """Fisher information of each sample (N, p, p) on the local chart (mm, rad).

    Parameters
    ----------
    flange_poses : array_like, shape (N, 6)
        Flange poses (KUKA) of the design.
    setup : handeye.model.simulation.simulate.Setup
        Nominal sensor pose, sphere and noise levels.
    sphere_centre : array_like, shape (3,)
        mm, base frame.

    Raises
    ------
    handeye.model.simulation.simulate.SimulationError
        When a pose's laser plane misses the sphere or sees too little of it.
    """
    from handeye.model.simulation import simulate

    quiet = dataclasses.replace(setup, sigma_point=0.0, sigma_robot=0.0, linearity=0.0)
    t_x = transform_from_pose(setup.sensor_pose)
    flanges = transform_from_pose(np.asarray(flange_poses, float))
    centre = np.asarray(sphere_centre, float)
    radius = setup.diameter / 2
    circles, covs = [], []
    for flange in flanges:
        in_sensor = np.linalg.solve(flange @ t_x, np.append(centre, 1.0))[:3]
        pts = simulate.profile_points(in_sensor, radius, quiet, np.random.default_rng(0))
        exact = circle.Circle(in_sensor[0], in_sensor[2], float(np.sqrt(radius**2 - in_sensor[1] ** 2)))
        cov = circle.circle_covariance(pts[:, 0], pts[:, 1], exact, sigma=setup.sigma_point)
        circles.append([exact.x, exact.z, exact.r])
        covs.append(observations.circle_noise(cov, exact.r, radius, setup.sigma_robot))
    whiten = observations.whitening(np.array(covs))
    model = CalibrationModel.from_circles(flanges, np.array(circles), radius, centre, "local", unknowns, whiten=whiten)
    _, jac = model.residual_and_jacobian(model.point_from(t_x, centre))
    return np.einsum("ikn,ikm->inm", jac, jac)


def crlb(simulation, unknowns="sensor"):
    """Bound (p, p) on the covariance of the sensor pose (mm, rad) for a simulation's design.

    Parameters
    ----------
    simulation : handeye.model.simulation.simulate.Simulation
        Any simulation; its poses and setup are used (the noise is re-derived noise-free).
    """
    info = information(simulation.flange_poses, simulation.setup, simulation.true_centre, unknowns)
    return np.linalg.inv(info.sum(axis=0))
