"""Batched solvers (``solve_many``) against single starts (``solve``), the linear algebra on
stacks, and the batch's bookkeeping (a row that fails, a row at its limit, an empty batch).

The full comparison, 2000 starts per method, is the ``batch-equivalence`` study; here a
smaller sample from the same generator and the same comparison code.
"""
import dataclasses

import numpy as np
import pytest

from handeye import solvers
from handeye.app.engine import problems
from handeye.app.engine.problems import calibration_problem
from handeye.app.engine.problems import testfunction_problem as potential_problem
from handeye.model.chain.pose import transform_from_pose
from handeye.model.datasets.dataset import load
from handeye.model.fit.calibration import CalibrationModel
from handeye.solvers import Problem, UnsupportedProblem, solve, solve_many, stacks
from handeye.studies import study_batch
from handeye.studies.study_testfunction import METHODS


def _start_counts():
    """24 starts per method in the default tier (steepest descent's, thousands of iterations each, 12);
    80 per method (IPOPT 24) in the full suite: :func:`test_every_method_over_80_starts`."""
    for method in METHODS:
        yield pytest.param(method, 12 if method == "sd" else 24, id=method)


def _same_ends(method, n):
    """Batch and single runs of ``n`` test-function starts end at the same stationary point, in as many iterations
    (to one), with no exception."""
    starts = problems.testfunction_starts(n, seed=5)
    c = study_batch.compare(method, starts, chunks=1)
    assert c.same_end.mean() >= 0.999, (method, c.exceptions())
    assert c.iteration_gap[c.same_end].max() <= 1, (method, c.exceptions())
    assert not c.exceptions()
    d = c.to_dict()
    assert d["starts"] == len(starts) and d["exceptions"] == []


@pytest.mark.parametrize("method,n", list(_start_counts()))
def test_batch_and_single_starts_end_at_the_same_stationary_point(method, n):
    _same_ends(method, n)


@pytest.mark.slow(sibling="test_batch_and_single_starts_end_at_the_same_stationary_point[newton-ls]")
def test_every_method_over_80_starts():
    """As the default tier's test, on 80 starts per method (IPOPT's 24 there already)."""
    for method in METHODS:
        if method != "ipopt":
            _same_ends(method, 80)


def test_a_different_row_would_be_caught():
    """The comparison is not vacuous: a batch that ends elsewhere is an exception."""
    starts = problems.testfunction_starts(10, seed=1)
    c = study_batch.compare("lm", starts, chunks=1)
    c.batch[3, :2] = [50.0, 50.0]
    c.same_end[3] = False
    c.batch[5, 3] += 2
    assert [e["start"] for e in c.exceptions()] == [starts[3].tolist(), starts[5].tolist()]


def _calibration(rotation):
    d = load("thesis-sim")
    model = CalibrationModel(d.flange2base(), d.centre_in_sensor, d.sphere_centre, rotation)
    rng = np.random.default_rng(4)
    poses = [[20, 10, 15, 5, -80, 3], [6, 1, 4, 1, -89, 1]]
    poses += [[*rng.uniform(-30, 30, 3), *rng.uniform(-10, 10, 3) + [0, -80, 0]] for _ in range(3)]
    return calibration_problem(model), np.stack([model.point_from(transform_from_pose(p)) for p in poses])


def _one_point_at_a_time(problem):
    """The same problem with callables that take one point (``vectorised=False``)."""
    def one(fn):
        return None if fn is None else (lambda *args: fn(*(np.asarray(a, float) for a in args)))

    return dataclasses.replace(problem, residual=one(problem.residual), jacobian=one(problem.jacobian),
                               hessian=one(problem.hessian), retract=one(problem.retract), vectorised=False)


@pytest.mark.parametrize("method,rotation,vectorised",
                         [(m, r, v) for m in ("gn", "lm", "newton", "newton-ls", "bfgs", "tr", "dogleg")
                          for r in ("euler", "local") for v in (True, False)])
def test_calibration_starts_end_in_a_batch_where_they_end_alone(method, rotation, vectorised):
    """The calibration model evaluates stacks of points (``local`` moves through its
    retraction on stacks); a wrapper taking one point at a time runs row by row. Either way
    every start ends bit for bit where it ends alone."""
    problem, starts = _calibration(rotation)
    assert problem.vectorised
    if not vectorised:
        problem = _one_point_at_a_time(problem)
    batch = solve_many(problem, starts, method)
    for i, x0 in enumerate(starts):
        one = solve(problem, x0, method)
        np.testing.assert_array_equal(batch.x[i], one.x)
        assert batch.iterations[i] == one.iterations and batch.status[i] == one.status
        assert batch.nfev[i] == one.nfev and batch.njev[i] == one.njev
        assert batch.message(i) == one.message


def test_a_failing_row_stops_alone():
    """A start where f is not finite stops with status -1; its neighbours end as they would alone."""
    problem = potential_problem()
    starts = np.array([[3.0, 3.0], [np.nan, 1.0], [-1.2, -2.3], [40.0, -35.0]])
    for method in ("newton", "sd", "bfgs", "gn", "lm", "tr", "dogleg"):
        batch = solve_many(problem, starts, method)
        assert batch.status[1] == -1 and not batch.converged[1]
        for i in (0, 2, 3):
            one = solve(problem, starts[i], method)
            np.testing.assert_array_equal(batch.x[i], one.x)
            assert batch.iterations[i] == one.iterations


def test_rows_at_the_iteration_limit_and_the_summary():
    problem = potential_problem()
    starts = np.array([[3.0, 3.0], [45.0, 45.0], [-1.2, -2.3]])
    batch = solve_many(problem, starts, "sd", {"max_iter": 5})
    assert list(batch.status) == [0, 0, 0] and list(batch.iterations) == [5, 5, 5]
    d = batch.to_dict()
    assert d["starts"] == 3 and d["converged"] == 0.0 and d["status"] == {0: {"count": 3, "message": solvers.STATUS_MESSAGES[0]}}
    assert len(batch) == 3


def test_an_empty_batch_and_bad_shapes():
    problem = potential_problem()
    empty = solve_many(problem, np.zeros((0, 2)), "lm")
    assert len(empty) == 0 and empty.x.shape == (0, 2)
    with pytest.raises(UnsupportedProblem, match="stack of points"):
        solve_many(problem, [1.0, 2.0], "lm")


def test_vectorised_problem_of_my_own():
    """A user's vectorised least-squares problem (Rosenbrock), stacks in and out."""
    def residual(x):
        x = np.atleast_2d(x)
        return np.stack([10 * (x[:, 1] - x[:, 0] ** 2), 1 - x[:, 0]], axis=-1)

    def jacobian(x):
        x = np.atleast_2d(x)
        z = np.zeros(len(x))
        return np.stack([np.stack([-20 * x[:, 0], 10 + z], -1), np.stack([-1 + z, z], -1)], axis=1)

    problem = Problem(n=2, residual=residual, jacobian=jacobian, vectorised=True)
    starts = np.random.default_rng(2).uniform(-2, 2, size=(50, 2))
    batch = solve_many(problem, starts, "lm")
    assert batch.converged.all()
    np.testing.assert_allclose(batch.x, 1.0, atol=1e-6)


def test_stack_algebra_against_numpy_row_by_row():
    rng = np.random.default_rng(0)
    for width in (1, 2, 6, stacks.NARROW, stacks.NARROW + 3):
        a, b = rng.normal(size=(7, width)), rng.normal(size=(7, width))
        m = rng.normal(size=(7, 5, width))
        np.testing.assert_allclose(stacks.dot_rows(a, b), [ai @ bi for ai, bi in zip(a, b)], rtol=1e-14)
        np.testing.assert_allclose(stacks.norm_rows(a), np.linalg.norm(a, axis=1), rtol=1e-14)
        np.testing.assert_array_equal(stacks.max_abs_rows(a), np.abs(a).max(axis=1))
        np.testing.assert_allclose(stacks.matvec(m, a), [mi @ ai for mi, ai in zip(m, a)], rtol=1e-13, atol=1e-14)
        np.testing.assert_allclose(stacks.transpose_times(m, rng.normal(size=(7, 5))).shape, (7, width))
        sq = rng.normal(size=(7, width, width))
        np.testing.assert_allclose(stacks.quad_rows(a, sq), [ai @ si @ ai for ai, si in zip(a, sq)], rtol=1e-12)
        bad = a.copy()
        bad[2, -1] = np.nan
        bad[4, 0] = np.inf
        assert list(stacks.finite_rows(bad, b)) == [True, True, False, True, False, True, True]
    tall = rng.normal(size=(5, 6, 3))
    tall[1] = np.outer(rng.normal(size=6), [1.0, 2.0, 3.0])  # rank one
    rhs = rng.normal(size=(5, 6))
    p, rank = stacks.lstsq_rows(tall, rhs)
    for i in range(5):
        ref, _, r, _ = np.linalg.lstsq(tall[i], rhs[i], rcond=None)
        np.testing.assert_allclose(p[i], ref, rtol=1e-10, atol=1e-12)
        assert rank[i] == r
    sing = np.array([[[1.0, 2.0], [2.0, 4.0]], [[2.0, 0.0], [0.0, 3.0]]])
    x, ok = stacks.solve_rows(sing, np.ones((2, 2)))
    assert list(ok) == [False, True]
    np.testing.assert_allclose(x[1], [0.5, 1 / 3])


def test_a_row_computes_the_same_alone_and_in_a_crowd():
    """The stack functions give bit-identical rows for a stack of one and of many."""
    rng = np.random.default_rng(9)
    for width in (2, 6, 20):
        a, b = rng.normal(size=(300, width)), rng.normal(size=(300, width))
        m = rng.normal(size=(300, width, width))
        for f, args in ((stacks.dot_rows, (a, b)), (stacks.norm_rows, (a,)), (stacks.matvec, (m, a)),
                        (stacks.quad_rows, (a, m)), (stacks.half_squares, (a,))):
            crowd = f(*args)
            alone = np.array([f(*(x[i : i + 1] for x in args))[0] for i in range(0, 300, 37)])
            np.testing.assert_array_equal(crowd[::37], alone)
