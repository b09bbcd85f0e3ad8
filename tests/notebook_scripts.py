"""The notebooks' scripts (``notebooks/execute.py``, ``notebooks/student.py``) as modules for the tests:
they live beside the notebooks, outside the installed package."""
from __future__ import annotations

import importlib.util
import pathlib

NOTEBOOKS = pathlib.Path(__file__).resolve().parents[1] / "notebooks"


def load(name):
    """``notebooks/<name>.py`` imported as the module ``notebook_<name>``."""
    spec = importlib.util.spec_from_file_location(f"notebook_{name}", NOTEBOOKS / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module
