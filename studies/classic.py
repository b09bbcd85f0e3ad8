"""``handeye calibrate --method kim-cho|li-two-step``: the closed-form baselines on a dataset.

Gross errors are screened first, exactly as ``calibrate`` does (robust pass and deletion
tests, :func:`studies.robust.screen`; ``--keep-all`` skips it), then the closed-form method of
:mod:`model.classics` runs on the samples kept. The estimate is reported beside what the
nonlinear least squares makes of the same samples when started from it (distance,
iterations), so a user sees at once how far the linear method is from the least-squares
optimum. No uncertainty: these are baselines, and the report says so.
"""
from __future__ import annotations

import time

import numpy as np

from model import classics
from model.calibration import CalibrationModel
from model.pose import pose_from_transform, transform_from_pose
from model.rotation import transform_distance
from studies import robust
from studies.calibrate import CalibrationInputError, resolve_start
from studies.robust import ALPHA

METHODS = ("kim-cho", "li-two-step")


def estimate(method, flange2base, centre_in_sensor, sphere_centre=None):
    """Run one closed-form method; ``sphere_centre`` None lets Li et al. estimate it."""
    if method == "kim-cho":
        return classics.kim_cho(flange2base, centre_in_sensor)
    if method == "li-two-step":
        return classics.li_two_step(flange2base, centre_in_sensor, sphere_centre)
    raise CalibrationInputError(f"--method: unknown closed-form method {method!r}; choose one of {', '.join(METHODS)}")


def calibrate_classic(dataset, method, unknowns="sensor", outliers=True, alpha=ALPHA):
    """JSON-ready result of a closed-form method on ``dataset``.

    ``unknowns='sensor+sphere'`` does not use the dataset's sphere centre: Kim & Cho never
    need it (the centre is then the mean of the predicted centres), Li et al. estimate it in
    step 2. ``outliers`` screens gross errors first (module docstring). Raises
    CalibrationInputError naming the file when the motions the method needs are missing.
    """
    f2b_all, xs_all = dataset.flange2base(), dataset.centre_in_sensor
    known = None if unknowns == "sensor+sphere" else np.asarray(dataset.sphere_centre, float)
    mask, excluded = np.ones(len(xs_all), bool), []
    if outliers:
        start = transform_from_pose(resolve_start(dataset, unknowns)[0])
        screening = robust.screen(f2b_all, xs_all, dataset.sphere_centre, unknowns, start, dataset.ids, dataset.rows,
                                  alpha=alpha)
        mask, excluded = screening.inliers, screening.excluded
    f2b, xs = f2b_all[mask], xs_all[mask]
    classics.axxb_system(np.eye(4)[None], p=np.zeros((1, 3)), q=np.zeros((1, 3)))  # load the generated code untimed
    t0 = time.perf_counter()
    try:
        est = estimate(method, f2b, xs, known)
    except classics.MissingMotions as exc:
        raise CalibrationInputError(f"{dataset.path / 'measurements.csv'}: {exc}"
                                    + (f" ({len(excluded)} sample(s) excluded as gross errors)" if excluded else "")
                                    ) from None
    elapsed = time.perf_counter() - t0
    rot, trans = est.sensor2flange[:3, :3], est.sensor2flange[:3, 3]
    predicted = np.einsum("nij,jk,nk->ni", f2b_all[:, :3, :3], rot, xs_all) + f2b_all[:, :3, :3] @ trans \
        + f2b_all[:, :3, 3]
    centre = known if known is not None else (est.sphere_centre if est.sphere_centre is not None
                                              else predicted[mask].mean(axis=0))
    e = predicted - centre
    norms = np.linalg.norm(e, axis=1)
    model = CalibrationModel(f2b, xs, centre, "local", "sensor" if known is not None else "sensor+sphere")
    refined = robust.least_squares(model, model.point_from(est.sensor2flange, centre))
    dt, dr = transform_distance(model.sensor2flange(refined.x), est.sensor2flange)
    warnings = ["closed-form baseline: no uncertainty estimate"
                + ("" if outliers else "; every sample used (--keep-all: no outlier screening)")]
    if est.details.get("orthogonality_error", 0) > 0.01:
        warnings.append(f"the linear solution's rotation block was {est.details['orthogonality_error']:.3g} from "
                        "orthogonal (|R^T R - I|) before projection onto SO(3)")
    return {
        "dataset": str(dataset.path), "method": method, "unknowns": unknowns, "converged": True,
        "status": "closed form", "message": "closed-form estimate (no iterations)",
        "sensor_pose": pose_from_transform(est.sensor2flange).tolist(),
        "sensor_matrix": est.sensor2flange.tolist(), "linear_matrix": est.linear.tolist(),
        "sphere_center": np.asarray(centre).tolist(), "n_used": int(mask.sum()),
        "rms_mm": float(np.sqrt(np.mean(norms[mask] ** 2))), "max_residual_mm": float(norms[mask].max()),
        "residuals": [{"id": i, "row": int(r), "vector": v.tolist(), "norm": float(n), "used": bool(u)}
                      for i, r, v, n, u in zip(dataset.ids, dataset.rows, e, norms, mask)],
        "excluded": excluded, "outliers": [x["id"] for x in excluded],
        "details": est.details, "time_ms": elapsed * 1e3,
        "least_squares_from_here": {"distance_mm": float(dt), "distance_deg": float(dr),
                                    "iterations": int(refined.iterations), "converged": bool(refined.status > 0),
                                    "rms_mm": float(np.sqrt(2 * refined.cost / len(xs)))},
        "warnings": warnings,
    }


def classic_text(res):
    """Readable report of :func:`calibrate_classic`."""
    d, ls = res["details"], res["least_squares_from_here"]
    used = (f"{d['pairs']} motion pairs, condition number {d['condition']:.3g} (column-scaled D)" if "pairs" in d
            else f"{len(d['translation_pairs'])} pure-translation pairs spanning {d['directions']} directions")
    lines = [
        f"handeye calibrate: dataset {res['dataset']}, method {res['method']} (closed form), unknowns {res['unknowns']}",
        f"used: {used}; {res['time_ms']:.2f} ms",
        "sensor pose  (x y z mm, A B C deg): " + " ".join(f"{v:10.4f}" for v in res["sensor_pose"]),
        "sphere centre in base (mm): " + " ".join(f"{v:12.4f}" for v in res["sphere_center"]),
        f"RMS residual {res['rms_mm']:.4f} mm over {res['n_used']} samples used, max {res['max_residual_mm']:.4f} mm",
        f"least squares started here: {'converged' if ls['converged'] else 'NOT converged'} in {ls['iterations']} "
        f"iterations, {ls['distance_mm']:.4f} mm and {ls['distance_deg']:.4f} deg away, RMS {ls['rms_mm']:.4f} mm",
    ]
    if res["excluded"]:
        lines.append("excluded samples (gross errors, screened as calibrate does):")
        lines += [f"  {x['id']} (row {x['row']}): {x['reason']}" for x in res["excluded"]]
    lines += [f"warning: {w}" for w in res["warnings"]]
    return "\n".join(lines)
