"""Studies: each tells one story (model, data, solve, report), writes its figures (PNG),
tables (CSV and Markdown) and a JSON summary into ``out``, and ends by asserting what it
claims. ``quick`` runs a small, honest version (fewer replicates) for CI.

``handeye study NAME [--out DIR] [--quick]``; ``handeye study all`` runs every study.
"""
from __future__ import annotations

import csv
import importlib
import json
import pathlib

import numpy as np

from handeye.app.common.errors import RequestError
from handeye.app.common.registry import STUDIES, StudyClaimFailed
from handeye.app.present import figure_style
from handeye.app.present.plotting import figure  # noqa: F401 - the studies' figures
from handeye.model.common.rotation import rotvec_from_matrix


def claim(condition, text):
    """Assert a study's claim; the message says what was claimed."""
    if not condition:
        raise StudyClaimFailed(f"claim not supported by the data: {text}")


def save(fig, path, rect=None):
    """Lay ``fig`` out (``tight_layout(rect=rect)``), write it in the one style
    (:func:`handeye.app.present.figure_style.save`) and close it."""
    import matplotlib.pyplot as plt

    fig.tight_layout(rect=rect)
    figure_style.save(fig, path, option="--out")
    plt.close(fig)


def pose_error(est, truth):
    """Errors of an estimated 4 x 4 transform: translation (3,) mm and rotation (3,) deg, the
    rotation vector of ``truth^T est``."""
    return est[:3, 3] - truth[:3, 3], np.degrees(rotvec_from_matrix(truth[:3, :3].T @ est[:3, :3]))


def write_table(out, name, header, rows):
    """Write ``name.csv`` and ``name.md`` with the same rows."""
    out = pathlib.Path(out)
    with open(out / f"{name}.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        w.writerows(rows)

    def fmt(v):
        return f"{v:.4g}" if isinstance(v, float) else str(v)

    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(fmt(v) for v in r) + " |" for r in rows]
    (out / f"{name}.md").write_text("\n".join(lines) + "\n")


def write_summary(out, summary):
    (pathlib.Path(out) / "summary.json").write_text(json.dumps(summary, indent=1, default=float) + "\n")


def run(name, out, quick=False):
    """Run one study (or ``all``); returns ``{name: summary}``."""
    names = list(STUDIES) if name == "all" else [name]
    results = {}
    for n in names:
        if n not in STUDIES:
            raise RequestError(f"unknown study {n!r}; choose one of {', '.join(STUDIES)} or all")
        folder = pathlib.Path(out) / n
        folder.mkdir(parents=True, exist_ok=True)
        results[n] = importlib.import_module(STUDIES[n]).run(folder, quick=quick)
    return results
