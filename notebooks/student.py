"""Write the student edition of the notebooks: the same course without its solutions.

    python notebooks/student.py OUT_DIR              # every notebook, README.md and notation.md
    python notebooks/student.py OUT_DIR NAME.ipynb   # some of them

Each copy keeps every teaching cell and its outputs, and each exercise's own cell (tagged
``exercise``: "your turn", ``answer = None`` and its check), with that cell's output cleared; it
drops the worked solutions: the cells tagged ``solution``, the collapsed ``<details>``
explanations above them, and the "### Solutions" and "**N.**" headings. The edition runs as it
is: the solutions come last and nothing before them uses them.

A script beside the notebooks, not a ``handeye`` subcommand: the notebooks are not installed
with the package (pyproject.toml lists the packages; ``tests/test_packaging.py`` checks that
nothing else lands in site-packages), so only a checkout of the repository has them to copy.
From Python, load this file and call :func:`student_edition`.
"""
import pathlib
import re
import shutil
import sys

import nbformat

HERE = pathlib.Path(__file__).resolve().parent
#: A markdown cell that only heads the solutions ("### Solutions", "**2.**").
SOLUTION_HEADING = re.compile(r"^\s*(### Solutions|\*\*\d+\.\*\*)\s*$")
NOTE = ("*Student edition: the worked solutions are left out. Each exercise has a cell of its own "
        "that checks your answer.*\n\n")


def is_solution(cell):
    """Whether ``cell`` (an ``nbformat`` cell) is part of a worked solution: tagged ``solution``, a
    collapsed ``<details>`` explanation, or a solutions heading."""
    if "solution" in cell.get("metadata", {}).get("tags", []):
        return True
    source = "".join(cell.get("source", ""))
    return cell["cell_type"] == "markdown" and ("<details>" in source or bool(SOLUTION_HEADING.match(source)))


def student_notebook(nb):
    """The student copy of a notebook.

    Parameters
    ----------
    nb : nbformat.NotebookNode
        The notebook as committed (left unchanged).

    Returns
    -------
    nbformat.NotebookNode
        A copy without the solution cells (:func:`is_solution`), with the exercise cells'
        outputs cleared and a note under the title.
    """
    nb = nbformat.from_dict(nb)
    nb.cells = [c for c in nb.cells if not is_solution(c)]
    for cell in nb.cells:
        if cell.cell_type == "code" and "exercise" in cell.get("metadata", {}).get("tags", []):
            cell.outputs, cell.execution_count = [], None
    head = nb.cells[0]
    lines = head.source.split("\n", 1)
    head.source = lines[0] + "\n\n" + NOTE + (lines[1].lstrip("\n") if len(lines) > 1 else "")
    return nb


def student_edition(out_dir, names=None):
    """Write the student edition of the notebooks.

    Parameters
    ----------
    out_dir : str or pathlib.Path
        Folder to write into (created when missing); the course's README.md and notation.md are
        copied beside the notebooks.
    names : list of str, optional
        Notebook file names (``"least_squares.ipynb"``); default all.

    Returns
    -------
    list of pathlib.Path
        The notebooks written.
    """
    out = pathlib.Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = [HERE / n for n in names] if names else sorted(HERE.glob("*.ipynb"))
    written = []
    for path in paths:
        target = out / path.name
        nbformat.write(student_notebook(nbformat.read(path, as_version=4)), target)
        written.append(target)
    for page in ("README.md", "notation.md"):
        shutil.copyfile(HERE / page, out / page)
    return written


def main(argv):
    if not argv:
        sys.exit(__doc__)
    for path in student_edition(argv[0], argv[1:] or None):
        print(f"{path}: written")


if __name__ == "__main__":
    main(sys.argv[1:])
