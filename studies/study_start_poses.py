"""Study: Table 7-2's start poses x methods x rotation parametrisations on thesis-sim.

Story. The thesis started its two methods (its Gauss-Newton and MATLAB's trust region) from
ten manipulated poses (Table 7-2) and printed the final angles (Table 7-3): trust region
failed from three, and the angles A and C "drifted". We run every method in every
parametrisation it supports from the same ten starts and report iterations, the error of the
result as a transform (mm, degrees) and the time, beside Table 7-3. (Random starts over all
of SO(3): the ``random-starts`` study.)

Claims: every method reaches the truth (< 1e-6 mm, 1e-6 deg) from every Table 7-2 start in
every parametrisation, local Newton on Euler angles included (its Hessian is singular at
B = -90 deg exactly, yet the polished fit reaches the truth from all ten).
"""
from __future__ import annotations

import time

import handeye
from handeye.app.engine.request import SUPPORTED
from handeye.model.chain.pose import transform_from_pose
from handeye.model.common.rotation import transform_distance
from handeye.model.datasets.dataset import load
from handeye.studies.study import claim, figure, save, write_summary, write_table

TABLE_7_2 = [
    (5, 0, 5, 0, -90, 0), (75, 0, 5, 0, -90, 0), (5, 60, 5, 0, -90, 0), (5, 0, 45, 0, -90, 0),
    (5, 0, 5, 0.001, -90, 0), (5, 0, 5, 0, -90.1, 0), (5, 0, 5, 0, -90, 0.001), (75, 75, 55, 0, -90, 0),
    (5, 0, 5, 0.005, -90.1, 0.005), (75, 75, 55, 0.01, -90.1, 0.01),
]
#: Table 7-3's iterations: Gauss-Newton and trust region (None: no result printed)
TABLE_7_3 = {"gn": [1, 4, 4, 4, 4, 4, 4, 4, 4, 4], "tr": [1, 6, 6, 5, None, 9, None, 6, 12, None]}


def run(out, quick=False):
    d = load("thesis-sim")
    truth = transform_from_pose(d.truth["sensor_pose"])
    rows = []
    for method, rotations in SUPPORTED.items():
        for rotation in rotations:
            for k, start in enumerate(TABLE_7_2):
                t0 = time.perf_counter()
                res = handeye.calibrate(d, method=method, rotation=rotation, start=start, keep_all=True, no_loo=True)
                elapsed = (time.perf_counter() - t0) * 1e3
                dt, dr = transform_distance(res.sensor2flange, truth)
                thesis = TABLE_7_3.get(method, [None] * 10)[k] if rotation == "euler" else None
                rows.append((k, method, rotation, int(res.iterations), bool(res.converged), float(dt), float(dr),
                             elapsed, "-" if thesis is None else thesis, res.start_used))
    write_table(out, "start_poses", ["start", "method", "rotation", "iterations", "converged", "error_mm", "error_deg",
                                     "time_ms", "thesis_iterations", "start_used"], rows)
    summary = {}
    for method, rotations in SUPPORTED.items():
        for rotation in rotations:
            sel = [r for r in rows if r[1] == method and r[2] == rotation]
            ok = [r for r in sel if r[4] and r[5] < 1e-6 and r[6] < 1e-6]
            summary[f"{method}/{rotation}"] = {"reached_truth": len(ok), "of": len(sel),
                                               "iterations": [r[3] for r in sel]}
    fig, ax = figure().subplots(figsize=(10, 4))
    labels = list(summary)
    ax.boxplot([summary[k]["iterations"] for k in labels])
    ax.set_xticks(range(1, len(labels) + 1), labels, rotation=45, ha="right", rotation_mode="anchor")
    ax.set(ylabel="iterations", title="thesis-sim from Table 7-2's ten starts")
    save(fig, out / "start_poses.png")
    write_summary(out, summary)
    for key, s in summary.items():
        claim(s["reached_truth"] == s["of"], f"{key} reaches the truth from all ten starts")
    return summary
