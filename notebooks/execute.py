"""Execute every notebook under a real Jupyter kernel and save it with its outputs.

    python notebooks/execute.py            # all notebooks, in place
    python notebooks/execute.py NAME.ipynb

Needs the ``notebooks`` extra (``pip install '.[notebooks]'``). Figures are inline PNGs at
80 dpi; cell timings are not recorded, so a re-run changes a notebook only where its results
change -- and in the saved widget state (new model ids each run), which lets JupyterLab show
the interactive panels' last figure before a kernel runs. ``tests/test_notebooks.py``
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


def main(argv):
    paths = [HERE / a for a in argv] if argv else sorted(HERE.glob("*.ipynb"))
    for path in paths:
        nb = execute(path)
        nbformat.write(nb, path)
        images = sum("image/png" in o.get("data", {}) for c in nb.cells if c.cell_type == "code" for o in c.outputs)
        print(f"{path.name}: executed, {images} figures")


if __name__ == "__main__":
    main(sys.argv[1:])
