"""Figures written to files by the CLI and the studies: matplotlib on its non-interactive backend.

The backend is chosen here, when a command draws, never at import and never in a notebook
(which keeps its inline backend: the notebooks draw with ``matplotlib.pyplot`` directly).
"""
from __future__ import annotations


def figure():
    """``matplotlib.pyplot`` on the non-interactive Agg backend (for files)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt
