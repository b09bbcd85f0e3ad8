"""Plain-text and figure presentation of a calibration result (the CLI prints what this returns)."""
from __future__ import annotations

import pathlib

import numpy as np

#: What the orientation columns of each convention hold.
_CONVENTION_UNITS = {"abb": "mm, unit quaternion w x y z", "ur": "mm, rotation vector in rad",
                     "fanuc": "mm, W P R in deg", "kuka": "mm, A B C in deg"}


def _fmt(values, width=10, prec=4):
    return " ".join(f"{v:{width}.{prec}f}" for v in values)


#: One row of each residual model, in words.
_PER = {"centre": "sphere centre", "measurement": "circle", "points": "profile point"}


def _loo_line(res):
    if res.loo_error_mm is None:
        if res.effects:
            return "leave-one-out error: not computed (the effects are fitted to every sample used)"
        return "leave-one-out error: not computed (--no-loo)"
    model = (res.loo or {}).get("model", res.model)
    weights = ", weighted as the fit," if (res.loo or {}).get("weighted") else ""
    return (f"leave-one-out error {res.loo_error_mm:.4f} mm per sphere centre (the {model} model{weights} refitted "
            "without each used sample; RMS of the distance of that sample's sphere centre through the refitted chain "
            "from the refitted sphere centre: comparable across --model)")


def _rms_lines(res):
    """The RMS figures, each saying what it measures, and why two of them differ."""
    lines = [f"RMS residual {res.rms_mm:.4f} mm per sphere centre over {res.n_used} samples used (root mean square "
             "of |e_i|, sample i's sphere centre through the calibrated chain against the sphere centre; unweighted), "
             f"max {res.max_residual_mm:.4f} mm"]
    obj = res.objective
    if obj is not None and (obj["model"] != "centre" or obj["weighted"]):
        per = _PER.get(obj["model"], "row")
        if obj["weighted"]:
            lines.append(f"the fit minimised (--model {obj['model']}): weighted RMS {obj['rms']:.4f} sd per {per} over "
                         f"{obj['rows']:,} {per}s (|W_i e_i|, each {per} whitened by its stated covariance: about "
                         f"{np.sqrt(3 if obj['model'] != 'points' else 1):.2f} when the noise is as stated); unweighted "
                         f"{obj['rms_unweighted_mm']:.4f} mm per {per}")
        else:
            lines.append(f"the fit minimised (--model {obj['model']}): RMS {obj['rms']:.4f} mm per {per} over "
                         f"{obj['rows']:,} {per}s (unweighted {obj['residual']})")
    lines.append(_loo_line(res))
    if res.before is not None:
        lines.append("before exclusion (every sample, plain least squares of the centre model, unweighted): RMS "
                     f"{res.before.rms_mm:.4f} mm per sphere centre"
                     + (f", leave-one-out {res.before.loo_error_mm:.4f} mm (the centre model refitted)"
                        if res.before.loo_error_mm is not None else ""))
        if res.rms_note is not None:
            lines.append(f"why they differ: {res.rms_note}")
    return lines


#: The text report lists every row up to this many; beyond, the first and the worst half of
#: this many each and a count (the JSON report keeps every row).
REPORT_ROWS = 50


def _residual_line(r):
    loo = f"{r.loo_error_mm:8.3f}" if r.loo_error_mm is not None else " " * 8
    flag = "" if r.used else "  EXCLUDED"
    return f"{r.id:>10} {r.row:>4} " + _fmt(r.vector, 9, 3) + f" {r.norm:9.3f} {loo}{flag}"


def residual_lines(residuals, limit=REPORT_ROWS):
    """The residual table of the text report: a header and one line per row (mm) up to ``limit``
    rows; beyond, the first ``limit // 2`` rows, the ``limit // 2`` largest ``|e|`` among the
    others (in row order) and how many are not shown.

    Parameters
    ----------
    residuals : sequence of handeye.app.present.residual_table.SampleResidual (or a ResidualTable), length N
    limit : int

    Returns
    -------
    list of str
    """
    head = [f"{'id':>10} {'row':>4} {'ex':>9} {'ey':>9} {'ez':>9} {'|e|':>9} {'loo':>8}  (mm)"]
    n = len(residuals)
    if n <= limit:
        return head + [_residual_line(r) for r in residuals]
    first = limit // 2
    norms = np.asarray(residuals.norms if hasattr(residuals, "norms") else [r.norm for r in residuals], float)
    rest = np.arange(first, n)
    worst = np.sort(rest[np.argsort(-np.nan_to_num(norms[first:], nan=np.inf), kind="stable")[:limit - first]])
    lines = head + [_residual_line(residuals[k]) for k in range(first)]
    lines.append(f"{'...':>10} ({n - limit:,} of the {n:,} rows not shown; below, the {len(worst)} largest |e| of "
                 "the others; the JSON report, --json, keeps every row)")
    return lines + [_residual_line(residuals[int(k)]) for k in worst]


#: The frame each mount's pose and centre are given in, as the report names it.
_MOUNT_FRAME = {"flange": "flange", "world": "base", "positioner": "table"}
_CELL_WORDS = {("flange", "world"): "the sensor on the flange and the sphere fixed in the robot's base frame",
               ("world", "flange"): "the sensor fixed in the robot's base frame and the sphere carried on the flange",
               ("flange", "positioner"): "the sensor on the flange and the sphere on the positioner's table"}


def cell_lines(res):
    """The sensor's 4x4 and the sphere centre in their mounts' frames, the positioner's axes, and in
    words what was calibrated (the seed's cell: the lines of earlier versions, unchanged)."""
    sensor_mount, sphere_mount = getattr(res, "sensor_mount", "flange"), getattr(res, "sphere_mount", "world")
    lines = [f"sensor2{_MOUNT_FRAME[sensor_mount]} (4x4):"] + ["  " + _fmt(row, 12, 6) for row in res.sensor2flange]
    lines.append(f"sphere centre in {_MOUNT_FRAME[sphere_mount]} (mm): " + _fmt(res.sphere_centre, 12, 4))
    positioner = getattr(res, "positioner", None)
    if (sensor_mount, sphere_mount) == ("flange", "world") and positioner is None:
        return lines
    parts = res.unknowns.split("+")
    lines.append(f"cell: {_CELL_WORDS[(sensor_mount, sphere_mount)]}; estimated: {', '.join(parts)}"
                 + ("; held: " + ", ".join(p for p in ("sensor", "sphere", "positioner") if p not in parts
                                           and (p != "positioner" or positioner is not None))
                    if len(parts) < 2 + (positioner is not None) else ""))
    for j, axis in enumerate(positioner.axes if positioner is not None else ()):
        sd = "" if positioner.point_sd is None else (
            f"  (1 sd: point {_fmt(positioner.point_sd[j], 7, 3).strip()} mm, tilt {positioner.tilt_sd_deg[j]:.4f} deg)")
        lines.append(f"positioner axis {axis.name} ({'calibrated' if positioner.calibrated else 'as set up'}): point "
                     + _fmt(axis.point, 11, 4).strip() + " mm, direction " + _fmt(axis.direction, 10, 7).strip() + sd)
    return lines


#: A warning's first clauses in the verdict's lines (the whole of it is at the end of the report).
VERDICT_WARNING_CHARS = 110
#: A warning in a comment is cut at a clause boundary (``;`` or ``:``) at most this long (characters):
#: a warning's first clause says what failed, the rest how to look into it (the file has it whole).
WARNING_CHARS = 160


def shorten(text, limit=WARNING_CHARS):
    """``text`` on one line, cut at the last clause boundary before ``limit`` characters (marked ``...``)."""
    text = " ".join(str(text).split())
    if len(text) <= limit:
        return text
    cut = max(text.rfind("; ", 0, limit), text.rfind(": ", 0, limit))
    return (text[:cut] if cut > limit // 3 else text[:limit - 4]).rstrip() + " ..."


def verdict_lines(res):
    """The verdict in the report's first lines: what the result is (a calibration to use, exit 0, its largest 1 sd;
    or no calibration, exit 1), and the first clause of each warning (the whole at the end)."""
    if not res.converged:
        head = "verdict: NOT a calibration (exit 1): do not use this pose; why: the status above and the warnings below"
    elif res.std is None or res.std.sensor_translation_mm is None:
        head = "verdict: a calibration (exit 0), with no sd (see the warnings)"
    else:
        mm, deg = float(np.max(res.std.sensor_translation_mm)), float(np.max(res.std.sensor_rotation_deg))
        head = f"verdict: a calibration to use (exit 0): 1 sd up to {mm:.3g} mm / {deg:.3g} deg (below)"
    warned = [f"  warning: {shorten(w, VERDICT_WARNING_CHARS)}" for w in res.warnings]
    return [head + (f"; {len(warned)} warning(s), each whole at the end:" if warned else "")] + warned


def calibration_text(res):
    """A readable report of a :class:`handeye.app.present.results.CalibrationResult`."""
    if res.closed_form is not None:
        return classic_text(res)
    lines = [
        f"handeye calibrate: dataset {res.dataset}, method {res.method}, rotation {res.rotation}, "
        f"unknowns {res.unknowns}, model {res.model}",
        f"status: {'converged' if res.converged else 'NOT CONVERGED'} after {res.iterations} iterations "
        f"({res.message})",
        *verdict_lines(res),
        "",
    ]
    if res.convention == "kuka":
        lines += ["start pose   (kuka: x y z mm, A B C deg): " + _fmt(res.start_pose),
                  "sensor pose  (kuka: x y z mm, A B C deg): " + _fmt(res.sensor_pose_kuka)]
    else:
        units = _CONVENTION_UNITS[res.convention]
        lines += [f"start pose   ({res.convention}: {','.join(res.columns)}; {units}): " + _fmt(res.start_pose, 10, 6),
                  f"sensor pose  ({res.convention}: {','.join(res.columns)}; {units}): " + _fmt(res.sensor_pose, 10, 6),
                  "sensor pose  (as KUKA x y z mm, A B C deg): " + _fmt(res.sensor_pose_kuka)]
    if res.own_axes is not None:
        lines.append("poses of the sensor's own frame (its profiles turned into handeye's by [profile] own_axes)")
    lines += cell_lines(res)
    lines.append(f"start: {res.start_used}")
    if res.rms_mm is None:  # no finite solution: nothing more to describe
        lines += ["", "no residuals, uncertainty or identifiability: the solve ended without a finite solution"]
        lines += [f"warning: {w}" for w in res.warnings]
        return "\n".join(lines)
    lines += [""] + residual_lines(res.residuals)
    lines += cleaning_lines(res.cleaning)
    if res.excluded:
        lines += ["", "excluded samples (gross errors, rows that contradict themselves, profiles that are no arc; "
                  "not used in the fit):"]
        lines += [f"  {e.id} (row {e.row}): {e.reason}" for e in res.excluded[:REPORT_ROWS]]
        if len(res.excluded) > REPORT_ROWS:
            lines.append(f"  ... and {len(res.excluded) - REPORT_ROWS:,} more (the JSON report, --json, lists every one)")
    per = "profile point" if res.model == "points" else "component of a sphere centre"
    lines += [""] + _rms_lines(res) + [
        "",
        "uncertainty (1 sd; " + (f"sigma = {res.sigma_mm:.4f} mm per {per}" if res.sigma_mm is not None
                                 else f"weighted residual, scale {res.sigma_scale:.3f}") + ", estimated from the fit):",
    ]
    if res.std.sensor_translation_mm is None:
        lines.append("  sensor pose: held as given (its uncertainty is its own calibration's)")
    else:
        lines += ["  sensor translation (mm):      " + _fmt(res.std.sensor_translation_mm),
                  "  sensor rotation (deg, about sensor x y z): " + _fmt(res.std.sensor_rotation_deg)]
    if res.std.sphere_center_mm is not None:
        lines.append("  sphere centre (mm):           " + _fmt(res.std.sphere_center_mm))
    if getattr(res, "t_factor", None) is not None and res.t_factor > 1.0:
        lines.append(f"  (Student-t on {res.dof} dof: the fit's sd x {res.t_factor:.3f}, so that 3 sd cover as a normal's)")
    if getattr(res, "power", None) is not None:
        lines.append(f"  {res.power.text}")
    lines += _effect_lines(res)
    ident = res.identifiability
    lines += [
        "",
        f"identifiability: rank {ident.rank} of {ident.n}, condition number {ident.condition:.3g} "
        f"(column-scaled), singular values " + " ".join(f"{v:.3g}" for v in ident.singular_values),
    ]
    lines += [f"warning: {w}" for w in res.warnings]
    return "\n".join(lines)


def _effect_lines(res):
    """The calibrated effects (``--effects``): values, 1 sd and what the sd is."""
    if not res.effects:
        return []
    from handeye.model import effects as catalogue

    lines = ["", "effects calibrated with the sensor pose (value +- 1 sd):"]
    for e in res.effects:
        doc = catalogue.get(e.name).DOC if e.name in catalogue.MODULES else ""
        values = ", ".join(f"{p} = {v:+.4g}" + ("" if e.std is None or e.std.get(p) is None or not np.isfinite(e.std[p])
                                                 else f" +- {e.std[p]:.2g}") for p, v in e.parameters.items())
        lines.append(f"  {e.name}: {values}" + (f" ({doc})" if doc else ""))
        if e.note:
            lines.append(f"    {e.note}")
    return lines


def calibration_plot(res, dataset, path):
    """Residual per measurement and the sphere centres seen through the calibrated chain
    (the sphere mount's frame, mm) around the calibrated centre; written to ``path`` (PNG).

    Parameters
    ----------
    res : handeye.app.present.results.CalibrationResult
    dataset : handeye.model.datasets.dataset.Dataset
        The dataset ``res`` was calibrated on (with a positioner: at the axes ``res`` holds,
        :func:`handeye.app.engine.cell_stage.dataset_at`).
    path : str or pathlib.Path
    """
    from handeye.app.present.plotting import figure

    plt = figure()
    if res.rms_mm is None:  # no finite solution: a figure that says so, not a crash
        fig, ax = plt.subplots(figsize=(6, 2))
        ax.axis("off")
        ax.text(0.5, 0.5, f"{res.dataset}: no finite solution ({res.message})", ha="center", va="center", wrap=True)
        _saved(plt, fig, path, tight=False)
        return
    fig, axes = plt.subplots(1, 2, figsize=(13, 5), gridspec_kw={"width_ratios": [1.7, 1]})
    used = np.array([r.used for r in res.residuals])
    _residual_bars(axes[0], res, used)
    sensor = np.asarray(res.sensor2flange)
    seen = (dataset.motions() @ sensor @ np.column_stack([dataset.centre_in_sensor, np.ones(len(dataset))])[..., None])
    _centres_seen(fig, axes[1], res, seen[:, :3, 0] - np.asarray(res.sphere_centre), used)
    _saved(plt, fig, path)


def _saved(plt, fig, path, option="--plot", tight=True):
    """``fig`` laid out (``tight``), saved in the one style (:func:`handeye.app.present.figure_style.save`) and closed."""
    from handeye.app.present import figure_style as style

    if tight:
        fig.tight_layout()
    style.save(fig, path, option=option)
    plt.close(fig)


def _residual_bars(ax, res, used):
    """``calibration_plot``'s left panel: |e_i| per sample, used in blue, excluded in vermillion."""
    from handeye.app.present import figure_style as style

    norms = np.array([r.norm for r in res.residuals])
    k = np.arange(len(norms))
    ax.bar(k[used], norms[used], color=style.BLUE, label="used")
    ax.bar(k[~used], norms[~used], color=style.VERMILLION, hatch="//", label="excluded")
    ax.set_xticks(k, [r.id for r in res.residuals], rotation=90)
    ax.set_xlim(-0.6, len(k) - 0.4)
    ax.set(ylabel="|e_i| (mm)", yscale="log", title=f"{res.dataset}: residuals ({res.method}, {res.rotation}, "
           f"RMS {res.rms_mm:.3f} mm of {int(used.sum())} used)")
    ax.legend()


def _centres_seen(fig, ax, res, d, used):
    """``calibration_plot``'s right panel: the centres through the chain minus the calibrated one;
    colour dz (with its bar); excluded samples as crosses, those beyond the view as edge arrows."""
    from handeye.app.present import figure_style as style

    dz = np.abs(d[used, 2]).max() if used.any() else 1.0
    sc = ax.scatter(d[used, 0], d[used, 1], c=d[used, 2], cmap="cividis", vmin=-dz, vmax=dz, s=28,
                    edgecolors="0.3", linewidths=0.4, label="used")
    fig.colorbar(sc, ax=ax, label="dz (mm)", shrink=0.9)
    ax.scatter(d[~used, 0], d[~used, 1], marker="x", s=40, color=style.VERMILLION, label="excluded")
    lim = max(1.15 * np.abs(d[used, :2]).max() if used.any() else 0.0, 1e-3)
    frame = _MOUNT_FRAME[getattr(res, "sphere_mount", "world")]
    ax.set(xlabel=f"dx (mm, {frame})", ylabel=f"dy (mm, {frame})", aspect="equal",
           title="sphere centres through the chain")
    style.edge_arrows(ax, d[:, 0], d[:, 1], [r.id for r in res.residuals], xlim=(-lim, lim), ylim=(-lim, lim))
    ax.legend(loc="best")


def _pm(value, sd, prec=4):
    text = f"{value:+.{prec}f}".replace("-0." + "0" * prec, "+0." + "0" * prec)  # no -0.0000
    return text + ("" if sd is None else f" +- {sd:.{prec}f}")


def validation_text(res):
    """The text report of ``handeye validate`` (:class:`handeye.app.outputs.validate.ValidationResult`)."""
    lines = [f"validation of {res.scan} through {res.calibration}"]
    lines += [f"calibration: {res.status}"] if getattr(res, "status", None) else []
    for s in res.spheres:
        lines += [f"[{s.label}] {s.n_points:,} points from {s.n_poses} poses"
                  + (f" ({s.excluded_points} largest deviations left out)" if s.excluded_points else ""),
                  f"  fitted radius      {s.radius_mm:.4f} +- {s.radius_sd_mm:.4f} mm (setup {s.setup_diameter_mm / 2:.4f})",
                  f"  PS size error      {_pm(s.size_error_mm, s.size_error_sd_mm)} mm (fitted - setup diameter)",
                  f"  PF form error      {s.form_error_mm:.4f} mm (max - min radial deviation; RMS {s.rms_mm:.4f}, "
                  f"max |dev| {s.max_abs_deviation_mm:.4f})",
                  f"  centre ({getattr(res, 'frame', 'base')})".ljust(19) + _fmt(s.centre) + " mm, 1 sd" + _fmt(s.centre_sd_mm)]
        if s.centre_offset_mm is not None:
            lines.append("  centre - setup    " + _fmt(s.centre_offset_mm) + f" mm (|d| = "
                         f"{np.linalg.norm(s.centre_offset_mm):.4f})")
        parts = [f"{k} {v['radius_mm']:.4f}/{v['centre_mm']:.4f}" for k, v in s.sd_sources.items() if v is not None]
        lines.append("  1 sd radius/centre by source (mm): " + ", ".join(parts))
    if res.spacing is not None:
        g = res.spacing
        lines.append(f"SD sphere spacing   {_pm(g.error_mm, g.error_sd_mm)} mm (measured {g.distance_mm:.4f}, setup "
                     f"{g.setup_distance_mm:.4f})")
    if res.centres is not None:
        c = res.centres.to_dict()
        lines += [f"{len(c['poses'])} sphere centres through the calibration against the setup's centre "
                  f"{_fmt(c['setup_centre']).strip()}:",
                  f"  mean offset {_fmt(c['mean_offset_mm']).strip()} mm; |eps|: RMS {c['rms_mm']:.4f} mm, median "
                  f"{c['median_mm']:.4f} mm, max {c['max_mm']:.4f} mm",
                  "  id            eps_x      eps_y      eps_z      |eps|   1 sd (calibration)"]
        lines += [f"  {p['id']:<10}" + _fmt(p["epsilon_mm"]) + f"{p['norm_mm']:10.4f}"
                  + ("" if p["predicted_sd_mm"] is None else f"{p['predicted_sd_mm']:10.4f}") for p in c["poses"]]
    if res.acceptance is not None:
        a = res.acceptance
        lim = ", ".join(f"{k} {v:g}" for k, v in a.limits.items())
        lines.append(f"acceptance (MPE {lim} mm): " + ("PASSED" if a.passed else "FAILED: " + ", ".join(
            f"{k} = {a.measured[k]:+.4f}" for k in a.failed)))
    lines += [f"skipped {s}" for s in res.skipped]
    lines += [f"note: {n}" for n in res.notes]
    return "\n".join(lines)


def validation_figure(res, path, max_points=20_000):
    """Radial deviation of every point on the sphere (3-D scatter, diverging colours, mm) and
    their histogram; for centre validation the |epsilon| of each pose. Written to ``path``."""
    from handeye.app.present import figure_style as style
    from handeye.app.present.plotting import figure

    plt = figure()
    if not res.spheres:
        c = res.centres
        fig, ax = plt.subplots(figsize=(10, 4))
        norms = np.linalg.norm(c.epsilon, axis=1)
        k = np.arange(len(norms))
        ax.bar(k, norms, color=style.BLUE, label="|epsilon|")
        if c.predicted_sd_mm is not None:
            ax.plot(k, c.predicted_sd_mm, "k_", ms=12, label="1 sd (calibration)")
        ax.set_xticks(k, c.ids, rotation=90)
        ax.set(ylabel="mm", yscale="log", title=f"{res.scan}: sphere centres through the calibration")
        ax.legend()
        _saved(plt, fig, path)
        return
    n = len(res.spheres)
    fig = plt.figure(figsize=(11, 4.8 * n))
    rng = np.random.default_rng(0)  # which points are drawn, when there are too many to draw
    for k, s in enumerate(res.spheres):
        ax = fig.add_subplot(n, 2, 2 * k + 1, projection="3d")
        idx = np.arange(len(s.points))
        if len(idx) > max_points:
            idx = np.sort(rng.choice(idx, max_points, replace=False))
        lim = float(np.max(np.abs(s.deviations))) or 1e-6
        p = s.points[idx] - s.centre
        sc = ax.scatter(p[:, 0], p[:, 1], p[:, 2], c=s.deviations[idx], cmap="cividis", vmin=-lim, vmax=lim, s=2)
        fig.colorbar(sc, ax=ax, shrink=0.7, pad=0.15, label="radial deviation (mm)")
        shown = f", {len(idx):,} of {len(s.points):,} drawn" if len(idx) < len(s.points) else ""
        ax.set(xlabel="x - cx (mm)", ylabel="y - cy (mm)", zlabel="z - cz (mm)",
               title=f"[{s.label}] PF {s.form_error_mm:.3f} mm, PS {s.size_error_mm:+.3f} mm{shown}")
        ax.title.set_fontsize(10)
        ah = fig.add_subplot(n, 2, 2 * k + 2)
        ah.hist(s.deviations, bins=80, color=style.BLUE)
        ah.axvline(0, color="k", lw=0.8)
        ah.set(xlabel="radial deviation (mm)", ylabel="points",
               title=f"RMS {s.rms_mm:.4f} mm over {s.n_points:,} points, {s.n_poses} poses")
    fig.suptitle(f"{res.scan}: radial deviations from the least-squares sphere (robot base, calibration "
                 f"{res.calibration})", fontsize=11)
    _saved(plt, fig, path)


def classic_text(res):
    """Readable report of :func:`calibrate_classic` (a CalibrationResult with ``closed_form``)."""
    d, ls = res.closed_form.details, res.closed_form.least_squares_from_here
    used = (f"{d['pairs']} motion pairs, condition number {d['condition']:.3g} (column-scaled D)" if "pairs" in d
            else f"{len(d['translation_pairs'])} pure-translation pairs spanning {d['directions']} directions")
    lines = [
        f"handeye calibrate: dataset {res.dataset}, method {res.method} (closed form), unknowns {res.unknowns}",
        f"used: {used}; {res.closed_form.time_ms:.2f} ms",
        "sensor pose  (x y z mm, A B C deg): " + " ".join(f"{v:10.4f}" for v in res.sensor_pose_kuka),
    ]
    if res.convention != "kuka":
        lines.append(f"sensor pose ({res.convention}: {','.join(res.columns)}): "
                     + " ".join(f"{v:10.6f}" for v in res.sensor_pose))
    lines += [
        "sphere centre in base (mm): " + " ".join(f"{v:12.4f}" for v in res.sphere_centre),
        f"RMS residual {res.rms_mm:.4f} mm over {res.n_used} samples used, max {res.max_residual_mm:.4f} mm",
        f"least squares started here: {'converged' if ls['converged'] else 'NOT converged'} in {ls['iterations']} "
        f"iterations, {ls['distance_mm']:.4f} mm and {ls['distance_deg']:.4f} deg away, RMS {ls['rms_mm']:.4f} mm",
    ]
    lines += cleaning_lines(res.cleaning)
    if res.excluded:
        lines.append("excluded samples (gross errors, screened as calibrate does):")
        lines += [f"  {x.id} (row {x.row}): {x.reason}" for x in res.excluded]
    lines += [f"warning: {w}" for w in res.warnings]
    return "\n".join(lines)


def diagnosis_text(res):
    """A readable report of a :class:`handeye.app.present.diagnosis_results.DiagnosisResult`."""
    lines = [f"handeye diagnose: dataset {res.dataset}, unknowns {res.unknowns}"
             + (" (the sphere centre estimated with the pose in every model)" if res.unknowns == "sensor+sphere" else ""),
             ""]
    lines.append("effects named:" if res.effects else "effects named: none")
    for eff in res.effects:
        lines.append(f"  {eff.name}: " + (", ".join(eff.parameters["ids"]) if eff.std is None else ", ".join(
            f"{k} = {v:.5g} +- {eff.std[k]:.2g}" for k, v in eff.parameters.items())))
        if eff.note:
            lines.append(f"    {eff.note}")
    if res.robot_alternatives:
        lines.append(f"  {res.robot_alternatives}")
    lines += cleaning_lines(getattr(res, "cleaning", None))[1:]
    lines.append("outliers excluded: " + (", ".join(res.outliers) or "none"))
    lines += [f"  configuration: {res.configuration}"] if getattr(res, "configuration", None) else []
    lines += [f"  {e.id} (row {e.row}): {e.reason}" for e in res.inconsistent]
    lines.append("not identifiable (absorbed): " + ("none" if not res.absorbed_by else ""))
    lines += [f"  {sentence}" for sentence in res.absorbed_explained]
    lines += ["", f"{'step':<34} {'RMS mm':>9} {'held-out':>9} {'chi2/dof':>9}"]
    lines += [f"{step.step:<34} {step.rms_mm:9.4f} {step.heldout_rms_mm:9.4f} {step.chi2_dof:9.2f}" for step in res.steps]
    lines += ["", f"chi2/dof against a nominal sigma of {res.nominal_sigma_mm} mm per component",
              f"sensor pose ({res.convention}: {','.join(res.columns)}): "
              + " ".join(f"{v:.4f}" for v in (res.sensor_pose_as if res.sensor_pose_as is not None else res.sensor_pose)),
              "  1 sd: translation mm " + " ".join(f"{v:.4f}" for v in res.std.sensor_translation_mm)
              + "; rotation deg (about the sensor's axes) " + " ".join(f"{v:.4f}" for v in res.std.sensor_rotation_deg),
              "sphere centre (mm): " + " ".join(f"{v:.4f}" for v in res.sphere_centre)
              + ("  1 sd " + " ".join(f"{v:.4f}" for v in res.std.sphere_center_mm)
                 if res.unknowns == "sensor+sphere" and res.std.sphere_center_mm is not None else ""),
              f"unexplained: {res.unexplained}"]
    if res.against_calibrate:
        lines.append(f"against calibrate: {res.against_calibrate}")
    return "\n".join(lines)


def draw_gap(ax, steps, sigma_mm):
    """The discrepancy workflow's gap on ``ax``: RMS per sphere centre fitted and held out at each
    step (``steps``: ``step``, ``rms_mm``, ``heldout_rms_mm`` as diagnose's JSON has them) against the
    noise floor, the stated ``sigma_mm`` per component as an RMS per centre (sqrt(3) sigma)."""
    labels = [s["step"] for s in steps]
    ax.plot(labels, [s["rms_mm"] for s in steps], "o-", label="fitted")
    ax.plot(labels, [s["heldout_rms_mm"] for s in steps], "s--", label="held out (5-fold)")
    floor = np.sqrt(3.0) * sigma_mm  # RMS of |e| per centre when the noise is as stated
    ax.axhline(floor, color="0.4", lw=1, ls=":", label=f"noise floor: stated {sigma_mm:g} mm x sqrt(3)")
    ax.set(ylabel="RMS per sphere centre (mm)", yscale="log", title="the gap, step by step")
    ax.set_ylim(bottom=min(floor, *(s["rms_mm"] for s in steps)) / 2)  # the floor in view, below the legend
    ax.tick_params(axis="x", rotation=20)
    for t in ax.get_xticklabels():  # the long step names end under their point, inside the figure
        t.set(ha="right", rotation_mode="anchor")
    ax.legend(loc="center left")


def diagnosis_figures(res, out):
    """Residuals before/after per sample, the gap shrinking step by step (PNG files in ``out``)."""
    from handeye.app.present import figure_style as style
    from handeye.app.present.plotting import figure

    out = pathlib.Path(out)
    out.mkdir(parents=True, exist_ok=True)
    plt = figure()
    fig, ax = plt.subplots(figsize=(10, 4))
    ids = [r.id for r in res.residuals]
    k = np.arange(len(ids))
    ax.bar(k - 0.2, [r.before_mm for r in res.residuals], 0.4, label="base model")
    ax.bar(k + 0.2, [r.after_mm for r in res.residuals], 0.4, label="with named effects")
    for i, r in enumerate(res.residuals):
        if not r.used:
            ax.annotate("excluded", (i + 0.2, r.after_mm), rotation=90, fontsize=style.MIN_FONT_PT, ha="center",
                        va="bottom")
    ax.set_xticks(k, ids, rotation=90)
    ax.set_xlim(-0.7, len(k) - 0.3)
    ax.set(ylabel="|residual| (mm)", yscale="log", title=f"{res.dataset}: residuals per measurement")
    ax.set_ylim(top=ax.get_ylim()[1] * 30)  # room for the labels above the tallest bars
    ax.legend()
    _saved(plt, fig, out / "residuals.png", option="--figures")
    fig, ax = plt.subplots(figsize=(8.4, 4.8))
    draw_gap(ax, [s.to_dict() for s in res.steps], res.nominal_sigma_mm)
    _saved(plt, fig, out / "gap.png", option="--figures")
    return [out / "residuals.png", out / "gap.png"]


def cleaning_lines(report, limit=20):
    """The text report's lines of a result's ``cleaning``
    (:func:`handeye.app.present.result_parts.cleaning_summary`; empty when there is nothing to say)."""
    if not report:
        return []
    if not report["applied"]:
        return ["", "profile cleaning: off (--no-clean): every profile point is fitted",
                *_bend_lines(report.get("bend"), report.get("profiles"))]
    what = report.get("what", "profile")
    head = (f"{what} cleaning: {report['dropped']:,} of {report['points']:,} points dropped on "
            f"{len(report['samples'])} of {report['profiles']} {what}s")
    sizes = report.get("diameters")
    size = ([f"fitted sphere diameters (radius free): mean {sizes['mean']:.4f} mm, sd {sizes['sd']:.2g} mm, range "
             f"{sizes['min']:.4f}-{sizes['max']:.4f} mm"] if sizes else [])
    if not report["dropped"]:
        return ["", head + f" (every point lies on its {'arc' if what == 'profile' else 'sphere'})", *size,
                *_bend_lines(report.get("bend"), report["profiles"])]
    why = ", ".join(f"{name} {n:,}" for name, n in report["reasons"].items())
    lines = ["", f"{head} ({why}; speckle, background or clusters, not the sphere):", *size]
    for s in report["samples"][:limit]:
        parts = ", ".join(f"{name} {n:,}" for name, n in s["reasons"].items())
        lines.append(f"  {s['id']} (row {s['row']}): {s['dropped']:,} of {s['points']:,} dropped ({parts})"
                     + (" -- an arc wider than the sphere, kept" if s["status"] == "wider" else ""))
    if len(report["samples"]) > limit:
        lines.append(f"  ... and {len(report['samples']) - limit} more (the JSON report, --json, lists every one)")
    return lines + _bend_lines(report.get("bend"), report["profiles"])


def _bend_lines(bend, profiles=None):
    """The line of the profiles' depth bend (:mod:`handeye.model.geometry.profile_bend`): said where one was
    fitted (degree above 0), applied or not, and why; where too few profiles were there to measure one, that."""
    from handeye.model.geometry.profile_bend import MIN_PROFILES

    if bend is None and profiles:
        why = (f"{profiles} profiles; it takes {MIN_PROFILES}" if profiles < MIN_PROFILES else
               "no fit of the profiles' shape could be made")
        return [f"profile bend along the sensor's depth: not measured ({why}): a linearity error of the sensor would "
                "go unseen"]
    if not bend or not bend["degree"]:
        return []
    lo, hi = bend["depths_mm"]
    return [f"profile bend along the sensor's depth: {bend['bend_mm']:.3g} mm over {lo:.0f}-{hi:.0f} mm (degree "
            f"{bend['degree']}, steepest slope {100 * bend['slope']:.2g} %, p = {bend['p_value']:.2g}); {bend['why']}"]
