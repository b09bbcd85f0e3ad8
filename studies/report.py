"""Plain-text presentation of a calibration result (the CLI prints what this returns)."""
from __future__ import annotations


def _fmt(values, width=10, prec=4):
    return " ".join(f"{v:{width}.{prec}f}" for v in values)


def _loo_line(res):
    if res["loo_error_mm"] is None:
        return "leave-one-out error: not computed (--no-loo)"
    return (f"leave-one-out error {res['loo_error_mm']:.4f} mm (RMS distance of each used sample's predicted sphere "
            "centre from the centre fitted without it)")


def calibration_text(res):
    """A readable report of :func:`studies.calibrate.calibrate`'s result."""
    ident = res["identifiability"]
    lines = [
        f"handeye calibrate: dataset {res['dataset']}, method {res['method']}, rotation {res['rotation']}, "
        f"unknowns {res['unknowns']}, model {res['model']}",
        f"status: {'converged' if res['converged'] else 'NOT CONVERGED'} after {res['iterations']} iterations "
        f"({res['message']})",
        "",
        "start pose   (x y z mm, A B C deg): " + _fmt(res["start_pose"]),
        "sensor pose  (x y z mm, A B C deg): " + _fmt(res["sensor_pose"]),
    ]
    if "sensor_pose_as" in res and res["sensor_pose_as"]["convention"] != "kuka":
        conv = res["sensor_pose_as"]
        lines.append(f"sensor pose ({conv['convention']}: {','.join(conv['columns'])}): " + _fmt(conv["pose"], 10, 6))
    lines += [
        "sensor2flange (4x4):",
    ]
    lines += ["  " + _fmt(row, 12, 6) for row in res["sensor_matrix"]]
    lines.append("sphere centre in base (mm): " + _fmt(res["sphere_center"], 12, 4))
    lines.append(f"start: {res['start_used']}")
    lines += ["", f"{'id':>10} {'row':>4} {'ex':>9} {'ey':>9} {'ez':>9} {'|e|':>9} {'loo':>8}  (mm)"]
    for r in res["residuals"]:
        loo = f"{r['loo_error_mm']:8.3f}" if r["loo_error_mm"] is not None else " " * 8
        flag = "" if r["used"] else "  EXCLUDED"
        lines.append(f"{r['id']:>10} {r['row']:>4} " + _fmt(r["vector"], 9, 3) + f" {r['norm']:9.3f} {loo}{flag}")
    if res["excluded"]:
        lines += ["", "excluded samples (gross errors; not used in the fit):"]
        lines += [f"  {e['id']} (row {e['row']}): {e['reason']}" for e in res["excluded"]]
    lines += [
        "",
        f"RMS residual {res['rms_mm']:.4f} mm over {res['n_used']} samples used (root mean square of |e_i|), "
        f"max {res['max_residual_mm']:.4f} mm",
        _loo_line(res),
        f"before exclusion (every sample, plain least squares): RMS {res['before']['rms_mm']:.4f} mm"
        + (f", leave-one-out {res['before']['loo_error_mm']:.4f} mm" if res["before"]["loo_error_mm"] is not None else ""),
        "",
        "uncertainty (1 sd; " + (f"sigma = {res['sigma_mm']:.4f} mm per residual component" if res["sigma_mm"] is not None
                                 else f"weighted residual, scale {res['sigma_scale']:.3f}") + ", estimated from the fit):",
        "  sensor translation (mm):      " + _fmt(res["std"]["sensor_translation_mm"]),
        "  sensor rotation (deg, about sensor x y z): " + _fmt(res["std"]["sensor_rotation_deg"]),
    ]
    if res["std"]["sphere_center_mm"] is not None:
        lines.append("  sphere centre (mm):           " + _fmt(res["std"]["sphere_center_mm"]))
    lines += [
        "",
        f"identifiability: rank {ident['rank']} of {ident['n']}, condition number {ident['condition_number']:.3g} "
        f"(column-scaled), singular values " + " ".join(f"{v:.3g}" for v in ident["singular_values"]),
    ]
    lines += [f"warning: {w}" for w in res["warnings"]]
    return "\n".join(lines)
