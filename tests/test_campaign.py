"""The fault-and-input campaign: whatever the input, handeye ends with exit 0/1/2 (3 only for a
bug) and one line naming the cause, never writes over a file it reads, leaves no temporary file,
and heals a damaged cache on the next run."""
import math
import os
import pathlib
import shutil
import subprocess
import sys

import pytest

import handeye
from handeye.app.command import cli
from handeye.model.chain import codegen
from handeye.model.common.statistics import chi2_survival, f_survival
from handeye.model.compiled import fast

SIM = pathlib.Path(handeye.load_dataset("thesis-sim").path)


def _copy(tmp_path, name="d"):
    target = tmp_path / name
    shutil.copytree(SIM, target)
    return target


def _edit_cell(folder, row, column, value):
    path = folder / "measurements.csv"
    lines = path.read_text().splitlines()
    header = lines[0].split(",")
    cells = lines[row - 1].split(",")
    cells[header.index(column)] = value
    lines[row - 1] = ",".join(cells)
    path.write_text("\n".join(lines) + "\n")


def _run(capsys, *argv):
    code = cli.main([str(a) for a in argv])
    out, err = capsys.readouterr()
    assert "Traceback" not in err
    return code, out, err


def _no_temporary_files(folder):
    return not [p for p in pathlib.Path(folder).rglob("*") if p.name.endswith(".tmp") or "handeye-probe" in p.name]


# -- data loss --------------------------------------------------------------------------------

def test_no_command_writes_over_a_file_it_reads(tmp_path, capsys):
    d = _copy(tmp_path)
    before = {p.name: p.read_bytes() for p in d.iterdir()}
    (tmp_path / "link.csv").symlink_to(d / "measurements.csv")
    for argv in (("calibrate", d, "--out", d / "measurements.csv"),
                 ("calibrate", d, "--out", tmp_path / "link.csv"),
                 ("calibrate", d, "--plot", d / "setup.toml"),
                 ("diagnose", d, "--out", d / "measurements.csv"),
                 ("plan", "--dataset", d, "--out", d / "setup.toml")):
        code, _, err = _run(capsys, *argv)
        assert code == cli.EXIT_BAD_INPUT and "reads" in err, argv
    assert {p.name: p.read_bytes() for p in d.iterdir()} == before
    code, _, err = _run(capsys, "plan", "--n", "4", "--candidates", tmp_path / "c.csv", "--out", tmp_path / "c.csv")
    assert code == cli.EXIT_BAD_INPUT


# -- hangs and non-finite numbers ----------------------------------------------------------------

def test_tail_probabilities_terminate_on_nan_and_inf():
    for d2 in (3, 4, 7):
        assert math.isnan(f_survival(math.nan, 3, d2))
        assert f_survival(math.inf, 3, d2) == 0.0
    assert math.isnan(chi2_survival(math.nan, 3)) and chi2_survival(math.inf, 3) == 0.0


@pytest.mark.parametrize("rows", ["one", "every"])
def test_absurd_values_are_named_by_row_and_column(tmp_path, capsys, rows):
    d = _copy(tmp_path)
    for row in ([3] if rows == "one" else range(2, 15)):
        _edit_cell(d, row, "xs", "1e300")
    for command in ("calibrate", "diagnose"):
        code, _, err = _run(capsys, command, d, "--json")
        assert code == cli.EXIT_BAD_INPUT and ("row 3" in err or "row 2" in err), err
        assert "column 'xs'" in err and "[limits] sensor_mm" in err
    d2 = _copy(tmp_path, "p")
    _edit_cell(d2, 4, "x", "1e300")
    code, _, err = _run(capsys, "calibrate", d2)
    assert code == cli.EXIT_BAD_INPUT and "row 4, column 'x'" in err
    code, _, err = _run(capsys, "calibrate", "thesis-sim", "--start=1e300,0,0,0,0,0")
    assert code == cli.EXIT_BAD_INPUT and "--start" in err


def test_json_is_strict(capsys, break_solver):
    """A NaN in a result is written as null, never as NaN (invalid JSON)."""
    import json

    break_solver()
    code, out, _ = _run(capsys, "calibrate", "thesis-sim", "--method", "lm", "--keep-all", "--no-loo", "--json")
    assert code == cli.EXIT_NOT_CONVERGED
    res = json.loads(out, parse_constant=lambda c: pytest.fail(f"non-finite {c} in the JSON"))
    assert res["sensor_matrix"][0][0] is None and res["converged"] is False


# -- output paths -------------------------------------------------------------------------------

@pytest.mark.parametrize("where", ["folder", "missing-parent", "proc"])
def test_output_paths_are_checked_before_the_work(tmp_path, capsys, where):
    target = {"folder": tmp_path, "missing-parent": tmp_path / "no" / "x.out", "proc": pathlib.Path("/proc/x.out")}[where]
    for argv in (("calibrate", "thesis-sim", "--out", target), ("calibrate", "thesis-sim", "--plot", target),
                 ("diagnose", "thesis-sim", "--out", target), ("plan", "--n", "4", "--out", target)):
        code, out, err = _run(capsys, *argv)
        assert code == cli.EXIT_BAD_INPUT and ("--out" in err or "--plot" in err), (argv, err)
        assert out == ""  # nothing computed, nothing printed: not half a result
    if where != "folder":
        code, _, err = _run(capsys, "simulate", "--out", target)
        assert code == cli.EXIT_BAD_INPUT and "--out" in err
        code, _, err = _run(capsys, "diagnose", "thesis-sim", "--figures", target)
        assert code == cli.EXIT_BAD_INPUT and "--figures" in err
    assert _no_temporary_files(tmp_path)


def test_a_failed_rename_leaves_no_temporary_file(tmp_path, monkeypatch):
    from handeye.app.common import files

    def refuse(src, dst):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(files.os, "replace", refuse)
    with pytest.raises(handeye.InputError, match="--out"):
        files.write_text_atomically(tmp_path / "r.json", "{}")
    assert list(tmp_path.iterdir()) == []


# -- diagnose runs calibrate's gate ----------------------------------------------------------------

def test_diagnose_refuses_what_calibrate_refuses(tmp_path, capsys):
    few = _copy(tmp_path, "few")
    lines = (few / "measurements.csv").read_text().splitlines()
    (few / "measurements.csv").write_text("\n".join(lines[:3]) + "\n")
    same = _copy(tmp_path, "same")
    row = lines[1].split(",")
    (same / "measurements.csv").write_text("\n".join([lines[0]] + [",".join([f"r{k}"] + row[1:]) for k in range(8)]) + "\n")
    for d in (few, same):
        for command in ("calibrate", "diagnose"):
            code, out, err = _run(capsys, command, d)
            assert code == cli.EXIT_BAD_INPUT and "measurements.csv" in err, (d, command, err)


# -- damaged caches heal -------------------------------------------------------------------------

def _calibrate_in_subprocess(cache, env_extra=None):
    env = dict(os.environ, HANDEYE_CACHE=str(cache), **(env_extra or {}))
    code = ("import sys, handeye; from handeye.model.compiled import fast; "
            "r = handeye.calibrate('thesis-sim', method='lm', no_loo=True); "
            "print('OK', r.converged, fast.library() is not None)")
    return subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=600)


@pytest.mark.slow(sibling="test_a_broken_library_is_rebuilt_and_a_bad_compiler_never_cached")
def test_a_damaged_cache_heals_itself(tmp_path):
    cache = tmp_path / "cache"
    first = _calibrate_in_subprocess(cache)
    assert first.returncode == 0 and "OK True" in first.stdout, first.stderr
    sources = list(cache.glob("*.py"))
    assert sources
    sources[0].write_text(sources[0].read_text()[:40])  # truncated
    sources[1].write_text("")  # emptied
    healed = _calibrate_in_subprocess(cache)
    assert healed.returncode == 0 and "OK True" in healed.stdout, healed.stderr
    assert codegen._read_checked(sources[0]) is not None and codegen._read_checked(sources[1]) is not None


def test_a_broken_library_is_rebuilt_and_a_bad_compiler_never_cached(tmp_path):
    cache = tmp_path / "cache"
    fake = tmp_path / "fakecc"
    fake.write_text("#!/bin/sh\n# exits 0 and writes a broken library\nfor a; do o=$a; done\n"
                    "while [ $# -gt 0 ]; do if [ \"$1\" = -o ]; then echo broken > \"$2\"; fi; shift; done\n")
    fake.chmod(0o755)
    bad = _calibrate_in_subprocess(cache, {"CC": str(fake)})
    assert bad.returncode == 0 and "OK True False" in bad.stdout, bad.stderr + bad.stdout  # VM path, still correct
    assert not list((cache / "c").glob("*.so"))  # the broken library was never cached
    good = _calibrate_in_subprocess(cache)  # a working compiler is back
    assert good.returncode == 0 and "OK True True" in good.stdout, good.stderr
    (so,) = list((cache / "c").glob("*.so"))
    so.write_bytes(b"")  # emptied
    (cache / "c" / "tmpstale").mkdir()
    os.utime(cache / "c" / "tmpstale", (0, 0))  # left by a killed compile long ago
    again = _calibrate_in_subprocess(cache)
    assert again.returncode == 0 and "OK True True" in again.stdout, again.stderr
    assert so.stat().st_size > 0 and not (cache / "c" / "tmpstale").exists()
    assert fast.STALE_BUILD_S > 0


# -- messages ---------------------------------------------------------------------------------------

def test_readers_name_the_cause(tmp_path, capsys):
    semi = _copy(tmp_path, "semi")
    (semi / "measurements.csv").write_text((semi / "measurements.csv").read_text().replace(",", ";"))
    code, _, err = _run(capsys, "calibrate", semi)
    assert code == cli.EXIT_BAD_INPUT and "separator" in err
    bom = _copy(tmp_path, "bom")
    (bom / "setup.toml").write_bytes(b"\xef\xbb\xbf" + (bom / "setup.toml").read_bytes())
    assert _run(capsys, "calibrate", bom, "--no-loo")[0] == cli.EXIT_OK
    dev = _copy(tmp_path, "dev")
    (dev / "measurements.csv").unlink()
    (dev / "measurements.csv").symlink_to("/dev/zero")
    code, _, err = _run(capsys, "calibrate", dev)
    assert code == cli.EXIT_BAD_INPUT and "regular file" in err
    for bad in ("0", "4294967296", "2147483648"):
        code, _, err = _run(capsys, "calibrate", "thesis-sim", "--max-iter", bad)
        assert code == cli.EXIT_BAD_INPUT and "--max-iter" in err


def test_profile_paths_stay_in_the_dataset_and_a_collinear_profile_is_named(tmp_path, capsys):
    s = handeye.simulate(tmp_path / "p", seed=1, n_poses=8, profiles=True)
    outside = tmp_path / "outside.csv"
    outside.write_text("x,z\n0,200\n1,201\n2,203\n")
    lines = (s.path / "measurements.csv").read_text().splitlines()
    cells = lines[2].split(",")
    cells[-1] = "../outside.csv"
    lines[2] = ",".join(cells)
    (s.path / "measurements.csv").write_text("\n".join(lines) + "\n")
    code, _, err = _run(capsys, "calibrate", s.path)
    assert code == cli.EXIT_BAD_INPUT and "row 3, column 'profile'" in err and "leaves the dataset folder" in err
    cells[-1] = "profiles/line.csv"
    lines[2] = ",".join(cells)
    (s.path / "measurements.csv").write_text("\n".join(lines) + "\n")
    (s.path / "profiles" / "line.csv").write_text("x,z\n0,200\n1,201\n2,202\n3,203\n")  # collinear, xs given
    code, out, _ = _run(capsys, "calibrate", s.path, "--model", "measurement")  # one of 8: set aside, named (issue 39)
    assert code == 0 and "row 3: its profile profiles/line.csv is not an arc of the" in out, out


def test_ctrl_c_exits_130_with_one_line(capsys, monkeypatch):
    from handeye.app.public import api

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(api, "calibrate", interrupted)
    code, out, err = _run(capsys, "calibrate", "thesis-sim")
    assert code == 130 and err.strip() == "handeye: interrupted"


# -- a second campaign (an independent tester's 335 cases) ------------------------------------------

def test_outputs_never_replace_inputs_by_any_name_link_or_kind(tmp_path, capsys):
    s = handeye.simulate(tmp_path / "p", seed=1, n_poses=8, profiles=True)
    lines = (s.path / "measurements.csv").read_text().splitlines()
    cells = lines[1].split(",")
    (s.path / "profiles" / cells[-1].split("/")[-1]).rename(s.path / "profiles" / "p.txt")
    cells[-1] = "profiles/p.txt"
    lines[1] = ",".join(cells)
    (s.path / "measurements.csv").write_text("\n".join(lines) + "\n")
    before = (s.path / "profiles" / "p.txt").read_bytes()
    code, _, err = _run(capsys, "calibrate", s.path, "--out", s.path / "profiles" / "p.txt")
    assert code == cli.EXIT_BAD_INPUT and (s.path / "profiles" / "p.txt").read_bytes() == before
    os.link(s.path / "measurements.csv", tmp_path / "hl.png")  # a hard link to an input
    code, _, err = _run(capsys, "calibrate", s.path, "--plot", tmp_path / "hl.png")
    assert code == cli.EXIT_BAD_INPUT and "reads" in err
    figs = tmp_path / "figs"
    figs.mkdir()
    (figs / "residuals.png").symlink_to(s.path / "measurements.csv")
    code, _, err = _run(capsys, "diagnose", s.path, "--figures", figs)
    assert code == cli.EXIT_BAD_INPUT and (s.path / "measurements.csv").read_text().startswith("id,")
    os.mkfifo(tmp_path / "fifo")
    code, _, err = _run(capsys, "calibrate", "thesis-sim", "--out", tmp_path / "fifo")
    assert code == cli.EXIT_BAD_INPUT and "regular file" in err and (tmp_path / "fifo").is_fifo()
    code, _, err = _run(capsys, "calibrate", "thesis-sim", "--plot", tmp_path / "r.txt")
    assert code == cli.EXIT_BAD_INPUT and "extensions" in err


def test_huge_profile_values_and_odd_paths_are_named_fast(tmp_path, capsys):
    import time

    s = handeye.simulate(tmp_path / "p", seed=2, n_poses=8, profiles=True)
    profile = next((s.path / "profiles").glob("*.csv"))
    rows = profile.read_text().splitlines()
    rows[4] = "1e160,200"
    profile.write_text("\n".join(rows) + "\n")
    t0 = time.perf_counter()
    code, _, err = _run(capsys, "calibrate", s.path)
    assert code == cli.EXIT_BAD_INPUT and "[limits] sensor_mm" in err and time.perf_counter() - t0 < 30
    profile.unlink()
    profile.symlink_to(profile.name)  # a symlink to itself
    code, _, err = _run(capsys, "calibrate", s.path)
    assert code == cli.EXIT_BAD_INPUT and "profile" in err


@pytest.mark.parametrize("toml", ["diameter = 1" + "0" * 400, "centre_mm = 1e-300", "centre_mm = 1e300",
                                  "sensor_mm = 1e308"])
def test_absurd_setup_numbers_are_bad_input(tmp_path, capsys, toml):
    d = _copy(tmp_path)
    setup = (d / "setup.toml").read_text()
    if toml.startswith("diameter"):
        setup = "\n".join(toml if line.startswith("diameter") else line for line in setup.splitlines())
    else:
        setup += f"\n[{'noise' if 'centre' in toml else 'limits'}]\n{toml}\n"
    (d / "setup.toml").write_text(setup)
    code, _, err = _run(capsys, "calibrate", d)
    assert code == cli.EXIT_BAD_INPUT and "setup.toml" in err


def test_more_bad_options_and_cells(tmp_path, capsys):
    for argv in (("calibrate", "thesis-sim", "--sigma", "1e-200"), ("diagnose", "thesis-sim", "--sigma", "1e-200"),
                 ("calibrate", "thesis-sim", "--effects", ""), ("calibrate", "thesis-sim", "--effects", ","),
                 ("calibrate", "thesis-sim", "--effects", "sensor_scale")):
        code, _, err = _run(capsys, *argv)
        assert code == cli.EXIT_BAD_INPUT and err.count("\n") == 1, (argv, err)
    d = _copy(tmp_path)
    _edit_cell(d, 3, "x", "1_000")
    code, _, err = _run(capsys, "calibrate", d)
    assert code == cli.EXIT_BAD_INPUT and "row 3, column 'x'" in err
    same = tmp_path / "c.csv"
    same.write_text("id,x,y,z,a,b,c\n" + "".join(f"p{k},1400,-600,1300,0,0,180\n" for k in range(20)))
    code, _, err = _run(capsys, "plan", "--candidates", same, "--n", "6")
    assert code == cli.EXIT_BAD_INPUT


@pytest.mark.slow(sibling="test_a_broken_library_is_rebuilt_and_a_bad_compiler_never_cached")
def test_a_truncated_library_is_never_loaded(tmp_path):
    cache = tmp_path / "cache"
    assert "OK True True" in _calibrate_in_subprocess(cache).stdout
    (so,) = list((cache / "c").glob("*.so"))
    data = so.read_bytes()
    so.write_bytes(data[: len(data) // 2])  # dlopen of this can crash the process (SIGBUS)
    healed = _calibrate_in_subprocess(cache)
    assert healed.returncode == 0 and "OK True True" in healed.stdout, healed.stderr
    assert so.read_bytes() == data


def test_output_that_cannot_be_written_is_one_line(tmp_path):
    with open("/dev/full", "w") as full:
        out = subprocess.run([sys.executable, "-m", "handeye.app.command.cli", "calibrate", "thesis-sim", "--no-loo"],
                             stdout=full, stderr=subprocess.PIPE, text=True, timeout=300)
    assert out.returncode == cli.EXIT_BAD_INPUT and "cannot write the output" in out.stderr


def test_ctrl_c_ends_a_running_study_at_once(tmp_path):
    import signal
    import time

    proc = subprocess.Popen([sys.executable, "-c", "import sys; from handeye.app.command.cli import main; sys.exit(main())",
                             "study", "random-starts", "--out", str(tmp_path / "x"), "--jobs", "1"],
                            stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True)
    time.sleep(3.0)
    proc.send_signal(signal.SIGINT)
    t0 = time.perf_counter()
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130 and "handeye: interrupted" in err and time.perf_counter() - t0 < 10
