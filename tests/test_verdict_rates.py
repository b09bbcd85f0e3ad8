"""The verdict's rates on data no one here wrote (issue 39's done-when), from tests/indep_systematic.py.

(a) The generator is independent (numpy, the standard library and the other independent generators only) and
    agrees with an independent reading of its own files: at the truth the chain closes to exactly the noise it
    injected (centres: row by row, in norm; profiles: the robot's noise plus the circle fit's own error), each
    planted error shows as what it is (a pairing shift undone closes the chain, a non-arc profile is no
    circle, a scale or a taught centre moves the chain by its size), and ``handeye.load_dataset`` reads the
    same flanges, centres (its own circle fit), axis angles, sphere and noise as this module's own parser.
(b) Default tier: one clean cell exits 0 at the truth, keeps every sample and names no effect; one cell of a
    sensor scale does not exit 0 away from it.
(c) ``slow``: the rates of tests/verdict_rates.py over many cells per class, as shards (tests/shards.py):
    every class: no exit 0 away from the truth beyond 4.5 sd ("far", ``verdict_rates.FAR_SD``), wrong exits
    0 (the issue's 3 sd) within that criterion's own chance rate ("wrong"), no exit 3; the clean classes
    also: no false alarm, cells losing a good sample or naming an effect no one planted at <= alpha (binomial
    allowance: the search's family-wise level), sd ratio 0.8-1.25.
    A rate main fails is in :data:`KNOWN_FAILING` with the measured failure: the completing shard asserts
    every other rate, then xfails while that rate fails and fails once it holds (a strict xfail of one rate,
    not of the class: a marker would hide the other rates and the shards' own checks), so a fix flips it.
"""
import ast
import math
import pathlib

import indep_systematic as gen
import numpy as np
import pytest
import shards as sh
import verdict_rates as vr

import handeye

#: the family-wise level of calibrate's outlier tests (its --alpha default): clean data lose samples at <= it
ALPHA = 0.01
#: the chance that a right answer with exactly its reported sd lies beyond 3 sd in some component of the
#: translation or the rotation (1 - (1 - 0.0027)^6): the rate at which the issue's "wrong" criterion itself
#: calls a right exit 0 wrong; wrong exits 0 are allowed up to the binomial allowance of this rate
CHANCE_WRONG = 1.0 - (1.0 - 0.0027) ** 6
#: a rate over N cells passes while the count stays within Binomial(N, p)'s upper 99 % quantile
ALLOWANCE_LEVEL = 0.01
#: the issue's sd ratio band (RMS of error / reported sd over the clean cells, per block)
SD_RATIO = (0.8, 1.25)


def allowance(n, p):
    """The largest count k with P(Binomial(n, p) >= k) >= ALLOWANCE_LEVEL: more than k is beyond chance."""
    tail, k = 1.0, 0
    while True:
        tail -= math.comb(n, k) * p**k * (1 - p) ** (n - k)  # now P(X >= k + 1)
        if tail < ALLOWANCE_LEVEL:
            return k
        k += 1


# ----------------------------------------------------------------------------- (a) the generator itself
def test_generator_is_independent_of_handeye():
    """tests/indep_systematic.py imports numpy, the standard library and the other independent generators."""
    tree = ast.parse(pathlib.Path(gen.__file__).read_text())
    names = {a.name.split(".")[0] for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
    names |= {n.module.split(".")[0] for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) and n.module}
    assert names <= {"__future__", "csv", "dataclasses", "math", "pathlib", "tomllib", "numpy", "indep_cells",
                     "indep_robots"}, names


def _clean_cells(tmp_path, wanted=None):
    """Clean cells of ``wanted`` (mount, mode) pairs (default: every mount in both modes), the first seed that
    gives each, with their truth."""
    wanted = wanted or [(m, mode) for m in gen.MOUNTS for mode in ("centre", "profile")]
    found = {}
    for seed in range(60):
        spec = gen.draw_spec("clean", seed)
        if (spec.mount, spec.mode) in wanted and (spec.mount, spec.mode) not in found:
            found[(spec.mount, spec.mode)] = gen.make(tmp_path / f"clean-{seed}", "clean", seed)
        if len(found) == len(wanted):
            return list(found.values())
    raise AssertionError(f"only {sorted(found)} of {wanted} in 60 seeds")


def test_the_chain_closes_at_the_truth_to_the_injected_noise(tmp_path):
    """Read back with the module's own parser: at the truth each centre row misses by exactly the noise
    injected into it (in norm: the chain turns it); each profile row by the robot's noise plus the circle
    fit's own error (RMS < 0.1 mm at 0.01-0.04 mm point noise on arcs down to 60 deg near the equator, where
    the cut's y carries the radius's error amplified); the centre rows' RMS near the stated noise."""
    for truth in _clean_cells(tmp_path):
        r = gen.chain_residuals(truth)
        if truth.spec.mode == "centre":
            injected = np.linalg.norm(truth.data["centre_noise"], axis=1)
            assert np.allclose(np.linalg.norm(r, axis=1), injected, atol=1e-6), truth.spec
            assert 0.6 < np.sqrt(np.mean(r**2)) / truth.spec.noise < 1.6, truth.spec
        else:
            sign = -1.0 if truth.spec.mount == "eye_to_hand" else 1.0  # S m - F c: the flange's noise enters negated
            assert np.sqrt(np.mean((r - sign * truth.data["robot_noise"]) ** 2)) < 0.1, truth.spec


def test_handeye_reads_the_same_numbers(tmp_path):
    """``handeye.load_dataset`` of each folder: the flanges (1e-9 mm), the centres (given: exactly; from
    profiles: its circle fit against this module's, 1e-3 mm), the axis angles, the sphere, the noise, the mounts;
    on three cells (every mount, profiles on two: where the readings could differ)."""
    for truth in _clean_cells(tmp_path, [("eye_in_hand", "profile"), ("eye_to_hand", "centre"), ("positioner", "profile")]):
        data, back = handeye.load_dataset(truth.folder), gen.read_back(truth.folder)
        assert np.abs(np.asarray(data.flange2base()) - back["flanges"]).max() < 1e-9
        assert np.abs(np.asarray(data.centre_in_sensor) - back["measured"]).max() < 1e-3
        if truth.data["axes"] is not None:
            assert np.allclose(data.axis_angles, back["angles"])
        assert data.sphere_diameter == pytest.approx(truth.spec.diameter)
        if truth.spec.centre_known:
            assert np.allclose(data.sphere_centre, truth.centre, atol=1e-6)
        stated = data.noise_centre_mm if truth.spec.mode == "centre" else data.noise_robot_mm
        assert stated == pytest.approx(truth.spec.noise)
        assert (data.mounts.sensor, data.mounts.sphere) == gen._MOUNT_KEYS[truth.spec.mount]


def _first(tmp_path, kind, mode):
    """The first cell of ``kind`` whose mode is ``mode``."""
    for seed in range(60):
        if gen.draw_spec(kind, seed).mode == mode:
            return gen.make(tmp_path / f"{kind}-{seed}", kind, seed)
    raise AssertionError(f"no {mode} cell of {kind} in 60 seeds")


def test_each_planted_error_is_what_it_says(tmp_path):
    """Each class holds the error it names, read back from its files: a pairing shift misses the chain by
    far more than the noise and, paired back, closes it; a sensor scale, undone, closes it to the injected
    noise; a taught centre and a declared diameter differ from the truth by what was planted; a non-arc
    profile is no circle (its circle fit misses its points by more than 5 times their noise)."""
    shift = _first(tmp_path, "pairing-shift", "centre")
    back = gen.read_back(shift.folder)
    assert np.sqrt(np.mean(gen.chain_residuals(shift, back) ** 2)) > 20 * shift.spec.noise
    poses, measured = (slice(1, None), slice(None, -1)) if shift.planted["shift"] > 0 else (slice(None, -1), slice(1, None))
    paired = dict(back, flanges=back["flanges"][poses], angles=back["angles"][poses], measured=back["measured"][measured])
    assert np.sqrt(np.mean(gen.chain_residuals(shift, paired) ** 2)) < 1.6 * shift.spec.noise
    scale = _first(tmp_path, "scale", "centre")
    back = gen.read_back(scale.folder)
    assert np.sqrt(np.mean(gen.chain_residuals(scale, back) ** 2)) > 3 * scale.spec.noise
    undone = dict(back, measured=back["measured"] / (1.0 + scale.planted["sensor_scale"]))
    injected = np.linalg.norm(scale.data["centre_noise"], axis=1)
    assert np.allclose(np.linalg.norm(gen.chain_residuals(scale, undone), axis=1), injected, atol=1e-3)
    taught = _first(tmp_path, "taught-centre", "centre")
    written = gen.read_back(taught.folder)["setup"]["sphere"]["center"]
    assert np.allclose(np.subtract(written, taught.centre), taught.planted["centre_offset_mm"], atol=1e-6)
    diameter = _first(tmp_path, "diameter", "profile")
    declared = gen.read_back(diameter.folder)["setup"]["sphere"]["diameter"]
    assert declared / diameter.spec.diameter - 1.0 == pytest.approx(diameter.planted["diameter_error"], abs=1e-5)
    edge = _first(tmp_path, "non-arc", "profile")
    for prof in gen.read_back(edge.folder)["profiles"]:
        xc, zc, r = gen.fit_circle(prof)
        assert np.sqrt(np.mean((np.hypot(prof[:, 0] - xc, prof[:, 1] - zc) - r) ** 2)) > 5 * edge.data["point_sd"]


# ----------------------------------------------------------------------------- (b) one cell each, default tier
def _exit_at_the_truth(row):
    """The row's failure in words, or None: an exit 0 away from the truth, or (clean) any exit but 0."""
    if row["exit"] == 0 and row["wrong"]:
        return f"exit 0 WRONG: {row['mm']:.3f} mm / {row['deg']:.4f} deg, z {np.round(row['z'], 1).tolist()}"
    if row["kind"] in gen.CLEAN and row["exit"] != 0:
        return f"false alarm, exit {row['exit']}: {row['error']}"
    return None


@pytest.mark.parametrize("kind, seed", [("clean", 6), ("scale", 6)])
def test_one_cell_exits_as_promised(tmp_path, kind, seed):
    """A clean cell (a fixed sensor, FANUC, profiles only, the centre estimated) exits 0 at the truth and
    keeps every sample and names no effect; a cell with a sensor scale of -0.33 % (sensor on the flange, UR,
    profiles, the centre given) does not exit 0 away from the truth."""
    row = vr.run_cell(kind, seed, tmp_path)
    assert _exit_at_the_truth(row) is None, (row["cell"], row["planted"], _exit_at_the_truth(row))
    assert row["exit"] != 3, row["error"]
    if kind in gen.CLEAN:
        assert row["excluded"] == 0 and not row["effects"], row


def test_profiles_scaled_by_the_sensor_are_no_wrong_diameter(tmp_path):
    """Profiles a sensor scales by -0.24 % (a fixed sensor, KUKA, 18 poses, the centre given) look like a sphere
    0.27 % small: the radius alone fits them to the stated noise, and they were named a wrong ``[sphere]
    diameter`` (exit 2). ``sensor_scale``, of as many parameters, fits them clearly better (a BIC lower by 10:
    taught_sphere._rival): no slip is named, and the search calibrates the scale, at the truth."""
    row = vr.run_cell("scale", 11, tmp_path)
    assert row["exit"] == 0 and not row["wrong"] and row["effects"] == ["sensor_scale"], row


def test_rebuilt_centres_noise_is_no_wrong_diameter(tmp_path):
    """A clean fixed-sensor cell (ABB, 38 profile centres, 0.036 mm robot noise, a 36 mm sphere): its rebuilt
    centres err in y many times more near the equator than near the pole. Fitted with equal weights, that
    noise read as a diameter 0.075 mm off (F p < 1e-9, the pose 4.4 sd away: exit 2, a false alarm, the one of
    600 clean cells); the diameter check now tests in the centres' own metric (taught_sphere.check_radius)."""
    row = vr.run_cell("clean", 528, tmp_path)
    assert _exit_at_the_truth(row) is None, (row["cell"], _exit_at_the_truth(row))


# ----------------------------------------------------------------------------- (c) the rates, slow
#: cells per class of the slow rates: the clean classes more (their false-alarm and lost-sample rates are
#: bounded near 0), 16 for every other class (a class failing in 10 % of its cells fails here with 82 %; the
#: README's table runs 30 of each through tests/verdict_rates.py) but those whose rates other generators hold
#: over more cells in the full suite: pairing shifts (tests/test_pairing.py, 60 shifted cells), profiles of
#: no arc (tests/test_arcs.py) and setup slips (tests/test_independent_cells.py, 12 seeds per slip) -- the
#: full suite's 20 minutes (19.97 with 30 of each, 19.7 with 20, quiet)
CELLS = {"clean": 60, "clean-robot": 40, "pairing-shift": 10, "non-arc": 10, "slip": 20}
DEFAULT_CELLS = 16
#: cells per shard (tests/shards.py): about 10 s of test time each
PER_SHARD = 10
#: (class, rate) -> its failure measured on main: the completing shard asserts every other rate first, then
#: calls ``pytest.xfail`` with this reason while the rate still fails, and FAILS once it passes (strict: a fix
#: flips it; drop the entry).  The rates: ``wrong`` (exit 0 away from the truth), ``false_alarms``,
#: ``losing`` (clean cells losing a good sample), ``false_effects`` (clean cells naming an effect), ``sd_ratio``.
KNOWN_FAILING = {
    # Fixed since main bdd4729 (the same seeds): clean cells losing a sample 6 -> 2 of 60 (the centres' own metric),
    # scale wrong 15 -> 1 of 30 (the search on a positioner, centre_scale), diameter far 3 -> 0, pairing shift
    # wrong 6 -> 0 (a pairing shift is a slip: all 30 exit 2).
    # Fixed by the power statement (branch power, issue 39's few poses): link lengths' seed 4 (UR5e, a2 +0.37
    # and a3 +0.34 mm, 21 poses) exited 0 at 0.38 mm / 0.09 deg, 6.0 sd; the sd now includes what the data
    # could not see.
}


def _shard_params():
    """``(kind, shard, n_shards)`` of every shard of every class."""
    out = []
    for kind in gen.CLASSES:
        n_shards = math.ceil(CELLS.get(kind, DEFAULT_CELLS) / PER_SHARD)
        out += [pytest.param(kind, shard, n_shards, id=f"{kind}-{shard}") for shard in range(n_shards)]
    return out


def _rates(kind, rows):
    """Each rate of the issue over every cell of the class: name -> (holds, the evidence)."""
    s = vr.summary(rows)[kind]
    wrong = [(r["seed"], r["cell"], _exit_at_the_truth(r)) for r in rows if r["exit"] == 0 and r["wrong"]]
    far = [(r["seed"], r["cell"], _exit_at_the_truth(r)) for r in rows if r["exit"] == 0 and vr.far(r)]
    out = {"other": (s["other"] == 0, [(r["seed"], r["error"]) for r in rows if r["exit"] == 3]),
           "wrong": (s["wrong"] <= allowance(s["cells"], CHANCE_WRONG), wrong), "far": (not far, far)}
    if kind in gen.CLEAN:
        alarms = [(r["seed"], r["cell"], _exit_at_the_truth(r)) for r in rows if r["exit"] != 0]
        losing = [(r["seed"], r["cell"], r["excluded"]) for r in rows if r["exit"] == 0 and r["excluded"]]
        out["false_alarms"] = (s["false_alarms"] == 0, alarms)
        out["losing"] = (s["losing"] <= allowance(s["cells"] - s["false_alarms"], ALPHA), losing)
        named = [(r["seed"], r["cell"], r["effects"]) for r in rows if r["exit"] == 0 and r["effects"]]
        out["false_effects"] = (s["false_effects"] <= allowance(s["cells"] - s["false_alarms"], ALPHA), named)
        ratios = (s["sd_ratio_t"], s["sd_ratio_r"])
        out["sd_ratio"] = (all(SD_RATIO[0] <= v <= SD_RATIO[1] for v in ratios), ratios)
    return out


def _assert_rates(kind, rows):
    """Every rate not known to fail holds; then the known failures xfail while they fail, and fail once
    they pass (a fix must drop its entry from :data:`KNOWN_FAILING`)."""
    rates = _rates(kind, rows)
    broken = {name: evidence for name, (holds, evidence) in rates.items() if not holds and (kind, name) not in KNOWN_FAILING}
    assert not broken, (kind, broken)
    fixed = [name for name, (holds, _) in rates.items() if holds and (kind, name) in KNOWN_FAILING]
    assert not fixed, f"{kind}: {fixed} now hold (strict xfail passed): drop them from KNOWN_FAILING"
    known = [f"{name}: {KNOWN_FAILING[(kind, name)]}" for name in rates if (kind, name) in KNOWN_FAILING]
    if known:
        pytest.xfail("; ".join(known))


@pytest.mark.slow(sibling="test_one_cell_exits_as_promised")
@pytest.mark.parametrize("kind, shard, n_shards", _shard_params())
def test_verdict_rates(tmp_path, tmp_path_factory, kind, shard, n_shards):
    """Every cell of the shard calibrated as a user would (tests/verdict_rates.py), none with exit 3; the
    shard that completes the class asserts its rates (:func:`_assert_rates`)."""
    rows = [vr.run_cell(kind, seed, tmp_path) for seed in sh.shards(CELLS.get(kind, DEFAULT_CELLS), n_shards)[shard]]
    assert not [r for r in rows if r["exit"] == 3], [(r["seed"], r["error"]) for r in rows if r["exit"] == 3]
    pooled = sh.pool(tmp_path_factory, f"verdict-rates-{kind}", shard, n_shards, rows)
    if pooled is None:
        return  # the rates are asserted by the shard that completes the set
    _assert_rates(kind, [r for part in pooled for r in part])
