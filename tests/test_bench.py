"""The benchmark runs and every fast-path result agrees with the reference methods (speed is
measured by `handeye bench`, never asserted here)."""
import numpy as np

from model import fast
from model.rotation import transform_distance
from studies import bench


def test_fast_path_matches_the_exact_least_squares_solution():
    for case in (bench.real_case(), bench.simulated_case(30, seed=1)):
        f2b, xs, centre, start = case
        t, its, cost, ok = fast.calibrate_fast(f2b, xs, centre, start)
        methods = bench._methods(f2b, xs, centre, start, len(xs))
        ref, _, ref_cost = methods["scipy-exact"]()
        assert ok and abs(cost - ref_cost) <= 1e-9 * max(1.0, ref_cost)
        dt, dr = transform_distance(t, ref)
        assert dt < 1e-5 and dr < 1e-5


def test_bench_reports_every_method(capsys):
    res = bench.run(reps=1, sizes=(), throughput_n=4)
    table = res["cases"]["thesis-real"]
    assert set(table) == {"fast", "thesis", "scipy-2point", "scipy-exact", "ipopt-matrix"}
    for row in table.values():
        assert row["median_ms"] > 0 and np.isfinite(row["cost"]) and isinstance(row["agrees"], bool)
    assert res["speedup_vs_scipy"] > 0 and res["throughput_per_s"] > 0
    assert "fast path vs scipy" in bench.text(res)
