"""Study: thesis-real through every method, beside Tables 7-4 and 7-5.

Story. The seed's Table 7-4 gives one result (Gauss-Newton on Euler angles from the CAD start,
32 iterations): p2End = (189.69, 99.71, 130.36, -181.40, -89.24, 0.155). We run every method
and parametrisation on the data as printed, once as the thesis did (every sample, plain least
squares) and once as ``calibrate`` does (gross errors screened), and report each result's
distance from Table 7-4 as a transform, its RMS and, for the thesis's validation (Table 7-5),
the residual of each sample.

Claims: with screening, every method and parametrisation lands on the same transform
(within 1e-4 mm and 1e-4 deg), and its RMS is below 10 mm while the unscreened fit's exceeds
300 mm.
"""
from __future__ import annotations

import handeye
from handeye.app.engine.request import SUPPORTED
from handeye.model.chain.pose import transform_from_pose
from handeye.model.common.rotation import transform_distance
from handeye.model.datasets.dataset import load
from handeye.studies.study import claim, figure, save, write_summary, write_table

TABLE_7_4 = (189.69, 99.71, 130.36, -181.40, -89.24, 0.155)


def run(out, quick=False):
    d = load("thesis-real")
    thesis = transform_from_pose(TABLE_7_4)
    rows, results = [], {}
    for screened in (False, True):
        for method, rotations in SUPPORTED.items():
            for rotation in rotations:
                res = handeye.calibrate(d, method=method, rotation=rotation, keep_all=not screened, no_loo=True)
                est = res.sensor2flange
                dt, dr = transform_distance(est, thesis)
                results[(screened, method, rotation)] = (res, est)
                rows.append(("screened" if screened else "all samples", method, rotation, bool(res.converged),
                             int(res.iterations), float(res.rms_mm), float(dt), float(dr),
                             " ".join(f"{v:.2f}" for v in res.sensor_pose_kuka), ",".join(res.outliers)))
    write_table(out, "real_data", ["fit", "method", "rotation", "converged", "iterations", "rms_mm",
                                   "distance_to_table_7_4_mm", "distance_to_table_7_4_deg", "sensor_pose",
                                   "excluded"], rows)
    screened = [(k, v) for k, v in results.items() if k[0]]
    ref = screened[0][1][1]
    spread = max(max(transform_distance(est, ref)) for _, (_, est) in screened)
    summary = {"screened_agreement": float(spread),
               "screened_rms_mm": float(screened[0][1][0].rms_mm),
               "unscreened_rms_mm": [float(v[0].rms_mm) for k, v in results.items() if not k[0]],
               "table_7_4_distance": [float(x) for x in transform_distance(ref, thesis)]}
    fig, ax = figure().subplots(figsize=(10, 4))
    for screened_flag, label in ((False, "every sample (as the thesis)"), (True, "gross errors screened")):
        res = results[(screened_flag, "ipopt", "matrix")][0]
        ax.semilogy([r.norm for r in res.residuals], "o-" if screened_flag else "s--", label=label, ms=4)
    ax.set_xticks(range(len(d)), d.ids, rotation=90)
    ax.set(ylabel="|e_i| (mm)", title="thesis-real: residual per measurement (IPOPT, matrix)")
    ax.legend()
    save(fig, out / "real_data.png")
    write_summary(out, summary)
    claim(spread < 1e-4, f"every screened fit lands on the same transform (spread {spread:.1e})")
    claim(summary["screened_rms_mm"] < 10 and min(summary["unscreened_rms_mm"]) > 300,
          "screening turns a useless fit (RMS > 300 mm) into a sane one (< 10 mm)")
    return summary
