"""Parallel sweeps for the studies: joblib over this machine's cores, or a Dask cluster.

A study hands :func:`run` a function and its argument tuples; the backend comes from the
innermost :func:`using` block (default: joblib over all cores)::

    from handeye.app.tools import sweep
    from handeye.studies import study

    with sweep.using(jobs=2):                       # handeye study NAME --jobs 2
        study.run("random-starts", "out", quick=True)
    with sweep.using(dask="local"):                 # handeye study NAME --dask local
        study.run("random-starts", "out", quick=True)
    with sweep.using(dask="tcp://scheduler:8786"):  # handeye study NAME --dask tcp://scheduler:8786
        study.run("testfunction", "out")

``dask="local"`` starts a ``distributed.LocalCluster`` with one single-threaded worker process
per core (``jobs`` of them when given); an address connects to a running scheduler (``dask
scheduler`` and ``dask worker ADDRESS`` on the machines, or a SLURM / Kubernetes deployment
through dask-jobqueue / dask-kubernetes). The cluster is started once per ``using`` block.
Results come back in task order whatever the backend, and the studies draw every random
number in the calling process, so a sweep's results do not depend on where it ran.
Tasks and results travel pickled: study functions take data, not paths, so that workers on
other machines need nothing but handeye installed (``pip install 'handeye[dask]'``).
"""
from __future__ import annotations

import contextlib
import dataclasses
import os
import signal
import sys

from handeye.app.common.errors import RequestError


@dataclasses.dataclass(frozen=True)
class Backend:
    """Where sweeps run: the request of ``handeye study``'s ``--jobs`` and ``--dask``, checked when
    made (what the cluster says of its address is said where it is reached, :func:`using`).

    Attributes
    ----------
    jobs : int or None
        joblib worker processes (None: all cores); with ``dask="local"``, the workers.
    dask : str or None
        ``"local"`` or a scheduler address; None: joblib.
    """

    jobs: int | None = None
    dask: str | None = None

    def __post_init__(self):
        if self.jobs is not None and self.jobs < 1:
            raise RequestError("--jobs must be at least 1")
        if self.jobs is not None and self.dask not in (None, "local"):
            raise RequestError("--jobs applies to --dask local only; a cluster has the workers it was started with")


_STACK = [Backend()]
_CLIENTS = {}


def backend():
    """The :class:`Backend` in force."""
    return _STACK[-1]


def n_jobs():
    """Parallel workers of the backend in force (joblib processes, or Dask worker threads)."""
    b = backend()
    if b.dask is not None and id(b) in _CLIENTS:
        return max(1, sum(_CLIENTS[id(b)].nthreads().values()))
    return b.jobs or os.cpu_count() or 1


@contextlib.contextmanager
def using(jobs=None, dask=None):
    """Run the sweeps inside the block on ``jobs`` processes or on a Dask cluster."""
    b = Backend(jobs, dask)
    _STACK.append(b)
    try:
        if dask is not None:
            with _dask_client(b) as client:
                _CLIENTS[id(b)] = client
                try:
                    yield b
                finally:
                    del _CLIENTS[id(b)]
        else:
            yield b
    finally:
        _STACK.pop()


@contextlib.contextmanager
def _dask_client(b):
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise RequestError("--dask needs Dask's distributed scheduler: pip install 'handeye[dask]'") from None
    if b.dask == "local":
        workers = b.jobs or os.cpu_count() or 1
        with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
            with Client(cluster) as client:
                yield client
    else:
        try:
            client = Client(b.dask, timeout="20s")
        except ValueError as exc:
            raise RequestError(f"--dask {b.dask!r} is not a scheduler address (tcp://HOST:PORT) or 'local': {exc}") from None
        except (OSError, TimeoutError) as exc:
            raise RequestError(f"--dask {b.dask}: no Dask scheduler answered ({exc})") from None
        with client:
            yield client


def _progress(label, k, total):
    if sys.stderr.isatty() or k == total:  # a live bar on a terminal, one line in a log
        print(f"\r{label}: [{'#' * int(30 * k / total):<30}] {k}/{total}", end="\n" if k == total else "", file=sys.stderr)


def _scatter_shared(client, tasks):
    """Arguments that are the same object in every task (a dataset, a model) are sent to the
    workers once, not pickled into each task."""
    shared = [j for j in range(len(tasks[0]))
              if len(tasks) > 1 and all(len(t) == len(tasks[0]) and t[j] is tasks[0][j] for t in tasks)
              and not isinstance(tasks[0][j], (int, float, str, bool, type(None)))]
    if not shared:
        return tasks
    futures = {j: client.scatter(tasks[0][j], broadcast=True, hash=False) for j in shared}
    return [tuple(futures.get(j, a) for j, a in enumerate(t)) for t in tasks]


def _in_worker(parent, function, *args):
    """``function(*args)``; in a worker process, Ctrl-C is left to the parent (the terminal sends
    it to the whole process group): the parent ends the run with one line and stops the workers
    (SIGTERM, :func:`_worker_end`); a worker's IPOPT would only add its own warning."""
    if os.getpid() != parent:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, _worker_end)
    return function(*args)


def _worker_end(signum, frame):
    """SIGTERM in a worker (the parent's handler sends it on its way out): its temporary files
    go, and it ends at once, silently (the parent says the one line)."""
    from handeye.model.common import scratch

    try:
        scratch.remove_all()
    finally:
        os._exit(128 + signum)


def run(function, tasks, label="sweep"):
    """``[function(*task) for task in tasks]`` on the backend in force, in task order, printing
    progress to stderr."""
    tasks = list(tasks)
    total = len(tasks)
    b = backend()
    if not tasks:
        return []
    if b.dask is not None:
        from distributed import as_completed

        client = _CLIENTS[id(b)]
        tasks = _scatter_shared(client, tasks)
        futures = [client.submit(function, *t, pure=False) for t in tasks]
        for k, _ in enumerate(as_completed(futures), start=1):
            _progress(label, k, total)
        return client.gather(futures)
    from joblib import Parallel, delayed

    results = []
    parent = os.getpid()
    with Parallel(n_jobs=n_jobs(), return_as="generator") as parallel:
        for k, result in enumerate(parallel(delayed(_in_worker)(parent, function, *t) for t in tasks), start=1):
            results.append(result)
            _progress(label, k, total)
    return results
