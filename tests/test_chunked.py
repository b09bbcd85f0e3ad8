"""Sums over the rows chunk by chunk (a million rows never held as one Jacobian) agree with the
full arrays: the normal equations, the Jacobian's triangular factor, the exact Hessian, the
leave-one-out deletion formula, and Levenberg-Marquardt on the normal equations. Tiny chunks
on small models stand for the million rows."""
import numpy as np
import pytest

from handeye import solvers
from handeye.app.engine import robust
from handeye.app.engine.problems import calibration_problem
from handeye.model.common.statistics import covariance, covariance_normal
from handeye.model.design import identifiability
from handeye.model.fit import calibration
from tests.test_calibration_model import random_model, start_point

KINDS = [("centre", "sensor"), ("centre", "sensor+sphere"), ("measurement", "sensor"), ("points", "sensor+sphere")]


@pytest.mark.parametrize("kind, unknowns", KINDS)
def test_normal_equations_by_chunks_equal_the_full_jacobian(kind, unknowns):
    model = random_model("local", unknowns, n=23, kind=kind)
    x = start_point(model)
    r, j = model.residual(x), model.jacobian(x)
    jtj, jtr, rtr = model.normal_equations(x, chunk=5)
    np.testing.assert_allclose(jtj, j.T @ j, rtol=1e-12, atol=1e-9 * np.abs(j.T @ j).max())
    np.testing.assert_allclose(jtr, j.T @ r, rtol=1e-10, atol=1e-10 * np.abs(j.T @ r).max())
    assert rtr == pytest.approx(r @ r, rel=1e-12)
    weights = np.random.default_rng(3).uniform(0, 2, model.n_meas)
    sw = np.sqrt(np.repeat(weights, model.m))
    wjtj, wjtr, wrtr = model.normal_equations(x, weights, chunk=4)
    np.testing.assert_allclose(wjtj, (sw[:, None] * j).T @ (sw[:, None] * j), rtol=1e-10, atol=1e-9 * np.abs(jtj).max())
    assert wrtr == pytest.approx(float((sw * r) @ (sw * r)), rel=1e-12)


def test_normal_equations_of_a_stack_of_points_are_each_points():
    model = random_model("local", "sensor", n=17)
    xs = np.stack([start_point(model, seed) for seed in (1, 2, 3)])
    jtj, jtr, rtr = model.normal_equations(xs, chunk=6)
    for k, x in enumerate(xs):
        one = model.normal_equations(x, chunk=6)
        np.testing.assert_allclose(jtj[k], one[0], rtol=1e-13)
        np.testing.assert_allclose(jtr[k], one[1], rtol=1e-12, atol=1e-12 * np.abs(one[1]).max())


@pytest.mark.parametrize("kind, unknowns", KINDS)
def test_triangular_factor_gives_the_jacobians_singular_values(kind, unknowns):
    model = random_model("local", unknowns, n=21, kind=kind)
    x = start_point(model)
    j = model.jacobian(x)
    r = model.jacobian_r(x, chunk=4)
    np.testing.assert_allclose(np.linalg.svd(r, compute_uv=False), np.linalg.svd(j, compute_uv=False), rtol=1e-11)
    full, by_r = identifiability.analyse(j, model.names), identifiability.analyse(r, model.names, rows=len(j))
    np.testing.assert_allclose(by_r.singular_values, full.singular_values, rtol=1e-11)
    assert by_r.weakest_direction == pytest.approx(full.weakest_direction, abs=2e-4)
    assert by_r.observability == pytest.approx(full.observability, rel=1e-10)


def test_covariance_from_normal_equations_equals_the_jacobians():
    model = random_model("local", "sensor", n=30)
    x = start_point(model)
    r, j = model.residual(x), model.jacobian(x)
    jtj, _, rtr = model.normal_equations(x, chunk=7)
    full, normal = covariance(r, j), covariance_normal(jtj, rtr, len(r))
    np.testing.assert_allclose(normal.std, full.std, rtol=1e-9)
    assert normal.sigma == pytest.approx(full.sigma, rel=1e-12)


@pytest.mark.parametrize("kind, unknowns", KINDS)
def test_exact_hessian_by_chunks(kind, unknowns, monkeypatch):
    model = random_model("local", unknowns, n=19, kind=kind)
    x = start_point(model)
    full = model.cost_hessian(x)
    monkeypatch.setattr(calibration, "ROW_CHUNK", 4)
    np.testing.assert_allclose(model.cost_hessian(x), full, rtol=1e-10, atol=1e-10 * np.abs(full).max())
    np.testing.assert_allclose(model.gradient(x), model.jacobian(x).T @ model.residual(x), rtol=1e-9,
                               atol=1e-10 * np.abs(full).max())


@pytest.mark.parametrize("kind", ["centre", "measurement"])
def test_deletion_formula_by_chunks_equals_the_per_sample_arrays(kind):
    model = random_model("local", "sensor", n=40, kind=kind)
    x = robust.least_squares(model, start_point(model)).x
    mask = np.ones(model.n_meas, bool)
    mask[[3, 17]] = False
    predictor = calibration.CalibrationModel(model.flange2base, model.centre_in_sensor[:, :3], model.fixed_centre,
                                             "local", "sensor") if kind != "centre" else model
    step, leverage, _, _ = robust._deletion_steps(model, x, mask)
    d, dj = predictor.residual_and_jacobian(x)
    expected = np.linalg.norm(d[mask] + np.einsum("gkp,gp->gk", dj[mask], step), axis=1)
    expected[~(leverage <= robust.LOO_LEVERAGE)] = np.nan  # refitted exactly: compared below
    got = robust._deletion_errors(model, x, mask, predictor, chunk=6)
    same = np.isfinite(expected)
    np.testing.assert_allclose(got[same], expected[same], rtol=1e-9)


def test_levenberg_marquardt_on_normal_equations_ends_where_on_the_jacobian():
    rough = random_model("local", "sensor+sphere", n=60)
    truth = start_point(rough)
    t2, c = rough.sensor2flange(truth), rough.sphere_centre(truth)
    ideal = np.linalg.solve(rough.flange2base @ t2, np.append(c, 1.0))[:, :3]  # centres seen from the true pose
    noisy = ideal + np.random.default_rng(4).normal(0, 0.05, ideal.shape)
    model = calibration.CalibrationModel(rough.flange2base, noisy, c + 3.0, "local", "sensor+sphere")
    x0 = model.retract(model.point_from(t2, c), np.array([2.0, -1.0, 1.5, 0.02, -0.01, 0.03, 1.0, 2.0, -1.0]))
    plain = calibration_problem(model)
    normal = solvers.Problem(n=plain.n, residual=plain.residual, jacobian=plain.jacobian, retract=plain.retract,
                             vectorised=True, normal=lambda x: model.normal_equations(x, chunk=7))
    a, b = solvers.solve(plain, x0, "lm"), solvers.solve(normal, x0, "lm")
    assert a.converged and b.converged
    np.testing.assert_allclose(b.x, a.x, rtol=1e-8, atol=1e-8)
    many = solvers.solve_many(normal, np.stack([x0, start_point(model, 5)]), "lm")
    np.testing.assert_allclose(many.x[0], b.x, rtol=1e-10, atol=1e-10)


@pytest.mark.parametrize("unknowns, skip", [("sensor", ()), ("sensor+sphere", ()), ("sensor", ("sphere_radius",))])
def test_effect_score_tests_by_chunks_equal_the_full_arrays(unknowns, skip):
    """The effect tests' own fit on normal equations and their two chunked passes
    (:func:`handeye.model.fit.extended.score_by_sums`) give the full arrays' scores and gates."""
    import handeye
    from handeye.app.public.api import load_dataset
    from handeye.model.fit import extended

    dataset = load_dataset("thesis-real")
    fitted = handeye.calibrate("thesis-real", unknowns=unknowns, no_loo=True, effects="none").fit  # the model as asked
    mask = fitted.residuals.used.copy()
    mask[[2, 7]] = False
    prob = extended.Samples(dataset)
    sensor = fitted.sensor2flange
    args = (dataset, extended.Calibrated(mask, sensor, fitted.sphere_centre, unknowns), skip)
    full, chunked = extended.score_effects(*args), extended.score_effects(*args, chunk=5)
    assert [t.name for t in chunked] == [t.name for t in full] and (full or unknowns != "sensor")
    # each path fits its own point (the full arrays' solve and the normal equations'), both stopped by the solver's
    # xtol/ftol within 3e-7 mm of each other: the scores agree to what that leaves (1e-7 relative), not to rounding
    for a, b in zip(full, chunked):
        assert b.score == pytest.approx(a.score, rel=1e-7)
        assert b.gate == pytest.approx(a.gate, rel=1e-7)
        assert b.p_bonferroni == pytest.approx(a.p_bonferroni, rel=1e-6, abs=1e-300)
    structure = extended.Structure(centre=unknowns == "sensor+sphere", data_effects=skip)
    x0 = prob.point(structure, sensor)
    a, b = prob.fit(structure, mask, x0), prob.fit(structure, mask, x0, chunk=4)
    assert b.jac is None and b.p == a.p and b.ssr == pytest.approx(a.ssr, rel=1e-10)
    np.testing.assert_allclose(b.e, a.e, rtol=1e-6, atol=1e-7)  # one minimum, tolerances apart
    jtj, jtr, rtr = prob.normal_equations(structure, a.x, a.params, mask, chunk=3)
    j = a.jac[mask].reshape(-1, a.p)
    np.testing.assert_allclose(jtj, j.T @ j, rtol=1e-11, atol=1e-11 * np.abs(jtj).max())
    assert rtr == pytest.approx(a.ssr, rel=1e-12)


def test_deletion_statistics_by_chunks_equal_the_full_arrays():
    """The screening's deletion statistics in two chunked passes (information and SSR, then
    per-sample statistics) give the full arrays' statistics, p-values and residuals."""
    from handeye.model.common.statistics import deletion_statistics, deletion_statistics_chunked

    model = random_model("local", "sensor+sphere", n=29)
    x = start_point(model)
    fitted = np.ones(model.n_meas, bool)
    fitted[[3, 11, 20]] = False
    e, j = model.residual_and_jacobian(x)
    stat, p_value = deletion_statistics(e, j, fitted, n_tests=model.n_meas)
    stat_c, p_c, e_c = deletion_statistics_chunked(lambda: model.chunks(x, 4), fitted, n_tests=model.n_meas)
    np.testing.assert_allclose(stat_c, stat, rtol=1e-10)
    np.testing.assert_allclose(p_c, p_value, rtol=1e-8, atol=1e-300)
    np.testing.assert_array_equal(e_c, e)
    by_screen = robust._deletion(model, x, fitted, chunk=5)
    np.testing.assert_allclose(by_screen[0], stat, rtol=1e-10)
