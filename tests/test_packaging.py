"""What `pip install .` installs: one package, `handeye`, holding every source package and its data.

A subpackage missing from the wheel passes every test run from the source tree and fails only
for users (it happened: model.effects was not installed, so `handeye diagnose` could not import);
a top-level `model` package would shadow, or be shadowed by, a user's own `model.py`.
"""
import json
import subprocess
import sys
import sysconfig
from importlib import metadata
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
LAYERS = ("model", "solvers", "app", "studies")


def _distribution():
    """handeye's distribution in site-packages (not a handeye.egg-info that a build left in the
    working directory, which importlib.metadata would find first)."""
    found = [d for d in metadata.distributions(path=[sysconfig.get_paths()["purelib"]])
             if d.metadata["Name"] == "handeye"]
    if not found:
        pytest.fail("handeye is not installed: the tests run against the installed package (pip install '.[test]')")
    return found[0]


def _editable():
    direct = _distribution().read_text("direct_url.json")
    return bool(direct and json.loads(direct).get("dir_info", {}).get("editable"))


def _installed_files():
    files = _distribution().files
    if files is None or _editable():
        pytest.skip("editable install: files come from the source tree")
    return {str(f).replace("\\", "/") for f in files}


def test_only_handeye_is_installed():
    """Nothing top-level in site-packages but `handeye` and its dist-info (and the script)."""
    for f in _installed_files():
        top = f.split("/")[0]
        assert top == "handeye" or (top.startswith("handeye-") and top.endswith(".dist-info")) or top == "..", f
    top_level = _distribution().read_text("top_level.txt")
    assert top_level is None or top_level.split() == ["handeye"]


def test_every_source_package_is_installed():
    installed = _installed_files()
    assert "handeye/__init__.py" in installed
    for top in LAYERS:
        for init in (ROOT / top).rglob("*.py"):
            rel = "handeye/" + init.relative_to(ROOT).as_posix()
            assert rel in installed, f"{rel} is in the source tree but not in the installed distribution"


def test_package_data_is_installed():
    installed = _installed_files()
    for pattern in ("model/data/*/*.csv", "model/data/*/*.toml", "model/compiled/*.c", "app/present/web/*.js",
                    "app/present/web/*.css"):
        paths = list(ROOT.glob(pattern))
        assert paths, pattern
        for path in paths:
            rel = "handeye/" + path.relative_to(ROOT).as_posix()
            assert rel in installed, f"{rel} is not installed"


def test_the_tests_import_the_installed_package():
    """handeye comes from site-packages (or, editable, from this tree through its finder), never
    from the working directory; the source folders are never imported as top-level modules."""
    import handeye

    where = Path(handeye.__file__).resolve().parent
    assert where == (ROOT if _editable() else Path(sysconfig.get_paths()["purelib"]).resolve() / "handeye")
    leaked = sorted(m for m in sys.modules if m.split(".")[0] in LAYERS)
    assert not leaked, f"source folders imported as top-level modules: {leaked}"


def test_a_users_own_model_py_does_not_shadow_handeye(tmp_path):
    """From a folder holding its own model.py, solvers.py and studies.py (as a user's notebook
    folder might), the public API still imports and calibrates with handeye's code."""
    for name in ("model", "solvers", "studies", "app"):
        (tmp_path / f"{name}.py").write_text("raise ImportError('the user\\'s own module was imported')\n")
    code = ("import json, handeye\n"
            "r = handeye.calibrate('thesis-sim', no_loo=True)\n"
            "d = r.to_dict()\n"
            "json.dumps(d)\n"
            "print(json.dumps({'shape': list(r.sensor2flange.shape), 'converged': r.converged}))\n")
    out = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert json.loads(out.stdout.strip().splitlines()[-1]) == {"shape": [4, 4], "converged": True}
