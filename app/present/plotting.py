"""Figures written to files by the CLI and the studies: matplotlib on its non-interactive backend,
in the one style of :mod:`handeye.app.present.figure_style` (save through its ``save``).

The backend is chosen here, when a command draws, never at import and never in a notebook
(which keeps its inline backend: the notebooks draw with ``matplotlib.pyplot`` directly).
"""
from __future__ import annotations


def figure():
    """``matplotlib.pyplot`` on the non-interactive Agg backend (for files), the style applied."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from handeye.app.present import figure_style

    figure_style.apply()
    return plt
