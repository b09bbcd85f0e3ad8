"""The calibration residual: exact derivatives against CasADi AD and central differences;
what the data can and cannot determine (the seed's 12 unknowns)."""
import numpy as np
import pytest

from handeye.model.chain import symbolic
from handeye.model.chain.pose import transform_from_pose
from handeye.model.datasets.dataset import load
from handeye.model.design import identifiability
from handeye.model.fit.calibration import ROTATIONS, UNKNOWNS, CalibrationModel

CASES = [(r, u) for r in ROTATIONS for u in UNKNOWNS]
KIND_CASES = [(r, k) for r in ROTATIONS for k in ("measurement", "points")]


def random_model(rotation, unknowns, seed=0, n=12, kind="centre"):
    rng = np.random.default_rng(seed)
    f2b = transform_from_pose(np.column_stack([rng.uniform(-800, 800, (n, 3)), rng.uniform(-170, 170, (n, 3)) * [1, 0.5, 1]]))
    centre = rng.uniform(-500, 500, 3)
    if kind == "centre":
        xs = rng.uniform(-20, 20, (n, 3)) + [0, 0, 230]
        return CalibrationModel(f2b, xs, centre, rotation, unknowns)
    if kind == "measurement":
        circles = np.column_stack([rng.uniform(-10, 10, n), rng.uniform(200, 260, n), rng.uniform(20, 29, n)])
        a = rng.normal(size=(n, 3, 3))
        return CalibrationModel.from_circles(f2b, circles, 29.97, centre, rotation, unknowns, whiten=a)
    profiles = [np.column_stack([rng.uniform(-20, 20, 5), rng.uniform(200, 260, 5)]) for _ in range(n)]
    return CalibrationModel.from_profiles(f2b, profiles, 29.97, centre, rotation, unknowns)


def start_point(m, seed=1):
    rng = np.random.default_rng(seed)
    pose = np.concatenate([rng.uniform(-200, 200, 3), rng.uniform(-170, 170, 3) * [1, 0.5, 1]])
    return m.point_from(transform_from_pose(pose), m.fixed_centre + rng.normal(0, 5, 3))


def test_rotation_names_agree_with_the_symbolic_source():
    from handeye.model.fit.calibration import KINDS

    assert ROTATIONS == symbolic.ROTATIONS
    assert KINDS == symbolic.KINDS


@pytest.mark.parametrize("rotation,kind", KIND_CASES)
def test_measurement_and_point_residuals_derivatives(rotation, kind):
    """Jacobians against central differences; cost gradient and Hessian against CasADi AD
    (where IPOPT's parametrisations apply) or second differences (local)."""
    import casadi as ca

    m = random_model(rotation, "sensor+sphere", seed=7, kind=kind)
    x = start_point(m, seed=8)
    j = m.jacobian(x)
    h = 1e-6
    fd = np.stack([(m.residual(m.retract(x, h * e)) - m.residual(m.retract(x, -h * e))) / (2 * h)
                   for e in np.eye(m.n)], axis=1)
    np.testing.assert_allclose(j, fd, rtol=1e-5, atol=1e-6 * np.abs(j).max())
    if rotation == "local":
        return
    nlp = m.nlp()
    f = ca.Function("f", [nlp["x"], nlp["p"]], [nlp["f"]])
    hs = ca.Function("h", [nlp["x"], nlp["p"]], [ca.hessian(nlp["f"], nlp["x"])[0]])
    assert float(f(x, nlp["p_value"])) == pytest.approx(m.cost(x), rel=1e-10)
    np.testing.assert_allclose(np.array(hs(x, nlp["p_value"])), m.cost_hessian(x), rtol=1e-8,
                               atol=1e-8 * np.abs(m.cost_hessian(x)).max())


def test_measurement_residual_matches_its_definition():
    """e = (p_x - xc, p_z - zc, (R^2 - p_y^2 - r^2) / 2r) with p the centre predicted in the sensor."""
    m = random_model("local", "sensor", seed=9, kind="measurement")
    m = CalibrationModel.from_circles(m.flange2base, m.centre_in_sensor, m.radius, m.fixed_centre)
    x = start_point(m, seed=10)
    t2 = m.sensor2flange(x)
    p = np.linalg.solve(m.flange2base @ t2, np.append(m.fixed_centre, 1.0))[:, :3]
    xc, zc, r = m.centre_in_sensor.T
    expected = np.column_stack([p[:, 0] - xc, p[:, 2] - zc, (m.radius**2 - p[:, 1] ** 2 - r**2) / (2 * r)])
    np.testing.assert_allclose(m.residuals(x), expected, atol=1e-9)


@pytest.mark.parametrize("rotation,unknowns", CASES)
def test_jacobian_against_central_differences(rotation, unknowns):
    m = random_model(rotation, unknowns)
    x = start_point(m)
    j = m.jacobian(x)
    h = 1e-6
    fd = np.stack(
        [(m.residual(m.retract(x, h * e)) - m.residual(m.retract(x, -h * e))) / (2 * h) for e in np.eye(m.n)], axis=1
    )
    np.testing.assert_allclose(j, fd, rtol=1e-6, atol=1e-6 * np.abs(j).max())


@pytest.mark.parametrize("rotation,unknowns", [c for c in CASES if c[0] != "matrix"])
def test_cost_hessian_against_second_differences(rotation, unknowns):
    """Exact Hessian of the pull-back cost f(retract(x, d)) at d = 0."""
    m = random_model(rotation, unknowns, seed=2)
    x = start_point(m, seed=3)
    hess = m.cost_hessian(x)
    h = 1e-3  # cost ~1e7 mm^2: a larger step keeps rounding (eps f / h^2) below truncation
    eye = np.eye(m.n)

    def g(d):
        return m.cost(m.retract(x, d))

    fd = np.array([[(g(h * eye[i] + h * eye[j]) - g(h * eye[i] - h * eye[j]) - g(-h * eye[i] + h * eye[j])
                     + g(-h * eye[i] - h * eye[j])) / (4 * h * h) for j in range(m.n)] for i in range(m.n)])
    np.testing.assert_allclose(hess, fd, rtol=1e-5, atol=1e-5 * np.abs(hess).max())
    np.testing.assert_allclose(hess, hess.T, rtol=1e-12, atol=1e-9)


@pytest.mark.parametrize("rotation,unknowns", [c for c in CASES if c[0] != "local"])
def test_derivatives_against_casadi_ad(rotation, unknowns):
    """CasADi differentiates the NLP's cost by AD; compare gradient and Hessian."""
    import casadi as ca

    m = random_model(rotation, unknowns, seed=4)
    x = start_point(m, seed=5)
    nlp = m.nlp()
    f = ca.Function("f", [nlp["x"], nlp["p"]], [nlp["f"]])
    g = ca.Function("g", [nlp["x"], nlp["p"]], [ca.gradient(nlp["f"], nlp["x"])])
    h = ca.Function("h", [nlp["x"], nlp["p"]], [ca.hessian(nlp["f"], nlp["x"])[0]])
    p = nlp["p_value"]
    assert float(f(x, p)) == pytest.approx(m.cost(x), rel=1e-12)
    np.testing.assert_allclose(np.array(g(x, p)).ravel(), m.gradient(x), rtol=1e-10, atol=1e-8)
    np.testing.assert_allclose(np.array(h(x, p)), m.cost_hessian(x), rtol=1e-10, atol=1e-8)


def test_residual_is_the_seeds_chain():
    """e_i = T(p1_i) T(p2) x_s,i - T(p3) x_p' (seed 4-3), written out with 4x4 matrices."""
    d = load("thesis-real")
    p2 = [150.0, 90.0, 120.0, 170.0, -80.0, 5.0]
    m = CalibrationModel(d.flange2base(), d.centre_in_sensor, d.sphere_centre, "euler")
    x = m.point_from(transform_from_pose(p2))
    lhs = transform_from_pose(d.flange_poses) @ transform_from_pose(p2) @ np.column_stack(
        [d.centre_in_sensor, np.ones(len(d))])[..., None]
    rhs = transform_from_pose(d.plate_pose) @ np.append(d.centre_in_plate, 1.0)
    np.testing.assert_allclose(m.residuals(x), (lhs[..., 0] - rhs)[:, :3], atol=1e-9)


def test_local_retraction_stays_on_so3():
    m = random_model("local", "sensor")
    x = start_point(m)
    rng = np.random.default_rng(6)
    for _ in range(50):
        x = m.retract(x, rng.normal(0, 0.5, m.n))
    r = m.sensor_rotation(x)
    np.testing.assert_allclose(r.T @ r, np.eye(3), atol=1e-13)


def test_seed_step_two_plate_pose_is_not_identifiable():
    """Seed 4.4.2 estimates p2 and p3 (12 unknowns); only c = T(p3) x_p' enters the residual."""
    d = load("thesis-real")
    ident = identifiability.plate_pose_analysis(
        d.flange2base(), d.centre_in_sensor, transform_from_pose(d.start_pose), d.plate_pose, d.centre_in_plate)
    assert ident.n == 12 and ident.rank == 9
    assert ident.singular_values[8] > 1e-3 and ident.singular_values[9] < 1e-10
    # the three null directions live entirely in the plate pose
    for direction in ident.null_directions:
        assert set(direction) <= {"x3", "y3", "z3", "A3", "B3", "C3"}
    # while sensor + sphere centre (9 unknowns) are all identifiable from the same data
    m = CalibrationModel(d.flange2base(), d.centre_in_sensor, d.sphere_centre, "local", "sensor+sphere")
    assert identifiability.structural(m, m.point_from(transform_from_pose(d.start_pose))).full_rank


def test_degenerate_poses_are_detected():
    d = load("thesis-real")
    f2b = d.flange2base()
    start = transform_from_pose(d.start_pose)
    same = np.repeat(f2b[:1], 10, axis=0)
    m = CalibrationModel(same, np.repeat(d.centre_in_sensor[:1], 10, 0), d.sphere_centre, "local", "sensor")
    ident = identifiability.structural(m, m.point_from(start))
    assert ident.rank == 3 and not ident.full_rank
    # pure translations: fine for the sensor alone, not with the sphere centre unknown
    shifted = np.repeat(f2b[:1], 6, axis=0)
    shifted[:, :3, 3] += np.random.default_rng(7).uniform(-50, 50, (6, 3))
    xs = np.repeat(d.centre_in_sensor[:1], 6, 0)
    m = CalibrationModel(shifted, xs, d.sphere_centre, "local", "sensor")
    assert identifiability.structural(m, m.point_from(start)).full_rank
    m = CalibrationModel(shifted, xs, d.sphere_centre, "local", "sensor+sphere")
    ident = identifiability.structural(m, m.point_from(start))
    assert ident.rank == 6
    assert all({"cx", "cy", "cz"} & set(v) for v in ident.null_directions)


def test_euler_angles_are_singular_at_the_seeds_sensor_orientation():
    """The seed's sensor sits at B = -90 deg: there A and C turn about the same axis, so the
    Euler Jacobian loses rank, while the local (rotation-vector) chart does not."""
    d = load("thesis-real")
    start = transform_from_pose(d.start_pose)
    for rotation, rank in (("euler", 5), ("local", 6)):
        m = CalibrationModel(d.flange2base(), d.centre_in_sensor, d.sphere_centre, rotation)
        ident = identifiability.analyse(m.jacobian(m.point_from(start)), m.names)
        assert ident.rank == rank
    (null,) = identifiability.analyse(
        CalibrationModel(d.flange2base(), d.centre_in_sensor, d.sphere_centre, "euler").jacobian(
            np.array([*d.start_pose])), ["tx", "ty", "tz", "A", "B", "C"]).null_directions
    assert null in ({"A": 1.0, "C": -1.0}, {"A": -1.0, "C": 1.0})


@pytest.mark.parametrize("rotation,unknowns,kind", [(r, u, k) for r in ROTATIONS for u in UNKNOWNS
                                                    for k in ("centre", "measurement", "points")])
def test_a_stack_of_points_evaluates_row_by_row(rotation, unknowns, kind):
    """Every evaluation takes a stack of points (..., n) and gives, row by row, what one point
    gives (whitening, free sphere centre and every residual kind included): what the batched
    solvers rely on."""
    m = random_model(rotation, unknowns, seed=3, kind=kind)
    points = np.stack([start_point(m, seed=s) for s in range(5)])
    steps = np.random.default_rng(9).normal(0, 0.05, (5, m.n))
    stacked = points.reshape(5, 1, -1)  # two batch axes
    for name in ("residual", "jacobian", "cost_hessian", "gradient", "residuals", "cost"):
        fn = getattr(m, name)
        many = fn(points)
        for i, x in enumerate(points):
            np.testing.assert_allclose(many[i], fn(x), rtol=1e-13, atol=1e-9, err_msg=name)
        assert np.shape(fn(stacked)) == (5, 1) + np.shape(fn(points[0])), name
    moved = m.retract(points, steps)
    for i in range(5):
        np.testing.assert_allclose(moved[i], m.retract(points[i], steps[i]), rtol=1e-15, atol=1e-15)


@pytest.mark.parametrize("kind", ["centre", "measurement", "points"])
@pytest.mark.parametrize("rotation", ROTATIONS)
def test_the_residual_alone_is_the_residual_of_the_residual_and_jacobian(rotation, kind):
    """Costs come from a residual-only generated function, Jacobians from the combined one:
    both are generated from the same expressions and must agree to rounding."""
    m = random_model(rotation, "sensor+sphere", seed=5, kind=kind)
    points = np.stack([start_point(m, seed=s) for s in range(4)])
    e, _ = m.residual_and_jacobian(points)
    alone = m.residual(points)
    np.testing.assert_allclose(alone, e.reshape(alone.shape), rtol=1e-13, atol=1e-10 * np.abs(e).max())
    np.testing.assert_allclose(m.residuals(points[0]), m._raw(points[0])[0], rtol=1e-13, atol=1e-10 * np.abs(e).max())
