"""Edges of the command line (issue 26): file modes, signals, a closed stdout, a light
``--help``, the code cache of a read-only install, pasteable suggestions, short argparse errors.

Most run the console script in a subprocess, as a user does: what is asserted is what the
shell sees (exit code, stderr lines, files left behind, modules loaded), never a time.
"""
import pathlib
import subprocess
import sys

import pytest

from handeye.app.cli import EXIT_BAD_INPUT, main

ROOT = pathlib.Path(__file__).resolve().parents[1]
_SCRIPT = pathlib.Path(sys.executable).with_name("handeye")
#: the console script of this environment, else the same entry point through the interpreter
HANDEYE = [str(_SCRIPT)] if _SCRIPT.exists() else [sys.executable, "-m", "handeye.app.cli"]


def handeye(*argv, **kwargs):
    """Run ``handeye ARGV`` (text mode, output captured unless told otherwise)."""
    kwargs.setdefault("capture_output", "stdout" not in kwargs)
    return subprocess.run(HANDEYE + [str(a) for a in argv], text=True, timeout=600, **kwargs)


# --- --help loads nothing heavy ---------------------------------------------------------------

HEAVY = ("numpy", "sympy", "casadi", "mpmath", "matplotlib", "scipy")


def test_help_imports_no_numpy_sympy_or_casadi():
    """``handeye --help`` and every ``handeye SUBCOMMAND --help`` build the parser from the
    options' names alone (handeye.app.choices, handeye.model.names): no numerical library."""
    code = (
        "import sys\n"
        "from handeye.app.cli import build_parser, main\n"
        "subs = [a for a in build_parser()._subparsers._group_actions[0].choices]\n"
        "for argv in [['--help']] + [[s, '--help'] for s in subs]:\n"
        "    try:\n"
        "        main(argv)\n"
        "    except SystemExit as exc:\n"
        "        assert exc.code == 0, argv\n"
        f"print(len(subs), sorted(m for m in {HEAVY!r} if m in sys.modules))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, cwd="/")
    assert out.returncode == 0, out.stderr
    count, loaded = out.stdout.strip().splitlines()[-1].split(" ", 1)
    assert int(count) >= 10 and loaded == "[]", out.stdout[-500:]


def test_choices_are_the_implementations_own():
    """The light names the parser offers are the very objects the implementing modules use."""
    from handeye.app import calibrate, choices, classic, export, robust, use
    from handeye.model import calibration, conventions, names

    assert calibrate.METHODS is choices.METHODS and classic.METHODS is choices.CLASSIC_METHODS
    assert robust.ALPHA == choices.ALPHA and export.FORMATS is choices.FORMATS and use.CLOUD_FORMATS is choices.CLOUD_FORMATS
    assert calibration.KINDS is names.KINDS and calibration.ROTATIONS is names.ROTATIONS
    assert calibration.UNKNOWNS is names.UNKNOWNS and conventions.CONVENTIONS is names.CONVENTIONS


# --- argparse errors: the line that matters first ----------------------------------------------

@pytest.mark.parametrize("argv,first", [
    (["calibrate", "--method", "simplex"],
     "handeye calibrate: error: argument --method: invalid choice: 'simplex'"),
    (["frobnicate"], "handeye: error: argument command: invalid choice: 'frobnicate'"),
    ([], "handeye: error: the following arguments are required: command"),
    (["cloud", "scan"], "handeye cloud: error: the following arguments are required: --out"),
    (["calibrate", "--max-iter", "many"], "handeye calibrate: error: argument --max-iter: invalid int value: 'many'"),
])
def test_argparse_errors_are_one_line_and_a_hint(capsys, argv, first):
    with pytest.raises(SystemExit) as exc:
        main(argv)
    err = capsys.readouterr().err
    lines = err.splitlines()
    prog = first.split(":")[0]
    assert exc.value.code == EXIT_BAD_INPUT
    assert len(lines) == 2 and lines[0].startswith(first) and lines[1] == f"see `{prog} --help`", err
    assert "usage:" not in err
