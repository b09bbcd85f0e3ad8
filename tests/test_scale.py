"""The pieces that make the default pipeline linear in the data agree with the exact ones."""
import numpy as np
import pytest

import handeye
from handeye.app.engine import request as request_module
from handeye.app.engine import robust
from handeye.app.tools import bench
from handeye.model.fit.calibration import CalibrationModel


def test_deletion_formula_leave_one_out_matches_exact_refits(monkeypatch):
    f2b, xs, centre, start = bench.simulated_case(300, seed=3)
    model = CalibrationModel(f2b, xs, centre, "local")
    mask = np.ones(300, bool)
    mask[[5, 17]] = False
    x = robust.least_squares(robust._subset(model, mask), model.point_from(start)).x  # the fit on the mask
    exact = robust.leave_one_out(model, x, mask)
    monkeypatch.setattr(robust, "LOO_EXACT_UP_TO", 10)
    fast = robust.leave_one_out(model, x, mask)
    assert np.array_equal(np.isnan(exact), np.isnan(fast))
    assert np.nanmax(np.abs(fast - exact)) < 1e-5 * np.nanmax(exact)  # measured: ~3e-8 mm of 0.07 mm


def test_the_callback_problem_for_ipopt_agrees_with_the_sx_one(monkeypatch):
    from handeye import solvers
    from handeye.model.fit import calibration

    f2b, xs, centre, start = bench.simulated_case(60, seed=1)
    model = CalibrationModel(f2b, xs, centre, "euler")
    sx = solvers.solve(solvers.Problem(n=6, nlp=model.nlp()), model.point_from(start), "ipopt")
    monkeypatch.setattr(calibration, "NLP_CALLBACK_ABOVE", 10)
    assert "callback" in model.nlp()
    cb = solvers.solve(solvers.Problem(n=6, nlp=model.nlp()), model.point_from(start), "ipopt")
    assert sx.converged and cb.converged
    assert np.max(np.abs(model.sensor2flange(sx.x) - model.sensor2flange(cb.x))) < 1e-9


@pytest.mark.parametrize("unknowns", ["sensor", "sensor+sphere"])
def test_the_centre_models_quadratic_problem_for_ipopt_agrees_with_every_rows_graph(unknowns):
    """The centre model in ``matrix`` is linear in its point: IPOPT gets its cost as one quadratic form (a graph of
    its 12 or 15 unknowns, whatever the rows); it ends where the graph of every row's residual ends."""
    from handeye import solvers
    from handeye.model.fit import calibration, nlp_problem

    f2b, xs, centre, start = bench.simulated_case(60, seed=1)
    model = CalibrationModel(f2b, xs, centre + (5.0 if unknowns == "sensor+sphere" else 0.0), "matrix", unknowns)
    quadratic = model.nlp()
    rows = {**nlp_problem._graph(model, calibration._sources("matrix", "centre")[0], 9), "lbg": quadratic["lbg"],
            "ubg": quadratic["ubg"]}
    assert quadratic["x"].shape[0] == model.n and quadratic["structure"][0] == "calibration-quadratic"
    x0 = model.point_from(start, centre)
    ends = [solvers.solve(solvers.Problem(n=model.n, nlp=nlp), x0, "ipopt") for nlp in (quadratic, rows)]
    assert all(r.converged for r in ends)
    assert np.max(np.abs(ends[0].x - ends[1].x)) < 1e-8


def test_large_datasets_default_to_lm_and_say_so(tmp_path, monkeypatch):
    monkeypatch.setattr(request_module, "LARGE", 10)
    r = handeye.calibrate("thesis-sim", no_loo=True)
    assert r.method == "lm" and any("default method is lm" in w for w in r.warnings)
    assert handeye.calibrate("thesis-sim", no_loo=True, method="ipopt").method == "ipopt"
    assert handeye.calibrate("thesis-sim", no_loo=True, rotation="matrix").method == "ipopt"
    monkeypatch.undo()
    small = handeye.calibrate("thesis-sim", no_loo=True)
    assert small.method == "ipopt" and np.allclose(small.sensor2flange, r.sensor2flange, atol=1e-9)


@pytest.mark.parametrize("many", [False, True])
def test_screening_finds_the_same_gross_errors_one_at_a_time_or_together(monkeypatch, many):
    d = handeye.load_dataset("thesis-real")
    from handeye.model.chain.pose import transform_from_pose

    if many:
        monkeypatch.setattr(robust, "LOO_EXACT_UP_TO", 5)
    s = robust.screen(d, "sensor", transform_from_pose(d.start_pose))
    assert {"x+22.5", "x+45", "x*+90", "y*+112.5"} <= {e.id for e in s.excluded}


@pytest.mark.slow(sibling="test_screening_finds_the_same_gross_errors_one_at_a_time_or_together[True]")
def test_text_report_summarises_beyond_fifty_rows_and_the_json_keeps_them_all(tmp_path, capsys):
    import json

    from handeye.app.command.cli import main
    from handeye.app.present import report

    folder = bench.write_dataset(tmp_path / "d", 6_000, seed=4)
    assert main(["calibrate", str(folder), "--no-loo"]) == 0
    text = capsys.readouterr().out
    rows = [line for line in text.splitlines() if line.strip().startswith("m") and line.split()[0][1:].isdigit()]
    assert len(rows) == report.REPORT_ROWS  # the first 25 and the 25 largest |e| of the others
    assert [r.split()[0] for r in rows[:25]] == [f"m{k}" for k in range(25)]
    assert "5,950 of the 6,000 rows not shown" in text and "keeps every row" in text
    assert main(["calibrate", str(folder), "--no-loo", "--json"]) == 0
    out = capsys.readouterr().out
    data = json.loads(out)
    assert len(data["residuals"]) == 6_000 and data["residuals"][5_999]["id"] == "m5999"
    assert set(data["residuals"][0]) == {"id", "row", "vector", "norm", "used", "loo_error_mm"}
    shown = {r.split()[0]: float(r.split()[5]) for r in rows[25:]}
    norms = sorted((r["norm"] for r in data["residuals"][25:]), reverse=True)
    assert sorted(shown.values(), reverse=True) == pytest.approx(norms[:25], abs=1e-3)  # the worst, as printed
    result = handeye.calibrate(str(folder), no_loo=True)
    assert data["residuals"] == json.loads(json.dumps(result.to_dict()["residuals"]))  # the table's dicts, same keys
    assert len(result.residuals) == 6_000 and result.residuals[-1].id == "m5999"


def test_a_plain_csv_reads_column_wise_as_row_by_row(tmp_path, monkeypatch):
    from handeye.model.datasets import dataset
    from handeye.model.readers import tables

    folder = bench.write_dataset(tmp_path / "d", 300, seed=5)
    monkeypatch.setattr(tables, "PLAIN_ABOVE_BYTES", 1 << 40)
    slow = dataset.load(folder)
    monkeypatch.setattr(tables, "PLAIN_ABOVE_BYTES", 0)
    fast = dataset.load(folder)
    for field in ("ids", "rows", "flange_poses", "centre_in_sensor", "raw_poses", "reconstructed", "profiles"):
        assert np.array_equal(np.asarray(getattr(fast, field)), np.asarray(getattr(slow, field))), field
    csv = folder / "measurements.csv"
    lines = csv.read_text().splitlines()
    lines[7] = lines[7].replace(lines[7].split(",")[4], "200", 1)  # an angle A beyond the controller's range
    csv.write_text("\n".join(lines) + "\n")
    with pytest.raises(dataset.DatasetError, match="row 8"):  # the row-by-row reader names it
        dataset.load(folder)


def test_the_quadratic_problem_is_the_rows_cost_whitened_and_never_negative_where_rank_deficient():
    """The quadratic form equals the model's cost and gradient with whitening too; written as |R d|^2 it stays a
    sum of squares where the Jacobian loses rank (3-8 poses with the sphere centre free: as d^T J^T J d it rounded
    to eigenvalues of -1e-11 and IPOPT diverged), and IPOPT ends where the callback ends."""
    import itertools

    import casadi as ca

    from handeye import solvers
    from handeye.model.fit import nlp_callback, nlp_problem

    rng = np.random.default_rng(3)
    f2b, xs, centre, start = bench.simulated_case(30, seed=2)
    whiten = np.linalg.cholesky(np.linalg.inv(np.eye(3) + 0.3 * np.diag(rng.uniform(size=3))))[None].repeat(30, 0)
    model = CalibrationModel(f2b, xs, centre, "matrix", "sensor+sphere", whiten=whiten)
    nlp = model.nlp()
    f = ca.Function("f", [nlp["x"], nlp["p"]], [nlp["f"], ca.gradient(nlp["f"], nlp["x"])])
    x = model.point_from(start, centre + 1.0)
    value, grad = f(x, nlp["p_value"])
    assert float(value) == pytest.approx(model.cost(x), rel=1e-10)
    np.testing.assert_allclose(np.array(grad).ravel(), model.gradient(x), rtol=1e-8, atol=1e-8)
    for n, seed in itertools.product((3, 4, 5, 6, 8), range(6)):  # the J^T J form diverged in 9 of these 30
        f2b, xs, centre, start = bench.simulated_case(n, seed=seed)
        model = CalibrationModel(f2b, xs, centre, "matrix", "sensor+sphere")
        x0 = model.point_from(start, centre) + 0.01 * np.random.default_rng(seed).standard_normal(model.n)
        quad = solvers.solve(solvers.Problem(n=model.n, nlp=model.nlp()), x0, "ipopt")
        cb = nlp_callback.cost_callback(model)
        z = ca.MX.sym("x", model.n)
        rows = {"x": z, "f": cb(z), "g": nlp_problem._constraints(z, "matrix"), "lbg": np.zeros(6), "ubg": np.zeros(6),
                "callback": cb}
        ref = solvers.solve(solvers.Problem(n=model.n, nlp=rows), x0, "ipopt")
        assert np.isfinite(quad.x).all()
        assert model.cost(quad.x) <= model.cost(ref.x) + 1e-9 * max(1.0, model.cost(ref.x)), (n, quad.message)
