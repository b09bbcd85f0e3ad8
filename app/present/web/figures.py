"""The report's 2-D figures, as PNG bytes: residuals in the sensor frame against the pose angles,
the unknowns' correlation matrix, and the discrepancy steps against the noise floor.

The one style of every figure (:mod:`handeye.app.present.figure_style`): 120 dpi and 1200 px wide,
text of at least 9 pt, a colour bar wherever colour encodes a value, Okabe and Ito's colour-blind-safe
colours, and a point beyond the axes drawn at the edge as a triangle pointing to it (with its value)."""
from __future__ import annotations

import functools
import io

import numpy as np

from handeye.app.present import figure_style
from handeye.app.present.figure_style import BLUE, GREEN, PURPLE, VERMILLION

#: Frame axes x, y, z.
AXIS_COLOURS = (VERMILLION, GREEN, BLUE)
#: Every report figure's resolution (dots per inch).
DPI = figure_style.MIN_DPI


def styled(draw):
    """Run ``draw`` in the one figure style (:func:`handeye.app.present.figure_style.style`: nothing
    global changes)."""
    @functools.wraps(draw)
    def run(*args, **kwargs):
        with figure_style.style():
            return draw(*args, **kwargs)
    return run


def new_figure(figsize=(10, 5)):
    """A matplotlib figure (Agg, no pyplot state); 10 in at 120 dpi is 1200 px. Call it from a
    :func:`styled` function."""
    from matplotlib.figure import Figure

    return Figure(figsize=figsize, dpi=DPI)


def png_bytes(fig):
    """The figure as PNG bytes at :data:`DPI` (10 in wide: 1200 px), its style checked
    (:func:`handeye.app.present.figure_style.violations`: a broken rule warns)."""
    figure_style.check(fig)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=DPI)
    return buf.getvalue()


def _limits(values):
    """Axis limits around ``values`` (the used samples'), with 10 % room."""
    lo, hi = (float(np.min(values)), float(np.max(values))) if len(values) else (-1.0, 1.0)
    pad = 0.1 * (hi - lo or abs(hi) or 1.0)
    return lo - pad, hi + pad


@styled
def residuals_against_angles(cell, poses, columns):
    """Residual components in each sample's sensor frame (rows: x, y, z) against the flange pose's
    three orientation angles (columns); excluded samples outside the axes drawn at the edge.

    Parameters
    ----------
    cell : handeye.app.present.web.cell.CellGeometry
    poses : ndarray, shape (N, 6)
        Flange poses, KUKA (mm, deg): the angles A, B, C are columns 3..5.
    columns : sequence of str
        Names of the three angle columns.
    """
    fig = new_figure(figsize=(10, 7.5))
    axes = fig.subplots(3, 3, sharex="col", sharey="row")
    e, used = cell.residual_sensor, cell.used
    for r in range(3):
        lims = _limits(e[used, r])
        for c in range(3):
            ax = axes[r, c]
            ang = poses[:, 3 + c]
            ax.scatter(ang[used], e[used, r], s=18, color=BLUE, label="used")
            _edge_points(ax, ang[~used], e[~used, r], lims)
            ax.axhline(0.0, color="0.5", lw=0.8)
            ax.set_ylim(*lims)
            if r == 2:
                ax.set_xlabel(f"flange {columns[c]} (deg)")
            if c == 0:
                ax.set_ylabel(f"e_{'xyz'[r]} sensor (mm)")
    axes[0, 0].legend(loc="best")
    fig.suptitle("residual in the sensor frame against the flange's orientation angles")
    fig.tight_layout()
    return png_bytes(fig)


def _edge_points(ax, x, y, lims):
    """Excluded samples: inside the limits as crosses, outside as triangles at the edge with the value."""
    inside = (y >= lims[0]) & (y <= lims[1])
    ax.scatter(x[inside], y[inside], s=40, marker="x", color=PURPLE, label="excluded")
    for xv, yv in zip(x[~inside], y[~inside]):
        top = yv > lims[1]
        edge = lims[1] if top else lims[0]
        ax.scatter([xv], [edge], s=60, marker="^" if top else "v", color=PURPLE, clip_on=False)
        ax.annotate(f"{yv:.3g}", (xv, edge), textcoords="offset points", xytext=(4, -12 if top else 4), fontsize=9, color=PURPLE)


@styled
def correlation_matrix(names, matrix):
    """The unknowns' correlation matrix as a heat map with its values and a colour bar (PNG)."""
    corr = np.asarray(matrix, float)
    n = len(names)
    fig = new_figure(figsize=(max(8.4, 0.75 * n + 3), max(6.5, 0.6 * n + 2.5)))
    ax = fig.add_subplot()
    im = ax.imshow(corr, cmap="cividis", vmin=-1, vmax=1)
    ax.set_xticks(range(n), names, rotation=45, ha="right")
    ax.set_yticks(range(n), names)
    for i in range(n):
        for j in range(n):
            ax.text(j, i, f"{corr[i, j]:.2f}", ha="center", va="center", fontsize=9,
                    color="white" if corr[i, j] < 0.2 else "black")
    fig.colorbar(im, ax=ax, label="correlation")
    ax.set_title("correlation of the unknowns (local chart: t mm, w rad about the sensor's axes)")
    fig.tight_layout()
    return png_bytes(fig)


@styled
def gap_steps(steps, sigma_mm):
    """The discrepancy workflow's steps (``diagnose``'s JSON ``steps``) against the noise floor, as
    ``diagnose --figures`` draws them (:func:`handeye.app.present.report.draw_gap`), PNG bytes."""
    from handeye.app.present.report import draw_gap

    fig = new_figure(figsize=(10, 5))
    draw_gap(fig.add_subplot(), steps, sigma_mm)
    fig.tight_layout()
    return png_bytes(fig)
