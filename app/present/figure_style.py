"""One style for every figure handeye saves (issue 30, item 3): the CLI's ``--plot`` and
``--figures``, ``bench --plot``, the studies' PNGs and the notebooks' static panels.

The rules, each checked by :func:`violations` on the drawn figure and enforced by :func:`save`:

- at least :data:`MIN_DPI` dots per inch and :data:`MIN_WIDTH_PX` pixels across (the dpi is
  raised for a narrow figure, never lowered);
- no text below :data:`MIN_FONT_PT` points: tick labels, legends, annotations, pose labels;
- colours from a colour-blind-safe palette: Okabe-Ito (:data:`OKABE_ITO`) for categories,
  greys for references, viridis or cividis (:data:`MAPS`) where colour encodes a value;
- a colour bar for every artist whose colour encodes a value;
- every data point inside its axes, or an arrow at the edge pointing to it (:func:`edge_arrows`,
  which draws those arrows).

:func:`style` applies the rcParams (sizes, palette, colour map) for a block; :func:`save`
draws, checks and writes a figure through :func:`handeye.app.common.files.save_figure_atomically`.
A figure that breaks a rule is still written (a cosmetic slip must not cost a user their
calibration's output), with a :class:`FigureStyleWarning` naming the rule; the test suite turns
that warning into an error.
"""
from __future__ import annotations

import contextlib
import io
import math
import warnings
from statistics import NormalDist

import numpy as np

#: Smallest resolution of a saved figure (dots per inch).
MIN_DPI = 120
#: Smallest width of a saved figure (pixels).
MIN_WIDTH_PX = 1000
#: Smallest text anywhere on a figure (points).
MIN_FONT_PT = 9.0
#: Okabe & Ito's eight colours, safe for the common colour-vision deficiencies; the cycle's
#: order puts blue and vermillion first (used / excluded, before / after).
OKABE_ITO = ("#0072B2", "#D55E00", "#009E73", "#E69F00", "#CC79A7", "#56B4E9", "#F0E442", "#000000")
#: Named Okabe-Ito colours, for meanings that recur (excluded samples are always vermillion).
BLUE, VERMILLION, GREEN, ORANGE, PURPLE, SKY, YELLOW, BLACK = OKABE_ITO
#: Colour maps allowed where colour encodes a value (perceptually uniform, colour-blind safe).
MAPS = ("viridis", "cividis")
#: Marker per category, so that categories differ without colour too.
MARKERS = ("o", "s", "^", "D", "v", "P", "X", "*")

RC = {
    "font.size": 10.0,
    "axes.titlesize": 11.0,
    "axes.labelsize": 10.0,
    "xtick.labelsize": 9.0,
    "ytick.labelsize": 9.0,
    "legend.fontsize": 9.0,
    "legend.title_fontsize": 9.0,
    "figure.titlesize": 12.0,
    "image.cmap": "viridis",
    "savefig.dpi": MIN_DPI,
    "figure.dpi": 100,
}


class FigureStyleWarning(UserWarning):
    """A saved figure breaks one of the module's rules (see :func:`violations`)."""


def rc():
    """The rcParams of the style (a new dict: sizes, the Okabe-Ito cycle, viridis)."""
    from cycler import cycler

    return {**RC, "axes.prop_cycle": cycler(color=list(OKABE_ITO))}


@contextlib.contextmanager
def style():
    """Context manager: matplotlib's rcParams set to the style inside the block."""
    import matplotlib

    with matplotlib.rc_context(rc()):
        yield


def apply():
    """Set the style's rcParams for the rest of the process (the Agg figures of the CLI and studies)."""
    import matplotlib

    matplotlib.rcParams.update(rc())


def dpi_for(width_in):
    """The dpi at which a figure ``width_in`` inches wide is at least :data:`MIN_WIDTH_PX` wide."""
    return max(MIN_DPI, math.ceil(MIN_WIDTH_PX / max(width_in, 1e-3)))


def save(fig, path, option="--plot", check=True):
    """Write ``fig`` to ``path`` (format from the suffix; atomically, as every output) at the
    style's resolution, after :func:`violations` (each found is a :class:`FigureStyleWarning`).

    Parameters
    ----------
    fig : matplotlib.figure.Figure
    path : str or pathlib.Path
    option : str
        The option that named ``path`` (for the message when it cannot be written).
    check : bool
        Check the style rules (the figure is drawn once more to do so).

    Returns
    -------
    int
        The dpi written.
    """
    from handeye.app.common.files import save_figure_atomically

    dpi = dpi_for(fig.get_figwidth())
    if check:
        _warn(violations(fig))
    save_figure_atomically(fig, path, option=option, dpi=dpi)
    return dpi


def png_bytes(fig, check=True, colours=256):
    """PNG bytes of ``fig`` cropped to its content (``bbox_inches="tight"``), at least
    :data:`MIN_WIDTH_PX` wide and :data:`MIN_DPI` dpi (a notebook panel's static figure).

    Parameters
    ----------
    fig : matplotlib.figure.Figure
    check : bool
        Warn of broken rules (:func:`violations`).
    colours : int or None
        Quantise to a palette of this many colours (Pillow, median cut): the panels' PNGs live
        inside the notebooks, and at 1,000 px a 6.5-inch contour panel is 370 kB in full colour,
        112 kB in 256 colours (142 kB at the old 80 dpi). None keeps full colour.
    """
    if check:
        _warn(violations(fig))
    fig.draw_without_rendering()
    width = fig.get_tightbbox().width + 0.2  # the 0.1 in padding each side
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi_for(width) + 2, bbox_inches="tight")  # +2: text extents vary with dpi
    if colours is None:
        return buf.getvalue()
    from PIL import Image

    image = Image.open(io.BytesIO(buf.getvalue()))
    out = io.BytesIO()
    image.convert("RGB").quantize(colours, method=Image.Quantize.MEDIANCUT).save(
        out, format="png", optimize=True, dpi=image.info["dpi"])
    return out.getvalue()


def check(fig):
    """Warn (:class:`FigureStyleWarning`) of every rule ``fig`` breaks (:func:`violations`)."""
    _warn(violations(fig))


def _warn(found):
    for text in found:
        warnings.warn(text, FigureStyleWarning, stacklevel=3)


def violations(fig):
    """The style rules ``fig`` breaks, as sentences (empty when it keeps them all).

    Checks text sizes, colour maps and colour bars, the palette of lines, bars and markers,
    and that every data point lies inside its axes or has an edge arrow (:func:`edge_arrows`).
    The figure is drawn first, so that tick labels exist.
    """
    fig.draw_without_rendering()
    found = _small_text(fig)
    bars = {id(m.colorbar.ax) for ax in fig.axes for m in _mappables(ax) if m.colorbar is not None}
    for ax in fig.axes:
        if id(ax) in bars:
            continue
        found += _unlabelled_maps(ax) + _off_palette(ax) + _off_axes(ax)
    return found


def _small_text(fig):
    from matplotlib.text import Text

    small = {}
    for t in fig.findobj(Text):
        if t.get_visible() and t.get_text().strip() and t.get_fontsize() < MIN_FONT_PT - 1e-9:
            small.setdefault(round(t.get_fontsize(), 1), []).append(t.get_text().strip())
    return [f"text at {size:g} pt (< {MIN_FONT_PT:g}): " + ", ".join(repr(s) for s in texts[:4])
            + (f" and {len(texts) - 4} more" if len(texts) > 4 else "") for size, texts in small.items()]


def _mappables(ax):
    """The artists of ``ax`` whose colour encodes a value (a ScalarMappable with an array)."""
    from matplotlib.cm import ScalarMappable

    return [a for a in ax.get_children() if isinstance(a, ScalarMappable) and a.get_array() is not None]


def _unlabelled_maps(ax):
    found = []
    for a in (m for m in _mappables(ax) if m.get_visible()):
        cmap = a.get_cmap().name
        if cmap not in MAPS and not cmap.startswith("okabe-ito"):
            found.append(f"colour map {cmap!r} (use one of {', '.join(MAPS)}, or an Okabe-Ito category map)")
        if a.colorbar is None and not (cmap.startswith("okabe-ito") and ax.figure.legends):  # categories: a legend
            found.append(f"colour encodes a value without a colour bar ({type(a).__name__} in {ax.get_title()!r})")
    return found


def _is_grey(rgba):
    return rgba[3] == 0 or (abs(rgba[0] - rgba[1]) < 1e-6 and abs(rgba[1] - rgba[2]) < 1e-6)


def _colour_ok(colour):
    from matplotlib.colors import to_hex, to_rgba

    rgba = to_rgba(colour)
    return _is_grey(rgba) or to_hex(rgba).lower() in {c.lower() for c in OKABE_ITO}


def _off_palette(ax):
    from matplotlib.collections import Collection
    from matplotlib.colors import to_hex
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    bad = set()
    for a in ax.get_children():
        if not a.get_visible() or a is ax.patch:
            continue
        if isinstance(a, Line2D):
            colours = [a.get_color(), a.get_markerfacecolor(), a.get_markeredgecolor()]
        elif isinstance(a, Patch):
            colours = [a.get_facecolor(), a.get_edgecolor()]
        elif isinstance(a, Collection) and a.get_array() is None:
            colours = [*a.get_facecolor(), *a.get_edgecolor()]
        else:
            continue
        bad.update(to_hex(c) for c in colours if not (isinstance(c, str) and c in ("none", "auto")) and not _colour_ok(c))
    return [f"colours outside the Okabe-Ito palette and greys in {ax.get_title()!r}: " + ", ".join(sorted(bad))] if bad else []


def _points(ax):
    """Every data point drawn in data coordinates on ``ax`` (lines, markers, bar ends)."""
    from matplotlib.collections import PathCollection
    from matplotlib.container import BarContainer
    from matplotlib.lines import Line2D

    pts = []
    for a in ax.get_children():
        if isinstance(a, Line2D) and a.get_visible() and a.get_transform() == ax.transData:
            pts.append(np.asarray(a.get_xydata(), float).reshape(-1, 2))  # unit-converted (categories: 0, 1, ...)
        elif isinstance(a, PathCollection) and a.get_visible() and a.get_offset_transform() == ax.transData:
            pts.append(np.asarray(a.get_offsets(), float).reshape(-1, 2))
    for c in ax.containers:
        if isinstance(c, BarContainer):
            horizontal = c.orientation == "horizontal"
            for r in c.patches:
                end = r.get_x() + r.get_width() if horizontal else r.get_y() + r.get_height()
                centre = r.get_y() + r.get_height() / 2 if horizontal else r.get_x() + r.get_width() / 2
                if r.get_width() != 0 and r.get_height() != 0:
                    pts.append(np.array([[end, centre]] if horizontal else [[centre, end]]))
    return np.vstack(pts) if pts else np.empty((0, 2))


def _inside(values, lim, log):
    lo, hi = sorted(lim)
    span = hi / lo if log and lo > 0 else hi - lo
    tol = span ** 1e-6 if log else 1e-6 * span
    if log:
        return (values > 0) & (values >= lo / tol) & (values <= hi * tol)
    return (values >= lo - tol) & (values <= hi + tol)


def _off_axes(ax):
    if ax.name != "rectilinear":
        return []
    pts = _points(ax)
    pts = pts[np.isfinite(pts).all(axis=1)]
    inside = (_inside(pts[:, 0], ax.get_xlim(), ax.get_xscale() == "log")
              & _inside(pts[:, 1], ax.get_ylim(), ax.get_yscale() == "log"))
    arrows = sum(1 for t in ax.texts if t.get_gid() == "edge-arrow")
    off = int(np.sum(~inside))
    return [f"{off} data points outside the axes of {ax.get_title()!r} with {arrows} edge arrows"] if off > arrows else []


def edge_arrows(ax, x, y, labels, xlim=None, ylim=None):
    """Arrows at the edge of ``ax`` towards the points outside its limits (the limits given, or
    the axes' own), each labelled with the point's name; arrows on one edge are spread along it
    and their labels staggered, so that none hides another.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
    x, y : array_like
        Data coordinates of every point drawn (those inside the limits get no arrow).
    labels : sequence of str
        One name per point.
    xlim, ylim : tuple of float, optional
        Limits to set first.

    Returns
    -------
    int
        The number of arrows drawn.
    """
    if xlim is not None:
        ax.set_xlim(xlim)
    if ylim is not None:
        ax.set_ylim(ylim)
    (x0, x1), (y0, y1) = sorted(ax.get_xlim()), sorted(ax.get_ylim())
    x, y = np.asarray(x, float), np.asarray(y, float)
    out = np.isfinite(x) & np.isfinite(y) & ((x < x0) | (x > x1) | (y < y0) | (y > y1))
    edges = {}  # (axis normal to the edge, side) -> [(position along the edge, name)]
    for xi, yi, name in zip(x[out], y[out], np.asarray(labels, dtype=object)[out]):
        u = np.array([(xi - (x0 + x1) / 2) / (x1 - x0), (yi - (y0 + y1) / 2) / (y1 - y0)])
        normal = int(abs(u[1]) > abs(u[0]))
        along = 0.5 + 0.5 * u[1 - normal] / abs(u[normal])
        edges.setdefault((normal, u[normal] > 0), []).append((along, str(name)))
    for (normal, high), items in edges.items():
        for k, (along, name) in enumerate(_spread(sorted(items))):
            tip, tail = np.zeros(2), np.zeros(2)
            tip[normal], tip[1 - normal] = (0.985 if high else 0.015), along
            tail[normal], tail[1 - normal] = tip[normal] + (-1 if high else 1) * (0.12 + 0.09 * (k % 2)), along
            ha = ("right" if high else "left") if normal == 0 else "center"
            va = ("top" if high else "bottom") if normal == 1 else "center"
            ax.annotate(name, xy=tip, xytext=tail, xycoords="axes fraction", textcoords="axes fraction",
                        ha=ha, va=va, fontsize=MIN_FONT_PT, gid="edge-arrow", color=VERMILLION,
                        arrowprops={"arrowstyle": "->", "color": VERMILLION, "lw": 1.2})
    return int(out.sum())


def _spread(items, gap=0.08):
    """Positions along an edge (axes fraction, sorted) pushed apart to ``gap`` and kept inside."""
    pos = np.clip([a for a, _ in items], 0.06, 0.94)
    for k in range(1, len(pos)):
        pos[k] = max(pos[k], pos[k - 1] + gap)
    pos -= max(pos[-1] - 0.94, 0.0) if len(pos) else 0.0  # pushed past the end: shift the row back
    return [(float(p), name) for p, (_, name) in zip(pos, items)]


def binomial_interval(successes, n, level=0.95):
    """Wilson score interval of a binomial rate, ``(low, high)`` (arrays when the inputs are).

    Parameters
    ----------
    successes, n : int or array_like
    level : float
        Two-sided coverage.
    """
    k, n = np.asarray(successes, float), np.asarray(n, float)
    z = NormalDist().inv_cdf(0.5 + level / 2)
    p = np.divide(k, n, out=np.full_like(k, np.nan), where=n > 0)
    centre = (p + z**2 / (2 * n)) / (1 + z**2 / n)
    half = z * np.sqrt(p * (1 - p) / n + z**2 / (4 * n**2)) / (1 + z**2 / n)
    return np.clip(np.minimum(centre - half, p), 0, 1), np.clip(np.maximum(centre + half, p), 0, 1)  # p inside, to round-off
