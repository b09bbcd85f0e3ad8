"""The report page: one HTML file, everything inlined (styles, script, figures as data URIs,
plotly's JavaScript), so it opens offline in any browser and can be mailed as it is.

Machines read it too: ``<script type="application/json" id="handeye-result">`` holds exactly the
``handeye calibrate --json`` object (``sensor_matrix`` included), ``id="handeye-cell"`` the cell's
geometry (:class:`handeye.app.present.web.cell.CellGeometry`) and, when diagnose ran,
``id="handeye-diagnosis"`` the ``handeye diagnose --json`` object.
"""
from __future__ import annotations

import base64
import datetime
import json
import pathlib

import numpy as np

from handeye.app.common.jsonio import dumps
from handeye.app.present.web import figures, parts, view

HERE = pathlib.Path(__file__).parent


def _asset(name):
    return (HERE / name).read_text(encoding="utf-8")


def embedded_json(element_id, text):
    """A ``<script type="application/json">`` element holding ``text`` (JSON), safe inside HTML:
    every ``<``, ``>`` and ``&`` written as JSON's ``\\u003c``, ``\\u003e``, ``\\u0026`` (inside strings,
    the only place JSON text has them), so no ``</script>`` or ``<!--`` of a sample's id can end or
    bend the element; JSON reads them back as the same characters."""
    safe = text.replace("<", "\\u003c").replace(">", "\\u003e").replace("&", "\\u0026")
    return f'<script type="application/json" id="{element_id}">{safe}</script>'


def image(png, alt):
    """A PNG as an ``<img>`` with a data URI (the page stays one file)."""
    return f"<img class='figure' alt='{parts.esc(alt)}' src='data:image/png;base64,{base64.b64encode(png).decode()}'>"


def snippets(result, source="the calibration"):
    """The export formats' text of the result's pose (:mod:`handeye.app.outputs.formats`), in the
    sensor's own frame when the profiles were turned, with the verdict and the failed checks as
    comments (as ``handeye export`` writes it: :func:`handeye.app.outputs.verdict.comment_lines`;
    a saved file's verdict as the page recomputed it)."""
    from handeye.app.outputs import formats, saved
    from handeye.app.outputs import verdict as verdicts

    if result.get("sensor_matrix") is None:
        return {}
    cal = saved.from_document(result, source)
    rms = result.get("rms_mm")
    status = (result.get("recomputed") or {}).get("verdict") or (
        f"{'converged' if result.get('converged') else 'NOT CONVERGED'}: calibrated now"
        + (f", RMS {rms:.4g} mm per sphere centre" if isinstance(rms, (int, float)) else ""))
    warnings = tuple(w for w in result.get("warnings") or [] if isinstance(w, str))
    lines = verdicts.comment_lines(verdicts.Checked(cal, warnings=warnings, status=status))
    return {fmt: formats.text(cal, fmt, verdict=lines) for fmt in parts.SNIPPETS}


def effects_note(result):
    """What the view draws when the fit corrected the centres by effects: the plain chain."""
    names = [e.get("name") for e in result.get("effects") or [] if isinstance(e, dict)]
    if not names:
        return ""
    return (f"<p class='hint'><b>Effects calibrated ({parts.esc(', '.join(names))}):</b> the view and the sensor-frame "
            "columns draw the plain chain (sensor pose and sphere centre, no effect applied); the table's |e| is the "
            "result's, of the corrected centres.</p>")


def cell_section(cell, title, interactive, result):
    """The 3-D cell: plotly's scene with the residual slider, or the static picture; the cell's
    numbers as JSON for the page's script. Returns (html, cell JSON dict)."""
    if cell is None:
        return "<section id='cell'><h2>The cell</h2><p>No calibrated chain to draw.</p></section>", None
    payload = cell.to_dict()
    payload["residual_drawn"] = np.round(view.capped_residuals(cell), 6).tolist()
    drawn = view.drawn_samples(cell)
    payload["drawn"] = drawn.tolist()
    if interactive:
        fig, traces, scale = view.figure(cell, title)
        payload.update(traces=traces, scale=scale)
        lo, hi = np.log10(max(scale / 100, 0.1)), np.log10(scale * 10)
        controls = (f"<div class='controls'><label for='residual-scale'>residual scale</label><input type='range' "
                    f"id='residual-scale' min='{lo:.3f}' max='{hi:.3f}' step='0.01' value='{np.log10(scale):.3f}'>"
                    f"<span id='residual-scale-value'>{view.scale_text(scale)}</span>"
                    "<span id='picked' class='hint'>pick a sample in the table or the view</span></div>")
        body = controls + view.html_div(fig)
    else:
        payload.update(traces=None, scale=view.default_scale(cell))
        body = ("<p class='hint'>A picture: install the report extra (pip install 'handeye[report]') for the "
                "interactive 3-D view.</p><span id='picked' class='hint'></span>" + image(view.static_png(cell, title),
                                                                                           "the cell in 3-D"))
    note = ("<p class='hint'>Frames: x vermillion, y green, z blue. Residual vectors (orange) start at the sphere "
            "centre and end at the measured centre through the chain, magnified; excluded samples (purple diamonds) "
            f"are drawn at most {view.EXCLUDED_CAP:g}× the longest used residual, their true length is in the table."
            + (f" Frames and fans of {view.MAX_DRAWN_POSES} of the {len(cell.ids)} poses, evenly spaced."
               if len(cell.ids) > view.MAX_DRAWN_POSES else "")
            + (f" Centres and residuals of {int(drawn.sum())} of the {len(cell.ids)} samples (every "
               "excluded one, the used ones evenly spaced); the table lists all, and picking one draws its chain."
               if len(cell.ids) > view.MAX_DRAWN_CENTRES else "") + "</p>" + effects_note(result))
    return f"<section id='cell'><h2>The cell in 3-D</h2>{note}{body}</section>", payload


def figures_section(result, cell, dataset):
    """Residual components in the sensor frame against the pose angles; the correlation matrix."""
    out = []
    if cell is not None:
        png = figures.residuals_against_angles(cell, np.asarray(dataset.flange_poses, float), ("A", "B", "C"))
        out.append("<h3>Residuals in the sensor frame against the flange's angles</h3>" + image(png, "residuals"))
    corr = result.get("correlation")
    if corr and corr.get("names"):
        out.append("<h3>Correlation of the unknowns</h3>" + image(
            figures.correlation_matrix(corr["names"], corr["matrix"]), "correlation matrix"))
    return f"<section id='figures'><h2>Figures</h2>{''.join(out)}</section>" if out else ""


def diagnosis_section(diagnosis):
    """The discrepancy workflow's steps and the gap against the noise floor (``handeye diagnose``)."""
    if diagnosis is None:
        return ""
    rows = "".join(f"<tr><td>{parts.esc(s['step'])}</td><td>{s['rms_mm']:.4f}</td><td>{s['heldout_rms_mm']:.4f}</td>"
                   f"<td>{s['chi2_dof']:.2f}</td></tr>" for s in diagnosis["steps"])
    named = ", ".join(e["name"] for e in diagnosis.get("effects") or []) or "none"
    pose = diagnosis.get("sensor_pose_as") or {}
    said = (f"<p>effects named: {parts.esc(named)}. Unexplained: {parts.esc(diagnosis.get('unexplained'))}</p>"
            f"<p>outliers diagnose excluded: {parts.esc(', '.join(diagnosis.get('outliers') or []) or 'none')}</p>"
            f"<p>its sensor pose ({parts.esc(pose.get('convention'))}: {parts.esc(','.join(pose.get('columns') or []))}): "
            + " ".join(f"{v:.4f}" for v in pose.get("pose") or []) + "</p>"
            f"<p>against calibrate: {parts.esc(diagnosis.get('against_calibrate') or '–')}</p>")
    return (f"<section id='diagnosis'><h2>Where model and data disagree (handeye diagnose)</h2>{said}"
            f"<table class='pose'><tr><th>step</th><th>RMS mm</th><th>held out mm</th><th>χ²/dof</th></tr>{rows}</table>"
            + image(figures.gap_steps(diagnosis["steps"], diagnosis["nominal_sigma_mm"]), "the gap, step by step")
            + "</section>")


def build(result, dataset, diagnosis=None, result_json=None, source="the calibration"):
    """The report's HTML text.

    Parameters
    ----------
    result : dict
        ``handeye calibrate --json``'s object of a calibration of ``dataset``.
    dataset : handeye.model.datasets.dataset.Dataset
    diagnosis : dict, optional
        ``handeye diagnose --json``'s object on the same dataset.
    result_json : str, optional
        The result's JSON text as ``calibrate --json`` prints it (default: ``result`` dumped).
    source : str
        Where ``result`` came from (a file's name), for messages.
    """
    from handeye.app.present.web.cell import cell_geometry

    title = f"handeye calibration report: {result.get('dataset')}"
    generated = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    cell = cell_geometry(result, dataset) if result.get("sensor_matrix") and result.get("sphere_center") else None
    cell_html, payload = cell_section(cell, title, view.have_plotly(), result)
    card = parts.result_card(result, snippets(result, source))
    body = [parts.header(result, title, generated), parts.verdict_strip(result), card,
            cell_html, parts.residual_table(result, cell), figures_section(result, cell, dataset),
            diagnosis_section(diagnosis),
            embedded_json("handeye-result", result_json or dumps(result)),
            embedded_json("handeye-cell", json.dumps(payload, allow_nan=False) if payload else "null")]
    if diagnosis is not None:
        body.append(embedded_json("handeye-diagnosis", dumps(diagnosis)))
    return (f"<!DOCTYPE html>\n<html lang='en'><head><meta charset='utf-8'><meta name='viewport' "
            f"content='width=device-width, initial-scale=1'><title>{parts.esc(title)}</title>"
            f"<style>{_asset('page.css')}</style></head><body>{''.join(body)}<script>{_asset('page.js')}</script>"
            f"</body></html>\n")
