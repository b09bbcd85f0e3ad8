"""Parallel sweeps for the studies: joblib over the machine's cores, with a progress line.

``handeye study NAME --jobs N`` sets the number of worker processes (default: all cores).
To take a sweep onto a cluster, register joblib's Dask backend before running a study::

    import handeye.studies.study
    from dask.distributed import Client
    from joblib import parallel_config
    client = Client("scheduler-address:8786")
    with parallel_config(backend="dask"):
        handeye.studies.study.run("testfunction", "out")

(``dask[distributed]`` is not a dependency of handeye; install it where the cluster is.)
"""
from __future__ import annotations

import os
import sys

#: Worker processes for sweeps; set by ``--jobs``.
JOBS = {"n": None}


def n_jobs():
    return JOBS["n"] or os.cpu_count() or 1


def run(function, tasks, label="sweep"):
    """``[function(*task) for task in tasks]`` in parallel, printing progress to stderr."""
    from joblib import Parallel, delayed

    tasks = list(tasks)
    results = []
    total = len(tasks)
    with Parallel(n_jobs=n_jobs(), return_as="generator") as parallel:
        for k, result in enumerate(parallel(delayed(function)(*t) for t in tasks), start=1):
            results.append(result)
            if sys.stderr.isatty() or k == total:  # a live bar on a terminal, one line in a log
                bar = "#" * int(30 * k / total)
                print(f"\r{label}: [{bar:<30}] {k}/{total}", end="\n" if k == total else "", file=sys.stderr)
    return results
