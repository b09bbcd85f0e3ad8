"""Interactive figures for the notebooks, with a static fallback.

A notebook hands :func:`panel` a drawing function and its controls::

    def draw(x1, x2):
        fig = Figure(figsize=(5, 4))          # matplotlib.figure.Figure, not pyplot
        ...
        return fig

    panel(draw, {"x1": slider(-3, 3, 0.1, 2.2), "x2": slider(-3, 3, 0.1, -0.4)})

With ipywidgets and a widget frontend (JupyterLab, Notebook 7, VS Code) the reader moves the
sliders and the figure is redrawn. The panel is displayed as one output holding both the
widget view and a PNG of the figure at the controls' start values, so that a frontend without
widgets (a repository page, nbconvert, a kernel with no frontend such as the tests' nbclient)
shows the static figure instead; without ipywidgets installed only the PNG is shown.

Figures are drawn on :class:`matplotlib.figure.Figure` objects, never through pyplot, so
nothing is shown twice by the inline backend and no backend is switched.
"""
from __future__ import annotations

import base64
import dataclasses
from typing import Callable, Optional

#: Smallest PNG resolution of the panels' figures (:func:`handeye.app.present.figure_style.png_bytes`
#: raises it until the figure is 1,000 px wide).
DPI = 120


@dataclasses.dataclass(frozen=True)
class Control:
    """One control of a panel: a slider over ``[low, high]`` by ``step`` or a choice.

    Attributes
    ----------
    value : float, int or str
        Start value (the static figure is drawn at it).
    low, high, step : float, optional
        Slider range and step (``int`` values give an integer slider).
    options : tuple of str, optional
        The choices of a drop-down (instead of a slider).
    description : str, optional
        Label; default the parameter's name.
    """

    value: object
    low: Optional[float] = None
    high: Optional[float] = None
    step: Optional[float] = None
    options: tuple = ()
    description: Optional[str] = None


def slider(low, high, step, value, description=None):
    """A slider control; integer when all four numbers are ints."""
    return Control(value=value, low=low, high=high, step=step, description=description)


def choice(options, value=None, description=None):
    """A drop-down control over ``options`` (start ``value``, default the first)."""
    options = tuple(options)
    return Control(value=options[0] if value is None else value, options=options, description=description)


def png_from_figure(fig):
    """PNG bytes of a matplotlib figure in the one style (at least :data:`DPI` and 1,000 px wide;
    :func:`handeye.app.present.figure_style.png_bytes`). The style rules are not checked here:
    the notebook that draws the figure owns its text sizes."""
    from handeye.app.present import figure_style

    with figure_style.style():
        return figure_style.png_bytes(fig, check=False)


def _widget(name, control):
    import ipywidgets

    label = control.description or name
    style = {"description_width": "initial"}
    if control.options:
        return ipywidgets.Dropdown(options=list(control.options), value=control.value, description=label, style=style)
    numbers = (control.low, control.high, control.step, control.value)
    cls = ipywidgets.IntSlider if all(isinstance(v, int) for v in numbers) else ipywidgets.FloatSlider
    return cls(min=control.low, max=control.high, step=control.step, value=control.value, description=label,
               continuous_update=False, style=style)


class Panel:
    """A figure that follows its controls (see module docstring).

    Attributes
    ----------
    values : dict
        The controls' current values.
    png : bytes
        The figure at the current values.
    widgets : dict or None
        name -> ipywidgets control (None without ipywidgets).
    box : ipywidgets.VBox or None
        The displayed widget (controls above the image).
    """

    def __init__(self, draw: Callable, controls: dict):
        self.draw = draw
        self.values = {name: c.value for name, c in controls.items()}
        self.png = png_from_figure(self.draw(**self.values))
        self.widgets, self.box, self._image = None, None, None
        try:
            import ipywidgets
        except ImportError:
            return
        self.widgets = {name: _widget(name, c) for name, c in controls.items()}
        self._image = ipywidgets.Image(value=self.png, format="png")
        self.box = ipywidgets.VBox([*self.widgets.values(), self._image])
        for name, w in self.widgets.items():
            w.observe(self._changed(name), names="value")

    def _changed(self, name):
        def handler(change):
            self.update(**{name: change["new"]})
        return handler

    def update(self, **values):
        """Redraw with some controls' values changed (what moving a slider does)."""
        self.values = {**self.values, **values}
        self.png = png_from_figure(self.draw(**self.values))
        if self._image is not None:
            self._image.value = self.png

    def _repr_mimebundle_(self, **kwargs):
        bundle = {"image/png": base64.b64encode(self.png).decode("ascii"),
                  "text/plain": f"<figure panel: {', '.join(f'{k}={v}' for k, v in self.values.items())}>"}
        if self.box is not None:
            view = self.box._repr_mimebundle_(**kwargs)
            bundle["application/vnd.jupyter.widget-view+json"] = view["application/vnd.jupyter.widget-view+json"]
        return bundle


def panel(draw, controls):
    """A :class:`Panel` of ``draw`` (keyword arguments: the controls' names; returns a
    :class:`matplotlib.figure.Figure`) and ``controls`` (name -> :class:`Control`).

    Make it the last expression of a cell (or pass it to ``display``) to show it.
    """
    return Panel(draw, dict(controls))
