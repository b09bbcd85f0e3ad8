"""Study: convergence from random start poses, with and without the closed-form start.

Story. A simulated dataset (thesis strategy, 36 poses, no effects) is calibrated from random
start poses: rotations uniform over SO(3) (error 0-180 deg), translations 0-500 mm off the
truth. Each method runs once from the start alone ("plain") and once as ``calibrate`` runs it,
which restarts from the closed-form estimate when the start does not converge. Success: the
result is within 1e-4 mm and 1e-4 deg of the reference calibration. Every method runs in every
rotation parametrisation it supports (Euler angles among them).

Solve. The plain runs of each method and parametrisation go through the batched solvers
(:func:`handeye.solvers.solve_many`, every start of a chunk at once; the calibration model
evaluates stacks of points; IPOPT, which has no batch form, loops over one solver object); the
compiled fast path's Levenberg-Marquardt (``lm-fast/local``, :func:`handeye.model.compiled.fast.calibrate_many`)
runs every start in one call, plain only: it has no closed-form restart. ``calibrate`` runs
start by start (screening, restart and polish are per dataset), spread over the sweep's workers.

Claim: with the closed-form restart every method succeeds from every start (100 %).
"""
from __future__ import annotations

import json
import time

import numpy as np

import handeye
from handeye import solvers
from handeye.app.engine.problems import calibration_problem
from handeye.app.engine.request import SUPPORTED
from handeye.app.present import figure_style
from handeye.app.tools import sweep
from handeye.model.chain.pose import pose_from_transform, transform_from_pose
from handeye.model.common import scratch
from handeye.model.common.rotation import matrix_from_rotvec, nearest_transform, rotation_angle_deg, transform_distance
from handeye.model.compiled import fast
from handeye.model.datasets import observations
from handeye.model.datasets.dataset import load
from handeye.model.simulation import simulate
from handeye.studies.study import claim, figure, save, write_summary, write_table

METHODS = ("lm", "gn", "dogleg", "tr", "newton", "ipopt")


def random_start(truth, rng):
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    angle = 2 * np.arccos(min(abs(q[0]), 1.0))
    axis = q[1:] / max(np.linalg.norm(q[1:]), 1e-12)
    start = np.eye(4)
    start[:3, :3] = matrix_from_rotvec(angle * axis) @ truth[:3, :3]
    d = rng.normal(size=3)
    start[:3, 3] = truth[:3, 3] + rng.uniform(0, 500) * d / np.linalg.norm(d)
    return start


def _success(pose, converged, reference):
    dt, dr = transform_distance(nearest_transform(pose), reference)
    return bool(converged and dt < 1e-4 and dr < 1e-4)


def _plain(d, reference, method, rotation, starts):
    """Success of ``method`` in ``rotation`` from each of ``starts`` (k, 4, 4) alone: one batch."""
    model = observations.build(d, "centre", rotation)
    points = np.stack([model.point_from(s) for s in starts])
    res = solvers.solve_many(calibration_problem(model), points, method)
    return [_success(model.sensor2flange(x), ok, reference) for x, ok in zip(res.x, res.converged)]


def _with_restart(d, reference, start, methods):
    """Success of every method and parametrisation as ``calibrate`` runs it from ``start``."""
    out = []
    for method in methods:
        for rotation in SUPPORTED[method]:
            res = handeye.calibrate(d, method=method, rotation=rotation, start=pose_from_transform(start),
                                    no_loo=True, keep_all=True)
            out.append(_success(res.sensor2flange, res.converged, reference))
    return out


def _fast(d, reference, starts):
    """The compiled fast path's LM (local chart) from every start in one call; plain only."""
    m = len(starts)
    f2b = np.broadcast_to(d.flange2base(), (m,) + d.flange2base().shape)
    xs = np.broadcast_to(d.centre_in_sensor, (m,) + d.centre_in_sensor.shape)
    poses, info = fast.calibrate_many(f2b, xs, d.sphere_centre, np.asarray(starts))
    return [_success(p, int(s) in solvers.CONVERGED, reference) for p, s in zip(poses, info[:, 3])]


#: Random starts of the quick study (the full one draws 1,000).
QUICK_STARTS = 40


def run(out, quick=False):
    n_starts = QUICK_STARTS if quick else 1000
    methods = METHODS if not quick else ("lm", "gn", "newton", "ipopt")
    rng = np.random.default_rng(7)
    with scratch.temporary_folder() as tmp:
        d = load(simulate.write(simulate.simulate(simulate.Setup(), seed=3), tmp + "/sim"))
        reference = handeye.calibrate(d, method="lm", no_loo=True, keep_all=True).sensor2flange
        truth = transform_from_pose(d.truth["sensor_pose"])
        starts = [random_start(truth, rng) for _ in range(n_starts)]  # drawn here: the same wherever the sweep runs
        combos = [(method, rotation) for method in methods for rotation in SUPPORTED[method]]
        # the dataset travels with each task (pickled), so that workers need no shared folder
        chunks = np.array_split(np.arange(n_starts), max(1, min(n_starts // 20, 4 * sweep.n_jobs())))
        tasks = [(d, reference, method, rotation, [starts[i] for i in c]) for method, rotation in combos for c in chunks]
        seconds = {}
        t0 = time.perf_counter()
        plain = sweep.run(_plain, tasks, label="plain runs (batched)")
        seconds["plain_batched"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        full = sweep.run(_with_restart, [(d, reference, s, methods) for s in starts], label="calibrate, start by start")
        seconds["calibrate"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        fast_ok = _fast(d, reference, starts)
        seconds["fast_path"] = time.perf_counter() - t0
    plain_ok = {combo: [ok for part in plain[c * len(chunks):(c + 1) * len(chunks)] for ok in part]
                for c, combo in enumerate(combos)}
    rows = []
    for k, start in enumerate(starts):
        rot_err = float(rotation_angle_deg(start[:3, :3], truth[:3, :3]))
        trans_err = float(np.linalg.norm(start[:3, 3] - truth[:3, 3]))
        for c, (method, rotation) in enumerate(combos):
            rows.append((k, f"{method}/{rotation}", rot_err, trans_err, plain_ok[(method, rotation)][k], full[k][c]))
        rows.append((k, "lm-fast/local", rot_err, trans_err, fast_ok[k], ""))
    write_table(out, "random_starts", ["start", "method", "rotation_error_deg", "translation_error_mm",
                                       "plain_success", "with_closed_form_success"], rows)
    methods = sorted({r[1] for r in rows})
    summary = {"starts": n_starts, "methods": {}}
    for method in methods:
        sel = [r for r in rows if r[1] == method]
        full = np.array([r[5] for r in sel if r[5] != ""], dtype=bool)
        summary["methods"][method] = {"plain_success_rate": float(np.mean([r[4] for r in sel])),
                                      "success_rate": float(full.mean()) if full.size else None}
    _draw(out, rows, methods, n_starts)
    write_summary(out, summary)
    (out / "timing.json").write_text(json.dumps(seconds, indent=1) + "\n")  # not in summary.json: that one is reproducible
    for method, s in summary["methods"].items():
        if s["success_rate"] is None:  # the fast path: plain runs only
            continue
        claim(s["success_rate"] == 1.0, f"{method} with the closed-form restart succeeds from every start")
    return summary


#: colour and marker per parametrisation (Okabe-Ito; the panel is the method's)
PARAM_STYLE = {"euler": (figure_style.BLUE, "o", -1), "local": (figure_style.VERMILLION, "s", 0),
               "matrix": (figure_style.GREEN, "^", 1)}


def _draw(out, rows, methods, n_starts):
    """Small multiples: one panel per method, the success rate of each parametrisation against
    the start's rotation error (Wilson 95 % intervals), beside the rate with the closed-form restart."""
    families = sorted({m.split("/")[0] for m in methods})
    cols = min(4, len(families))
    nrows = -(-len(families) // cols)
    fig, axes = figure().subplots(nrows, cols, figsize=(3.4 * cols, 3.2 * nrows + 0.8), sharex=True, sharey=True,
                                  squeeze=False)
    bins = np.linspace(0, 180, 7)
    mid, width = 0.5 * (bins[1:] + bins[:-1]), bins[1] - bins[0]
    for ax, family in zip(axes.flat, families):
        restart = []
        for method in (m for m in methods if m.split("/")[0] == family):
            sel = [r for r in rows if r[1] == method]
            idx = np.clip(np.digitize([r[2] for r in sel], bins) - 1, 0, len(mid) - 1)
            plain = np.array([r[4] for r in sel], dtype=bool)
            restart += [(b, bool(r[5])) for b, r in zip(idx, sel) if r[5] != ""]
            colour, marker, shift = PARAM_STYLE.get(method.split("/")[1], ("0.3", "D", 0))
            _rate(ax, mid + shift * 0.12 * width, idx, plain, len(mid), f"{method.split('/')[1]}, start alone",
                  color=colour, marker=marker)
        if restart:
            b, ok = np.array(restart).T
            _rate(ax, mid + 0.24 * width, b, ok.astype(bool), len(mid), "with closed-form restart", color="k",
                  marker="*", ls=":")
        ax.set_title(family)
        ax.legend(loc="lower left", fontsize=9)
    for ax in axes.flat[len(families):]:
        ax.axis("off")
    for ax in axes[-1]:
        ax.set_xlabel("start's rotation error (deg)")
        ax.set_xticks(bins[::2])
    for ax in axes[:, 0]:
        ax.set_ylabel("success rate")
    axes[0, 0].set_ylim(-0.04, 1.06)
    fig.suptitle(f"convergence from {n_starts} random starts (translations 0-500 mm off; "
                 "bars: Wilson 95 % intervals)")
    save(fig, out / "random_starts.png")


def _rate(ax, x, idx, ok, nbins, label, **style):
    """Success rate per bin with its Wilson 95 % interval, as points with error bars."""
    n = np.bincount(idx, minlength=nbins)
    k = np.bincount(idx, weights=ok.astype(float), minlength=nbins)
    has = n > 0
    rate = k[has] / n[has]
    low, high = figure_style.binomial_interval(k[has], n[has])
    ax.errorbar(x[has], rate, yerr=[rate - low, high - rate], capsize=2, ms=5, lw=1, label=label, **style)
