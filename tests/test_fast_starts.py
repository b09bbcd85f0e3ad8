"""The compiled per-start loop (``model/fast_starts``) against the numpy batch (``solve_many``).

One suite runs on both paths (the ``engine`` fixture): what every path must do on the test
function. Then the two paths side by side on a grid from both of the basin study's windows:
the same ends to round-off. And the fallback: without a C compiler, or with options the C does
not have, the compiled path declines and the basin study runs on the numpy batch, saying so.
"""
import numpy as np
import pytest

from handeye import solvers
from handeye.app.engine.problems import testfunction_options as options_for
from handeye.app.engine.problems import testfunction_problem as potential_problem
from handeye.model.chain import testfunction
from handeye.model.compiled import ccompile, fast_starts
from handeye.studies import study_testfunction

METHODS = fast_starts.METHODS


def _grid(n=21):
    """n x n starts over each of the basin study's windows (wide and zoom)."""
    out = []
    for lo, hi in ((-50.0, 50.0), (-4.0, 4.0)):
        axis = np.linspace(lo, hi, n)
        out.append(np.stack(np.meshgrid(axis, axis), axis=-1).reshape(-1, 2))
    return np.concatenate(out)


def _numpy(starts, method):
    return solvers.solve_many(potential_problem(), starts, method, options_for(method))


def _compiled(starts, method):
    res = fast_starts.solve_many(starts, method, options_for(method))
    if res is None:
        pytest.skip("no C compiler: the compiled loop is not available")
    return res


@pytest.fixture(params=["numpy", "compiled"])
def engine(request):
    return _numpy if request.param == "numpy" else _compiled


# -- the shared suite: both paths ---------------------------------------------------------------

@pytest.mark.parametrize("method", METHODS)
def test_starts_near_a_minimum_converge_to_it(engine, method):
    points = testfunction.stationary_points()
    offsets = np.array([[0.05, 0.0], [0.0, -0.05], [0.03, 0.03], [-0.04, 0.02]])
    for k, point in enumerate(points[:2]):
        res = engine(point.x + offsets, method)
        assert res.converged.all(), (method, res.status)
        assert (testfunction.end_kind(res.x, res.converged) == k).all()
        assert np.allclose(res.x, point.x, atol=1e-6)


@pytest.mark.parametrize("method", METHODS)
def test_statuses_counts_and_messages_are_the_solvers(engine, method):
    res = engine(_grid(7), method)
    limit = options_for(method)["max_iter"]
    assert set(res.status.tolist()) <= set(solvers.STATUS_MESSAGES)
    assert (res.iterations >= 0).all() and (res.iterations <= limit).all()
    assert (res.nfev >= 1).all() and (res.njev >= (0 if method == "gn" else 1)).all()
    assert ((res.nhev > 0) == (method in ("newton", "newton-ls", "tr"))).all()
    stopped_by_limit = res.status == 0
    assert (res.iterations[stopped_by_limit] == limit).all()
    for i in res.messages:  # only the line searches word their own stops
        assert method in ("newton-ls", "sd", "bfgs") and res.status[i] in (2, -1)
    converged = res.converged & (res.status == 1)
    assert (res.grad_norm[converged] <= 1e-10 * np.maximum(1.0, np.abs(res.cost[converged]))).all()


def test_plain_newton_finds_the_saddle_from_some_starts(engine):
    """The basin study's first claim, on a coarse zoom grid."""
    axis = np.linspace(-4.0, 4.0, 41)
    res = engine(np.stack(np.meshgrid(axis, axis), axis=-1).reshape(-1, 2), "newton")
    assert (testfunction.end_kind(res.x, res.converged) == 2).any()


# -- the two paths side by side ------------------------------------------------------------------

@pytest.mark.parametrize("method", METHODS)
def test_the_compiled_loop_ends_where_the_numpy_batch_ends(method):
    starts = _grid()
    ref, loop = _numpy(starts, method), _compiled(starts, method)
    kind_ref = testfunction.end_kind(ref.x, ref.converged)
    kind_loop = testfunction.end_kind(loop.x, loop.converged)
    assert np.mean(kind_ref == kind_loop) >= 0.998, np.flatnonzero(kind_ref != kind_loop)
    both = (kind_ref == kind_loop) & (kind_ref < 3)
    assert np.abs(ref.x[both] - loop.x[both]).max() <= 1e-6  # at a stationary point: round-off apart
    assert np.mean(ref.converged == loop.converged) >= 0.998
    # where no stop sits at rounding level, the iterations are the same, step for step
    assert np.mean(ref.iterations == loop.iterations) >= (0.99 if method in ("newton", "newton-ls", "sd", "tr") else 0.8)


def test_the_comparison_is_not_vacuous():
    """A compiled loop that ran another method would fail the comparison above."""
    starts = _grid(11)
    ref, other = _numpy(starts, "newton"), _compiled(starts, "tr")
    kinds = [testfunction.end_kind(r.x, r.converged) for r in (ref, other)]
    assert np.mean(kinds[0] == kinds[1]) < 0.998


# -- declining, and the fallback -------------------------------------------------------------------

def test_the_compiled_loop_declines_what_it_does_not_have():
    starts = _grid(3)
    assert fast_starts.solve_many(starts, "ipopt") is None
    assert fast_starts.solve_many(starts, "dogleg") is None
    assert fast_starts.solve_many(starts, "gn", {"jacobian": "forward"}) is None
    assert fast_starts.solve_many(starts, "tr", {"subproblem": "cg"}) is None
    assert not fast_starts.supports("tr", {"subproblem": "cg"}) and fast_starts.supports("tr")
    empty = fast_starts.solve_many(np.zeros((0, 2)), "lm")
    assert empty is None or len(empty) == 0


def test_no_compiler_no_library(tmp_path, monkeypatch):
    monkeypatch.setenv("HANDEYE_CACHE", str(tmp_path))
    monkeypatch.setattr(ccompile, "compiler", lambda: None)
    assert ccompile.cached_library("nothing", {"a.c": "int he_x(void) { return 0; }\n"}, ccompile.CFLAGS,
                                   ("he_x",)) is None
    assert not list(tmp_path.rglob("*.so"))


def test_the_basin_study_falls_back_to_the_numpy_batch_and_says_so(monkeypatch):
    starts = _grid(5)
    with_c = study_testfunction._ends("lm", starts)
    monkeypatch.setattr(fast_starts, "library", lambda: None)
    assert study_testfunction.engine("lm") == study_testfunction.NUMPY
    assert study_testfunction.engine("ipopt") != study_testfunction.COMPILED
    without = study_testfunction._ends("lm", starts)
    assert np.array_equal(study_testfunction.classify(with_c), study_testfunction.classify(without))
    ref = _numpy(starts, "lm")
    assert np.array_equal(without[:, :2], ref.x) and np.array_equal(without[:, 3], ref.iterations)


def test_the_solver_bench_sets_both_paths_side_by_side():
    from handeye.app.tools import bench_solvers

    res = bench_solvers.compiled(methods=("newton", "lm"), n=40)
    assert [r["method"] for r in res["rows"]] == ["newton", "lm"] and res["starts"] == 40
    for r in res["rows"]:
        assert r["numpy_seconds"] > 0
        if r["compiled_seconds"] is not None:
            assert r["ratio"] > 0 and r["same_ends"] >= 0.95
    text = "\n".join(bench_solvers._compiled_text(res))
    assert "numpy batch against the compiled per-start loop" in text and "newton" in text
