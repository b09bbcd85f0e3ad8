"""Study: which poses to measure -- planned (D-optimal) against the thesis strategy.

Story. Candidates are the thesis strategy's 36 orientations, each with the laser plane
cutting the sphere at 5, 15 or 25 mm from its centre (108 poses). For N poses we compare
(a) the thesis strategy (36 orientations, cut at 15 mm, an evenly spread subset of N) with
(b) the D-optimal choice of N from all candidates: the predicted standard deviations (the
Cramer-Rao bound) and, by simulation, the observed RMSE. A second panel shows the bound of
the full thesis strategy against the cut distance: where should the laser plane cut?

Claims: the planned set's information (log det) is never below the thesis subset's, and the
simulated RMSE of the planned 12 poses agrees with its prediction within 35 %.
"""
from __future__ import annotations

import numpy as np

import handeye
from handeye.model.chain.pose import transform_from_pose
from handeye.model.common import scratch
from handeye.model.datasets.dataset import load
from handeye.model.design import bounds, planning
from handeye.model.simulation import simulate
from handeye.studies.study import claim, figure, pose_error, save, write_summary, write_table


def _rmse(setup, ids, poses, reps):
    truth = transform_from_pose(setup.sensor_pose)
    errs = []
    with scratch.temporary_folder() as tmp:
        for r in range(reps):
            sim = simulate.simulate(setup, seed=500 + r, flange_poses=poses, ids=ids)
            d = load(simulate.write(sim, f"{tmp}/r{r}", profiles=True))
            res = handeye.calibrate(d, method="lm", model="measurement", no_loo=True, keep_all=True)
            errs.append(np.concatenate(pose_error(res.sensor2flange, truth)))
    return np.sqrt(np.mean(np.array(errs) ** 2, axis=0))


def run(out, quick=False):
    setup = simulate.Setup(linearity=0.0)
    centre = np.asarray(setup.sphere_centre)
    ids, poses = planning.thesis_candidates(setup, centre)
    info = bounds.information(poses, setup, centre)
    thesis = [k for k, i in enumerate(ids) if i.endswith("@15")]
    rows, summary = [], {"N": {}}
    for n in (6, 8, 12, 18, 24, 36):
        t_sel = [thesis[k] for k in np.unique(np.round(np.linspace(0, 35, n)).astype(int))]
        p_sel, value = planning.select(info, n)
        t_sd = planning.predicted_sd(info[t_sel].sum(axis=0))
        p_sd = planning.predicted_sd(info[p_sel].sum(axis=0))
        t_ld = planning.logdet(info[t_sel].sum(axis=0))
        rows.append((n, float(t_ld), value, float(t_sd[:3].max()), float(p_sd[:3].max()),
                     float(t_sd[3:].max()), float(p_sd[3:].max())))
        summary["N"][n] = {"thesis_logdet": t_ld, "planned_logdet": value,
                           "thesis_sd": t_sd.tolist(), "planned_sd": p_sd.tolist()}
        claim(value >= t_ld - 1e-9, f"the planned {n} poses carry at least the thesis subset's information")
    write_table(out, "planning", ["N", "thesis_logdet", "planned_logdet", "thesis_max_sd_mm", "planned_max_sd_mm",
                                  "thesis_max_sd_deg", "planned_max_sd_deg"], rows)
    cuts = np.arange(2.0, 29.0, 2.0)
    cut_sd = []
    for cut in cuts:
        c_ids, c_poses = planning.thesis_candidates(setup, centre, cuts=(float(cut),))
        cut_sd.append(planning.predicted_sd(bounds.information(c_poses, setup, centre).sum(axis=0)))
    cut_sd = np.array(cut_sd)
    write_table(out, "cut_distance", ["cut_mm", "max_sd_mm", "max_sd_deg"],
                [(float(c), float(s[:3].max()), float(s[3:].max())) for c, s in zip(cuts, cut_sd)])
    reps = 8 if quick else 60
    p12, _ = planning.select(info, 12)
    observed = _rmse(setup, [ids[k] for k in p12], poses[p12], reps)
    predicted = planning.predicted_sd(info[p12].sum(axis=0))
    summary["planned12"] = {"predicted_sd": predicted.tolist(), "observed_rmse": observed.tolist(), "replicates": reps,
                            "ids": [ids[k] for k in p12]}
    fig, axes = figure().subplots(1, 2, figsize=(10, 4))
    ns = [r[0] for r in rows]
    axes[0].plot(ns, [r[3] for r in rows], "o-", label="thesis strategy (cut 15 mm)")
    axes[0].plot(ns, [r[4] for r in rows], "s-", label="D-optimal from 108 candidates")
    axes[0].set(xlabel="number of poses N", ylabel="largest translation sd bound (mm)", yscale="log",
                title="predicted accuracy against N")
    axes[0].legend()
    axes[1].plot(cuts, cut_sd[:, :3].max(axis=1), "o-", label="translation (mm)")
    axes[1].plot(cuts, cut_sd[:, 3:].max(axis=1), "s-", label="rotation (deg)")
    axes[1].axvspan(0.71 * setup.diameter / 2, 0.97 * setup.diameter / 2, color="grey", alpha=0.2,
                    label="0.71R-0.97R (published zone)")
    axes[1].set(xlabel="distance of the laser plane from the centre (mm)", ylabel="largest sd bound",
                title="36 thesis poses against the cut distance")
    axes[1].legend()
    save(fig, out / "planning.png")
    write_summary(out, summary)
    ratio = observed / predicted
    tol = 0.35 * (1 + 2 / np.sqrt(reps)) if quick else 0.35
    claim(np.all(np.abs(ratio - 1) <= tol),
          f"simulated RMSE of the planned 12 poses matches prediction (ratios {np.round(ratio, 2)})")
    return summary
