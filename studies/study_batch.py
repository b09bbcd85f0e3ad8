"""Study: the batched solvers end where the single-start solvers end.

Story. ``handeye.solvers.solve_many`` runs many starts at once (state arrays of shape (N, d),
per-row step acceptance, line search, trust radius and stopping); ``handeye.solvers.solve``
is the same code at N = 1. Sharing the code is not proof that rows do not leak into each
other (a mask applied to the wrong rows, a radius updated for a stopped row), nor that a
row's arithmetic does not depend on how many rows run beside it. So every method is run from
the same random starts on the test function (6-16), half over [-50, 50]^2 and half over
[-4, 4]^2 (the basin study's two windows), once as a batch and once start by start, and the
two ends are compared: the same stationary point (global minimum, local minimum, saddle,
or none), or both failed, and iteration counts that differ by at most one. Every exception is
listed with its start, its two ends and statuses.

Model: :func:`handeye.app.engine.problems.testfunction_problem` (vectorised callables). Data: 2000
seeded random starts per method (``--quick``: 60). Solve: ``solve_many`` once per method;
``solve`` per start, in parallel through the sweep. IPOPT has no batch form: its batch is a
loop over one solver object built once, compared all the same.

Claims: for every method, at least 99.9 % of the starts end at the same stationary point in
both runs, and every iteration count differs by at most one outside the listed exceptions.
"""
from __future__ import annotations

import dataclasses
import time

import numpy as np

from handeye import solvers
from handeye.app.engine.problems import testfunction_options as options_for
from handeye.app.engine.problems import testfunction_problem, testfunction_starts
from handeye.app.tools import sweep
from handeye.studies.study import claim, figure, save, write_summary, write_table
from handeye.studies.study_testfunction import KINDS, METHODS, classify

__all__ = ["Comparison", "compare", "run"]


def _singles(method, starts):
    """``solve`` from each start: (x1, x2, converged, iterations, status) per row."""
    problem = testfunction_problem()
    out = []
    for x0 in starts:
        res = solvers.solve(problem, x0, method, options_for(method))
        out.append((*res.x, float(res.converged), res.iterations, res.status))
    return out


@dataclasses.dataclass
class Comparison:
    """One method's batch against its single starts.

    Attributes
    ----------
    method : str
    starts : ndarray, shape (N, 2)
    batch, single : ndarray, shape (N, 5)
        x1, x2, converged, iterations, status of each run.
    same_end : ndarray of bool, shape (N,)
        Both runs end at the same stationary point (same class of :data:`KINDS`, and within
        1e-8 of each other when they converged), or both fail.
    bit_identical : ndarray of bool, shape (N,)
        The two ends are the same floating-point numbers.
    batch_seconds, single_seconds : float
        Wall-clock time of the two runs (the single starts run on the sweep's workers).
    """

    method: str
    starts: np.ndarray
    batch: np.ndarray
    single: np.ndarray
    same_end: np.ndarray
    bit_identical: np.ndarray
    batch_seconds: float
    single_seconds: float

    @property
    def iteration_gap(self):
        """|batch iterations - single iterations| per start."""
        return np.abs(self.batch[:, 3] - self.single[:, 3]).astype(int)

    def exceptions(self):
        """Starts where the ends differ or the iteration counts differ by more than one."""
        bad = np.flatnonzero(~self.same_end | (self.iteration_gap > 1))
        kb, ks = classify(self.batch), classify(self.single)
        return [{"start": self.starts[i].tolist(), "batch_end": KINDS[kb[i]], "single_end": KINDS[ks[i]],
                 "batch_x": self.batch[i, :2].tolist(), "single_x": self.single[i, :2].tolist(),
                 "batch_iterations": int(self.batch[i, 3]), "single_iterations": int(self.single[i, 3]),
                 "batch_status": int(self.batch[i, 4]), "single_status": int(self.single[i, 4])} for i in bad]

    def to_dict(self):
        return {"method": self.method, "starts": len(self.starts), "same_end": float(np.mean(self.same_end)),
                "bit_identical": float(np.mean(self.bit_identical)),
                "max_iteration_gap": int(self.iteration_gap.max()) if len(self.starts) else 0,
                "exceptions": self.exceptions(), "batch_seconds": self.batch_seconds,
                "single_seconds": self.single_seconds,
                "speedup": self.single_seconds / self.batch_seconds if self.batch_seconds > 0 else float("nan")}


def compare(method, starts, chunks=8):
    """Run ``method`` from ``starts`` (N, 2) as one batch and start by start; compare the ends."""
    problem = testfunction_problem()
    t0 = time.perf_counter()
    res = solvers.solve_many(problem, starts, method, options_for(method))
    batch_seconds = time.perf_counter() - t0
    batch = np.column_stack([res.x, res.converged, res.iterations, res.status]).astype(float)
    t0 = time.perf_counter()
    parts = sweep.run(_singles, [(method, c) for c in np.array_split(starts, max(1, min(chunks, len(starts))))],
                      label=f"single starts {method}")
    single_seconds = time.perf_counter() - t0
    single = np.array([row for part in parts for row in part], dtype=float).reshape(len(starts), 5)
    kb, ks = classify(batch), classify(single)
    both = (batch[:, 2] > 0) & (single[:, 2] > 0)
    close = np.linalg.norm(batch[:, :2] - single[:, :2], axis=1) <= 1e-8 * (1 + np.linalg.norm(single[:, :2], axis=1))
    same_end = (kb == ks) & (~both | close)
    bit = np.all(batch[:, :2] == single[:, :2], axis=1)
    return Comparison(method, np.asarray(starts, float), batch, single, same_end, bit, batch_seconds, single_seconds)


def run(out, quick=False):
    # -- data: the same starts for every method -------------------------------------------
    n = 60 if quick else 2000
    starts = testfunction_starts(n, seed=16)
    # -- solve ------------------------------------------------------------------------------
    results = [compare(method, starts) for method in METHODS]
    # -- report -----------------------------------------------------------------------------
    rows = []
    for c in results:
        d = c.to_dict()
        rows.append((c.method, d["starts"], d["same_end"], d["bit_identical"], d["max_iteration_gap"],
                     len(d["exceptions"]), d["batch_seconds"], d["single_seconds"], d["speedup"]))
    write_table(out, "batch_equivalence", ["method", "starts", "same_end", "bit_identical", "max_iteration_gap",
                                           "exceptions", "batch_s", "single_s", "speedup"], rows)
    exceptions = [(c.method, *e.values()) for c in results for e in c.exceptions()]
    write_table(out, "batch_exceptions", ["method", "start", "batch_end", "single_end", "batch_x", "single_x",
                                          "batch_iterations", "single_iterations", "batch_status", "single_status"],
                exceptions)
    summary = {"starts_per_method": n, "seed": 16, "ipopt": "no batch form: one solver object, starts in a loop",
               "options": {m: options_for(m) for m in METHODS}, "methods": {c.method: c.to_dict() for c in results}}
    write_summary(out, summary)
    fig, ax = figure().subplots(figsize=(7, 3.5))
    ax.bar(range(len(results)), [c.to_dict()["speedup"] for c in results])
    ax.set_xticks(range(len(results)), [c.method for c in results])
    ax.set(yscale="log", ylabel="single-start time / batch time",
           title=f"same ends from {n} starts per method; the batch's speed-up")
    save(fig, out / "batch_speedup.png")
    for c in results:
        d = c.to_dict()
        claim(d["same_end"] >= 0.999, f"{c.method}: batch and single starts end at the same stationary point "
                                      f"({100 * d['same_end']:.2f} % of {n})")
        gaps = c.iteration_gap[c.same_end]
        claim(gaps.size == 0 or gaps.max() <= 1, f"{c.method}: iteration counts differ by at most one")
    return summary

