"""The one-file HTML calibration report (``handeye report``, ``calibrate --report``).

Stages, each a small module: :mod:`.cell` (the cell's geometry per sample, in the robot base,
from the dataset and the result's JSON object), :mod:`.view` (the interactive 3-D view: plotly,
the optional ``report`` extra; a static picture without it), :mod:`.figures` (the 2-D figures,
PNG), :mod:`.parts` (the result card, the verdict strip, the residual table) and :mod:`.page`
(the page itself, with ``page.css`` and ``page.js`` inlined: one file that opens offline).
"""
