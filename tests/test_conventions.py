"""Robot-brand conventions: every one from the one symbolic definition, round-tripped against
the others, at and near their singularities."""
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from handeye.model.chain import conventions as cv
from handeye.model.chain import symbolic
from handeye.model.chain.pose import transform_from_pose
from handeye.model.common.rotation import matrix_from_rotvec

NAMES = list(cv.CONVENTIONS)


def test_names_agree_with_the_symbolic_source():
    assert cv.CONVENTIONS == symbolic.CONVENTIONS


def test_worked_example_of_the_docstring():
    p = [156.99, 87.55, 115, 180, -90, 0]
    np.testing.assert_allclose(cv.convert(p, "kuka", "fanuc"), [156.99, 87.55, 115, 0, -90, 180], atol=1e-9)
    np.testing.assert_allclose(cv.convert(p, "kuka", "abb"), [156.99, 87.55, 115, 0, np.sqrt(0.5), 0, np.sqrt(0.5)],
                               atol=1e-9)
    np.testing.assert_allclose(cv.convert(p, "kuka", "ur"), [156.99, 87.55, 115, np.pi / np.sqrt(2), 0,
                                                             np.pi / np.sqrt(2)], atol=1e-9)


def test_independent_definitions():
    """Against definitions written here, not generated: FANUC as extrinsic X-Y-Z, ABB's
    quaternion by Hamilton product, UR by Rodrigues."""
    rng = np.random.default_rng(0)
    for _ in range(20):
        w, p, r = rng.uniform(-180, 180, 3)
        ext = transform_from_pose([0, 0, 0, r, p, w])[:3, :3]  # Rz(r) Ry(p) Rx(w)
        np.testing.assert_allclose(cv.matrix_from("fanuc", [w, p, r]), ext, atol=1e-12)
        rv = rng.normal(size=3)
        np.testing.assert_allclose(cv.matrix_from("ur", rv), matrix_from_rotvec(rv), atol=1e-12)
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        v = rng.normal(size=3)
        # rotate v by q with quaternion algebra: q v q*
        def mul(a, b):
            return np.array([a[0] * b[0] - a[1:] @ b[1:], *(a[0] * b[1:] + b[0] * a[1:] + np.cross(a[1:], b[1:]))])
        rotated = mul(mul(q, np.array([0, *v])), q * [1, -1, -1, -1])[1:]
        np.testing.assert_allclose(cv.matrix_from("abb", q) @ v, rotated, atol=1e-12)


def random_rotation(rng):
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    return cv.matrix_from("abb", q)


@pytest.mark.parametrize("source", NAMES)
@pytest.mark.parametrize("target", NAMES)
def test_round_trips_between_every_pair(source, target):
    rng = np.random.default_rng(1)
    t = np.eye(4)
    for _ in range(50):
        t[:3, :3] = random_rotation(rng)
        t[:3, 3] = rng.uniform(-1000, 1000, 3)
        pose = cv.pose_from(source, t)
        back = cv.convert(cv.convert(pose, source, target), target, source)
        np.testing.assert_allclose(cv.transform_from(source, back), t, atol=1e-9)


@pytest.mark.parametrize("convention", NAMES)
def test_singular_orientations(convention):
    """Pitch +-90 (KUKA B, FANUC P), a half turn (UR |r| = pi, ABB w = 0), no rotation (UR r = 0)."""
    cases = [transform_from_pose([1, 2, 3, 30, b, 40]) for b in (90, -90, 90 - 1e-7, -90 + 1e-7)]
    half = np.eye(4)
    half[:3, :3] = matrix_from_rotvec(np.pi * np.array([1.0, 0, 1]) / np.sqrt(2))
    cases += [half, np.eye(4)]
    for t in cases:
        np.testing.assert_allclose(cv.transform_from(convention, cv.pose_from(convention, t)), t, atol=1e-9)


@settings(max_examples=100, deadline=None)
@given(st.lists(st.floats(-1, 1, allow_nan=False), min_size=4, max_size=4).filter(lambda q: np.linalg.norm(q) > 0.1))
def test_quaternion_round_trip_up_to_sign(q):
    q = np.array(q) / np.linalg.norm(q)
    back = cv.quaternion_from_matrix(cv.matrix_from("abb", q))
    assert np.allclose(back, q, atol=1e-9) or np.allclose(back, -q, atol=1e-9)
    assert back[0] >= 0


@pytest.mark.parametrize("convention,values,needle", [
    ("abb", [1, 1, 0, 0], "unit norm"), ("ur", [7, 0, 0], "2 pi"), ("kuka", [400, 0, 0], "360"),
    ("fanuc", [0, float("nan"), 0], "finite"),
])
def test_invalid_values(convention, values, needle):
    with pytest.raises(cv.ConventionError, match=needle):
        cv.matrix_from(convention, values)
    with pytest.raises(cv.ConventionError, match="unknown convention"):
        cv.columns("yaskawa")
