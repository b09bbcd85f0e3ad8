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
to 45) and over [-4, 4]^2; ``--quick`` uses 21 x 21 grids. The full study runs about 1.5
million solves; measured here: about 7-8 minutes per method and grid on two cores, some two hours in all.

Claims: (1) plain Newton converges to the saddle point from a set of starts of positive area
(the thesis says no method finds it); (2) for at least one method the basin of the global
minimum is not star-shaped along the diagonal (a start beyond x0max converges there again).
"""
from __future__ import annotations

import numpy as np

from handeye import solvers
from handeye.app import sweep
from handeye.app.problems import testfunction_problem
from handeye.model import testfunction
from handeye.studies.study import claim, figure, write_summary, write_table

METHODS = ("newton", "newton-ls", "sd", "bfgs", "gn", "lm", "tr", "ipopt")
KINDS = ("global", "local", "saddle", "none")
OPTIONS = {"sd": {"max_iter": 2000}}


def _ends(method, points):
    problem = testfunction_problem()
    out = []
    for p in points:
        try:
            res = solvers.solve(problem, p, method, OPTIONS.get(method, {"max_iter": 200}))
            out.append((*res.x, res.converged, res.iterations))
        except Exception:  # noqa: BLE001 - a failed run is a point that does not converge
            out.append((np.nan, np.nan, False, -1))
    return out


def classify(ends):
    """Index into KINDS for each end point (N, 4: x1, x2, converged, iterations)."""
    pts = testfunction.stationary_points()
    targets = {"global": pts[0].x, "local": pts[1].x, "saddle": pts[2].x}
    kind = np.full(len(ends), 3)
    for k, name in enumerate(("global", "local", "saddle")):
        near = np.linalg.norm(ends[:, :2] - targets[name], axis=1) < 1e-4
        kind[near & (ends[:, 2] > 0)] = k
    return kind


def basin_map(method, lo, hi, n, label):
    axis = np.linspace(lo, hi, n)
    grid = np.array([(a, b) for b in axis for a in axis])
    chunks = np.array_split(grid, max(1, min(len(grid) // 100, 256)))
    parts = sweep.run(_ends, [(method, c) for c in chunks], label=f"{label} {method}")
    ends = np.array([e for part in parts for e in part], dtype=float)
    return axis, classify(ends).reshape(n, n), ends[:, 3].reshape(n, n)


def x0max(method, minimum, step=0.05, reach=50.0):
    """The thesis's number: farthest start m + k step (1, 1) such that all starts up to it
    converge to m; plus whether some start beyond converges to m again (not star-shaped)."""
    target = {"global": 0, "local": 1}[minimum]
    m = testfunction.stationary_points()[target].x
    ks = np.arange(1, int(reach / step) + 1)
    starts = m + np.outer(ks * step, [1.0, 1.0])
    kind = classify(np.array(_ends(method, starts), dtype=float))
    ok = kind == target
    last = int(np.argmin(ok)) if not ok.all() else len(ok)
    return {"x0max": (m + last * step).tolist(), "distance": float(last * step * np.sqrt(2)),
            "converges_beyond": bool(ok[last:].any())}


def run(out, quick=False):
    n = 15 if quick else 301
    maps = {}
    for lo, hi, label in ((-50.0, 50.0, "wide"), (-4.0, 4.0, "zoom")):
        maps[label] = {m: basin_map(m, lo, hi, n, label) for m in METHODS}
    rows, summary = [], {"grid": n, "methods": {}}
    for method in METHODS:
        entry = {}
        for label, data in maps.items():
            _, kind, iters = data[method]
            entry[label] = {k: float(np.mean(kind == i)) for i, k in enumerate(KINDS)}
        entry["table_7_1"] = {mn: x0max(method, mn, step=1.0 if quick else 0.05) for mn in ("global", "local")}
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
        end = np.array(_ends(method, [np.array(start)]), dtype=float)
        replay.append((method, target, str(start), its, KINDS[classify(end)[0]], int(end[0, 3])))
    write_table(out, "table_7_1_replayed", ["method", "thesis_minimum", "thesis_x0max", "thesis_iterations",
                                             "our_end", "our_iterations"], replay)
    summary["table_7_1_replayed"] = [dict(zip(("method", "minimum", "start", "thesis_iterations", "our_end",
                                               "our_iterations"), r)) for r in replay]
    write_table(out, "basins", ["method", "zoom_global", "zoom_local", "zoom_saddle", "zoom_none",
                                "x0max_local", "x0max_global", "global_converges_beyond_x0max"], rows)
    plt = figure()
    from matplotlib.colors import ListedColormap

    cmap = ListedColormap(["#1b9e77", "#7570b3", "#d95f02", "#dddddd"])
    for label, data in maps.items():
        fig, axes = plt.subplots(2, len(METHODS), figsize=(2.6 * len(METHODS), 5.6))
        for col, method in enumerate(METHODS):
            axis, kind, iters = data[method]
            ext = [axis[0], axis[-1], axis[0], axis[-1]]
            axes[0, col].imshow(kind, origin="lower", extent=ext, cmap=cmap, vmin=0, vmax=3, interpolation="nearest")
            axes[0, col].set_title(method, fontsize=9)
            im = axes[1, col].imshow(np.where(kind < 3, iters, np.nan), origin="lower", extent=ext, cmap="viridis",
                                     interpolation="nearest")
            fig.colorbar(im, ax=axes[1, col], fraction=0.046)
            for ax in axes[:, col]:
                ax.tick_params(labelsize=6)
        axes[0, 0].set_ylabel("where it ends\n(green global, purple local,\norange saddle, grey none)", fontsize=7)
        axes[1, 0].set_ylabel("iterations", fontsize=8)
        fig.suptitle(f"basins of attraction on (6-16), {n} x {n} starts over [{axis[0]:g}, {axis[-1]:g}]^2")
        fig.tight_layout()
        fig.savefig(out / f"basins_{label}.png", dpi=110)
        plt.close(fig)
    write_summary(out, summary)
    newton_saddle = summary["methods"]["newton"]["zoom"]["saddle"]
    claim(newton_saddle > 0, f"plain Newton converges to the saddle from {100 * newton_saddle:.2f} % of the zoom grid")
    claim(any(e["table_7_1"]["global"]["converges_beyond"] or e["table_7_1"]["local"]["converges_beyond"]
              for e in summary["methods"].values()),
          "some basin is not star-shaped along the diagonal: x0max misleads")
    return summary
