"""Every notebook's code cells run, in order, so that the notebooks never rot.

Executed without a Jupyter kernel (the cells are plain Python run in one namespace, with
matplotlib on its non-interactive backend); the notebooks end with assertions of what they
claim, so a passing run checks them.
"""
import json
import pathlib

import pytest

NOTEBOOKS = sorted((pathlib.Path(__file__).resolve().parents[1] / "notebooks").glob("*.ipynb"))


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.name for p in NOTEBOOKS])
def test_notebook_runs(path, monkeypatch, tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    monkeypatch.chdir(tmp_path)
    nb = json.loads(path.read_text())
    namespace = {"__name__": "__notebook__"}
    cells = [c for c in nb["cells"] if c["cell_type"] == "code"]
    assert cells
    for cell in cells:
        exec(compile("".join(cell["source"]), f"{path.name}", "exec"), namespace)  # noqa: S102
    import matplotlib.pyplot as plt

    plt.close("all")


def test_there_are_notebooks():
    assert NOTEBOOKS
