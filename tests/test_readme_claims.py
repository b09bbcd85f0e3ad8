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

from handeye.app.command import cli
from handeye.model.chain import testfunction

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
    """``handeye calibrate thesis-real --effects none --json``: the thesis's model (the taught centre
    held), which the search contradicts (exit 1, its pose still reported)."""
    code, out = run_cli("calibrate", "thesis-real", "--effects", "none", "--json")
    assert code == 1
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


def test_out_adds_the_provenance_the_readme_names(tmp_path):
    """`--out` adds ``provenance`` to calibrate's JSON: the README's key table names it and what it holds."""
    code, out = run_cli("calibrate", "thesis-sim", "--json", "--no-loo", "--out", str(tmp_path / "c.json"))
    assert code == 0 and "`--out` adds `provenance`" in FLAT
    assert set(json.loads(out)["provenance"]) >= {"tool", "version", "dataset_path", "dataset_sha256", "options",
                                                   "created_utc"}


# --- the thesis's real data, calibrated ----------------------------------------------------------


def test_the_calibration_of_the_printed_real_data(calibration):
    c = calibration
    ids = figure(r"\(`handeye calibrate thesis-real --effects none`\), excludes (\d) samples as gross errors: x\+22\.5 "
                 r"\(prediction error")
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


def test_the_main_job_is_the_model_the_data_choose(calibration, free_centre):
    code, out = run_cli("calibrate", "thesis-real", "--json")
    chosen = json.loads(out)
    assert code == 0 and chosen["warnings"][0].startswith("the data choose the model with sphere_center")
    np.testing.assert_allclose(chosen["sensor_matrix"], free_centre["sensor_matrix"], atol=1e-6)
    mm, deg, sd = figure(r"`--effects none`\) is refused \(exit 1\): the search puts the pose ([\d.]+) mm and ([\d.]+)° "
                         r"from it, ([\d.]+) sd")
    error = calibration["error"]
    assert "sphere_center" in error and f"{mm} mm and {deg} deg" in error and f"{sd} sd" in error, error


def test_the_sphere_centre_freed(calibration, free_centre):
    away, rms, loo, n = figure(r"the sphere centre is estimated with the pose, ([\d.]+) mm away from the one given by the "
                               r"taught plate pose \(Table 6-4\) and x_p′, with a 1-sd of [\d.]+ mm, and the RMS falls to "
                               r"([\d.]+) mm "
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


# --- diagnose on the real data -------------------------------------------------------------------


def test_what_diagnose_finds_in_the_real_data():
    code, out = run_cli("diagnose", "thesis-real", "--json")
    assert code == 0
    d = json.loads(out)
    assert [e["name"] for e in d["effects"]] == ["sphere_center"]
    printed_all = figure(r"It names one effect, `sphere_center`: \(([−+][\d.]+), ([−+][\d.]+), ([−+][\d.]+)\) ± "
                           r"\(([\d.]+), ([\d.]+), ([\d.]+)\) mm")
    e = d["effects"][0]
    for printed, value in zip(printed_all, [*e["parameters"].values(), *e["std"].values()]):
        assert agrees(printed, value), (printed, value)
    rms = figure(r"RMS ([\d.]+) → ([\d.]+) mm, held-out ([\d.]+) → ([\d.]+) mm, after excluding (.*?)\. Base frame")
    got = [d["rms_before_mm"], d["rms_after_mm"], d["heldout_rms_before_mm"], d["heldout_rms_after_mm"]]
    for printed, value in zip(rms[:4], got):
        assert agrees(printed, value), (printed, value)
    listed = [x.strip().split(" ")[0] for x in rms[4].split(",")]
    assert listed == d["outliers"]
    sigma, times = figure(r"What remains: σ = ([\d.]+) mm per component, about (\d+)× the nominal noise")
    assert agrees(sigma, d["sigma_after_mm"]) and agrees(times, d["sigma_after_mm"] / d["nominal_sigma_mm"])


# --- Table 7-2's starts on thesis-sim (the cheap methods of `handeye study start-poses`) ---------


def _start_poses_iterations(method, rotation):
    import handeye
    from handeye.model.chain.pose import transform_from_pose
    from handeye.model.common.rotation import transform_distance
    from handeye.model.datasets.dataset import load
    from handeye.studies.study_start_poses import TABLE_7_2

    d = load("thesis-sim")
    truth = transform_from_pose(d.truth["sensor_pose"])
    iterations = []
    for start in TABLE_7_2:  # as the study runs them
        res = handeye.calibrate(d, method=method, rotation=rotation, start=start, keep_all=True, no_loo=True)
        dt, dr = transform_distance(res.sensor2flange, truth)
        assert res.converged and dt < 1e-6 and dr < 1e-6, (method, rotation, start)
        iterations.append(int(res.iterations))
    return iterations[1:]  # the README quotes starts 1-9


@pytest.mark.parametrize("method,label", [("gn", "GN"), ("newton", "Newton")])
def test_table_7_2_iterations_of_newton_and_gauss_newton(method, label):
    text = figure(r"Iterations from starts 1–9 \(`handeye study start-poses`, `local` / `euler`\): (.*?)\[test_thesis")
    lo_l, hi_l, lo_e, hi_e, top_e = re.search(rf"\b{label} (\d+)–(\d+) / (\d+)–(\d+)(?:…(\d+))?", text).groups()
    for rotation, lo, hi, top in (("local", lo_l, hi_l, hi_l), ("euler", lo_e, hi_e, top_e or hi_e)):
        its = _start_poses_iterations(method, rotation)  # a range hi…top: the machine's rounding decides
        assert min(its) == int(lo) and int(hi) <= max(its) <= int(top), (method, rotation, its)


# --- the printed real data with its misprint corrected -------------------------------------------


@pytest.fixture(scope="module")
def corrected(tmp_path_factory):
    """thesis-real with C17's zs = 2237.395 read as 237.395 (a copy)."""
    import shutil

    from handeye.model.datasets.dataset import load

    folder = tmp_path_factory.mktemp("readme") / "thesis-real-fixed"
    shutil.copytree(load("thesis-real").path, folder)
    csv = folder / "measurements.csv"
    csv.write_text(csv.read_text().replace("2237.395", "237.395"))
    return load(folder)


def _gn(dataset, **options):
    """The thesis's model and method as fitted (the stages before the search)."""
    from handeye.app.engine.calibrate import CalibrationRequest, stages

    request = CalibrationRequest(method="gn", rotation="euler", options={"max_iter": 250, **options}, outliers=False,
                                 loo=False)
    return stages(request.checked(dataset), dataset).to_dict()


def test_the_corrected_real_data_against_table_7_4(corrected):
    from handeye.model.chain.pose import transform_from_pose
    from handeye.model.common.rotation import transform_distance
    from handeye.model.fit.calibration import CalibrationModel

    res = _gn(corrected)
    x, y, z, ac, b, its, rms = figure(r"every method converges to p2 = \(([\d.]+), ([\d.]+), ([\d.]+)\) mm, "
                                      r"A \+ C = ([\d.]+)°, B = (−[\d.]+)° \(GN: (\d+) iterations\), RMS ([\d.]+) mm")
    a, b_, c = res["sensor_pose"][3:]
    got = [*res["sensor_pose"][:3], a + c, b_, res["iterations"], res["rms_mm"]]
    for printed, value in zip((x, y, z, ac, b, its, rms), got):
        assert agrees(printed, value), (printed, value)
    end, mm, deg, rms74 = figure(r"Table 7-4's p2End = \(([^)]*)\) is ([\d.]+) mm and ([\d.]+)° away, and is not a minimum "
                                 r"of the printed data: its RMS is ([\d.]+) mm")
    thesis = transform_from_pose([float(v.replace("−", "-")) for v in end.split(", ")])
    dt, dr = transform_distance(np.array(res["sensor_matrix"]), thesis)
    assert agrees(mm, dt) and agrees(deg, dr)
    m = CalibrationModel(corrected.flange2base(), corrected.centre_in_sensor, corrected.sphere_centre, "local")
    assert agrees(rms74, np.sqrt(2 * m.cost(m.point_from(thesis)) / len(corrected)))


def test_forward_differences_send_the_euler_angles_astray(corrected):
    from handeye.model.common.rotation import transform_distance
    from handeye.model.datasets.dataset import load

    fixed = figure(r"the angles run off to ±([\d.]+·10\S+) degrees \(the misprint corrected, below\) with the "
                   r"transform unchanged; as printed\s+the run is as chaotic")
    sup = str.maketrans("⁰¹²³⁴⁵⁶⁷⁸⁹", "0123456789")
    mantissa, exponent = fixed.split("·10")
    res = _gn(corrected, jacobian="forward", fd_step=5e-7)
    a, c = res["solver_point"][3], res["solver_point"][5]
    assert np.sign(a) != np.sign(c)
    assert agrees(mantissa, max(abs(a), abs(c)) / 10.0 ** int(exponent.translate(sup))), (fixed, a, c)
    exact = _gn(corrected)  # the exact Jacobian's fit: the same transform, to the forward differences' error
    dt, dr = transform_distance(np.array(res["sensor_matrix"]), np.array(exact["sensor_matrix"]))
    assert dt < 0.01 and dr < 0.001, (dt, dr)
    printed = _gn(load("thesis-real"), jacobian="forward", fd_step=5e-7)  # chaotic: only that it does not converge
    assert not printed["converged"]


# --- Kim & Cho on thesis-real, as the commands run it --------------------------------------------


def test_kim_and_cho_and_the_taught_centre_against_the_free_centre(calibration, free_centre):
    from handeye.model.common.rotation import transform_distance

    km, kd, tm, td = figure(r"`handeye calibrate thesis-real --method kim-cho` lands ([\d.]+) mm / ([\d.]+)° from that "
                            r"fit, the taught-centre calibration \(`--effects none`\) ([\d.]+) mm / ([\d.]+)°")
    code, out = run_cli("calibrate", "thesis-real", "--method", "kim-cho", "--json")
    assert code == 1 and "a baseline with no sd of its own may miss" in json.loads(out)["message"]
    free = np.array(free_centre["sensor_matrix"])
    assert free_centre["n_used"] == 24
    dt, dr = transform_distance(np.array(json.loads(out)["sensor_matrix"]), free)
    assert agrees(km, dt) and agrees(kd, dr), (dt, dr)
    dt, dr = transform_distance(np.array(calibration["sensor_matrix"]), free)
    assert agrees(tm, dt) and agrees(td, dr), (dt, dr)


# --- an effect beyond the catalogue's range ----------------------------------------------------------


def test_a_ten_percent_scale_error_is_left_unexplained(tmp_path):
    command, dr, before, nearest, scaled = figure(
        r"a 10 % sensor scale error \(`handeye simulate (--seed 1 --effect sensor_scale=0\.1)`\), which a radius error "
        r"of ([\d.]+) mm absorbs in part \(RMS ([\d.]+) → ([\d.]+) mm, against ([\d.]+) mm with the scale\)")
    code, _ = run_cli("simulate", "--out", str(tmp_path / "scale"), *command.split())
    assert code == 0
    code, out = run_cli("diagnose", str(tmp_path / "scale"), "--json")
    assert code == 0
    d = json.loads(out)
    assert d["effects"] == [] and agrees(before, d["rms_before_mm"])
    got = re.search(r"sphere_radius \(dr = ([\d.]+)\) is only the nearest effect: sensor_scale beyond its range fits "
                    r"significantly better \(RMS ([\d.]+) against ([\d.]+) mm", d["unexplained"]).groups()
    for printed, value in zip((dr, nearest, scaled), got):
        assert agrees(printed, float(value)), (printed, value)


# --- limits ("What to know") ----------------------------------------------------------------------


def test_the_limits_said_are_the_codes(tmp_path):
    from handeye.app.engine import request, robust

    most, exact, lm_above = figure(r"`simulate --n-poses` takes 1 to (\d+) .*? it refits every sample exactly "
                                   r"up to ([\d,]+) used samples \(`LOO_EXACT_UP_TO`\), .*? above ([\d,]+) measurements "
                                   r"the default method is `lm`")
    assert int(exact.replace(",", "")) == robust.LOO_EXACT_UP_TO
    assert int(lm_above.replace(",", "")) == request.LARGE
    code, _ = run_cli("simulate", "--out", str(tmp_path / "more"), "--n-poses", str(int(most) + 1))
    assert code == cli.EXIT_BAD_INPUT and not (tmp_path / "more").exists()


# --- the long studies, through their saved summaries (tests/data/studies: command, machine, date) ----


def saved(name):
    """The ``summary.json`` of ``handeye study NAME`` as saved in tests/data/studies (the run the README quotes)."""
    doc = json.loads((ROOT / "tests" / "data" / "studies" / f"{name}.json").read_text())
    assert doc["command"] == f"handeye study {name} --out DIR" and doc["machine"]["date"]
    return doc["summary"]


def test_the_accuracy_study():
    s = saved("accuracy")
    assert s["replicates"] == int(figure(r"`handeye study accuracy`, (\d+) noisy replicates"))
    lo, hi, plo, phi = figure(r"RMSE/CRLB per parameter is ([\d.]+)–([\d.]+) for the weighted `centre` and the "
                              r"`measurement` models, ([\d.]+)–([\d.]+) for `points`")
    ratios = {m: s["models"][m]["rmse_over_crlb"] for m in ("centre", "measurement", "points")}
    assert agrees(lo, min(ratios["centre"] + ratios["measurement"]))
    assert agrees(hi, max(ratios["centre"] + ratios["measurement"]))
    assert agrees(plo, min(ratios["points"])) and agrees(phi, max(ratios["points"]))
    within, pwithin = figure(r"deviations match the observed scatter within (\d+) % \(centre, measurement\) and (\d+) % \(points")

    def worst(*models):
        return 100 * max(abs(r / o - 1) for m in models
                         for r, o in zip(s["models"][m]["reported_sd"], s["models"][m]["observed_sd"]))

    assert agrees(within, worst("centre", "measurement")) and agrees(pwithin, worst("points"))
    bound = figure(r"The bound itself: \(([\d.]+), ([\d.]+), ([\d.]+)\) mm, \(([\d.]+), ([\d.]+), ([\d.]+)\)°")
    for printed, value in zip(bound, s["crlb_sd"].values()):
        assert agrees(printed, value)
    loo, held = figure(r"accuracy figure \(([\d.]+) mm here\) agrees with the error of sphere centres predicted for 12 "
                       r"held-out poses per replicate \(([\d.]+) mm\)")
    assert agrees(loo, s["accuracy_figure_mm"]["leave_one_out"]) and agrees(held, s["accuracy_figure_mm"]["held_out"])


def test_the_classics_study():
    s = saved("classics")
    nominal, crlb = s["table"]["k=1,n=36"], s["table"]["k=1,n=36"]["crlb_mm"]
    kc, kcx, li, lix, ls, lsx = figure(r"RMS translation error Kim & Cho ([\d.]+) mm \(([\d.]+)× the Cramér–Rao bound\), "
                                       r"Li et al\. ([\d.]+) mm \(([\d.]+)×: .*?our least squares ([\d.]+) mm \(([\d.]+)×\)")
    for printed, value in zip((kc, kcx, li, lix, ls, lsx),
                              (nominal["kim-cho"]["rmse_mm"], nominal["kim-cho"]["rmse_mm"] / crlb,
                               nominal["li-two-step"]["rmse_mm"], nominal["li-two-step"]["rmse_mm"] / crlb,
                               nominal["nls"]["rmse_mm"], nominal["nls"]["rmse_mm"] / crlb)):
        assert agrees(printed, value), (printed, value)
    rot = figure(r"rotation ([\d.]+)°, ([\d.]+)°, ([\d.]+)°; the same ordering")
    for printed, m in zip(rot, ("kim-cho", "li-two-step", "nls")):
        assert agrees(printed, nominal[m]["rmse_deg"])
    low = figure(r"the projected rotation is ([\d.]+)–180° off on every replicate")
    assert agrees(low, min(v["li-printed"]["min_deg"] for v in s["table"].values()))
    starts, random = figure(r"plain Newton in the right basin in (\d+) % of replicates, against (\d+) % from random starts")
    assert agrees(starts, 100 * s["basin_newton"]["kim-cho"]) and agrees(starts, 100 * s["basin_newton"]["li-two-step"])
    assert agrees(random, 100 * s["basin_newton"]["random"])
    km, kd, tm, td = figure(r"lands ([\d.]+) mm / ([\d.]+)° from the least squares with the sphere centre free on the "
                            r"same 27 samples, while the least squares with the plate-taught centre is ([\d.]+) mm / "
                            r"([\d.]+)° from it")
    dist = s["thesis_real"]["distances"]
    assert s["thesis_real"]["n"] == 27
    assert agrees(km, dist["kim-cho"]["to_sensor_sphere"][0]) and agrees(kd, dist["kim-cho"]["to_sensor_sphere"][1])
    taught = dist["nls (taught centre)"]["to_sensor_sphere"]
    assert agrees(tm, taught[0]) and agrees(td, taught[1])


def test_the_circle_fits_honest_default_and_start_poses_studies():
    kasa = figure(r"Kåsa fit makes the circle ([\d.]+) mm too small")
    assert agrees(kasa, -saved("circle-fits")["arc30_noise005"]["kasa"]["bias_mm"])
    h = saved("honest-default")
    runs, at_truth, worst, polished = figure(r"(\d+) runs\): (\d+) converged at the truth \(largest error ([\d.]+) of the "
                                             r"run's own sd\), 0 false alarms, 0 false successes; IPOPT stopped early next to "
                                             r"the minimum in (\d+) of them")
    assert int(runs) == h["runs"] and int(at_truth) == h["converged_at_truth"] and agrees(worst, h["max_error_in_sd"])
    assert h["false_alarms"] == h["false_successes"] == 0 and int(polished) == h["polished"]
    text = figure(r"Iterations from starts 1–9 \(`handeye study start-poses`, `local` / `euler`\): (.*?)\[test_thesis")
    labels = {"GN": "gn", "LM": "lm", "dogleg": "dogleg", "trust region": "tr", "Newton": "newton"}
    s = saved("start-poses")
    for label, method in labels.items():
        lo_l, hi_l, lo_e, hi_e, top_e = re.search(rf"\b{label} (\d+)–(\d+) / (\d+)–(\d+)(?:…(\d+))?", text).groups()
        for rotation, lo, hi, top in (("local", lo_l, hi_l, hi_l), ("euler", lo_e, hi_e, top_e or hi_e)):
            its = s[f"{method}/{rotation}"]["iterations"][1:]  # saved on the machine that ran the study
            assert min(its) == int(lo) and int(hi) <= max(its) <= int(top), (method, rotation, its)
    lo_m, hi_m, lo_e, hi_e = re.search(r"IPOPT (\d+)–(\d+) \(`matrix`\) / (\d+)–(\d+)", text).groups()
    for key, lo, hi in (("ipopt/matrix", lo_m, hi_m), ("ipopt/euler", lo_e, hi_e)):
        its = s[key]["iterations"][1:]
        assert (min(its), max(its)) == (int(lo), int(hi))
    assert all(v["reached_truth"] == v["of"] == 10 for k, v in s.items() if isinstance(v, dict) and "of" in v)
