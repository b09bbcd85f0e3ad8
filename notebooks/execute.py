"""Execute every notebook under a real Jupyter kernel and save it with its outputs.

    python notebooks/execute.py            # all notebooks, in place
    python notebooks/execute.py NAME.ipynb

Needs the ``notebooks`` extra (``pip install '.[notebooks]'``). Figures are inline PNGs at
120 dpi (each notebook's first cell sets it, with fonts of at least 9 pt and the
Okabe-Ito palette); cell timings are not recorded, so a re-run changes a notebook only where its results
change. No widget state is saved: an interactive panel's output keeps only its static figure
(the PNG it carries beside the widget view), and ``metadata.widgets`` is dropped, so that
nbconvert, GitHub and JupyterLab before a kernel runs all show that figure (with the saved state
nbconvert drew an empty widget where the figure should be, and the state stored every panel's
image a second time); running the cell brings the live panel back. ``tests/test_notebooks.py``
re-executes each notebook and fails when the committed outputs are stale.
"""
import pathlib
import sys
import tempfile

import nbformat
from nbclient import NotebookClient

HERE = pathlib.Path(__file__).resolve().parent
#: Longest a cell may run.
TIMEOUT_S = 600


def execute(path, cwd=None):
    """The notebook at ``path`` executed in a fresh kernel (working folder ``cwd``, default a
    temporary one); returns the executed ``nbformat`` notebook."""
    nb = nbformat.read(path, as_version=4)
    with tempfile.TemporaryDirectory() as tmp:
        client = NotebookClient(nb, timeout=TIMEOUT_S, kernel_name="python3", record_timing=False,
                                resources={"metadata": {"path": str(cwd or tmp)}})
        client.execute()
    return nb


#: The widget view of an interactive panel's output (its static PNG sits beside it).
WIDGET_VIEW = "application/vnd.jupyter.widget-view+json"


def without_widget_state(nb):
    """The notebook without saved widget state: ``metadata.widgets`` dropped, and each output
    that carries a static figure beside a widget view keeps the figure only (module docstring)."""
    nb.metadata.pop("widgets", None)
    for cell in nb.cells:
        for output in cell.get("outputs", []):
            data = output.get("data", {})
            if WIDGET_VIEW in data and "image/png" in data:
                del data[WIDGET_VIEW]
    return nb


def main(argv):
    paths = [HERE / a for a in argv] if argv else sorted(HERE.glob("*.ipynb"))
    for path in paths:
        nb = without_widget_state(execute(path))
        nbformat.write(nb, path)
        images = sum("image/png" in o.get("data", {}) for c in nb.cells if c.cell_type == "code" for o in c.outputs)
        print(f"{path.name}: executed, {images} figures")


if __name__ == "__main__":
    main(sys.argv[1:])
