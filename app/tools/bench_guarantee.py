"""What the global guarantee costs: the default run with and without the global step and the
convention detective, side by side in one process (``handeye bench``'s ``guarantee`` section).

"Without" is today's pipeline with the two steps switched off (the centre-model search and
the extra final fits of :mod:`handeye.app.engine.guarantee`, the readings of
:mod:`handeye.app.engine.detective`); runs alternate between the two so that a machine's drift hits
both alike, and the medians are compared. The steps' own parts are timed alone as well.
"""
from __future__ import annotations

import contextlib

import numpy as np

import handeye
from handeye.app.tools.peak import timed


@contextlib.contextmanager
def _without_guarantee():
    """The pipeline without the global step and the detective (restored on exit)."""
    from handeye.app.engine import guarantee, slips

    saved = guarantee.centre_basin, guarantee.lowest, slips._check_conventions
    guarantee.centre_basin = lambda dataset, unknowns: None
    guarantee.lowest = lambda fit, basin, solve, exact_centre_model=False: (fit, None, None)
    slips._check_conventions = lambda *args: None
    try:
        yield
    finally:
        guarantee.centre_basin, guarantee.lowest, slips._check_conventions = saved


def _median_ms(function, reps):
    return 1e3 * float(np.median(timed(function, reps)[0]))


def measure(dataset="thesis-real", reps=7, unknowns="sensor"):
    """Median default-run times (ms) with and without the guarantee, and its parts alone.

    Returns
    -------
    dict
        ``with_ms``, ``without_ms``, ``overhead`` (with / without - 1), ``centre_search_ms``,
        ``detective_ms`` (every reading of the poses scored), ``dataset``, ``reps``.
    """
    from handeye.app.engine import detective, guarantee

    data = handeye.load_dataset(dataset)

    def run():
        handeye.calibrate(data, unknowns=unknowns)

    run()  # warm: generated code, caches
    with_ms, without_ms = [], []
    for _ in range(reps):
        with_ms.append(_median_ms(run, 1))
        with _without_guarantee():
            without_ms.append(_median_ms(run, 1))
    w, wo = float(np.median(with_ms)), float(np.median(without_ms))
    return {"dataset": dataset, "unknowns": unknowns, "reps": reps, "with_ms": w, "without_ms": wo,
            "overhead": w / wo - 1.0,
            "centre_search_ms": _median_ms(lambda: guarantee.centre_basin(data, unknowns), reps),
            "detective_ms": _median_ms(lambda: detective.best(data, unknowns), reps)}


def text(rows):
    lines = ["global guarantee (centre-model search, extra final fits, convention detective) in the default run:"]
    lines += [f"  {r['dataset']} ({r['unknowns']}): {r['with_ms']:.0f} ms with, {r['without_ms']:.0f} ms without "
              f"({100 * r['overhead']:+.1f} %); alone: centre search {r['centre_search_ms']:.2f} ms, detective "
              f"{r['detective_ms']:.1f} ms (median of {r['reps']})" for r in rows]
    return "\n".join(lines)
