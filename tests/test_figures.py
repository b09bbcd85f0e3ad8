"""One style for every saved figure (issue 30, item 3; app/present/figure_style.py): each
figure-producing command writes PNGs of at least 120 dpi and 1,000 px across (read back from
the file's IHDR and pHYs chunks), and the style's rules are checked on drawn figures: text of
at least 9 pt, a colour bar where colour encodes a value, the palette, every point in view or
pointed at. The studies' PNGs are read back in tests/test_studies.py (every quick study), and
every figure saved anywhere in the tests is checked: a FigureStyleWarning fails (pyproject.toml)."""
import struct
import warnings

import numpy as np
import pytest

from handeye.app.command import cli
from handeye.app.present import figure_style as style


def png_size(path_or_bytes):
    """``(width px, height px, dpi)`` of a PNG: IHDR's size and pHYs's pixels per metre (None without it)."""
    data = path_or_bytes if isinstance(path_or_bytes, bytes) else open(path_or_bytes, "rb").read()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and data[12:16] == b"IHDR"
    width, height = struct.unpack(">II", data[16:24])
    pos, dpi = 8, None
    while pos < len(data):
        length, kind = struct.unpack(">I4s", data[pos:pos + 8])
        if kind == b"pHYs":
            x, y, unit = struct.unpack(">IIB", data[pos + 8:pos + 17])
            assert unit == 1 and x == y  # per metre, square pixels
            dpi = x * 0.0254
        pos += 12 + length
    return width, height, dpi


def assert_readable(path):
    width, _, dpi = png_size(path)
    assert dpi is not None and dpi >= style.MIN_DPI - 0.5, (path, dpi)
    assert width >= style.MIN_WIDTH_PX, (path, width)
    return width, dpi


def test_calibrate_plot_is_readable_and_shows_every_sample(tmp_path, capsys):
    """thesis-real with the centre free: dz has its colour bar, the seven excluded samples lie
    beyond the centres' view and each has an edge arrow."""
    path = tmp_path / "F.png"
    assert cli.main(["calibrate", "thesis-real", "--unknowns", "sensor+sphere", "--plot", str(path)]) == cli.EXIT_OK
    assert assert_readable(path)[0] >= 1500


def test_diagnose_figures_are_readable(tmp_path, capsys):
    assert cli.main(["diagnose", "thesis-sim", "--figures", str(tmp_path)]) == cli.EXIT_OK
    for name in ("residuals.png", "gap.png"):
        assert_readable(tmp_path / name)


def test_validate_plots_are_readable(tmp_path, capsys):
    """Centres through a typed pose (no profiles) and a sphere fit of simulated profiles."""
    assert cli.main(["validate", "thesis-real", "--sensor-pose", "189.69,99.71,130.36,-181.40,-89.24,0.155",
                     "--plot", str(tmp_path / "centres.png")]) in (cli.EXIT_OK, 1)
    assert_readable(tmp_path / "centres.png")
    assert cli.main(["simulate", "--out", str(tmp_path / "sim"), "--profiles", "--n-poses", "12"]) == cli.EXIT_OK
    assert cli.main(["calibrate", str(tmp_path / "sim"), "--out", str(tmp_path / "cal.json"), "--no-loo"]) == cli.EXIT_OK
    assert cli.main(["validate", str(tmp_path / "sim"), "--calibration", str(tmp_path / "cal.json"),
                     "--plot", str(tmp_path / "sphere.png")]) in (cli.EXIT_OK, 1)
    assert_readable(tmp_path / "sphere.png")


def test_bench_plot_is_readable(tmp_path):
    from handeye.app.tools import bench

    rows = [{"n": n, "median_ms": 0.01 * n} for n in (30, 300, 3000)]
    cases = {f"sim-{n}": {m: {"median_ms": 0.1 * n * (k + 2)} for k, m in enumerate(bench.ORDER[1:])} for n in (30, 300)}
    bench.plot({"scaling": {"rows": rows, "slope": 1.0}, "cases": cases}, tmp_path / "bench.png")
    assert_readable(tmp_path / "bench.png")


def test_a_notebook_panels_static_png_is_readable():
    from matplotlib.figure import Figure

    from handeye.app.present import interactive

    fig = Figure(figsize=(5, 4))
    fig.add_subplot().plot([0, 1], [0, 1])
    width, _, dpi = png_size(interactive.png_from_figure(fig))
    assert width >= style.MIN_WIDTH_PX and dpi >= style.MIN_DPI - 0.5


def test_a_narrow_figure_is_saved_at_a_higher_dpi_a_wide_one_at_the_least(tmp_path):
    from handeye.app.present.plotting import figure

    plt = figure()
    for inches, dpi in ((5.0, 200), (12.0, 120)):
        fig, ax = plt.subplots(figsize=(inches, 3))
        ax.plot([1, 2], [1, 2])
        assert style.save(fig, tmp_path / "f.png") == dpi
        width, _, read = png_size(tmp_path / "f.png")
        assert round(read) == dpi and width == round(inches * dpi) >= style.MIN_WIDTH_PX
        plt.close(fig)


def _bad_figure(plt):
    fig, (a, b) = plt.subplots(1, 2, figsize=(10, 4))
    a.plot([0, 1, 2], [0, 1, 5], color="tab:red")  # outside the palette
    a.set_ylim(0, 2)  # (2, 5) out of view, no arrow
    a.set_xticks([0, 1, 2], ["p", "q", "r"], fontsize=6)  # too small
    b.scatter([0, 1], [1, 0], c=[0.2, 0.8], cmap="jet")  # a value in colour, no bar, not viridis/cividis
    return fig


def test_the_rules_are_measured_on_the_drawn_figure():
    from handeye.app.present.plotting import figure

    plt = figure()
    fig = _bad_figure(plt)
    found = " | ".join(style.violations(fig))
    for part in ("text at 6 pt", "'p', 'q', 'r'", "outside the Okabe-Ito palette", "#d62728", "colour map 'jet'",
                 "without a colour bar", "1 data points outside the axes"):
        assert part in found, (part, found)
    with pytest.warns(style.FigureStyleWarning):
        warnings.simplefilter("always", style.FigureStyleWarning)
        style.png_bytes(fig)
    plt.close(fig)


def test_a_figure_in_the_style_keeps_every_rule():
    """The defaults of the style (rcParams after plotting.figure) keep the rules on their own: a
    colour bar added, the point out of view pointed at."""
    from handeye.app.present.plotting import figure

    plt = figure()
    fig, (a, b) = plt.subplots(1, 2, figsize=(10, 4))
    a.plot([0, 1, 2], [0, 1, 5], "o-")
    a.set_xticks([0, 1, 2], ["p", "q", "r"])
    assert style.edge_arrows(a, [0, 1, 2], [0, 1, 5], ["p", "q", "r"], ylim=(0, 2)) == 1
    sc = b.scatter([0, 1], [1, 0], c=[0.2, 0.8], cmap="cividis")
    fig.colorbar(sc, ax=b, label="value")
    assert style.violations(fig) == []
    sizes = [t.get_fontsize() for t in fig.findobj(lambda x: hasattr(x, "get_fontsize")) if t.get_text()]
    assert min(sizes) >= style.MIN_FONT_PT
    plt.close(fig)


def test_wilson_interval_of_a_rate():
    """Wilson 95 %: 8 of 8 gives (0.676, 1); 0 of 40 gives (0, 0.088); 20 of 40 is symmetric about 0.5."""
    low, high = style.binomial_interval(8, 8)
    assert abs(low - 0.6756) < 1e-4 and high == 1.0
    low, high = style.binomial_interval(0, 40)
    assert low == 0.0 and abs(high - 0.0876) < 1e-4
    low, high = style.binomial_interval(np.array([20]), np.array([40]))
    assert abs(low[0] + high[0] - 1.0) < 1e-12 and abs(low[0] - 0.3520) < 1e-4
