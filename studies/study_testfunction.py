"""Study: basins of attraction on the thesis's test function (6-16), method by method.

Story. Every point of a grid of start points is handed to each method; the point is coloured
by where the method ends: the global minimum, the local minimum, the saddle, or nowhere
(no convergence, or elsewhere), and by the iterations it took. The thesis summarised each
method by one number, the farthest start on the diagonal from which it still found a minimum
(Table 7-1, "x0max"); we compute that number the same way beside the maps, and show where it
misleads: the basins are not star-shaped, so starts beyond x0max still converge, and starts
inside a basin's "radius" do not.

Methods: local Newton, damped Newton (Armijo), steepest descent (Armijo), BFGS (Wolfe),
Gauss-Newton and Levenberg-Marquardt on the exact sum-of-squares form ``f + 300 = |r|^2``,
trust-region Newton, IPOPT. Grids: 301 x 301 over [-50, 50]^2 (covering the thesis's x0max up
to 45) and over [-4, 4]^2; ``--quick`` uses 15 x 15 grids.

Solve. Every iterative method runs the whole grid in chunks spread over the sweep's workers,
each chunk through the compiled per-start loop (:mod:`handeye.model.compiled.fast_starts`: CasADi-generated
C of the test function and a C driver of each method's iteration, rule for rule), or, without a
C compiler, through the numpy batch (:func:`handeye.solvers.solve_many`), with a warning; the
summary names the engine of each method. Both end at the same stationary points: on the full
grid 3 of the 90,601 wide-window BFGS starts differ, where the batch's line search stops at
rounding level without an acceptable step (status -1, "none") and the C calls the same minimum
converged. IPOPT has no batch form (one solver object, starts in a loop, 2.5-7 ms each): it runs
on every fifth grid line (61 x 61 of the 301 x 301 starts, the same points), unless
:func:`basin_maps` is given ``ipopt_stride=1``; the summary and the figure say which grid each
method ran on. Measured here (2 cores): the full study 15.6 s with the compiled loop (basins
9.2 s, x0max 3.6 s; IPOPT is now most of it), 172 s with the numpy batch on a loaded machine
(basins 150 s, x0max 15 s); the single-start path took about two hours.

Claims: (1) plain Newton converges to the saddle point from a set of starts of positive area
(the thesis says no method finds it); (2) for at least one method the basin of the global
minimum is not star-shaped along the diagonal (a start beyond x0max converges there again).
"""
from __future__ import annotations

import json
import time
import warnings

import numpy as np

from handeye import solvers
from handeye.app.engine.problems import testfunction_options as options_for
from handeye.app.engine.problems import testfunction_problem
from handeye.app.present import figure_style
from handeye.app.tools import sweep
from handeye.model.chain import testfunction
from handeye.model.compiled import fast_starts
from handeye.studies.study import claim, figure, save, write_summary, write_table

METHODS = ("newton", "newton-ls", "sd", "bfgs", "gn", "lm", "tr", "ipopt")
KINDS = testfunction.END_KINDS
#: IPOPT runs on every IPOPT_STRIDE-th grid line (module docstring)
IPOPT_STRIDE = 5
COMPILED = "compiled per-start loop (C)"
NUMPY = "numpy batch"


def engine(method):
    """How ``method`` runs the starts here: the compiled per-start loop, else the numpy batch."""
    if method in fast_starts.METHODS and fast_starts.supports(method, options_for(method)):
        return COMPILED if fast_starts.library() is not None else NUMPY
    return "one solver object, starts in a loop" if method == "ipopt" else NUMPY


def _ends(method, points, compiled=True):
    """Where ``method`` ends from each of ``points`` (N, 2): rows (x1, x2, converged, iterations).

    The compiled per-start loop (:mod:`handeye.model.compiled.fast_starts`) where it has ``method`` and a
    C compiler is present (``compiled``), else :func:`handeye.solvers.solve_many`.
    """
    points = np.asarray(points, float).reshape(-1, 2)
    res = fast_starts.solve_many(points, method, options_for(method)) if compiled else None
    if res is None:
        res = solvers.solve_many(testfunction_problem(), points, method, options_for(method))
    return np.column_stack([res.x, res.converged, res.iterations]).astype(float)


def classify(ends):
    """Index into KINDS for each end point (N, >= 3: x1, x2, converged, ...)."""
    return testfunction.end_kind(ends[:, :2], ends[:, 2] > 0)


def grid_axis(lo, hi, n, method, ipopt_stride=IPOPT_STRIDE):
    """The grid line coordinates ``method`` runs on: every ``ipopt_stride``-th for IPOPT."""
    axis = np.linspace(lo, hi, n)
    return axis[::ipopt_stride] if method == "ipopt" else axis


def basin_maps(windows, n, ipopt_stride=IPOPT_STRIDE):
    """Every method over every window: ``{label: {method: (axis, kind, iterations)}}``.

    All (method, window) grids are cut into chunks and run as one sweep, the slowest
    methods first, so that every worker stays busy.
    """
    tasks, where = [], []
    workers = sweep.n_jobs()
    for label, (lo, hi) in windows.items():
        for method in METHODS:
            axis = grid_axis(lo, hi, n, method, ipopt_stride)
            grid = np.stack(np.meshgrid(axis, axis), axis=-1).reshape(-1, 2)  # row-major: x1 fastest
            pieces = max(1, min(len(grid) // 64, 2 * workers if method != "ipopt" else 8 * workers))
            for k, chunk in enumerate(np.array_split(grid, pieces)):
                tasks.append((method, chunk))
                where.append((label, method, k))
    slow_first = sorted(range(len(tasks)), key=lambda i: (tasks[i][0] != "ipopt", tasks[i][0] not in ("sd", "newton-ls")))
    parts = sweep.run(_ends, [tasks[i] for i in slow_first], label="basins")
    ends = {}
    for i, part in zip(slow_first, parts):
        label, method, k = where[i]
        ends.setdefault((label, method), {})[k] = part
    maps = {}
    for label, (lo, hi) in windows.items():
        maps[label] = {}
        for method in METHODS:
            axis = grid_axis(lo, hi, n, method, ipopt_stride)
            pieces = ends[(label, method)]
            e = np.concatenate([pieces[k] for k in sorted(pieces)])
            maps[label][method] = (axis, classify(e).reshape(len(axis), len(axis)), e[:, 3].reshape(len(axis), len(axis)))
    return maps


def x0max(method, minimum, step=0.05, reach=50.0):
    """The thesis's number: farthest start m + k step (1, 1) such that all starts up to it
    converge to m; plus whether some start beyond converges to m again (not star-shaped)."""
    target = {"global": 0, "local": 1}[minimum]
    m = testfunction.stationary_points()[target].x
    ks = np.arange(1, int(reach / step) + 1)
    starts = m + np.outer(ks * step, [1.0, 1.0])
    kind = classify(_ends(method, starts))
    ok = kind == target
    last = int(np.argmin(ok)) if not ok.all() else len(ok)
    return {"x0max": (m + last * step).tolist(), "distance": float(last * step * np.sqrt(2)),
            "converges_beyond": bool(ok[last:].any())}


def run(out, quick=False):
    n = 15 if quick else 301
    stride = 1 if quick else IPOPT_STRIDE
    windows = {"wide": (-50.0, 50.0), "zoom": (-4.0, 4.0)}
    t0 = time.perf_counter()
    maps = basin_maps(windows, n, stride)
    seconds = {"basins": time.perf_counter() - t0}
    t0 = time.perf_counter()
    step = 1.0 if quick else 0.05
    pairs = [(m, mn) for m in METHODS for mn in ("global", "local")]  # one task each: IPOPT's two run side by side
    found = sweep.run(x0max, [(m, mn, step) for m, mn in pairs], label="x0max")
    table = {m: {} for m in METHODS}
    for (m, mn), entry in zip(pairs, found):
        table[m][mn] = entry
    seconds["x0max"] = time.perf_counter() - t0
    grids = {m: f"{len(maps['wide'][m][0])} x {len(maps['wide'][m][0])}" for m in METHODS}
    solves = {m: len(windows) * len(maps["wide"][m][0]) ** 2 + 2 * int(50.0 / step) for m in METHODS}
    engines = {m: engine(m) for m in METHODS}
    if NUMPY in engines.values():
        warnings.warn("no C compiler: the basin study runs on the numpy batch (same ends to round-off, 10-30x slower)",
                      stacklevel=2)
    rows, summary = [], {"grid": n, "grids": grids, "solves": solves, "engines": engines, "methods": {},
                         "ipopt": f"no batch form: a loop over one solver object, on every {stride}-th grid line"
                         if stride > 1 else "no batch form: a loop over one solver object, on the full grid"}
    for method in METHODS:
        entry = {}
        for label, data in maps.items():
            _, kind, iters = data[method]
            entry[label] = {k: float(np.mean(kind == i)) for i, k in enumerate(KINDS)}
        entry["table_7_1"] = table[method]
        summary["methods"][method] = entry
        rows.append((method, entry["zoom"]["global"], entry["zoom"]["local"], entry["zoom"]["saddle"],
                     entry["zoom"]["none"], str(np.round(entry["table_7_1"]["local"]["x0max"], 2).tolist()),
                     str(np.round(entry["table_7_1"]["global"]["x0max"], 2).tolist()),
                     entry["table_7_1"]["global"]["converges_beyond"]))
    # Table 7-1's printed starts (x0max), run again: where do they end, in how many iterations?
    thesis = [("newton", "local", (1.25, 1.25), 9), ("newton", "global", (-1.25, -2.25), 7),
              ("gn", "local", (4.3, 4.3), 7), ("gn", "global", (35.0, 35.0), 10),
              ("tr", "local", (4.5, 4.5), 6), ("tr", "global", (45.0, 45.0), 7)]
    replay = []
    for method, target, start, its in thesis:
        res = solvers.solve(testfunction_problem(), start, method, options_for(method))  # one start: the single path
        end = np.array([[*res.x, res.converged, res.iterations]])
        replay.append((method, target, str(start), its, KINDS[classify(end)[0]], res.iterations))
    write_table(out, "table_7_1_replayed", ["method", "thesis_minimum", "thesis_x0max", "thesis_iterations",
                                             "our_end", "our_iterations"], replay)
    summary["table_7_1_replayed"] = [dict(zip(("method", "minimum", "start", "thesis_iterations", "our_end",
                                               "our_iterations"), r)) for r in replay]
    write_table(out, "basins", ["method", "zoom_global", "zoom_local", "zoom_saddle", "zoom_none",
                                "x0max_local", "x0max_global", "global_converges_beyond_x0max"], rows)
    _draw(out, maps, grids, n)
    write_summary(out, summary)
    (out / "timing.json").write_text(json.dumps(seconds, indent=1) + "\n")  # not in summary.json: that one is reproducible
    newton_saddle = summary["methods"]["newton"]["zoom"]["saddle"]
    claim(newton_saddle > 0, f"plain Newton converges to the saddle from {100 * newton_saddle:.2f} % of the zoom grid")
    claim(any(e["table_7_1"]["global"]["converges_beyond"] or e["table_7_1"]["local"]["converges_beyond"]
              for e in summary["methods"].values()),
          "some basin is not star-shaped along the diagonal: x0max misleads")
    return summary


def _draw(out, maps, grids, n):
    """One figure per window: where each method ends (categories: Okabe-Ito, named in the
    legend) above its iterations (viridis, with a colour bar)."""
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch

    plt = figure()
    colours = [figure_style.GREEN, figure_style.BLUE, figure_style.ORANGE, "#dddddd"]
    cmap = ListedColormap(colours, name="okabe-ito-basins")
    for label, data in maps.items():
        fig, axes = plt.subplots(2, len(METHODS), figsize=(2.7 * len(METHODS), 6.4))
        for col, method in enumerate(METHODS):
            axis, kind, iters = data[method]
            ext = [axis[0], axis[-1], axis[0], axis[-1]]
            axes[0, col].imshow(kind, origin="lower", extent=ext, cmap=cmap, vmin=0, vmax=3, interpolation="nearest")
            axes[0, col].set_title(f"{method} ({grids[method]})" if len(axis) != n else method)
            im = axes[1, col].imshow(np.where(kind < 3, iters, np.nan), origin="lower", extent=ext, cmap="viridis",
                                     interpolation="nearest")
            fig.colorbar(im, ax=axes[1, col], fraction=0.046)
        axes[0, 0].set_ylabel("where it ends")
        axes[1, 0].set_ylabel("iterations")
        fig.legend([Patch(color=c) for c in colours], [f"ends at the {k} minimum" if k in ("global", "local") else
                                                       {"saddle": "ends at the saddle", "none": "no convergence"}[k]
                                                       for k in KINDS],
                   loc="lower center", ncol=4, frameon=False)
        fig.suptitle(f"basins of attraction on (6-16), {n} x {n} starts over [{axis[0]:g}, {axis[-1]:g}]^2")
        save(fig, out / f"basins_{label}.png", rect=(0, 0.05, 1, 1))
