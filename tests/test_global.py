"""The global guarantee (issue 25): the centre model's global minimum in closed form, checked
numerically; calibrate starts from it and never reports a worse local minimum as a result."""
import json

import numpy as np
import pytest

import handeye
from handeye.app.command import cli
from handeye.app.engine import guarantee
from handeye.model.chain.pose import pose_from_transform, transform_from_pose
from handeye.model.common.rotation import matrix_from_rotvec, transform_distance
from handeye.model.fit import global_fit


def _chain(seed, n=15, noise=0.05):
    """Flange poses, sensor centres, truth and centre of a random cell (independent of simulate)."""
    rng = np.random.default_rng(seed)
    truth = transform_from_pose([rng.uniform(-200, 200), rng.uniform(-200, 200), rng.uniform(50, 250),
                                 *rng.uniform([-180, -89, -180], [180, 89, 180])])
    centre = rng.uniform([400, -600, 0], [1200, 600, 600])
    f2b, p = [], []
    for _ in range(n):
        seen = rng.uniform([-20, -20, 180], [20, 20, 280])
        rot = matrix_from_rotvec(rng.normal(size=3) * 0.6) @ transform_from_pose([0, 0, 0, 0, 180, 0])[:3, :3]
        sensor = np.eye(4)
        sensor[:3, :3], sensor[:3, 3] = rot, centre - rot @ seen
        f2b.append(sensor @ np.linalg.inv(truth))
        p.append(seen + rng.normal(0, noise, 3))
    return np.array(f2b), np.array(p), truth, centre


def _brute_cost(f2b, p, x, c):
    return 0.5 * sum(np.sum((fi[:3, :3] @ (x[:3, :3] @ pi + x[:3, 3]) + fi[:3, 3] - c) ** 2) for fi, pi in zip(f2b, p))


@pytest.mark.parametrize("seed", range(5))
def test_svd_is_the_minimum_no_perturbation_lowers_it(seed):
    f2b, p, truth, centre = _chain(seed)
    best = global_fit.centre_minima(f2b, p, centre).best
    assert best.cost == pytest.approx(_brute_cost(f2b, p, best.sensor2flange, centre), rel=1e-10)
    rng = np.random.default_rng(seed)
    for _ in range(200):
        x = best.sensor2flange.copy()
        x[:3, :3] = x[:3, :3] @ matrix_from_rotvec(rng.normal(size=3) * 1e-3)
        x[:3, 3] += rng.normal(size=3) * 1e-2
        assert _brute_cost(f2b, p, x, centre) >= best.cost
    dt, dr = transform_distance(best.sensor2flange, truth)
    assert dt < 0.5 and dr < 0.2


def test_reduced_form_equals_the_cost_with_t_and_c_solved():
    f2b, p, _, _ = _chain(7)
    form = global_fit.reduced_form(f2b, p)
    rng = np.random.default_rng(1)
    for _ in range(5):
        rot = matrix_from_rotvec(rng.normal(size=3))
        n = len(p)
        lhs = np.concatenate([f2b[:, :3, :3], np.broadcast_to(-np.eye(3), (n, 3, 3))], axis=2).reshape(3 * n, 6)
        rhs = (-f2b[:, :3, 3] - np.einsum("nab,bc,nc->na", f2b[:, :3, :3], rot, p)).ravel()
        s, *_ = np.linalg.lstsq(lhs, rhs, rcond=None)
        x = np.eye(4)
        x[:3, :3], x[:3, 3] = rot, s[:3]
        assert form.value(rot) == pytest.approx(2 * _brute_cost(f2b, p, x, s[3:]), rel=1e-9)


def test_newton_derivatives_on_so3_against_finite_differences():
    """Gradient and Hessian of w -> 2F(R exp([w]x)) at w = 0 against central differences."""
    f2b, p, _, _ = _chain(3)
    form = global_fit.reduced_form(f2b, p)
    rot = matrix_from_rotvec(np.array([0.3, -1.1, 0.7]))[None]
    value, grad, hess = global_fit._derivatives(form, rot)

    def chart(w):
        return form.value(rot @ matrix_from_rotvec(np.asarray(w, float)))[0]

    h, eye = 1e-4, np.eye(3)
    fd_grad = [(chart(h * eye[i]) - chart(-h * eye[i])) / (2 * h) for i in range(3)]
    fd_hess = [[(chart(h * (eye[i] + eye[j])) - chart(h * (eye[i] - eye[j])) - chart(h * (eye[j] - eye[i]))
                 + chart(-h * (eye[i] + eye[j]))) / (4 * h * h) for j in range(3)] for i in range(3)]
    scale = np.abs(hess[0]).max()
    assert np.allclose(fd_grad, grad[0], rtol=1e-6, atol=1e-7 * scale)
    assert np.allclose(fd_hess, hess[0], rtol=1e-4, atol=1e-5 * scale)


@pytest.mark.parametrize("seed", range(4))
def test_centre_free_search_finds_the_least_squares_minimum(seed):
    """The centre-free global search against scipy's least squares from the truth."""
    from scipy.optimize import least_squares

    f2b, p, truth, centre = _chain(seed, n=18)
    found = global_fit.centre_minima(f2b, p, None)

    def residual(z):
        x = np.eye(4)
        x[:3, :3], x[:3, 3] = truth[:3, :3] @ matrix_from_rotvec(z[:3]), z[3:6]
        return (np.einsum("nab,nb->na", f2b[:, :3, :3], p @ x[:3, :3].T + x[:3, 3]) + f2b[:, :3, 3] - z[6:]).ravel()

    ref = least_squares(residual, np.concatenate([[0, 0, 0], truth[:3, 3], centre]), xtol=1e-14, ftol=1e-14)
    assert found.best.cost == pytest.approx(ref.cost, rel=1e-7)
    assert np.allclose(found.best.centre, ref.x[6:], atol=1e-4)


def _recipe(tmp_path, seed):
    """The issue's UR cell: a 50.8 mm sphere, the README's plan, the CAD start simulate writes."""
    cell = handeye.simulate(tmp_path / f"cell{seed}", seed=3, convention="ur", diameter=50.8, center="700,-300,200",
                            profiles=True)
    poses = tmp_path / f"p{seed}.csv"
    handeye.plan(dataset=cell.path, n=12, max_tilt=45, margin="5,1", out=poses)
    return handeye.simulate(tmp_path / f"d{seed}", seed=seed, poses=poses, convention="ur", diameter=50.8,
                            center="700,-300,200", profiles=True)


def test_the_issues_local_minimum_is_left_for_the_global_one(tmp_path, capsys):
    sim = _recipe(tmp_path, 4)
    code = cli.main(["calibrate", str(sim.path), "--json"])
    res = json.loads(capsys.readouterr().out)
    truth = transform_from_pose(handeye.load_dataset(sim.path).truth["sensor_pose"])
    dt, dr = transform_distance(np.array(res["sensor_matrix"]), truth)
    assert code == cli.EXIT_OK and res["converged"] and dt < 0.5 and dr < 0.2 and res["rms_mm"] < 0.1
    g = res["global"]
    assert g["starts"] == 2 and g["reached"] == 1 and g["next_best_cost"] > 100 * res["cost_mm2"]
    assert any("local minimum" in w and "global minimum" in w for w in res["warnings"])


def test_the_centre_model_reports_the_svd_minimum_exactly(tmp_path):
    from conftest import simulate

    from handeye.app.engine.calibrate import CalibrationRequest, stages

    folder = simulate(tmp_path / "c", seed=2, n=20)
    data = handeye.load_dataset(folder)
    res = stages(CalibrationRequest(loo=False).checked(data), data)  # the centre model's fit itself (before the search)
    data = data.subset([r.used for r in res.residuals])
    svd = global_fit.centre_minima(data.flange2base(), data.centre_in_sensor, data.sphere_centre).best
    dt, dr = transform_distance(res.sensor2flange, svd.sensor2flange)
    assert res.converged and dt < 1e-6 and dr < 1e-6
    assert res.global_check.reached == 2 and res.global_check.next_best_cost is None
    assert res.global_check.method.startswith("absolute orientation")


def test_a_fit_in_a_wrong_basin_is_never_a_result(tmp_path):
    """If every start but the user's is disabled, the cross-check still refuses the wrong basin."""
    sim = _recipe(tmp_path, 4)
    data = handeye.load_dataset(sim.path)
    from handeye.app.engine.calibrate import calibrate

    real = guarantee.lowest
    try:
        guarantee.lowest = lambda fit, basin, solve, exact_centre_model=False: (
            fit, None, guarantee.GlobalCheck("disabled", 1, 1, None))
        res = calibrate(data, loo=False)
    finally:
        guarantee.lowest = real
    assert not res.converged and "wrong basin" in res.message


def test_global_in_the_json_of_the_thesis_data(capsys):
    assert cli.main(["calibrate", "thesis-real", "--json", "--no-loo"]) == cli.EXIT_OK
    g = json.loads(capsys.readouterr().out)["global"]
    assert set(g) >= {"method", "starts", "reached", "next_best_cost"} and g["reached"] >= 1


def test_the_centre_free_calibration_reports_its_search(capsys):
    assert cli.main(["calibrate", "thesis-sim", "--unknowns", "sensor+sphere", "--json"]) == cli.EXIT_OK
    res = json.loads(capsys.readouterr().out)
    assert res["global"]["centre_minima"] >= 1 and "SO(3)" in res["global"]["method"]
    assert res["sphere_center"] == pytest.approx([30, 5, 10], abs=1e-6)


def test_explains_nothing_uses_the_robots_motion():
    f2b, p, truth, centre = _chain(5)

    class Data:
        def __init__(self, f2b, p):
            self._f2b, self.centre_in_sensor = f2b, p

        def flange2base(self):
            return self._f2b

        motions = flange2base  # the seed's cell: the chain's carrier motions are the flange poses

        def __len__(self):
            return len(self.centre_in_sensor)

    good = Data(f2b, p)
    assert guarantee.explains_nothing(good, global_fit.centre_minima(f2b, p, centre), 0.05) is None
    shuffled = Data(f2b[np.random.default_rng(0).permutation(len(f2b))], p)
    message = guarantee.explains_nothing(shuffled, global_fit.centre_minima(shuffled.flange2base(), p, centre), 0.05)
    assert message is not None and "explains nothing" in message
    assert pose_from_transform(truth).shape == (6,)


def test_a_start_that_does_not_converge_is_replaced_by_the_global_one(tmp_path):
    """The given start's fit fails (an iteration limit of 1 from far away); the fit from the
    centre model's global minimum converges and is reported, the note says why."""
    from conftest import simulate

    folder = simulate(tmp_path / "c", seed=4, n=20, start_offset=[60, -40, 50, 40, 30, -35])
    res = handeye.calibrate(folder, no_loo=True, method="gn", rotation="local", max_iter=1, model="centre")
    assert res.converged and res.global_check.reached >= 1
    assert any("not converged" in w and "global minimum" in w for w in res.warnings)


def test_a_taught_centre_the_pose_would_absorb_is_named(tmp_path):
    """The README's planned UR cell with [sphere] center 1 mm off in z: the pose absorbed it
    (8 mm, 17 sd off, exit 0); now the centre is named with its shift (exit 2), while the correct
    centre and the thesis's (~6 mm off, but freeing it leaves residuals ten times the stated
    noise: other effects, left to diagnose) still calibrate."""
    sim = _recipe(tmp_path, 4)
    assert handeye.calibrate(sim.path, no_loo=True).converged
    setup = sim.path / "setup.toml"
    setup.write_text(setup.read_text().replace("center = [700.0, -300.0, 200.0]", "center = [700.0, -300.0, 201.0]"))
    with pytest.raises(handeye.InputError, match=r"\[sphere\] center.*-1\.0\d\) mm from the given one"):
        handeye.calibrate(sim.path, no_loo=True)
    assert handeye.calibrate(sim.path, no_loo=True, unknowns="sensor+sphere").converged
    assert handeye.calibrate("thesis-real", no_loo=True).converged
