"""The weighted Kabsch fast path of screening (robust.weighted_fit) against scipy's least
squares on the same weighted centre residual, and its applicability test."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import least_squares as scipy_least_squares
from scipy.spatial.transform import Rotation

from handeye.app.engine import robust
from handeye.model.fit.calibration import CalibrationModel


def _centre_problem(rng, n=15, noise=0.05, gross=()):
    truth = np.eye(4)
    truth[:3, :3] = Rotation.from_rotvec(rng.normal(size=3)).as_matrix()
    truth[:3, 3] = [190.0, 100.0, 130.0]
    centre = np.array([1534.0, -603.0, 1119.0])
    f2b = np.empty((n, 4, 4))
    xs = np.empty((n, 3))
    for i in range(n):
        f2b[i] = np.eye(4)
        f2b[i, :3, :3] = Rotation.from_rotvec(rng.normal(size=3)).as_matrix()
        seen = rng.uniform([-20, -25, 190], [20, -3, 290])
        sensor_in_base_t = centre - f2b[i, :3, :3] @ truth[:3, :3] @ seen - f2b[i, :3, :3] @ truth[:3, 3]
        f2b[i, :3, 3] = sensor_in_base_t
        xs[i] = seen + rng.normal(scale=noise, size=3)
    for i in gross:
        xs[i] += [15.0, 0.0, -10.0]
    return f2b, xs, centre, truth


def _scipy_weighted(f2b, xs, centre, weights, x0):
    def residual(v):
        rot = Rotation.from_rotvec(v[3:]).as_matrix()
        e = np.einsum("nab,nb->na", f2b[:, :3, :3], xs @ rot.T + v[:3]) + f2b[:, :3, 3] - centre
        return (np.sqrt(weights)[:, None] * e).ravel()

    return scipy_least_squares(residual, x0, xtol=1e-15, ftol=1e-15, gtol=1e-15)


@pytest.mark.parametrize("seed", range(5))
def test_weighted_kabsch_is_the_weighted_least_squares_minimum(seed):
    rng = np.random.default_rng(seed)
    f2b, xs, centre, truth = _centre_problem(rng, gross=(2, 7))
    model = CalibrationModel(f2b, xs, centre, "local", "sensor")
    weights = rng.uniform(0.01, 1.0, len(xs))
    weights[3] = 0.0  # excluded by screening
    x = robust.weighted_fit(model, model.point_from(np.eye(4)), weights)
    fast = model.sensor2flange(x)
    ref = _scipy_weighted(f2b, xs, centre, weights,
                          np.r_[truth[:3, 3], Rotation.from_matrix(truth[:3, :3]).as_rotvec()])
    want_rot = Rotation.from_rotvec(ref.x[3:]).as_matrix()
    assert np.allclose(fast[:3, 3], ref.x[:3], atol=1e-6)
    assert np.allclose(fast[:3, :3], want_rot, atol=1e-9)
    cost = 0.5 * np.sum(weights * np.sum(model.residuals(x) ** 2, axis=1))
    assert cost <= ref.cost * (1 + 1e-9) + 1e-12


def test_kabsch_fast_path_only_where_it_is_the_minimum():
    rng = np.random.default_rng(0)
    f2b, xs, centre, _ = _centre_problem(rng)
    assert robust._procrustes(CalibrationModel(f2b, xs, centre, "local", "sensor"))
    assert not robust._procrustes(CalibrationModel(f2b, xs, centre, "local", "sensor+sphere"))
    whiten = np.tile(np.eye(3), (len(xs), 1, 1))
    assert not robust._procrustes(CalibrationModel(f2b, xs, centre, "local", "sensor", whiten=whiten))
    # raw matrix entries: the unconstrained minimum is not a rotation, so no SVD shortcut
    assert not robust._procrustes(CalibrationModel(f2b, xs, centre, "matrix", "sensor"))


def test_degenerate_subset_falls_back_to_the_solver():
    """Two samples leave the rotation about their line free: no SVD answer, the solver's
    from the start (finite, and no worse than the start)."""
    rng = np.random.default_rng(1)
    f2b, xs, centre, truth = _centre_problem(rng)
    model = CalibrationModel(f2b, xs, centre, "local", "sensor")
    weights = np.zeros(len(xs))
    weights[:2] = 1.0
    x0 = model.point_from(truth)
    x = robust.weighted_fit(model, x0, weights)
    assert np.all(np.isfinite(x))
    cost = lambda z: np.sum(weights * np.sum(model.residuals(z) ** 2, axis=1))  # noqa: E731
    assert cost(x) <= cost(x0) + 1e-12
