"""Plain-text presentation of a calibration result (the CLI prints what this returns)."""
from __future__ import annotations


def _fmt(values, width=10, prec=4):
    return " ".join(f"{v:{width}.{prec}f}" for v in values)


def calibration_text(res):
    """A readable report of :func:`studies.calibrate.calibrate`'s result."""
    ident = res["identifiability"]
    lines = [
        f"handeye calibrate: dataset {res['dataset']}, method {res['method']}, rotation {res['rotation']}, "
        f"unknowns {res['unknowns']}",
        f"status: {'converged' if res['converged'] else 'NOT CONVERGED'} after {res['iterations']} iterations "
        f"({res['message']})",
        "",
        "start pose   (x y z mm, A B C deg): " + _fmt(res["start_pose"]),
        "sensor pose  (x y z mm, A B C deg): " + _fmt(res["sensor_pose"]),
        "sensor2flange (4x4):",
    ]
    lines += ["  " + _fmt(row, 12, 6) for row in res["sensor_matrix"]]
    lines.append("sphere centre in base (mm): " + _fmt(res["sphere_center"], 12, 4))
    lines += ["", f"{'id':>10} {'row':>4} {'ex':>9} {'ey':>9} {'ez':>9} {'|e|':>9}  (mm)"]
    for r in res["residuals"]:
        lines.append(f"{r['id']:>10} {r['row']:>4} " + _fmt(r["vector"], 9, 3) + f" {r['norm']:9.3f}")
    lines += [
        "",
        f"RMS residual {res['rms_mm']:.4f} mm (root mean square of |e_i|), max {res['max_residual_mm']:.4f} mm",
        f"identifiability: rank {ident['rank']} of {ident['n']}, condition number {ident['condition_number']:.3g} "
        f"(column-scaled), singular values " + " ".join(f"{v:.3g}" for v in ident["singular_values"]),
    ]
    lines += [f"warning: {w}" for w in res["warnings"]]
    return "\n".join(lines)
