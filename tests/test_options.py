"""Options declared once (issue 38): each command's option table (handeye.app.common.options) makes
its parser, its request's checks, its provenance record and its README table, and its public
function's keywords are the table's."""
import dataclasses
import importlib
import inspect
import pathlib

import pytest

from handeye.app.command.parser import build_parser
from handeye.app.common.options import COMMANDS, Opt
from handeye.app.engine.command_request import checked_values
from handeye.model.common.errors import InputError

README = (pathlib.Path(__file__).resolve().parents[1] / "README.md").read_text(encoding="utf-8")


def _function(command):
    module, _, name = COMMANDS[command].function.partition(":")
    return getattr(importlib.import_module(module), name)


def test_an_option_added_to_a_table_reaches_parser_request_record_and_docs():
    added = Opt("--damping", 0.5, type="float", unit="mm", check=("number", 0.0, 1.0), metavar="D",
                help="a new option, for the test")
    copy = dataclasses.replace(COMMANDS["calibrate"], options=COMMANDS["calibrate"].options + (added,))
    parser = build_parser({**COMMANDS, "calibrate": copy})
    assert parser.parse_args(["calibrate"]).damping == 0.5  # the default
    args = parser.parse_args(["calibrate", "thesis-sim", "--damping", "0.25", "--keep-all"])
    given = copy.keywords(vars(args))  # what the command line passes the function
    assert given["damping"] == 0.25 and given["keep_all"] is True and given["dataset"] == "thesis-sim"
    assert checked_values(copy, given)["damping"] == 0.25  # the request's check
    with pytest.raises(InputError, match=r"^--damping must lie in \[0, 1\], got 2.0$"):
        checked_values(copy, {**given, "damping": 2.0})
    record = copy.record(given)  # the provenance saved with --out
    assert record["damping"] == 0.25 and "out" not in record and set(record) == set(given) - {"out"}
    assert "| `--damping D` | `0.5` | a new option, for the test (mm) |" in copy.markdown()
    assert "--damping" not in COMMANDS["calibrate"].markdown()  # a copy: the command's own table is unchanged


@pytest.mark.parametrize("command", [c for c in COMMANDS if COMMANDS[c].function])
def test_public_keywords_and_defaults_are_the_tables(command):
    params = inspect.signature(_function(command)).parameters
    table = {opt.name: opt for opt in COMMANDS[command].options if opt.name}
    assert set(params) == set(table), command
    for name, opt in table.items():
        if params[name].default is not inspect.Parameter.empty:
            assert params[name].default == opt.default, (command, name)


@pytest.mark.parametrize("command", ["calibrate"])
def test_readme_option_tables_are_the_rendering(command):
    block = README.split(f"<!-- options: {command} -->\n", 1)[1].split("\n<!-- end options -->", 1)[0]
    assert block == COMMANDS[command].markdown(), (  # the table is made, not written
        f"README's {command} table is not the rendering of app/common/options.py: replace the block between its "
        f"markers by COMMANDS[{command!r}].markdown()")


def test_provenance_options_are_those_saved_before():
    given = COMMANDS["calibrate"].given({**{opt.name: opt.default for opt in COMMANDS["calibrate"].options},
                                        "start": (1, 2.5, 3, 0, 0, 0)})
    assert COMMANDS["calibrate"].record(given) == {
        "dataset": "thesis-real", "unknowns": "sensor", "calibration": None, "sensor_pose": None, "method": None,
        "rotation": None, "start": [1, 2.5, 3, 0, 0, 0], "convention": None, "max_iter": None, "model": None,
        "keep_all": False, "alpha": None, "no_loo": False, "no_clean": False, "sigma": None, "robot_sigma": None,
        "effects": None, "plot": None, "report": None}


def test_the_package_imports_and_runs_under_python_oo(tmp_path):
    """``python -OO`` strips docstrings: the tables' docstring sections are skipped, every command still runs."""
    import subprocess
    import sys

    code = "import handeye; from handeye.app.command.cli import main; raise SystemExit(main(['datasets']))"
    p = subprocess.run([sys.executable, "-OO", "-c", code], capture_output=True, text=True, timeout=120)
    assert p.returncode == 0 and "thesis-real" in p.stdout, p.stderr[-1000:]
