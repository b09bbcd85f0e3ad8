"""Edges of the command line (issue 26): file modes, signals, a closed stdout, a light
``--help``, the code cache of a read-only install, pasteable suggestions, short argparse errors.

Most run the console script in a subprocess, as a user does: what is asserted is what the
shell sees (exit code, stderr lines, files left behind, modules loaded), never a time.
"""
import json
import os
import pathlib
import shlex
import signal
import subprocess
import sys
import time

import pytest

from handeye.app.command.cli import EXIT_BAD_INPUT, main

ROOT = pathlib.Path(__file__).resolve().parents[1]
_SCRIPT = pathlib.Path(sys.executable).with_name("handeye")
#: the console script of this environment, else the same entry point through the interpreter
HANDEYE = [str(_SCRIPT)] if _SCRIPT.exists() else [sys.executable, "-m", "handeye.app.command.cli"]


def handeye(*argv, **kwargs):
    """Run ``handeye ARGV`` (text mode, output captured unless told otherwise)."""
    kwargs.setdefault("capture_output", "stdout" not in kwargs)
    return subprocess.run(HANDEYE + [str(a) for a in argv], text=True, timeout=600, **kwargs)


# --- --help loads nothing heavy ---------------------------------------------------------------

HEAVY = ("numpy", "sympy", "casadi", "mpmath", "matplotlib", "scipy")


def test_help_imports_no_numpy_sympy_or_casadi():
    """``handeye --help`` and every ``handeye SUBCOMMAND --help`` build the parser from the
    options' names alone (handeye.app.common.choices, handeye.model.chain.names): no numerical library."""
    code = (
        "import sys\n"
        "from handeye.app.command.cli import build_parser, main\n"
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
    from handeye.app.common import choices
    from handeye.app.engine import calibrate, classic, robust
    from handeye.app.outputs import commands as use
    from handeye.app.outputs import formats as export
    from handeye.model.chain import conventions, names
    from handeye.model.fit import calibration

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


# --- outputs get the umask's mode -----------------------------------------------------------------

def _with_umask(mask):
    return lambda: os.umask(mask)


@pytest.mark.parametrize("mask,mode", [(0o022, 0o644), (0o027, 0o640), (0o077, 0o600)])
def test_outputs_get_the_mode_the_umask_gives(tmp_path, mask, mode):
    """--out of calibrate and of export, and --plot: the mode ``open`` would give under the
    umask (not the temporary file's 0600), still through a temporary file and a rename."""
    result, script = tmp_path / "r.json", tmp_path / "tool.script"
    run = handeye("calibrate", "thesis-sim", "--method", "lm", "--no-loo", "--out", result, preexec_fn=_with_umask(mask))
    assert run.returncode == 0, run.stderr
    run = handeye("export", result, "--format", "ur", "--out", script, preexec_fn=_with_umask(mask))
    assert run.returncode == 0, run.stderr
    for path in (result, script):
        assert path.stat().st_mode & 0o777 == mode, (path, oct(path.stat().st_mode))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.json", "tool.script"]  # no temporary file


def test_a_file_written_over_keeps_its_mode(tmp_path):
    """As the shell's ``>`` does: an existing output that was made private stays private."""
    from handeye.app.common.files import write_text_atomically

    old = os.umask(0o022)
    try:
        fresh, private = tmp_path / "fresh.txt", tmp_path / "private.txt"
        private.write_text("old")
        private.chmod(0o600)
        write_text_atomically(fresh, "new")
        write_text_atomically(private, "new")
    finally:
        os.umask(old)
    assert fresh.stat().st_mode & 0o777 == 0o644 and private.stat().st_mode & 0o777 == 0o600
    assert private.read_text() == "new"


# --- a closed stdout is an error -----------------------------------------------------------------

def test_closed_stdout_is_an_error():
    """``handeye calibrate thesis-real >&-``: the result would be lost; exit 2, one line."""
    run = handeye("calibrate", "thesis-real", preexec_fn=lambda: os.close(1), stdout=None, stderr=subprocess.PIPE)
    assert run.returncode == EXIT_BAD_INPUT and run.stderr.count("\n") == 1, run.stderr
    assert "standard output is closed" in run.stderr and "Traceback" not in run.stderr


@pytest.mark.parametrize("argv", [["datasets"], ["calibrate", "thesis-sim", "--method", "lm", "--no-loo"]])
def test_stdout_a_closed_pipe_is_an_error(argv):
    """``handeye ... | head -c0``: the reader is gone before anything is written; exit 2, one line."""
    proc = subprocess.Popen(HANDEYE + argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    proc.stdout.close()  # no reader left: the first write fails with EPIPE
    err = proc.stderr.read()
    assert proc.wait(timeout=300) == EXIT_BAD_INPUT and err.count("\n") == 1, err
    assert "cannot write the output" in err and "broken pipe" in err and "Traceback" not in err


# --- signals: one line, 130 / 143, nothing left behind ---------------------------------------------

ENDINGS = {signal.SIGINT: (130, "handeye: interrupted\n"), signal.SIGTERM: (143, "handeye: terminated\n")}


def _mapped(pid, needle, timeout=120):
    """Wait until the process has loaded a shared library whose path contains ``needle``."""
    maps = pathlib.Path(f"/proc/{pid}/maps")
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            if needle in maps.read_text():
                return True
        except OSError:
            return False  # the process is gone
        time.sleep(0.005)
    return False


def _leftovers(folder):
    return sorted(p.name for p in pathlib.Path(folder).iterdir() if p.name.startswith(".") or p.suffix == ".tmp")


@pytest.mark.skipif(not pathlib.Path("/proc/self/maps").exists(), reason="needs /proc to see the moment")
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
@pytest.mark.parametrize("moment", ["_multiarray_umath", "casadi"], ids=["importing-numpy", "solving"])
def test_a_signal_at_start_up_or_in_the_solve_is_one_line(tmp_path, sig, moment):
    """While numpy is being imported (start-up) and once CasADi is loaded (the solve)."""
    proc = subprocess.Popen(HANDEYE + ["calibrate", "thesis-real", "--out", str(tmp_path / "x.json")],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    assert _mapped(proc.pid, moment)
    proc.send_signal(sig)
    err = proc.stderr.read()
    code, line = ENDINGS[sig]
    assert proc.wait(timeout=60) == code and err == line, err
    assert _leftovers(tmp_path) == [] and not (tmp_path / "x.json").exists()


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
@pytest.mark.parametrize("delay", [0.3, pytest.param(0.8, marks=pytest.mark.slow(
    sibling="test_a_signal_at_any_moment_leaves_no_temporary_file[0.3-SIGINT]")), 1.5, pytest.param(2.5, marks=pytest.mark.slow(
        sibling="test_a_signal_at_any_moment_leaves_no_temporary_file[1.5-SIGINT]"))])
def test_a_signal_at_any_moment_leaves_no_temporary_file(tmp_path, sig, delay):
    """Whenever it comes: the signal's code and its one line, or (too late) the run's own ending, or
    (too early: on a loaded machine 0.3 s may fall before the interpreter reaches handeye's handler)
    the signal's default death with nothing said and nothing written; never a temporary file, never
    a half-written --out."""
    out = tmp_path / "x.json"
    proc = subprocess.Popen(HANDEYE + ["calibrate", "thesis-real", "--no-loo", "--out", str(out)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    time.sleep(delay)
    proc.send_signal(sig)
    err = proc.stderr.read()
    code, line = ENDINGS[sig]
    rc = proc.wait(timeout=60)
    assert (rc, err) in ((code, line), (-sig, "")) or (rc in (0, 1) and "Traceback" not in err), (rc, err)
    assert _leftovers(tmp_path) == []
    if out.exists():
        assert json.loads(out.read_text())["dataset"] == "thesis-real"


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_a_signal_while_the_output_is_written_removes_the_temporary_file(tmp_path, sig):
    """The moment the issue names: the temporary file of --out exists, half written, when the
    signal comes (sent by the writer itself, so the moment is certain)."""
    code = (
        "import os, sys, time\n"
        "from handeye.app.command import cli; from handeye.app.common import files\n"
        "cli.install_signal_handlers()\n"
        "def write(fh):\n"
        "    fh.write(b'{\"half\": ')\n"
        "    fh.flush()\n"
        "    print('TMP', [p for p in os.listdir(sys.argv[1]) if p.endswith('.tmp')], flush=True)\n"
        f"    os.kill(os.getpid(), {int(sig)})\n"
        "    time.sleep(30)\n"
        "files.write_stream_atomically(os.path.join(sys.argv[1], 'x.json'), write)\n"
    )
    run = subprocess.run([sys.executable, "-c", code, str(tmp_path)], capture_output=True, text=True, timeout=60)
    expected, line = ENDINGS[sig]
    assert "'.x.json." in run.stdout  # the temporary file was there when the signal came
    assert run.returncode == expected and run.stderr == line, run.stderr
    assert list(tmp_path.iterdir()) == []


# --- the generated-code cache of a read-only install -----------------------------------------------

def _unwritable(tmp_path):
    """A cache folder this process cannot write: read-only by mode, or (as root, whom modes do
    not stop) below a regular file."""
    if os.geteuid() == 0:
        (tmp_path / "blocker").write_text("a file where a folder would be needed")
        return tmp_path / "blocker" / "cache"
    ro = tmp_path / "readonly"
    ro.mkdir()
    ro.chmod(0o555)
    return ro / "cache"


_PROBE = ("import sys; from handeye.app.command.cli import main; code = main(); "
          "print('SYMPY', 'sympy' in sys.modules, file=sys.stderr); sys.exit(code)")


def _calibrate_with(env):
    env = {k: v for k, v in os.environ.items() if k not in ("HANDEYE_CACHE", "XDG_CACHE_HOME")} | env
    return subprocess.run([sys.executable, "-c", _PROBE, "calibrate", "thesis-sim", "--method", "lm", "--no-loo"],
                          env=env, capture_output=True, text=True, timeout=600, cwd="/")


@pytest.mark.parametrize("xdg", [pytest.param(True, id="XDG_CACHE_HOME", marks=pytest.mark.slow(
    sibling="test_an_unwritable_cache_falls_back_to_the_user_cache[HOME]")), pytest.param(False, id="HOME")])
def test_an_unwritable_cache_falls_back_to_the_user_cache(tmp_path, xdg):
    """HANDEYE_CACHE read-only: the code goes to $XDG_CACHE_HOME/handeye (or ~/.cache/handeye),
    silently, and the next run is warm (no sympy)."""
    env = {"HANDEYE_CACHE": str(_unwritable(tmp_path)), "HOME": str(tmp_path / "home")}
    user = tmp_path / "xdg" / "handeye" if xdg else tmp_path / "home" / ".cache" / "handeye"
    if xdg:
        env["XDG_CACHE_HOME"] = str(tmp_path / "xdg")
    cold, warm = _calibrate_with(env), _calibrate_with(env)
    assert cold.returncode == 0 and "SYMPY True" in cold.stderr and "warning" not in cold.stderr, cold.stderr
    assert warm.returncode == 0 and warm.stderr.strip() == "SYMPY False", warm.stderr
    assert any(user.glob("*.py"))


def test_no_writable_cache_is_said_once(tmp_path):
    """Neither HANDEYE_CACHE nor the user's cache writable: one warning line, naming both and
    the fix, and the calibration still runs (deriving the code)."""
    blocked = _unwritable(tmp_path)
    env = {"HANDEYE_CACHE": str(blocked), "XDG_CACHE_HOME": str(blocked.parent / "xdg"),
           "HOME": str(tmp_path / "home")}
    run = _calibrate_with(env)
    warnings = [line for line in run.stderr.splitlines() if "warning" in line]
    assert run.returncode == 0 and len(warnings) == 1, run.stderr
    assert warnings[0].startswith("handeye: warning: the generated-code cache cannot be written")
    assert str(blocked) in warnings[0] and "set HANDEYE_CACHE to a writable folder" in warnings[0]


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes through a read-only mode")
def test_a_read_only_filled_cache_is_read(tmp_path):
    """A read-only install's pre-filled cache is used as it is: warm, nothing written elsewhere."""
    cache = tmp_path / "filled"
    assert _calibrate_with({"HANDEYE_CACHE": str(cache)}).returncode == 0
    for path in [cache, *cache.rglob("*")]:
        path.chmod(path.stat().st_mode & ~0o222)
    env = {"HANDEYE_CACHE": str(cache), "XDG_CACHE_HOME": str(tmp_path / "xdg"), "HOME": str(tmp_path / "home")}
    warm = _calibrate_with(env)
    assert warm.returncode == 0 and warm.stderr.strip() == "SYMPY False", warm.stderr
    assert not (tmp_path / "xdg").exists()


# --- suggestions a user can paste --------------------------------------------------------------

def _suggested_commands(text):
    return [c for c in text.split("`")[1::2] if c.startswith("handeye ")]


@pytest.mark.parametrize("name", [pytest.param("thesis-real", marks=pytest.mark.slow(
    sibling="test_suggested_commands_are_complete_and_run[folder with space]")), "folder with space"])
def test_suggested_commands_are_complete_and_run(tmp_path, capsys, name):
    """The warnings name the dataset as the user did (the embedded name, not its installed path;
    a folder by its path, quoted), with calibrate's dataset argument; pasted, each runs."""
    import shutil

    from handeye.model.datasets.dataset import DATA_DIR

    dataset = "thesis-real"
    if name != "thesis-real":
        dataset = str(tmp_path / name)
        shutil.copytree(DATA_DIR / "thesis-real", dataset)
    main(["calibrate", dataset, "--no-loo", "--json"])
    warnings = json.loads(capsys.readouterr().out)["warnings"]
    commands = sorted({c for w in warnings for c in _suggested_commands(w)})
    assert any(c.startswith("handeye diagnose") for c in commands), warnings
    assert any(c.startswith("handeye calibrate") and "--effects" in c for c in commands), warnings
    for command in commands:
        argv = shlex.split(command)
        assert argv[2] == dataset, command  # the dataset exactly as given, right after the subcommand
        assert str(DATA_DIR) not in command
        run = handeye(*argv[1:], *(["--no-loo"] if argv[1] == "calibrate" else []))
        assert run.returncode in (0, 1), (command, run.stderr)


def test_a_read_only_filled_cache_is_read_without_deriving(tmp_path, monkeypatch):
    """The same as root can check it: a HANDEYE_CACHE taken as unwritable is still read first,
    the user's cache comes after it, and a hit derives nothing and writes nothing."""
    import sympy as sp

    from handeye.model.chain import codegen

    filled, xdg = tmp_path / "filled", tmp_path / "xdg"
    monkeypatch.setenv("HANDEYE_CACHE", str(filled))
    monkeypatch.setenv("XDG_CACHE_HOME", str(xdg))
    x = sp.Symbol("x")

    def build():
        return (x,), [x**2 + 1]

    text = codegen.generated_source("edges_probe", build)
    monkeypatch.setattr(codegen, "_writable", lambda folder: filled not in (pathlib.Path(folder), *pathlib.Path(folder).parents))
    assert codegen.cache_dirs() == [filled, xdg / "handeye"] and codegen.cache_dir() == xdg / "handeye"

    def must_not_derive():
        raise AssertionError("derived again although the read-only cache has it")  # same file: same cache key

    assert codegen.generated_source("edges_probe", must_not_derive) == text
    assert not xdg.exists()


def _group(pgid):
    """Command lines of the live processes of a process group (from /proc)."""
    out = []
    for stat in pathlib.Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
            if int(fields[2]) == pgid and fields[0] != "Z":
                out.append((stat.parent / "cmdline").read_text().replace("\0", " "))
        except (OSError, IndexError, ValueError):
            continue
    return out


#: CPU seconds after which a sweep's worker has done its imports (about 1 s) and is computing.
WORKER_BUSY_S = 2.5


def _worker_cpu(pgid):
    """CPU seconds (user + system) of each live loky worker of a process group (from /proc)."""
    out, tick = [], os.sysconf("SC_CLK_TCK")
    for stat in pathlib.Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
            cmd = (stat.parent / "cmdline").read_text()
            if int(fields[2]) == pgid and fields[0] != "Z" and "loky" in cmd and "resource_tracker" not in cmd:
                out.append((int(fields[11]) + int(fields[12])) / tick)
        except (OSError, IndexError, ValueError):
            continue
    return out


@pytest.mark.skipif(not pathlib.Path("/proc/self/stat").exists(), reason="needs /proc to see the workers")
@pytest.mark.slow(sibling="test_a_signal_while_the_output_is_written_removes_the_temporary_file[SIGINT]")
def test_ctrl_c_in_a_terminal_stops_the_workers_of_a_study_too(tmp_path):
    """The terminal's Ctrl-C goes to the whole process group, the sweep's workers included: the
    run still ends with the one line (no worker's IPOPT warning, no report of the pool's
    clean-up), and no worker is left computing for a run that has stopped."""
    proc = subprocess.Popen(HANDEYE + ["study", "random-starts", "--quick", "--jobs", "2", "--out", str(tmp_path / "s")],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, start_new_session=True)
    deadline = time.monotonic() + 120
    # the workers are computing: each has spent more CPU than its imports take (on a loaded machine a
    # fixed wait caught a worker still importing joblib, whose interrupted import prints a traceback)
    while sum(cpu >= WORKER_BUSY_S for cpu in _worker_cpu(proc.pid)) < 2:
        assert time.monotonic() < deadline and proc.poll() is None, "no worker started computing"
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGINT)
    err = proc.stderr.read()
    assert proc.wait(timeout=60) == 130 and err.splitlines()[-1] == "handeye: interrupted", err
    assert "Warning" not in err and "WARNING" not in err and "Traceback" not in err, err
    deadline = time.monotonic() + 20
    while _group(proc.pid) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert _group(proc.pid) == []


def _profiles_started(folder, timeout=120):
    """Wait until a simulate run has written a profile into its (temporary) folder."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if any(pathlib.Path(folder).glob(".d.*/profiles/*")):
            return True
        time.sleep(0.005)
    return False


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_an_interrupted_simulate_leaves_no_half_written_dataset(tmp_path, sig):
    """simulate writes into a temporary folder renamed into place at the end: a signal while the
    profiles are written leaves nothing (the same command then runs), never a folder that
    holds profiles but no measurements.csv."""
    proc = subprocess.Popen(HANDEYE + ["simulate", "--out", str(tmp_path / "d"), "--profiles", "--seed", "1"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, cwd=tmp_path)
    assert _profiles_started(tmp_path)
    proc.send_signal(sig)
    err = proc.stderr.read()
    code, line = ENDINGS[sig]
    rc = proc.wait(timeout=60)
    assert (rc, err) == (code, line), (rc, err)
    assert list(tmp_path.iterdir()) == []
    done = handeye("simulate", "--out", tmp_path / "d", "--seed", "1")
    assert done.returncode == 0 and (tmp_path / "d" / "measurements.csv").exists(), done.stderr


@pytest.mark.slow(sibling="test_a_signal_while_the_output_is_written_removes_the_temporary_file[SIGINT]")
def test_advice_without_a_sphere_centre_names_diagnose_with_the_centre_free(tmp_path):
    """Where calibrate estimated the centre, its advice to run diagnose says --unknowns sensor+sphere
    (diagnose estimates it too), diagnose without it refuses naming the option, and with it names
    the effect."""
    import handeye

    sim = handeye.simulate(tmp_path / "d", seed=5, effect="sensor_scale=0.003", profiles=True)
    setup = sim.path / "setup.toml"
    setup.write_text("\n".join(line for line in setup.read_text().splitlines() if not line.startswith("center")))
    res = handeye.calibrate(sim.path, unknowns="sensor+sphere", no_loo=True, effects="none")
    advice = [w for w in res.warnings if "handeye diagnose" in w]
    assert advice and all("/d --unknowns sensor+sphere`" in w for w in advice), advice
    chosen = handeye.calibrate(sim.path, unknowns="sensor+sphere", no_loo=True)  # the model the search chooses
    assert chosen.converged and "/d --unknowns sensor+sphere --effects sensor_scale`" in chosen.warnings[0]
    with pytest.raises(handeye.InputError, match="--unknowns sensor\\+sphere"):
        handeye.diagnose(sim.path)
    named = handeye.diagnose(sim.path, unknowns="sensor+sphere")
    assert [e.name for e in named.effects] == ["sensor_scale"]
