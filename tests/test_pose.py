"""Pose conversions: round trips, gimbal lock at B = +-90 deg, numpy vs definition."""
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from handeye.model.chain.pose import (
    kuka_from_matrix,
    matrix_from_kuka,
    pose_from_transform,
    transform_from_pose,
)
from handeye.model.common import rotation


def elementary(a, b, c):
    """Rz(A) Ry(B) Rx(C) written out independently of the generated code (degrees)."""
    a, b, c = np.radians([a, b, c])
    rz = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    ry = np.array([[np.cos(b), 0, np.sin(b)], [0, 1, 0], [-np.sin(b), 0, np.cos(b)]])
    rx = np.array([[1, 0, 0], [0, np.cos(c), -np.sin(c)], [0, np.sin(c), np.cos(c)]])
    return rz @ ry @ rx


def test_transform_matches_elementary_rotations_and_thesis_table_6_7():
    rng = np.random.default_rng(1)
    poses = np.column_stack([rng.uniform(-1e3, 1e3, (50, 3)), rng.uniform(-180, 180, (50, 3))])
    t = transform_from_pose(poses)
    for p, m in zip(poses, t):
        np.testing.assert_allclose(m[:3, :3], elementary(*p[3:]), atol=1e-14)
        np.testing.assert_allclose(m[:3, 3], p[:3])
        np.testing.assert_allclose(m[3], [0, 0, 0, 1])
    # Table 6-7: the CAD start pose and its printed matrix
    printed = np.array([[0, 0, 1, 156.99], [0, -1, 0, 87.55], [1, 0, 0, 115.0], [0, 0, 0, 1]])
    np.testing.assert_allclose(transform_from_pose([156.99, 87.55, 115, 180, -90, 0]), printed, atol=1e-12)
    # Table 6-4: plate pose p3 and its printed matrix (4 decimals)
    printed = np.array([[0.9988, 0.0485, -0.0002], [-0.0485, 0.9988, 0.0026], [0.0003, -0.0026, 0.9999]])
    r = transform_from_pose([1430.90, -698.77, 937.43, -2.78, -0.02, -0.15])[:3, :3]
    np.testing.assert_allclose(r, printed, atol=1.1e-4)


def test_vectorised_shapes():
    p = np.zeros((2, 3, 6))
    assert transform_from_pose(p).shape == (2, 3, 4, 4)
    assert pose_from_transform(transform_from_pose(p)).shape == (2, 3, 6)
    with pytest.raises(ValueError):
        transform_from_pose(np.zeros(5))


angles = st.floats(-180, 180, allow_nan=False)
pitch = st.floats(-90, 90, allow_nan=False)
coord = st.floats(-5e3, 5e3, allow_nan=False)


@settings(max_examples=300, deadline=None)
@given(coord, coord, coord, angles, pitch, angles)
def test_round_trip_transform(x, y, z, a, b, c):
    t = transform_from_pose([x, y, z, a, b, c])
    p = pose_from_transform(t)
    np.testing.assert_allclose(transform_from_pose(p), t, atol=1e-9)
    assert -180 < p[3] <= 180 and -90 <= p[4] <= 90 and -180 < p[5] <= 180


@settings(max_examples=200, deadline=None)
@given(angles, st.floats(-89.9, 89.9), angles)
def test_round_trip_angles_away_from_lock(a, b, c):
    p = kuka_from_matrix(matrix_from_kuka([a, b, c]))
    # angles are unique away from B = +-90 (modulo 360)
    d = (p - np.array([a, b, c]) + 180) % 360 - 180
    assert np.all(np.abs(d) < 1e-7)


@pytest.mark.parametrize("b", [90.0, -90.0, 90.0 - 1e-7, -90.0 + 1e-7, 90.0 + 1e-7, -90.0 - 1e-7, 89.9999, -89.9999])
def test_gimbal_lock_round_trips_as_transform(b):
    rng = np.random.default_rng(3)
    for a, c in rng.uniform(-180, 180, (200, 2)):
        r = matrix_from_kuka([a, b, c])
        p = kuka_from_matrix(r)
        np.testing.assert_allclose(matrix_from_kuka(p), r, atol=2e-15 * 8)
        assert abs(p[1]) <= 90.0


@pytest.mark.parametrize("b", [90.0, -90.0])
def test_gimbal_lock_documented_choice(b):
    """Exactly at B = +-90 only A - C (B = 90) or A + C (B = -90) is defined; we return C = 0."""
    p = kuka_from_matrix(matrix_from_kuka([30.0, b, 40.0]))
    assert abs(p[2]) < 1e-12
    assert p[1] == pytest.approx(b)
    expected = 30.0 - 40.0 if b > 0 else 30.0 + 40.0
    assert p[0] == pytest.approx(expected)


def test_rotvec_round_trip_including_pi():
    rng = np.random.default_rng(4)
    w = rng.normal(size=(500, 3))
    w = w / np.linalg.norm(w, axis=1, keepdims=True) * rng.uniform(0, np.pi, (500, 1))
    r = rotation.matrix_from_rotvec(w)
    np.testing.assert_allclose(rotation.matrix_from_rotvec(rotation.rotvec_from_matrix(r)), r, atol=1e-10)
    for angle in (np.pi, np.pi - 1e-9, 1e-12, 0.0):
        axis = np.array([1.0, -2.0, 0.5]) / np.linalg.norm([1.0, -2.0, 0.5])
        r = rotation.matrix_from_rotvec(angle * axis)
        np.testing.assert_allclose(rotation.matrix_from_rotvec(rotation.rotvec_from_matrix(r)), r, atol=1e-10)
    np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-15)


def test_nearest_rotation_and_distance():
    rng = np.random.default_rng(5)
    r = rotation.matrix_from_rotvec(rng.normal(size=3))
    noisy = r + 1e-3 * rng.normal(size=(3, 3))
    q = rotation.nearest_rotation(noisy)
    np.testing.assert_allclose(q @ q.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(q) == pytest.approx(1.0)
    assert np.linalg.det(rotation.nearest_rotation(-np.eye(3))) == pytest.approx(1.0)
    ta, tb = np.eye(4), np.eye(4)
    tb[:3, :3] = rotation.matrix_from_rotvec([0, 0, np.radians(10)])
    tb[:3, 3] = [3, 4, 0]
    dt, dr = rotation.transform_distance(ta, tb)
    assert dt == pytest.approx(5.0) and dr == pytest.approx(10.0)
