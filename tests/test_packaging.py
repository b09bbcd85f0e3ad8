"""What `pip install .` installs: every package and subpackage of the source tree, with its data.

A subpackage missing from the wheel passes every test run from the source tree and fails only
for users (it happened: model.effects was not installed, so `handeye diagnose` could not import).
"""
from importlib import metadata
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _installed_files():
    try:
        files = metadata.files("handeye")
    except metadata.PackageNotFoundError:
        pytest.skip("handeye is not installed (source tree only)")
    if files is None or any(str(f).endswith("__editable__.handeye-0.1.0.pth") or "__editable__" in str(f)
                            for f in files):
        pytest.skip("editable install: files come from the source tree")
    return {str(f).replace("\\", "/") for f in files}


def test_every_source_package_is_installed():
    installed = _installed_files()
    for top in ("model", "solvers", "studies"):
        for init in (ROOT / top).rglob("__init__.py"):
            rel = init.relative_to(ROOT).as_posix()
            assert rel in installed, f"{rel} is in the source tree but not in the installed distribution"


def test_package_data_is_installed():
    installed = _installed_files()
    for pattern in ("model/data/*/*.csv", "model/data/*/*.toml", "model/*.c"):
        for path in ROOT.glob(pattern):
            rel = path.relative_to(ROOT).as_posix()
            assert rel in installed, f"{rel} is not installed"
