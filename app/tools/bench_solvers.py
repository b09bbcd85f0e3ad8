"""``handeye bench --solvers``: the solver-comparison study, batched against single starts.

Sections, in one process and one run:

* ``study`` -- the wall time of ``handeye study testfunction`` run as a user runs it (the CLI
  in a subprocess, with the sweep's workers): full, both 301 x 301 windows, every method,
  Table 7-1's x0max search and replay; ``--quick``: the 15 x 15 version. Its phases come from
  the study's ``timing.json`` and its solve counts from its ``summary.json``.
* ``per_start`` -- per method, the time per start of the single-start path
  (:func:`handeye.solvers.solve`, one start at a time, on a sample) and of the batch
  (:func:`handeye.solvers.solve_many` over all the starts at once), both here on one core,
  from the same seeded starts over the study's two windows; the ratio beside them.
* ``extrapolated`` -- the study's solve counts at the two paths' per-start times: what its
  solves cost on one core without the batch (an estimate, labelled as one), and with it.
* ``compiled`` -- per batchable method, the numpy batch against the compiled per-start loop
  (:mod:`handeye.model.compiled.fast_starts`, C) over the same seeded starts, both on one core, the
  ratio, and the share of starts that end alike (at the same stationary point, or at none,
  as the basin study classifies them); a total line over all of them.
* ``scaling`` -- the batch's time and peak memory (``tracemalloc``, numpy's buffers included)
  against the number of starts N, with the log-log slope per method.

Timing is measured here, never in tests.
"""
from __future__ import annotations

import json
import os
import pathlib
import subprocess
import sys
import tracemalloc

import numpy as np

from handeye import solvers
from handeye.app.engine.problems import calibration_problem, testfunction_options, testfunction_problem, testfunction_starts
from handeye.app.tools.peak import machine, machine_line, once, timed
from handeye.model.chain import testfunction
from handeye.model.common import scratch
from handeye.model.compiled import fast_starts

METHODS = ("newton", "newton-ls", "sd", "bfgs", "gn", "lm", "tr", "ipopt")
SCALING = (10, 100, 1000, 10000, 30000)
SEED = 16


def study(quick=False):
    """Run ``handeye study testfunction`` (``--quick``) as a subprocess; its wall time and phases.

    Returns
    -------
    dict
        ``seconds`` (wall, whole command), ``phases`` (the study's timing.json),
        ``solves`` (per method, from its summary.json), ``grids``, ``exit_code``.
    """
    with scratch.temporary_folder() as tmp:
        cmd = [sys.executable, "-m", "handeye.app.command.cli", "study", "testfunction", "--out",
               tmp] + (["--quick"] if quick else [])
        seconds, done = once(lambda: subprocess.run(cmd, capture_output=True, text=True, env=dict(os.environ)))
        if done.returncode != 0:
            return {"seconds": seconds, "exit_code": done.returncode, "error": done.stderr.strip()[-2000:]}
        phases, summary = (json.loads(pathlib.Path(tmp, "testfunction", name).read_text())
                           for name in ("timing.json", "summary.json"))
    return {"seconds": seconds, "exit_code": 0, "phases": phases, "solves": summary["solves"],
            "grids": summary["grids"], "quick": quick}


def _sample(starts, k):
    """``k`` of ``starts`` spread evenly over both windows."""
    return starts[np.linspace(0, len(starts) - 1, min(k, len(starts))).astype(int)]


def _single_and_batch(problem, starts, method, opts, n_single):
    """``(seconds per start of the single-start path on a sample of n_single of starts, seconds per
    start of the batch over them all, the batch, whether the sample's single and batch ends agree
    within 1e-8)``."""
    sample = _sample(starts, n_single)
    single_s, single = once(lambda: np.array([solvers.solve(problem, x0, method, opts).x for x0 in sample]))
    batch_s, batch = once(lambda: solvers.solve_many(problem, starts, method, opts))
    picked = np.linspace(0, len(starts) - 1, len(sample)).astype(int)
    same = bool(np.allclose(batch.x[picked], single, rtol=0, atol=1e-8))
    return single_s / len(sample), batch_s / len(starts), batch, same


def per_start(methods=METHODS, n_batch=20000, n_single=200, seed=SEED):
    """Per method: seconds per start of the single-start path and of the batch, and their ratio.

    Parameters
    ----------
    methods : sequence of str
    n_batch : int
        Starts in the batch (IPOPT, which has no batch form, loops over ``n_single``).
    n_single : int
        Starts solved one by one with :func:`handeye.solvers.solve` (a sample of the batch's).
    seed : int

    Returns
    -------
    list of dict
        ``method``, ``single_per_start``, ``batch_per_start`` (s), ``speedup``, the starts
        behind each, and ``same_ends`` (the sample's single and batch ends agree within 1e-8).
    """
    problem = testfunction_problem()
    rows = []
    for method in methods:
        opts = testfunction_options(method)
        starts = testfunction_starts(n_single if method == "ipopt" else n_batch, seed)
        single_s, batch_s, _, same = _single_and_batch(problem, starts, method, opts, n_single)
        rows.append({"method": method, "single_per_start": single_s, "single_starts": len(_sample(starts, n_single)),
                     "batch_per_start": batch_s, "batch_starts": len(starts), "speedup": single_s / batch_s,
                     "same_ends": same})
    return rows


def compiled(methods=fast_starts.METHODS, n=20000, seed=SEED):
    """Per method: the numpy batch against the compiled per-start loop over the same ``n`` starts.

    Returns
    -------
    dict
        ``rows``: ``method``, ``numpy_seconds``, ``compiled_seconds`` (None without a C
        compiler), ``ratio``, ``same_ends`` (share of starts that end at the same stationary point, or
        at none on both paths, as the basin study classifies them); ``starts``.
    """
    problem, starts, rows = testfunction_problem(), testfunction_starts(n, seed), []
    fast_starts.library()  # built (or loaded) before the clock starts
    for method in methods:
        opts = testfunction_options(method)
        numpy_s, batch = once(lambda: solvers.solve_many(problem, starts, method, opts))
        loop_s, loop = once(lambda: fast_starts.solve_many(starts, method, opts))
        if loop is None:
            loop_s = same = None
        else:
            kinds = [testfunction.end_kind(r.x, r.converged) for r in (batch, loop)]
            same = float(np.mean(kinds[0] == kinds[1]))
        rows.append({"method": method, "numpy_seconds": numpy_s, "compiled_seconds": loop_s,
                     "ratio": numpy_s / loop_s if loop_s else None,
                     "same_ends": same})
    return {"rows": rows, "starts": n}


def _compiled_text(res):
    lines = ["", f"numpy batch against the compiled per-start loop (C), same {res['starts']} starts, one core",
             f"{'method':10s} {'numpy batch s':>14s} {'compiled s':>11s} {'ratio':>7s} {'same ends':>10s}"]
    rows = res["rows"]
    if any(r["compiled_seconds"] is None for r in rows):
        return lines + ["  no C compiler: the compiled loop is not available (the studies use the numpy batch)"]
    lines += [f"{r['method']:10s} {r['numpy_seconds']:14.3f} {r['compiled_seconds']:11.3f} {r['ratio']:7.1f} "
              f"{100 * r['same_ends']:9.2f}%" for r in rows]
    numpy_s, loop_s = sum(r["numpy_seconds"] for r in rows), sum(r["compiled_seconds"] for r in rows)
    lines.append(f"{'all':10s} {numpy_s:14.3f} {loop_s:11.3f} {numpy_s / loop_s:7.1f}")
    return lines


def extrapolated(rows, solves):
    """The study's solves (``solves``: method -> count) at each path's per-start time, one core."""
    by = {r["method"]: r for r in rows}
    single = sum(by[m]["single_per_start"] * n for m, n in solves.items() if m in by)
    batch = sum(by[m]["batch_per_start"] * n for m, n in solves.items() if m in by)
    return {"single_seconds": single, "batch_seconds": batch, "speedup": single / batch,
            "solves": int(sum(solves.values())), "note": "estimate: the study's solve counts x per-start times, one core"}


def _slope(ns, values):
    """Least-squares slope of log(values) against log(ns)."""
    return float(np.polyfit(np.log(ns), np.log(values), 1)[0])


def scaling(methods=("newton", "bfgs", "lm", "tr"), sizes=SCALING, seed=SEED):
    """The batch's time (best of 3, 1 for the largest) and peak memory against N, per method.

    Returns
    -------
    dict
        ``sizes``; per method ``seconds``, ``peak_bytes`` (lists over sizes), ``time_slope`` and
        ``memory_slope`` (log-log, over sizes >= 1000 where the fixed costs no longer dominate).
    """
    problem = testfunction_problem()
    out = {"sizes": list(sizes), "methods": {}}
    for method in methods:
        opts = testfunction_options(method)
        seconds, peaks = [], []
        for n in sizes:
            starts = testfunction_starts(n, seed)
            best = min(timed(lambda: solvers.solve_many(problem, starts, method, opts), 3 if n < max(sizes) else 1)[0])
            tracemalloc.start()
            solvers.solve_many(problem, starts, method, opts)
            peaks.append(tracemalloc.get_traced_memory()[1])
            tracemalloc.stop()
            seconds.append(best)
        big = [i for i, n in enumerate(sizes) if n >= 1000] or list(range(len(sizes)))
        ns = np.asarray(sizes, float)[big]
        out["methods"][method] = {"seconds": seconds, "peak_bytes": peaks,
                                  "time_slope": _slope(ns, np.asarray(seconds)[big]) if len(big) > 1 else None,
                                  "memory_slope": _slope(ns, np.asarray(peaks, float)[big]) if len(big) > 1 else None}
    return out


CALIBRATION_METHODS = (("lm", "local"), ("gn", "euler"), ("newton", "local"), ("tr", "local"), ("dogleg", "local"))


def _calibration_starts(n, seed):
    """A simulated calibration (thesis strategy, 36 poses) and ``n`` starts: rotations up to
    90 deg and translations up to 200 mm off the truth (seeded)."""
    from handeye.model.chain.pose import transform_from_pose
    from handeye.model.common.rotation import matrix_from_rotvec
    from handeye.model.fit.calibration import CalibrationModel
    from handeye.model.simulation import simulate

    setup = simulate.Setup()
    sim = simulate.simulate(setup, seed=3)
    f2b = transform_from_pose(sim.flange_poses)
    truth = transform_from_pose(setup.sensor_pose)
    rng = np.random.default_rng(seed)
    axes = rng.normal(size=(n, 3))
    axes *= (np.radians(rng.uniform(0, 90, n)) / np.linalg.norm(axes, axis=1))[:, None]
    shifts = rng.normal(size=(n, 3))
    shifts *= (rng.uniform(0, 200, n) / np.linalg.norm(shifts, axis=1))[:, None]
    starts = np.repeat(truth[None], n, axis=0)
    starts[:, :3, :3] = matrix_from_rotvec(axes) @ truth[:3, :3]
    starts[:, :3, 3] += shifts
    model = {rot: CalibrationModel(f2b, sim.centre_in_sensor, setup.sphere_centre, rot) for rot in ("local", "euler")}
    return model, f2b, sim.centre_in_sensor, np.asarray(setup.sphere_centre, float), starts


def calibration(n_batch=400, n_single=40, seed=SEED):
    """Per start, one calibration problem (36 simulated poses) from many starts: the single-start
    path against the batch for each of :data:`CALIBRATION_METHODS`, and the compiled fast path's
    ``calibrate_many`` beside them (one core).

    Returns
    -------
    list of dict
        ``method`` (``name/rotation``), ``single_per_start``, ``batch_per_start`` (s),
        ``speedup``, ``same_ends`` (sample's single and batch ends within 1e-8), ``converged``
        (fraction of the batch).
    """
    from handeye.model.compiled import fast

    models, f2b, xs, centre, starts = _calibration_starts(n_batch, seed)
    rows = []
    for method, rotation in CALIBRATION_METHODS:
        model = models[rotation]
        problem = calibration_problem(model)
        points = np.stack([model.point_from(s) for s in starts])
        single_s, batch_s, batch, same = _single_and_batch(problem, points, method, None, n_single)
        rows.append({"method": f"{method}/{rotation}", "single_per_start": single_s, "batch_per_start": batch_s,
                     "speedup": single_s / batch_s, "converged": float(np.mean(batch.converged)), "same_ends": same})
    m = len(starts)
    single_s, _ = once(lambda: [fast.calibrate_fast(f2b, xs, centre, s) for s in _sample(starts, n_single)])
    single_s /= min(n_single, m)
    batch_s, (_, info) = once(lambda: fast.calibrate_many(np.broadcast_to(f2b, (m,) + f2b.shape),
                                                           np.broadcast_to(xs, (m,) + xs.shape), centre, starts))
    batch_s /= m
    rows.append({"method": "lm-fast/local", "single_per_start": single_s, "batch_per_start": batch_s,
                 "speedup": single_s / batch_s, "converged": float(np.mean(np.isin(info[:, 3], sorted(solvers.CONVERGED)))),
                 "same_ends": None, "compiled": fast.library() is not None})
    return rows


def run(quick=False, with_study=True):
    """Every section. ``quick``: the 15 x 15 study, 2000 batch starts, 40 single, N up to 3000."""
    res = {"quick": quick, "machine": machine()}
    res["per_start"] = rows = per_start(n_batch=2000 if quick else 20000, n_single=40 if quick else 200)
    res["calibration"] = calibration(n_batch=100 if quick else 400, n_single=20 if quick else 40)
    res["compiled"] = compiled(n=2000 if quick else 20000)
    res["scaling"] = scaling(sizes=SCALING[:-1] if quick else SCALING)
    if with_study:
        res["study"] = study(quick=quick)
        if res["study"]["exit_code"] == 0:
            res["extrapolated"] = extrapolated(rows, res["study"]["solves"])
    return res


def text(res):
    """The bench as plain-text tables."""
    lines = ["solver-comparison bench (test function 6-16; one core unless said)",
             *([machine_line(res["machine"])] if "machine" in res else []), "",
             f"{'method':10s} {'single ms/start':>16s} {'batch ms/start':>15s} {'speed-up':>9s} {'same ends':>10s}"]
    lines += [f"{r['method']:10s} {1e3 * r['single_per_start']:16.3f} {1e3 * r['batch_per_start']:15.4f} "
              f"{r['speedup']:9.1f} {str(r['same_ends']):>10s}" for r in res["per_start"]]
    lines.append(f"(single: {res['per_start'][0]['single_starts']} starts one by one; batch: "
                 f"{res['per_start'][0]['batch_starts']} starts at once; IPOPT has no batch form: its batch is a loop)")
    if res.get("calibration"):
        lines += ["", "one calibration (36 simulated poses) from many starts (rotations 0-90 deg, 0-200 mm off)",
                  f"{'method':14s} {'single ms/start':>16s} {'batch ms/start':>15s} {'speed-up':>9s} "
                  f"{'same ends':>10s} {'converged':>10s}"]
        lines += [f"{r['method']:14s} {1e3 * r['single_per_start']:16.3f} {1e3 * r['batch_per_start']:15.4f} "
                  f"{r['speedup']:9.1f} {str(r['same_ends']) if r['same_ends'] is not None else '-':>10s} "
                  f"{100 * r['converged']:9.1f}%" for r in res["calibration"]]
        lines.append("(lm-fast: the compiled fast path, calibrate_fast one by one against calibrate_many; "
                     "its own LM, so its ends are not compared)")
    if res.get("compiled"):
        lines += _compiled_text(res["compiled"])
    st = res.get("study")
    if st:
        lines.append("")
        if st["exit_code"] != 0:
            lines.append(f"handeye study testfunction{' --quick' if st.get('quick') else ''}: exit {st['exit_code']}: "
                         f"{st['error']}")
        else:
            phases = ", ".join(f"{k} {v:.1f} s" for k, v in st["phases"].items())
            lines.append(f"handeye study testfunction{' --quick' if st['quick'] else ''}: {st['seconds']:.1f} s wall "
                         f"(sweep workers: {os.cpu_count()} cores; {phases})")
            ex = res["extrapolated"]
            lines.append(f"its {ex['solves']} solves on one core: single-start path {ex['single_seconds']:.0f} s "
                         f"(estimate), batch {ex['batch_seconds']:.1f} s; ratio {ex['speedup']:.0f}x")
    sc = res["scaling"]
    lines += ["", "batch time and peak memory against starts N (log-log slope over N >= 1000)",
              f"{'method':10s} " + " ".join(f"{n:>9d}" for n in sc["sizes"]) + f" {'slope':>6s}"]
    for method, d in sc["methods"].items():
        t = " ".join(f"{s:8.3f}s" for s in d["seconds"])
        m = " ".join(f"{b / 2**20:7.2f}MB" for b in d["peak_bytes"])
        ts, ms = (f"{d[key]:6.2f}" if d[key] is not None else "     -" for key in ("time_slope", "memory_slope"))
        lines += [f"{method:10s} {t} {ts}", f"{'':10s} {m} {ms}"]
    return "\n".join(lines)
