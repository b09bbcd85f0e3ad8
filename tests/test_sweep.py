"""Sweeps give the same results wherever they run: joblib processes or a Dask cluster.

The Dask tests use a real ``distributed.LocalCluster`` (worker processes, not threads).
"""
import time

import pytest

from handeye.app.command import cli
from handeye.app.tools import sweep


def _slow_square(x, delay):
    time.sleep(delay)
    return x * x


def test_using_sets_the_backend_for_its_block_only():
    with sweep.using(jobs=2) as b:
        assert sweep.backend() is b and sweep.n_jobs() == 2
        assert sweep.run(_slow_square, [(k, 0.0) for k in range(4)]) == [0, 1, 4, 9]
    assert sweep.backend() == sweep.Backend()


def test_dask_local_cluster_sweeps_return_results_in_task_order():
    pytest.importorskip("distributed")
    with sweep.using(jobs=2, dask="local") as b:
        assert sweep.n_jobs() == 2 and b.dask == "local"
        # later tasks finish first: the results must still come back in task order
        assert sweep.run(_slow_square, [(k, 0.05 * (5 - k)) for k in range(6)]) == [k * k for k in range(6)]


@pytest.mark.slow(sibling="test_dask_local_cluster_sweeps_return_results_in_task_order")
def test_random_starts_on_dask_gives_the_same_summary_as_two_jobs(tmp_path, monkeypatch):
    """The quick study on 8 starts (drawn in this process, they travel with the tasks): every sweep of each run on
    its backend, the same tables from both."""
    from handeye.studies import study_random_starts

    pytest.importorskip("distributed")
    monkeypatch.setattr(study_random_starts, "QUICK_STARTS", 8)
    ran_on = []
    real_run = sweep.run

    def spy(function, tasks, label="sweep"):
        ran_on.append(sweep.backend().dask)
        return real_run(function, tasks, label)

    monkeypatch.setattr(sweep, "run", spy)
    assert cli.main(["study", "random-starts", "--quick", "--jobs", "2", "--out", str(tmp_path / "jobs")]) == cli.EXIT_OK
    first = list(ran_on)
    ran_on.clear()
    assert cli.main(["study", "random-starts", "--quick", "--dask", "local", "--out", str(tmp_path / "dask")]) == cli.EXIT_OK
    # the study sweeps twice (batched plain runs, then calibrate start by start): every sweep of
    # the first run ran on joblib, every sweep of the second on the cluster
    assert first and set(first) == {None}
    assert ran_on and set(ran_on) == {"local"}
    for name in ("summary.json", "random_starts.csv"):
        jobs = (tmp_path / "jobs" / "random-starts" / name).read_text()
        dask = (tmp_path / "dask" / "random-starts" / name).read_text()
        assert jobs == dask, name


def test_bad_dask_requests_are_request_errors():
    pytest.importorskip("distributed")
    from handeye.app.common.errors import RequestError

    with pytest.raises(RequestError, match="--jobs"):
        with sweep.using(jobs=2, dask="tcp://127.0.0.1:1"):
            pass
    with pytest.raises(RequestError, match="not a scheduler address"):
        with sweep.using(dask="no such thing://"):
            pass


def test_dask_without_distributed_installed_is_a_clear_request_error(without_package):
    without_package("distributed")
    from handeye.app.common.errors import RequestError

    with pytest.raises(RequestError, match=r"handeye\[dask\]"):
        with sweep.using(dask="local"):
            pass
