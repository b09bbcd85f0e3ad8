"""The README's deterministic figures, checked against the commands it names (issue 31).

Each test reads a figure out of the README's own text and compares it with what the command
the README names prints now, to the printed digits: a change that moves a figure fails here
until the README moves with it. One run per command (module-scoped fixtures); the studies
that take minutes are checked through the seeded quick runs the README quotes, or not here.
Machine-dependent figures (times, speed-ups, memory) are not checked: ``handeye bench``
writes them with the machine and the date.
"""
from __future__ import annotations

import contextlib
import fnmatch
import io
import json
import re
from pathlib import Path

import numpy as np
import pytest

from handeye.app import cli
from handeye.model import testfunction

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text(encoding="utf-8")
#: the folders whose every file the README's tour names
TOURED = ("app", "model", "solvers", "studies")


def flat(text):
    """``text`` with every run of white space one blank (README lines wrap anywhere)."""
    return re.sub(r"\s+", " ", text)


FLAT = flat(README)


def figure(pattern):
    """The groups of ``pattern`` (a regex over the README with white space collapsed; exactly one match)."""
    found = re.findall(pattern, FLAT)
    assert len(found) == 1, f"README: {len(found)} matches of {pattern!r}"
    return found[0]


def agrees(printed, value):
    """``value`` rounds to the ``printed`` figure (its digits; a minus sign as printed, thousands commas allowed)."""
    text = printed.replace("−", "-").replace(",", "").lstrip("+")
    decimals = len(text.split(".")[1]) if "." in text else 0
    return abs(float(value) - float(text)) <= 0.5 * 10.0**-decimals * (1 + 1e-9)


def run_cli(*args):
    """``handeye ARGS`` in this process: (exit code, stdout)."""
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        code = cli.main(list(args))
    return code, out.getvalue()


@pytest.fixture(scope="module")
def calibration():
    """``handeye calibrate thesis-real --json``, the README's main job."""
    code, out = run_cli("calibrate", "thesis-real", "--json")
    assert code == 0
    return json.loads(out)


@pytest.fixture(scope="module")
def free_centre():
    """``handeye calibrate thesis-real --unknowns sensor+sphere --json``."""
    code, out = run_cli("calibrate", "thesis-real", "--unknowns", "sensor+sphere", "--json")
    assert code == 0
    return json.loads(out)


# --- the file tour --------------------------------------------------------------------------


def tour_names():
    """File names (and globs, ``bench*.py``; ``effects/x.py`` with its folder) in the tour's block."""
    block = README.split("## A short tour", 1)[1].split("```", 2)[1]
    return set(re.findall(r"[\w*/]*[\w*]+\.(?:py|c)\b", block))


def _named(path, name):
    tail = "/".join(path.parts[-len(name.split("/")):])
    return fnmatch.fnmatch(tail, name)


def test_the_tour_names_every_source_file_and_nothing_that_does_not_exist():
    names = tour_names()
    assert all(n not in ("*.py", "*.c") for n in names)
    files = [p.relative_to(ROOT) for d in TOURED for p in (ROOT / d).rglob("*")
             if p.suffix in (".py", ".c") and "__pycache__" not in p.parts]
    missing = sorted(str(p) for p in files if not any(_named(p, n) for n in names))
    assert not missing, f"files the README's tour does not name: {missing}"
    everywhere = [p.relative_to(ROOT) for p in ROOT.rglob("*") if p.suffix in (".py", ".c")
                  and not {".venv", "__pycache__", ".git"} & set(p.parts)]
    ghosts = sorted(n for n in names if not any(_named(p, n) for p in everywhere))
    assert not ghosts, f"names in the README's tour that no file has: {ghosts}"


# --- calibrate --json's keys -------------------------------------------------------------------


def test_the_json_keys_listed_are_exactly_calibrates(calibration):
    table = README.split("has these keys", 1)[1].split("\n\n", 2)[1]
    listed = set()
    for row in table.splitlines()[2:]:
        listed |= set(re.findall(r"`(\w+)`", row.split(" | ")[0]))
    assert listed == set(calibration), (sorted(listed - set(calibration)), sorted(set(calibration) - listed))


# --- the thesis's real data, calibrated ----------------------------------------------------------


def test_the_calibration_of_the_printed_real_data(calibration):
    c = calibration
    ids = figure(r"`handeye calibrate` excludes (\d) samples as gross errors: x\+22\.5 \(prediction error")
    assert int(ids) == len(c["outliers"]) == 4
    for sample in ("x+22.5", "x+45", "x*+90", "y*+112.5"):
        assert sample in c["outliers"]
    p2 = figure(r"On the 27 others: p2 = \(([\d.]+), ([\d.]+), ([\d.]+)\) mm, B = (−[\d.]+)°, RMS ([\d.]+) mm, "
                r"leave-one-out error ([\d.]+) mm \(before exclusion: RMS ([\d.]+) mm, leave-one-out ([\d.]+) mm\)")
    got = [*c["sensor_pose"][:3], c["sensor_pose"][4], c["rms_mm"], c["loo_error_mm"],
           c["before"]["rms_mm"], c["before"]["loo_error_mm"]]
    assert c["n_used"] == 27
    for printed, value in zip(p2, got):
        assert agrees(printed, value), (printed, value)
    sd = figure(r"1-sd uncertainty \(([\d.]+), ([\d.]+), ([\d.]+)\) mm and \(([\d.]+), ([\d.]+), ([\d.]+)\)°")
    for printed, value in zip(sd, [*c["std"]["sensor_translation_mm"], *c["std"]["sensor_rotation_deg"]]):
        assert agrees(printed, value), (printed, value)


def test_the_sphere_centre_freed(calibration, free_centre):
    away, rms, loo, n = figure(r"the sphere centre is estimated ([\d.]+) mm away from the one given by the taught plate "
                               r"pose \(Table 6-4\) and x_p′, with a 1-sd of [\d.]+ mm, and the RMS falls to ([\d.]+) mm "
                               r"\(leave-one-out ([\d.]+) mm, (\d+) samples")
    f = free_centre
    given = np.asarray(calibration["sphere_center"])
    assert agrees(away, np.linalg.norm(np.asarray(f["sphere_center"]) - given))
    assert agrees(rms, f["rms_mm"]) and agrees(loo, f["loo_error_mm"]) and int(n) == f["n_used"]
    for sample in ("x+67.5", "x+135", "y+90"):
        assert sample in f["outliers"]


# --- exit codes ----------------------------------------------------------------------------------


def test_the_exit_codes_listed_are_the_clis():
    listed = {int(c) for c in re.findall(r"\*\*(\d+)\*\*", figure(r"(Exit codes: \*\*0\*\*.*?\*\*143\*\*)"))}
    assert listed == {0, 1, 2, 3, 4, 130, 143}
    constants = {v for k, v in vars(cli).items() if k.startswith("EXIT_") and isinstance(v, int)}
    assert listed == constants, (listed, constants)


# --- the test function -----------------------------------------------------------------------------


def test_the_test_functions_printed_saddle_and_the_true_one():
    grad = figure(r"The printed \*\*saddle point \(0\.105, −0\.205\) is not stationary\*\*: \|∇f\| = ([\d.]+) there")
    assert agrees(grad, np.linalg.norm(testfunction.gradient(np.array([0.105, -0.205]))))
    x1, x2, f, l1, l2 = figure(r"the saddle is \(([\d.]+), (−[\d.]+)\), f = (−[\d.]+), Hessian eigenvalues "
                               r"(−[\d.]+) and (\d+\.\d+)")
    x = np.array([float(x1), -float(x2[1:])])
    assert np.linalg.norm(testfunction.gradient(x)) < 1e-6
    assert agrees(f, testfunction.value(x))
    eig = np.linalg.eigvalsh(testfunction.hessian(x))
    assert agrees(l1, eig[0]) and agrees(l2, eig[1])
