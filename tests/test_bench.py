"""The fast path lands on the least-squares minimum, compiled or not, one by one or in batch;
degenerate data are refused; the benchmark reports every method (speed is measured by
`handeye bench`, never asserted here)."""
import numpy as np
import pytest

import handeye
from handeye.app.tools import bench
from handeye.model.common.rotation import transform_distance
from handeye.model.compiled import fast
from handeye.model.fit.calibration import CalibrationModel

#: The benchmark's runs of every section (10-20 s even small) are in the full suite; the default
#: tier runs its sections one by one: the fast path, the guarantee's measurement, the pipeline,
#: a child's peak memory, the machine record (and test_points_fast_path.py's points and peers).
_SECTION = "test_the_pipeline_bench_times_every_stage_against_one_ipopt_solve"

def _newton_polished(f2b, xs, centre, sensor2flange, steps=4):
    """The minimum by exact Newton steps (cost Hessian of the symbolic model, not the fast path's)."""
    model = CalibrationModel(f2b, xs, centre, "local")
    x = model.point_from(sensor2flange)
    for _ in range(steps):
        g = model.jacobian(x).T @ model.residual(x)
        x = model.retract(x, np.linalg.solve(model.cost_hessian(x), -g))
    return model.sensor2flange(x)


@pytest.mark.parametrize("compiled", [True, False])
def test_fast_path_lands_on_the_minimum(compiled):
    for case in (bench.real_case(), bench.simulated_case(30, seed=1), bench.simulated_case(500, seed=2)):
        f2b, xs, centre, start = case
        res = fast.calibrate_fast(f2b, xs, centre, start, compiled=compiled)
        assert res.converged, res.message
        ref = _newton_polished(f2b, xs, centre, res.sensor2flange)
        dt, dr = transform_distance(res.sensor2flange, ref)
        assert dt < 1e-8 and dr < 1e-8  # mm, deg: thesis-real's large residuals used to stop it 4e-6 short
        model = CalibrationModel(f2b, xs, centre, "local")
        r = model.residual(model.point_from(res.sensor2flange))
        assert res.cost == pytest.approx(0.5 * r @ r, rel=1e-12)


def test_compiled_and_python_iterations_agree():
    f2b, xs, centre, start = bench.real_case()
    if fast.library() is None:
        pytest.skip("no C compiler")
    a = fast.calibrate_fast(f2b, xs, centre, start, compiled=True)
    b = fast.calibrate_fast(f2b, xs, centre, start, compiled=False)
    assert a.iterations == b.iterations and a.status == b.status
    dt, dr = transform_distance(a.sensor2flange, b.sensor2flange)
    assert dt < 1e-10 and dr < 1e-10


def test_batch_equals_one_by_one_and_recovers_the_truth():
    flanges, xs, centre, start, truth = bench.simulated_batch(6, 31, seed=5)
    poses, info = fast.calibrate_many(flanges, xs, centre, np.broadcast_to(start, (6, 4, 4)))
    assert np.all(info[:, 3] > 0)
    for k in range(6):
        one = fast.calibrate_fast(flanges[k], xs[k], centre, start)
        assert np.allclose(poses[k], one.sensor2flange, atol=1e-12)
        dt, dr = transform_distance(poses[k], truth)
        assert dt < 0.5 and dr < 0.5  # 0.02 mm noise, 31 measurements


@pytest.mark.parametrize("compiled", [True, False])
def test_degenerate_data_are_not_a_calibration(compiled):
    f2b, xs, centre, start = bench.simulated_case(36, seed=3)
    same = np.zeros(36, int)  # one robot pose measured 36 times: the sensor rotation is free
    res = fast.calibrate_fast(f2b[same], xs[same], centre, start, compiled=compiled)
    assert res.status == -3 and not res.converged
    assert "not constrained" in res.message
    res = fast.calibrate_fast(f2b[:1], xs[:1], centre, start, compiled=compiled)
    assert not res.converged


@pytest.mark.slow(sibling=_SECTION)
def test_bench_reports_every_method():
    """The whole benchmark but for the start-up, each section timed once (``reps=1``: every section's
    repetitions are capped by it; repetitions sharpen the timing, which is the benchmark's printout, not a
    test's assertion); the point clouds up to 307,200 points (the benchmark's own 3 million took 35 of this
    test's 54 s: two sizes above 100,000 give the slope)."""
    res = bench.run(reps=1, sizes=(30,), throughput_n=8, with_startup=False, scaling_sizes=(30, 60, 120, 240),
                    pipeline_sizes=(6_000, 12_000), cloud_sizes=(10_240, 102_400, 307_200))
    table = res["cases"]["thesis-real"]
    assert set(table) == {"fast", "fast-vm", "thesis", "scipy-2point", "scipy-exact", "ipopt-matrix"}
    for row in table.values():
        assert row["median_ms"] > 0 and np.isfinite(row["cost"]) and isinstance(row["agrees"], bool)
    assert table["fast-vm"]["agrees"] and table["ipopt-matrix"]["agrees"]
    # scipy's trf is Gauss-Newton-type: on this large-residual cell it converges linearly and
    # stops where the cost's decrease reaches rounding -- the same cost, but some 1e-6 mm short
    # along the flattest direction, by how much depends on the last bits (README, Speed)
    exact = table["scipy-exact"]
    assert abs(exact["cost"] - table["fast"]["cost"]) <= 1e-11 * table["fast"]["cost"]
    assert exact["distance_mm"] < 1e-4 and exact["distance_deg"] < 1e-4
    assert res["speedup_vs_scipy"] > 0 and res["throughput"]["converged"] == 8
    assert len(res["scaling"]["rows"]) >= 4 and np.isfinite(res["scaling"]["slope"])
    text = bench.text(res)
    assert "fast path vs scipy" in text and "log-log slope" in text and "Monte Carlo" in text
    assert np.isfinite(res["use"]["cloud_time_slope"]) and np.isfinite(res["use"]["validate_time_slope"])
    pipe = res["pipeline"]
    # the slope is measured, not asserted: two sizes on a loaded two-core machine gave -0.05 once
    assert [r["exit"] for r in pipe["rows"]] == [0, 0] and np.isfinite(pipe["time_slope"]) and "by size" in text


@pytest.mark.slow(sibling="test_the_pipeline_bench_times_every_stage_against_one_ipopt_solve")
def test_guarantee_overhead_is_measured():
    """The guarantee section's measurement, once (the benchmark repeats it nine times for both
    unknowns)."""
    from handeye.app.tools import bench_guarantee

    g = bench_guarantee.measure("thesis-real", reps=1, unknowns="sensor")
    assert g["with_ms"] > 0 and g["without_ms"] > 0 and g["overhead"] == g["with_ms"] / g["without_ms"] - 1
    assert g["centre_search_ms"] > 0 and g["detective_ms"] > 0
    assert "thesis-real (sensor)" in bench_guarantee.text([g])


@pytest.mark.slow(sibling=_SECTION)
def test_quick_bench_reports_every_section_and_plots(tmp_path, monkeypatch):
    """A small run of every section (the guarantee's measurement, timed above, stubbed; the
    smallest point cloud; no pipeline): the report names each, and the plot is drawn."""
    from handeye.app.tools import bench_guarantee

    monkeypatch.setattr(bench_guarantee, "measure", lambda dataset, reps, unknowns: {
        "dataset": dataset, "unknowns": unknowns, "reps": reps, "with_ms": 2.0, "without_ms": 1.0, "overhead": 1.0,
        "centre_search_ms": 0.1, "detective_ms": 0.2})
    res = bench.run(reps=1, sizes=(30, 100), throughput_n=4, with_startup=False, scaling_sizes=(30, 100),
                    pipeline_sizes=(), cloud_sizes=bench.CLOUD[:1])
    table = res["cases"]["thesis-real"]
    assert set(table) == {"fast", "fast-vm", "thesis", "scipy-2point", "scipy-exact", "ipopt-matrix"}
    assert table["fast-vm"]["agrees"] and table["ipopt-matrix"]["agrees"]
    assert res["throughput"]["converged"] == 4 and "pipeline" not in res
    assert [g["unknowns"] for g in res["guarantee"]] == ["sensor", "sensor+sphere"]
    assert [(r["points"], r["cloud"]["exit"], r["validate"]["exit"]) for r in res["use"]["rows"]] == [(bench.CLOUD[0], 0, 0)]
    text = bench.text(res)
    for section in ("fast path vs scipy", "log-log slope", "Monte Carlo", "global guarantee", "handeye cloud"):
        assert section in text
    bench.plot(res, tmp_path / "bench.png")
    assert (tmp_path / "bench.png").stat().st_size > 10_000


def test_fast_path_refuses_wrong_shapes_instead_of_reading_past_the_arrays():
    f2b, xs, centre, start = bench.simulated_case(30, seed=1)
    with pytest.raises(ValueError, match="shapes"):
        fast.calibrate_fast(f2b, xs[:-1], centre, start)
    with pytest.raises(ValueError, match="shapes"):
        fast.calibrate_fast(f2b, xs, centre[:2], start)
    res = fast.calibrate_fast(f2b, xs, centre, np.asfortranarray(start))  # any memory layout is accepted
    assert res.converged and np.allclose(res.sensor2flange[3], [0, 0, 0, 1])


@pytest.mark.slow(sibling="test_solver_bench_reports_a_failed_study")
def test_solver_bench_reports_both_paths_and_the_study():
    """``handeye bench --solvers`` on a tiny sample: every method has both per-start times,
    their ends agree, the scaling has a slope per method, and the study section comes from
    the study's own files (a real quick run of ``handeye study testfunction``, a subprocess)."""
    _check_solver_bench()


@pytest.mark.slow(sibling="test_solver_bench_reports_a_failed_study")
def test_solver_bench_reports_both_paths_and_the_study_run_in_process(monkeypatch):
    """The same, the study's command run in this process (no interpreter start-up)."""
    import subprocess

    from handeye.app.command.cli import main

    class Done:
        def __init__(self, returncode):
            self.returncode, self.stderr = returncode, ""

    def run(cmd, **kwargs):
        assert cmd[1:3] == ["-m", "handeye.app.command.cli"]
        return Done(main(cmd[3:]))

    monkeypatch.setattr(subprocess, "run", run)
    _check_solver_bench()


def _check_solver_bench():
    from handeye.app.tools import bench_solvers

    rows = bench_solvers.per_start(n_batch=30, n_single=6)
    assert [r["method"] for r in rows] == list(bench_solvers.METHODS)
    for r in rows:
        assert r["single_per_start"] > 0 and r["batch_per_start"] > 0 and r["same_ends"], r
        assert r["single_starts"] == 6 and r["batch_starts"] == (6 if r["method"] == "ipopt" else 30)
    cal = bench_solvers.calibration(n_batch=8, n_single=3)
    assert [r["method"] for r in cal] == [f"{m}/{r}" for m, r in bench_solvers.CALIBRATION_METHODS] + ["lm-fast/local"]
    for r in cal[:-1]:
        assert r["same_ends"] and r["batch_per_start"] > 0, r
    assert cal[0]["converged"] == 1.0 and cal[-1]["converged"] == 1.0  # LM from within 90 deg, both paths
    sc = bench_solvers.scaling(methods=("newton",), sizes=(1000, 2000))
    d = sc["methods"]["newton"]
    assert len(d["seconds"]) == 2 and d["peak_bytes"][1] > d["peak_bytes"][0] > 0
    assert d["time_slope"] is not None and d["memory_slope"] > 0.5  # the state grows with N
    st = bench_solvers.study(quick=True)
    assert st["exit_code"] == 0, st.get("error")
    assert set(st["solves"]) == set(bench_solvers.METHODS) and st["solves"]["newton"] == 2 * 15 * 15 + 2 * 50
    ex = bench_solvers.extrapolated(rows, st["solves"])
    assert ex["solves"] == sum(st["solves"].values()) and ex["speedup"] > 0
    text = bench_solvers.text({"quick": True, "per_start": rows, "calibration": cal, "scaling": sc, "study": st,
                               "extrapolated": ex})
    assert "handeye study testfunction --quick" in text and "estimate" in text
    for method in bench_solvers.METHODS + ("lm-fast/local", "dogleg/local"):
        assert method in text


def test_solver_bench_reports_a_failed_study(monkeypatch):
    """A study that exits non-zero is reported with its exit code, not parsed."""
    import subprocess

    from handeye.app.tools import bench_solvers

    class Done:
        returncode, stderr = 4, "claim failed: xyz"

    monkeypatch.setattr(subprocess, "run", lambda *a, **k: Done())
    st = bench_solvers.study(quick=True)
    assert st["exit_code"] == 4 and "xyz" in st["error"]


def test_the_pipeline_bench_times_every_stage_against_one_ipopt_solve():
    from handeye.app.tools import bench_pipeline

    res = bench_pipeline.pipeline_vs_solve("thesis-sim", reps=1)
    assert set(res["stages"]) == set(bench_pipeline.STAGES) == set(res["stages_no_loo"])
    assert all(v >= 0 for v in res["stages"].values()) and res["ipopt"] > 0 and res["ipopt_converged"]
    assert res["ratio"] == res["total"] / res["ipopt"] and res["total"] >= sum(res["stages"].values()) * 0.999
    assert res["lean"] > 0 and res["lean_converged"] and res["calibrate"] >= res["total"] * 0.5
    assert res["ratio_calibrate_lean"] == res["calibrate"] / res["lean"]
    text = "\n".join(bench_pipeline.text(res))
    assert "one IPOPT solve" in text and "describe" in text and "lean user's solve" in text
    table = "\n".join(bench_pipeline.ratios_text([res], load=[0.5, 0.4, 0.3]))
    assert f"{res['ratio_lean']:.1f}x" in table and "thesis-sim" in table and "load [0.5" in table
    assert bench_pipeline.target(27) == bench_pipeline.target(3_000) == 3.0 and bench_pipeline.target(30_000) == 1.5


def test_the_lean_users_solve_lands_on_calibrates_pose():
    """The bench's reference is a real solve: on thesis-sim's samples it ends at the pose calibrate reports."""
    from handeye.app.engine import calibrate as engine
    from handeye.app.engine.request import CalibrationRequest
    from handeye.app.tools import bench_pipeline

    data = handeye.load_dataset("thesis-sim")
    prep = engine.prepare(CalibrationRequest(loo=False).checked(data), data)
    screened = engine.screen(prep)
    seconds, ok, pose = bench_pipeline._lean_user_solve(screened.used, prep.start_pose, data.sphere_centre)
    result = handeye.calibrate("thesis-sim", no_loo=True, model="centre", effects="none")
    assert ok and seconds > 0
    dt, dr = transform_distance(pose, result.sensor2flange)
    assert dt < 1e-4 and dr < 1e-5, (dt, dr)


def test_a_childs_peak_memory_is_its_own_not_the_bench_processs():
    """``ru_maxrss`` carries the parent's size over fork and exec on Linux: a bench process of
    300 MB would report every child as at least 300 MB. The child reports its own high-water mark."""
    import resource

    ballast = np.ones(300 * 2**20 // 8)  # 300 MB, touched
    own = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    tiny = bench.measure_python("pass", "0")
    assert ballast[-1] == 1.0 and own > 300
    assert tiny["exit"] == 0 and tiny["peak_mb"] is not None
    assert tiny["peak_mb"] < 100 < own / 3  # python -c pass: some 10 MB
    grows = bench.measure_python("import numpy as np; a = np.ones(50 * 2**20 // 8)", "int(a[-1]) - 1")
    assert grows["exit"] == 0 and 50 < grows["peak_mb"] - tiny["peak_mb"] < 150  # the child's own 50 MB seen


def test_the_bench_says_which_machine_and_when():
    """Times and memory mean little without the machine: both benches record it and print it first."""
    from handeye.app.tools import peak

    record = peak.machine()
    assert {"host", "system", "cpus", "load", "python", "date"} <= set(record) and record["cpus"] >= 1
    line = peak.machine_line(record)
    assert line.startswith("machine: ") and record["date"] in line and f"{record['cpus']} cpus" in line
