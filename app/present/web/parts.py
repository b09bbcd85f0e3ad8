"""The report's HTML parts, each from the calibration's JSON object: the header, the result card,
the verdict strip and the residual table. Every value is escaped; nothing here computes a result."""
from __future__ import annotations

import html

import numpy as np

#: Export formats shown as snippets on the result card (``handeye export --format NAME``).
SNIPPETS = ("ur", "ros2", "urdf", "kuka", "abb", "fanuc", "matrix")


def esc(value):
    """``value`` as HTML text (quotes too: safe in attributes)."""
    return html.escape(str(value), quote=True)


def _p(value):
    """A p-value as text (3 significant digits), or a dash."""
    return f"{value:.3g}" if isinstance(value, (int, float)) and np.isfinite(value) else "–"


def _num(value, digits=4):
    """A number with ``digits`` decimals, or a dash for None; anything else escaped as text."""
    if value is None:
        return "–"
    return f"{value:.{digits}f}" if isinstance(value, (int, float)) and np.isfinite(value) else esc(value)


def header(result, title, generated):
    """Title and provenance: dataset, its SHA-256 and path, the tool's version, the options, when."""
    from handeye.app.common.files import tool_version
    from handeye.model.chain.mounts import CELLS

    cell = CELLS.get((result.get("sensor_mount", "flange"), result.get("sphere_mount", "world")), "")
    rows = [("dataset", f"{result.get('dataset')} ({result.get('dataset_path')})"),
            ("dataset SHA-256", result.get("dataset_sha256")), ("cell", cell),
            ("method", f"{result.get('method')}, rotation {result.get('rotation')}, unknowns {result.get('unknowns')}, "
                       f"model {result.get('model')}"),
            ("made by", f"handeye {tool_version()}, {generated}")]
    again = result.get("recomputed") or {}
    if again.get("verdict"):  # a saved file's verdict, recomputed from the data at its pose
        rows.append(("verdict", again["verdict"]))
    prov = result.get("provenance") or {}
    if prov.get("options"):
        rows.append(("options", ", ".join(f"{k}={v}" for k, v in prov["options"].items() if v not in (None, False))))
    body = "".join(f"<tr><th>{esc(k)}</th><td>{esc(v)}</td></tr>" for k, v in rows)
    return f"<header><h1>{esc(title)}</h1><table class='prov'>{body}</table></header>"


def result_card(result, snippets):
    """The pose in the robot's convention with its 1-sd, the 4x4 with a copy button, the sphere
    centre, and the export snippets (``snippets``: format -> text)."""
    pose_as = result.get("sensor_pose_as") or {}
    own = result.get("sensor_frame") == "own"  # profiles turned by dataset new: the sensor's own frame
    std = result.get("std") or {}
    frame = "robot base" if result.get("sensor_mount") == "world" else "flange"
    cells = "".join(f"<th>{esc(c)}</th>" for c in pose_as.get("columns") or [])
    vals = "".join(f"<td>{_num(v)}</td>" for v in pose_as.get("pose") or [])
    sd_t, sd_r = std.get("sensor_translation_mm"), std.get("sensor_rotation_deg")
    sd_line = ("<p class='sd'>1 sd: translation " + " ".join(_num(v) for v in sd_t) + " mm (x, y, z in the "
               f"{esc(frame)} frame); rotation " + " ".join(_num(v) for v in sd_r) + " deg (about the sensor's own x, y, z)</p>"
               ) if sd_t and sd_r else "<p class='sd'>no uncertainty (the fit did not give one)</p>"
    if own:
        sd_line += ("<p class='hint'>The sensor's own frame (its driver's points, what <code>handeye export</code> "
                    "writes): the profiles were turned into the laser plane by <code>[profile] own_axes</code>; the "
                    "drawn sensor frames and the residual columns below are of the sensor's own frame too.</p>")
    matrix = result.get("sensor_matrix")
    csd = result.get("sphere_center_sd")
    mtext = "\n".join(" ".join(f"{v: .9f}" for v in row) for row in matrix) if matrix else "none"
    ctext = (" ".join(_num(v, 3) for v in result.get("sphere_center") or [])
             + (" ± " + " ".join(_num(v, 3) for v in csd) if csd else " (given)"))
    if result.get("converged"):
        snips = "".join(f"<details><summary>{esc(k)}</summary><pre>{esc(v)}</pre></details>" for k, v in snippets.items())
    else:
        snips = ("<p class='refused'>Not offered: the calibration did not converge, so it is no calibration "
                 "(<code>handeye export</code> refuses it too, unless forced).</p>")
    title = f"Sensor pose{' (its own frame)' if own else ''} in the {esc(frame)} frame ({esc(pose_as.get('convention'))})"
    return (f"<section id='card'><h2>{title}</h2>"
            f"<table class='pose'><tr>{cells}</tr><tr>{vals}</tr></table>{sd_line}"
            f"<h3>4×4 sensor matrix (mm) <button id='copy-matrix' type='button'>copy</button>"
            f"<span id='copy-state'></span></h3><pre id='matrix'>{esc(mtext)}</pre>"
            f"<p>sphere centre (mm, in its mount's frame): {ctext}</p>{_effects(result)}{_positioner(result)}"
            f"<h3>For the controller (handeye export)</h3>{snips}</section>")


def _effects(result):
    """The catalogue effects calibrated with the pose (``--effects``), each value with its 1-sd."""
    rows = []
    for e in result.get("effects") or []:
        std = e.get("std") or {}
        for k, v in (e.get("parameters") or {}).items():
            if isinstance(v, (int, float)):
                rows.append(f"<tr><td>{esc(e.get('name'))}</td><td>{esc(k)}</td><td>{v:.6g}</td>"
                            f"<td>{_num(std.get(k), 6)}</td></tr>")
    if not rows:
        return ""
    return ("<h3>Effects calibrated with the pose</h3><table class='pose'><tr><th>effect</th><th>parameter</th>"
            f"<th>value</th><th>1 sd</th></tr>{''.join(rows)}</table>")


def _positioner(result):
    """The positioner's axes (robot base, all angles zero): calibrated with their 1-sd, or as set up."""
    axes = result.get("positioner") or []
    if not axes:
        return ""
    def vec(v, d=4):
        return "–" if v is None else " ".join(_num(x, d) for x in v)
    rows = "".join(f"<tr><td>{esc(a.get('name'))}</td><td>{vec(a.get('point'), 3)}</td><td>{vec(a.get('point_sd'), 3)}</td>"
                   f"<td>{vec(a.get('direction'), 6)}</td><td>{_num(a.get('tilt_sd_deg'), 4)}</td>"
                   f"<td>{'calibrated' if a.get('calibrated') else 'as set up'}</td></tr>" for a in axes)
    return ("<h3>Positioner axes (robot base, all axis angles zero)</h3><table class='pose'><tr><th>axis</th>"
            "<th>point mm</th><th>1 sd mm</th><th>direction</th><th>tilt 1 sd deg</th><th></th></tr>"
            f"{rows}</table>")


def _box(state, title, text):
    mark = {"ok": "✓ pass", "warn": "! check", "fail": "✗ fail", "info": "for information"}[state]
    return (f"<div class='verdict {state}'><div class='vt'>{esc(title)}</div><div class='vs'>{esc(mark)}</div>"
            f"<div class='vx'>{esc(text)}</div></div>", state, title)


#: A correlation of two unknowns beyond this says the poses barely separate them.
TIED = 0.99


def tied_pairs(correlation):
    """Pairs of unknowns whose |correlation| exceeds :data:`TIED`, as ``'ty-wx -1.00'``."""
    if not correlation or not correlation.get("names"):
        return []
    names, c = correlation["names"], np.asarray(correlation["matrix"], float)
    return [f"{names[i]}–{names[j]} {c[i, j]:+.2f}" for i in range(len(names)) for j in range(i + 1, len(names))
            if abs(c[i, j]) > TIED]


def headline(boxes_states, result):
    """One sentence above the strip: can the pose be used, and if not, what to read."""
    fails = [t for s, t in boxes_states if s == "fail"]
    if not result.get("converged"):
        return "fail", "Not a calibration: the fit did not converge (exit 1). Do not use this pose."
    if fails:
        return "warn", (f"Converged (exit 0), but {len(fails)} check(s) fail: {', '.join(fails)}. The pose is the best "
                        "this model gets from these data; read the warnings before using it.")
    look = [t for s, t in boxes_states if s == "warn"]
    if look:
        return "ok", f"Converged (exit 0) and no check fails; look at: {', '.join(look)}."
    return "ok", "Converged (exit 0) and every check passes: the pose and its 1-sd can be used."


def verdict_strip(result):
    """One box per check: convergence, RMS against the stated noise, chi^2, leave-one-out,
    identifiability, the global check, exclusions; then the warnings in full."""
    boxes = [_box("ok" if result.get("converged") else "fail", "convergence", result.get("message") or "")]
    nt = result.get("noise_test")
    if nt:
        boxes.append(_box("ok" if nt.get("passed") else "fail", "RMS against stated noise",
                          f"sd {_num(nt.get('ratio'), 2)} × the stated {nt.get('nominal')}; RMS "
                          f"{_num(result.get('rms_mm'))} mm per centre"))
        boxes.append(_box("ok" if nt.get("passed") else "fail", "χ² test",
                          f"χ² = {_num(nt.get('statistic'), 1)} on {nt.get('dof')} dof, p = {_p(nt.get('p_value'))}"))
    if result.get("loo_error_mm") is not None:
        boxes.append(_box("info", "leave-one-out", f"{_num(result['loo_error_mm'])} mm per centre (RMS of the "
                          f"held-out errors) against {_num(result.get('rms_mm'))} mm fitted"))
    ident = result.get("identifiability")
    if ident:
        bad = ident.get("not_identifiable") or []
        tied = tied_pairs(result.get("correlation"))
        state = "fail" if bad else "warn" if tied else "ok"
        boxes.append(_box(state, "identifiability",
                          f"rank {ident.get('rank')} of {ident.get('n')}, condition number "
                          f"{_num(ident.get('condition_number'), 1)} (columns scaled)"
                          + (f"; not identifiable: {', '.join(bad)}" if bad else "")
                          + (f"; nearly tied (|correlation| > {TIED}): {', '.join(tied)}: these poses barely "
                             "separate them" if tied else "")))
    glob = result.get("global")
    if glob:
        reached, starts = glob.get("reached"), glob.get("starts")
        state = "fail" if not reached else "ok" if reached == starts else "warn"
        boxes.append(_box(state, "global check", f"{reached} of {starts} starts reached the minimum kept; "
                          f"{glob.get('method')}"))
    n_ex = len(result.get("excluded") or [])
    boxes.append(_box("warn" if n_ex else "ok", "excluded samples",
                      f"{n_ex} of {len(result.get('residuals') or [])}: {', '.join(result.get('outliers') or []) or 'none'}"))
    warns = result.get("warnings") or []
    boxes.append(_box("warn" if warns else "ok", "warnings", f"{len(warns)}"))
    items = "".join(f"<li>{esc(w)}</li>" for w in warns)
    state, sentence = headline([(b[1], b[2]) for b in boxes], result)
    return (f"<section id='verdict'><h2>Verdict</h2><p class='headline {state}'>{esc(sentence)}</p>"
            f"<div class='strip'>{''.join(b[0] for b in boxes)}</div>"
            + (f"<ul class='warnings'>{items}</ul>" if items else "") + "</section>")


#: The residual table's columns: (key, heading, numeric).
COLUMNS = (("i", "#", True), ("id", "id", False), ("row", "row", True), ("used", "used", False),
           ("norm", "|e| mm", True), ("ex", "e_x sensor mm", True), ("ey", "e_y sensor mm", True),
           ("ez", "e_z sensor mm", True), ("loo", "leave-one-out mm", True), ("why", "why excluded", False))


def residual_table(result, cell):
    """One row per sample, named by its id, sortable by any column (the page's script) and linked to
    the 3-D view: a click on a row picks the sample there (``data-i``: its index in the cell)."""
    index = {sid: k for k, sid in enumerate(cell.ids)} if cell is not None else {}
    why = {e["id"]: e.get("reason", "") for e in result.get("excluded") or []}
    head = "".join(f"<th data-key='{k}' data-num='{int(num)}' tabindex='0'>{esc(t)}</th>" for k, t, num in COLUMNS)
    rows = []
    for r in result.get("residuals") or []:
        k = index.get(r["id"], -1)
        e = cell.residual_sensor[k] if k >= 0 else (None, None, None)
        vals = {"i": k + 1, "id": r["id"], "row": r.get("row"), "used": "yes" if r.get("used") else "no",
                "norm": r.get("norm"), "ex": e[0], "ey": e[1], "ez": e[2], "loo": r.get("loo_error_mm"),
                "why": why.get(r["id"], "")}
        tds = "".join(f"<td data-v='{esc(_sort_value(vals[key]))}'>{_cell_text(vals[key], key)}</td>"
                      for key, _, _ in COLUMNS)
        cls = "" if r.get("used") else " class='excluded'"
        rows.append(f"<tr data-i='{k}' data-id='{esc(r['id'])}'{cls}>{tds}</tr>")
    return (f"<section id='residuals'><h2>Residuals, one row per sample</h2><p class='hint'>Click a heading to sort, "
            f"a row to pick the sample in the 3-D view.</p><div class='scroll'><table id='residual-table'><thead><tr>"
            f"{head}</tr></thead><tbody>{''.join(rows)}</tbody></table></div></section>")


def _sort_value(v):
    if isinstance(v, (int, float, np.floating)) and not isinstance(v, bool):
        return repr(float(v)) if np.isfinite(v) else ""
    return "" if v is None else str(v)


def _cell_text(v, key):
    if key in ("i", "row"):
        return esc(v)
    if isinstance(v, (float, np.floating)):
        return _num(float(v))
    return esc("–" if v is None else v)
