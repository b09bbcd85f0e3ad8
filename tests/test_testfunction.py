"""The seed's test function (6-16): derivatives, least-squares form, stationary points, and
the seed's printed Hessian (C7, typos) against its code (C9, right)."""
import numpy as np
import pytest

from handeye.model.chain import testfunction as tf

RNG_POINTS = np.random.default_rng(10).uniform(-4, 4, (40, 2))


def central_gradient(f, x, h=1e-6):
    return np.array([(f(x + h * e) - f(x - h * e)) / (2 * h) for e in np.eye(len(x))])


def test_gradient_and_hessian_against_central_differences():
    for x in RNG_POINTS:
        np.testing.assert_allclose(tf.gradient(x), central_gradient(tf.value, x), rtol=1e-6, atol=1e-7)
        fd = np.stack([central_gradient(lambda y: tf.gradient(y)[k], x) for k in range(2)])
        np.testing.assert_allclose(tf.hessian(x), fd, rtol=1e-5, atol=1e-6)
        np.testing.assert_allclose(tf.residual_jacobian(x), np.stack(
            [central_gradient(lambda y: tf.residual(y)[k], x) for k in range(4)]), rtol=1e-6, atol=1e-8)


def test_derivatives_against_casadi_ad():
    import casadi as ca

    from handeye.app.engine.problems import testfunction_nlp

    nlp = testfunction_nlp()
    x = nlp["x"]
    g = ca.Function("g", [x], [ca.gradient(nlp["f"], x)])
    h = ca.Function("h", [x], [ca.hessian(nlp["f"], x)[0]])
    for p in RNG_POINTS:
        np.testing.assert_allclose(np.array(g(p)).ravel(), tf.gradient(p), rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(np.array(h(p)), tf.hessian(p), rtol=1e-12, atol=1e-12)


def test_shifted_function_is_a_sum_of_squares():
    for x in RNG_POINTS:
        r = tf.residual(x)
        assert r @ r == pytest.approx(tf.value(x) + 300.0, rel=1e-13)
        # and the least-squares gradient J^T r is half the gradient of f
        np.testing.assert_allclose(tf.residual_jacobian(x).T @ r, 0.5 * tf.gradient(x), rtol=1e-10, atol=1e-12)


def test_sum_of_squares_identity_symbolically():
    import sympy as sp

    from handeye.model.chain import symbolic

    s = symbolic.test_function()
    assert sp.simplify((s["r"].T * s["r"])[0] - (s["f"] + 300)) == 0


def test_minima_match_the_seed_table_6_2():
    """Seed 6.2 prints f, x1, x2 with three decimals, Table 7-1 the minima with four."""
    pts = tf.stationary_points()
    kinds = [p.kind for p in pts]
    assert kinds.count("minimum") == 2 and kinds.count("saddle") == 1 and len(pts) == 3
    glob, loc, saddle = pts
    assert glob.kind == "minimum" and loc.kind == "minimum" and saddle.kind == "saddle"
    # Table 6.2 (three decimals) and Table 7-1 (four): equal to within one unit of the last digit
    # (the seed mixes rounding and truncation: f = -207.15990 is printed -207.159)
    np.testing.assert_allclose([glob.value, *glob.x], [-207.159, -0.995, -1.992], atol=1e-3)
    np.testing.assert_allclose([loc.value, *loc.x], [-114.425, 0.979, 0.968], atol=1e-3)
    np.testing.assert_allclose(loc.x, [0.9789, 0.9684], atol=1e-4)
    np.testing.assert_allclose(glob.x, [-0.9948, -1.9922], atol=1e-4)
    for p in pts:
        assert np.linalg.norm(tf.gradient(p.x)) < 1e-9  # >= 10 correct digits


def test_the_seeds_saddle_point_is_not_stationary():
    """Seed 6.2 prints the saddle at (0.105, -0.205), f = -67.484. f is right *there*, but the
    gradient there is not zero; the true saddle is (0.16905, -0.24643), f = -67.579."""
    printed = np.array([0.105, -0.205])
    assert tf.value(printed) == pytest.approx(-67.484, abs=5e-4)
    assert np.linalg.norm(tf.gradient(printed)) > 2.0
    saddle = tf.stationary_points()[2]
    np.testing.assert_allclose(saddle.x, [0.169046840, -0.246429740], atol=1e-8)
    assert saddle.value == pytest.approx(-67.5788342, abs=1e-6)
    # every stationary point lies on the line through a = (1, 1) and b = (-1, -2)
    d = tf.B_POINT - tf.A_POINT
    for p in tf.stationary_points():
        v = p.x - tf.A_POINT
        assert abs(v[0] * d[1] - v[1] * d[0]) < 1e-12


def hessian_c7_as_printed(x):
    """Appendix C7 transcribed literally."""
    x1, x2 = x
    q1 = (x1 - 1) ** 2 + (x2 - 1) ** 2 + 1
    q2 = (x1 + 1) ** 2 + (x2 + 2) ** 2 + 1
    h11 = -800 * (x1 - 1) ** 2 / q1**3 + 200 / q1**2 + 400 / q2**2 - (-1600 * (x1 - 1) ** 2) / q2**3
    h12 = -800 * (x1 - 1) * (x2 - 1) / q1**3 - 1600 * (x1 + 1) * (x2 + 2) / q2**3
    h22 = -800 * (x1 - 1) ** 2 / q1**3 + 200 / q1**2 + 400 / q2**2 - (-1600 * (x1 - 1) ** 2) / q2**3
    return np.array([[h11, h12], [h12, h22]])


def hessian_c9_as_printed(x):
    """Appendix C9's MATLAB HesseMinFunc_001, transcribed literally."""
    x1, x2 = x
    q1 = (x1 - 1) ** 2 + (x2 - 1) ** 2 + 1
    q2 = (x1 + 1) ** 2 + (x2 + 2) ** 2 + 1
    hxx = -(800 * (x1 - 1) ** 2) / q1**3 + 200 / q1**2 + 400 / q2**2 - (1600 * (x1 + 1) ** 2) / q2**3
    hxy = -800 * (x1 - 1) * (x2 - 1) / q1**3 - 1600 * (x1 + 1) * (x2 + 2) / q2**3
    hyy = -(800 * (x2 - 1) ** 2) / q1**3 + 200 / q1**2 + 400 / q2**2 - (1600 * (x2 + 2) ** 2) / q2**3
    return np.array([[hxx, hxy], [hxy, hyy]])


def test_c9_hessian_is_right_and_c7_has_typos():
    for x in RNG_POINTS:
        np.testing.assert_allclose(hessian_c9_as_printed(x), tf.hessian(x), rtol=1e-12, atol=1e-12)
    wrong = [not np.allclose(hessian_c7_as_printed(x), tf.hessian(x), rtol=1e-6) for x in RNG_POINTS]
    assert all(wrong)
    # The off-diagonal of C7 is right; H11's last term has the wrong sign and (x1-1) for (x1+1),
    # H22 repeats H11 instead of using (x2-1) and (x2+2).
    x = RNG_POINTS[0]
    assert hessian_c7_as_printed(x)[0, 1] == pytest.approx(tf.hessian(x)[0, 1], rel=1e-12)
    assert hessian_c7_as_printed(x)[0, 0] == pytest.approx(hessian_c7_as_printed(x)[1, 1], rel=1e-12)
