"""The report's 3-D cell: plotly's WebGL scene (the optional ``report`` extra), or a picture.

Why plotly: its ``scatter3d`` and ``mesh3d`` draw on a WebGL ``<canvas>`` with rotation, zoom and
hover built in; its JavaScript inlines into the page (one file, offline), and its
``restyle`` lets the page's own script move the residual vectors (the scale slider) and show the
sample picked in the table. Hand-written WebGL would be smaller but a second renderer to keep
right; three.js needs a module loader and carries no axes, hover or legend. Without plotly the
report is complete but for interaction: the cell is a matplotlib 3-D picture (:func:`static_png`).

The JavaScript inlined is plotly.js's own ``gl3d`` partial bundle (``plotly-gl3d.min.js`` beside this module,
from the npm package ``plotly.js-gl3d-dist-min``, MIT, ``plotly-gl3d.LICENSE.txt``): every trace the view
draws, 1.75 MB where the full bundle the Python package ships is 4.8 MB; thesis-real's page opened in headless
Chromium in 1.5 s instead of 2.9 s. It is used where its version is the one the installed plotly ships (the
figure's JSON is written for that version, :data:`BUNDLE_VERSION`); with another plotly the full bundle is
inlined instead.

Colours are Okabe and Ito's colour-blind-safe set: frame axes x, y, z vermillion, bluish green,
blue; used centres blue; excluded samples reddish purple diamonds; residual vectors orange. Flange frames
are thin, sensor frames thick and shorter, the base frame long.
"""
from __future__ import annotations

import pathlib

import numpy as np

from handeye.app.present.figure_style import BLACK, BLUE, ORANGE, PURPLE, SKY, YELLOW
from handeye.app.present.web.figures import AXIS_COLOURS, new_figure, png_bytes, styled

#: At most this many flange and sensor frames and laser fans are drawn (evenly spaced over the samples):
#: a cell of thousands of poses stays a scene a browser turns smoothly.
MAX_DRAWN_POSES = 300
#: Up to this many samples' centres and residual vectors are drawn: every excluded one (all of them where they are
#: more) and the used ones evenly spaced to fill the rest (:func:`drawn_samples`); the table lists every sample,
#: and picking one draws its chain. At 10,000 samples the scene drew all of them in 2.5 s of the page's 4.8 s to
#: open in headless Chromium.
MAX_DRAWN_CENTRES = 2000
#: Residual vectors of excluded samples are drawn at most this many times the longest used one
#: (their direction is true; their length is in the table).
EXCLUDED_CAP = 3.0


def have_plotly():
    """True when plotly (the ``report`` extra) can be imported."""
    try:
        import plotly.graph_objects  # noqa: F401
    except ImportError:
        return False
    return True


def default_scale(cell):
    """Residual magnification that draws the longest used residual at a tenth of the cell's size."""
    norms = np.linalg.norm(cell.residual_base[cell.used], axis=1)
    longest = float(norms.max()) if len(norms) else 0.0
    return float(np.clip(0.1 * cell.extent / longest, 1.0, 1e4)) if longest > 0 else 1.0


def scale_text(scale):
    """The residual magnification as the page writes it (``×18.2``, ``×2300``)."""
    return f"×{scale:.1f}" if scale < 10 else f"×{scale:.0f}"


def capped_residuals(cell):
    """The residual vectors in the base (N, 3), mm, those of excluded samples shortened to
    :data:`EXCLUDED_CAP` times the longest used one (direction kept): a gross error of metres
    would otherwise shrink the cell to a dot."""
    norms = np.linalg.norm(cell.residual_base, axis=1)
    cap = EXCLUDED_CAP * (norms[cell.used].max() if cell.used.any() else 1.0)
    factor = np.where(cell.used | (norms <= cap), 1.0, cap / np.where(norms > 0, norms, 1.0))
    return cell.residual_base * factor[:, None]


def drawn_samples(cell):
    """Which samples' centres and residuals the view draws (N,) bool (:data:`MAX_DRAWN_CENTRES`)."""
    drawn = ~np.asarray(cell.used, bool)
    used = np.flatnonzero(cell.used)
    room = min(len(used), MAX_DRAWN_CENTRES - int(drawn.sum()))
    if room > 0:
        drawn[used[np.unique(np.linspace(0, len(used) - 1, room).round().astype(int))]] = True
    return drawn


def residual_segments(cell, scale):
    """Line segments (with None breaks) from each drawn sphere centre (:func:`drawn_samples`) along its scaled
    residual (:func:`capped_residuals`): used samples and excluded ones, as two (x, y, z) lists."""
    vec, drawn = capped_residuals(cell) * scale, drawn_samples(cell)
    return [_segments(cell.sphere[m], cell.sphere[m] + vec[m]) for m in (cell.used & drawn, ~cell.used & drawn)]


def _segments(start, end):
    """Plotly line coordinates: start, end, None for each segment."""
    xyz = []
    for k in range(3):
        col = np.full(3 * len(start), np.nan)
        col[0::3], col[1::3] = start[:, k], end[:, k]
        xyz.append([None if np.isnan(v) else round(float(v), 4) for v in col])
    return xyz


def _triads(frames, length):
    """Three (x, y, z) line lists, one per frame axis, of every frame in ``frames`` (M, 4, 4)."""
    origin = frames[:, :3, 3]
    return [_segments(origin, origin + length * frames[:, :3, k]) for k in range(3)]


def _sphere_mesh(centre, radius, n=18):
    u, v = np.meshgrid(np.linspace(0, 2 * np.pi, n), np.linspace(0, np.pi, n // 2 + 1))
    return (centre[0] + radius * np.cos(u) * np.sin(v), centre[1] + radius * np.sin(u) * np.sin(v),
            centre[2] + radius * np.cos(v))


def figure(cell, title):
    """The plotly figure of ``cell`` and the indices of the traces the page's script changes.

    Returns
    -------
    fig : plotly.graph_objects.Figure
    traces : dict
        ``residuals``, ``residuals_excluded``, ``centres``, ``selected``: trace indices.
    scale : float
        The residual magnification drawn (:func:`default_scale`).
    """
    import plotly.graph_objects as go

    scale = default_scale(cell)
    traces, index = [], {}

    def add(name, trace):
        index[name] = len(traces)
        traces.append(trace)

    _frames(add, go, cell, 0.06 * cell.extent)
    _laser(add, go, cell)
    _sphere(add, go, cell)
    _points(add, go, cell, scale)
    if cell.mounts.axes:
        _positioner(add, go, cell)
    add("selected", go.Scatter3d(x=[], y=[], z=[], mode="lines+markers", name="picked sample",
                                 line=dict(color=BLACK, width=7), marker=dict(size=7, color=BLACK), hoverinfo="skip"))
    fig = go.Figure(traces)
    fig.update_layout(title=dict(text=title, font=dict(size=14)), height=640, margin=dict(l=0, r=0, t=40, b=0),
                      font=dict(size=13), legend=dict(itemsizing="constant", font=dict(size=12)),
                      scene=dict(aspectmode="data", xaxis_title="x base (mm)", yaxis_title="y base (mm)",
                                 zaxis_title="z base (mm)"), uirevision="cell")
    return fig, index, scale


def drawn_poses(n):
    """Indices of the poses whose frames and fans are drawn (:data:`MAX_DRAWN_POSES`, evenly spaced)."""
    return np.unique(np.linspace(0, n - 1, min(n, MAX_DRAWN_POSES)).round().astype(int)) if n else np.zeros(0, int)


def _frames(add, go, cell, length):
    some = drawn_poses(len(cell.ids))
    groups = (("base frame (long)", np.eye(4)[None], 2.0 * length, 7),
              ("flange frames (thin)", cell.flange2base[some], length, 2),
              ("sensor frames (thick)", cell.sensor2base[some] if cell.mounts.sensor == "flange"
               else cell.sensor2base[:1], 0.7 * length, 6))
    for name, frames, size, width in groups:
        for k, xyz in enumerate(_triads(frames, size)):
            add(f"{name} {'xyz'[k]}", go.Scatter3d(
                x=xyz[0], y=xyz[1], z=xyz[2], mode="lines", name=name, legendgroup=name, showlegend=k == 0,
                line=dict(color=AXIS_COLOURS[k], width=width), hoverinfo="skip"))


def _laser(add, go, cell):
    near = np.linalg.norm(capped_residuals(cell) - cell.residual_base, axis=1) < 1e-9  # a gross error's fan: not drawn
    near &= np.isin(np.arange(len(near)), drawn_poses(len(near)))
    tri = cell.fans[near].reshape(-1, 3)
    n = int(near.sum())
    add("fans", go.Mesh3d(x=tri[:, 0], y=tri[:, 1], z=tri[:, 2], i=3 * np.arange(n), j=3 * np.arange(n) + 1,
                          k=3 * np.arange(n) + 2, color=SKY, opacity=0.18, name="laser fans",
                          showlegend=True, hoverinfo="skip"))
    pts = [p for p, ok in zip(cell.profiles, near) if len(p) and ok]
    if pts:
        allp = np.vstack(pts)
        add("profiles", go.Scatter3d(x=allp[:, 0], y=allp[:, 1], z=allp[:, 2], mode="markers", name="profile points",
                                     marker=dict(size=1.6, color=BLACK), hoverinfo="skip"))


def _sphere(add, go, cell):
    first = int(np.flatnonzero(cell.used)[0]) if cell.used.any() else 0
    sx, sy, sz = _sphere_mesh(cell.sphere[first], cell.radius)
    add("sphere", go.Surface(x=sx, y=sy, z=sz, opacity=0.35, showscale=False, name="sphere", showlegend=True,
                             colorscale=[[0, "#999999"], [1, "#bbbbbb"]], hoverinfo="skip"))
    if cell.mounts.sphere != "world":
        add("sphere_centres", go.Scatter3d(
            x=cell.sphere[:, 0], y=cell.sphere[:, 1], z=cell.sphere[:, 2], mode="markers", name="sphere centre per sample",
            marker=dict(size=3, color="#777777"), text=cell.ids, hovertemplate="%{text}: sphere centre<extra></extra>"))


def _points(add, go, cell, scale):
    used, excl = residual_segments(cell, scale)
    add("residuals", go.Scatter3d(x=used[0], y=used[1], z=used[2], mode="lines", name=f"residuals {scale_text(scale)}",
                                  line=dict(color=ORANGE, width=5), hoverinfo="skip"))
    idx = np.arange(len(cell.ids))
    norms = np.linalg.norm(cell.residual_base, axis=1)
    shown = cell.sphere + scale * capped_residuals(cell)  # at the end of its drawn residual; |e| in the text
    drawn = drawn_samples(cell)
    for name, mask, style in (("centres", cell.used & drawn, dict(size=4, color=BLUE, symbol="circle")),
                              ("centres_excluded", ~cell.used & drawn, dict(size=5, color=PURPLE, symbol="diamond"))):
        label = "measured centres" if name == "centres" else "excluded samples"
        add(name, go.Scatter3d(
            x=shown[mask, 0], y=shown[mask, 1], z=shown[mask, 2], mode="markers", name=label,
            marker=style, customdata=idx[mask], text=[f"{cell.ids[i]}: |e| {norms[i]:.4g} mm" for i in idx[mask]],
            hovertemplate="%{text}<extra></extra>", visible=True if mask.any() else "legendonly"))
    add("residuals_excluded", go.Scatter3d(
        x=excl[0], y=excl[1], z=excl[2], mode="lines", name="excluded residuals (capped)",
        line=dict(color=PURPLE, width=4, dash="dash"), hoverinfo="skip",
        visible=True if (~cell.used).any() else "legendonly"))


def _positioner(add, go, cell):
    start, end = (np.array([a.point + sign * 0.3 * cell.extent * a.direction for a in cell.mounts.axes]) for sign in (-1, 1))
    xyz = _segments(start, end)
    add("positioner", go.Scatter3d(x=xyz[0], y=xyz[1], z=xyz[2], mode="lines", name="positioner axes",
                                   line=dict(color=YELLOW, width=6), hoverinfo="skip"))
    add("positioner_names", go.Scatter3d(x=end[:, 0], y=end[:, 1], z=end[:, 2], mode="text", showlegend=False,
                                         text=[a.name for a in cell.mounts.axes], textfont=dict(size=14),
                                         hoverinfo="skip"))


#: The plotly.js version of the ``gl3d`` bundle beside this module.
BUNDLE_VERSION = "4.1.1"
_BUNDLE = pathlib.Path(__file__).with_name("plotly-gl3d.min.js")


def plotly_js():
    """The plotly.js inlined in the page: the ``gl3d`` bundle where the installed plotly writes figures for its
    version (module docstring), else that plotly's full bundle."""
    import plotly.offline

    if plotly.offline.get_plotlyjs_version() == BUNDLE_VERSION and _BUNDLE.exists():
        return _BUNDLE.read_text(encoding="utf-8")
    return plotly.offline.get_plotlyjs()


def html_div(fig, div_id="cell3d"):
    """The figure as a ``<div>`` with plotly's JavaScript inlined (offline, :func:`plotly_js`), no MathJax, no
    logo."""
    div = fig.to_html(full_html=False, include_plotlyjs=False, div_id=div_id,
                      config={"displaylogo": False, "responsive": True, "toImageButtonOptions": {"scale": 2}})
    return ("<script type='text/javascript'>window.PlotlyConfig = {MathJaxConfig: 'local'};</script>"
            f"<script type='text/javascript'>{plotly_js()}</script>{div}")


@styled
def static_png(cell, title):
    """The cell as a matplotlib 3-D picture (PNG bytes): the report without plotly."""
    fig = new_figure(figsize=(10, 8))
    ax = fig.add_subplot(projection="3d")
    for frames in (cell.flange2base, cell.sensor2base):
        for k, xyz in enumerate(_triads(frames, 0.06 * cell.extent)):
            ax.plot(*(np.array(c, dtype=float) for c in xyz), color=AXIS_COLOURS[k], lw=1)
    scale = default_scale(cell)
    used, _ = residual_segments(cell, scale)
    shown = cell.sphere + scale * capped_residuals(cell)  # as the interactive view: at the end of each drawn residual
    ax.plot(*(np.array(c, dtype=float) for c in used), color=ORANGE, lw=2, label=f"residuals {scale_text(scale)}")
    ax.scatter(*shown[cell.used].T, color=BLUE, s=12, label="measured centres")
    if (~cell.used).any():
        ax.scatter(*shown[~cell.used].T, color=PURPLE, marker="x", s=40, label="excluded (capped)")
    ax.scatter(*cell.sphere[cell.used].T, color="0.5", s=30, label="sphere centre")
    ax.set(xlabel="x base (mm)", ylabel="y base (mm)", zlabel="z base (mm)", title=title)
    ax.legend(loc="upper left")
    return png_bytes(fig)
