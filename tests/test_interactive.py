"""The notebooks' interactive panels: a widget that redraws, and a PNG for frontends without one."""
import base64

import numpy as np
import pytest
from matplotlib.figure import Figure

from handeye.app.present import interactive


def _draw(a, kind="line"):
    fig = Figure(figsize=(2, 2))
    ax = fig.add_subplot()
    x = np.linspace(0, 1, 20)
    ax.plot(x, a * x if kind == "line" else a * x**2)
    ax.set_ylim(0, 3)
    return fig


CONTROLS = {"a": interactive.slider(0.0, 3.0, 0.5, 1.0), "kind": interactive.choice(["line", "square"])}


def test_the_panel_shows_a_widget_and_a_static_png_of_the_start_values():
    pytest.importorskip("ipywidgets")
    p = interactive.panel(_draw, CONTROLS)
    bundle = p._repr_mimebundle_()
    assert "application/vnd.jupyter.widget-view+json" in bundle
    png = base64.b64decode(bundle["image/png"])
    assert png.startswith(b"\x89PNG") and png == interactive.png_from_figure(_draw(1.0))
    assert p.values == {"a": 1.0, "kind": "line"}


def test_moving_a_control_redraws_the_figure():
    ipywidgets = pytest.importorskip("ipywidgets")
    p = interactive.panel(_draw, CONTROLS)
    before = p.png
    assert isinstance(p.widgets["a"], ipywidgets.FloatSlider) and isinstance(p.widgets["kind"], ipywidgets.Dropdown)
    p.widgets["a"].value = 2.5  # what a reader's drag does
    assert p.values["a"] == 2.5 and p.png != before and p._image.value == p.png
    assert p.png == interactive.png_from_figure(_draw(2.5))
    p.widgets["kind"].value = "square"
    assert p.png == interactive.png_from_figure(_draw(2.5, "square"))


def test_integer_controls_give_integer_sliders():
    ipywidgets = pytest.importorskip("ipywidgets")
    p = interactive.panel(lambda n: _draw(n / 10), {"n": interactive.slider(1, 30, 1, 10)})
    assert isinstance(p.widgets["n"], ipywidgets.IntSlider)


def test_without_ipywidgets_the_panel_is_a_static_figure(without_package):
    without_package("ipywidgets")
    p = interactive.panel(_draw, CONTROLS)
    bundle = p._repr_mimebundle_()
    assert p.widgets is None and set(bundle) == {"image/png", "text/plain"}
    p.update(a=2.0)  # still usable from code
    assert base64.b64decode(p._repr_mimebundle_()["image/png"]) == interactive.png_from_figure(_draw(2.0))
