"""The discrepancy workflow on data in which effects are hidden (the simulator's effects)."""
import json
import re

import numpy as np
import pytest

from handeye.app.command.cli import EXIT_OK, main
from handeye.app.engine.diagnose import diagnose
from handeye.model import effects
from handeye.model.chain.pose import pose_from_transform, transform_from_pose
from handeye.model.datasets.dataset import load
from handeye.model.simulation import simulate

SETUP = simulate.Setup()
STRUCTURAL = {"base_frame", "flange_frame", "laser_plane"}
CASES = {
    "none": {},
    "sphere_center": {"sphere_center": [1.2, -0.6, 0.9]},
    "sensor_scale": {"sensor_scale": 0.004},
    "sphere_radius": {"sphere_radius": 0.3},
    "sign_flip": {"sign_flip": ["x+45", "y-22.5"]},
    "centre+scale": {"sphere_center": [1.2, -0.6, 0.9], "sensor_scale": 0.004},
    "scale+radius": {"sensor_scale": 0.004, "sphere_radius": 0.3},
    "centre+radius+misprints": {"sphere_center": [-0.8, 0.5, 1.0], "sphere_radius": 0.3,
                                "outlier": ["x+0", "y*+45"]},
    "scale+flip+misprints": {"sensor_scale": 0.004, "sign_flip": ["x*+45"], "outlier": ["y+0", "x-45"]},
}


def run(tmp_path, effects_, seed):
    sim = simulate.simulate(SETUP, seed=seed, effects=effects_)
    return diagnose(load(simulate.write(sim, tmp_path / f"d{seed}"))).to_dict(), sim


@pytest.mark.parametrize("case", sorted(CASES))
@pytest.mark.parametrize("seed", [1, 2])
def test_hidden_effects_are_named_and_nothing_else(tmp_path, case, seed):
    hidden = CASES[case]
    res, sim = run(tmp_path, hidden, seed)
    named = {e["name"]: e for e in res["effects"]}
    expected = {k for k in hidden if k != "outlier"}
    assert set(named) == expected, (named.keys(), expected)
    present_outliers = [i for i in hidden.get("outlier", []) if i in sim.ids]
    assert sorted(res["outliers"]) == sorted(present_outliers)
    assert STRUCTURAL <= set(res["not_identifiable"]) and not STRUCTURAL & set(named)
    for name, eff in named.items():
        if name == "sign_flip":
            assert sorted(eff["parameters"]["ids"]) == sorted(hidden["sign_flip"])
            continue
        truth = {"sphere_center": dict(zip(("dx", "dy", "dz"), hidden.get("sphere_center", [0, 0, 0]))),
                 "sensor_scale": {"s": hidden.get("sensor_scale")},
                 "sphere_radius": {"dr": hidden.get("sphere_radius")}}[name]
        for key, value in eff["parameters"].items():
            assert abs(value - truth[key]) <= 3 * eff["std"][key], (name, key, value, truth[key], eff["std"][key])
    if expected - {"sign_flip"}:  # (flips reinstate samples the base fit had screened out)
        assert res["rms_after_mm"] < res["rms_before_mm"]
        assert res["heldout_rms_after_mm"] < res["heldout_rms_before_mm"]


@pytest.mark.slow(sibling="test_hidden_effects_are_named_and_nothing_else")  # its case "none", two seeds
def test_null_rate_over_thirty_seeds(tmp_path):
    """No effect hidden: no effect named and no sample excluded in at least 95 % of datasets
    (measured here: 40 of 40 in development, 30 of 30 in this test's seeds)."""
    clean = 0
    for seed in range(100, 130):
        res, _ = run(tmp_path, {}, seed)
        clean += not res["effects"] and not res["outliers"]
    assert clean / 30 >= 0.95


def test_a_base_frame_offset_is_absorbed_not_named(tmp_path):
    """A constant error of the robot base frame moves every flange pose; the data see it only
    as a different sphere centre. It is reported absorbed (by cx, cy, cz), never named."""
    sim = simulate.simulate(SETUP, seed=3)
    base_error = transform_from_pose([0.8, -0.5, 0.6, 0.02, -0.01, 0.015])
    sim.flange_poses = pose_from_transform(base_error @ transform_from_pose(sim.flange_poses))
    res = diagnose(load(simulate.write(sim, tmp_path / "base"))).to_dict()
    names = {e["name"] for e in res["effects"]}
    assert "base_frame" not in names and "base_frame" in res["not_identifiable"]
    assert set(res["absorbed_by"]["base_frame"]) <= {"cx", "cy", "cz"}
    assert names == {"sphere_center"}


@pytest.mark.parametrize("seed", [1, 2])
def test_an_effect_beyond_the_catalogues_range_is_unexplained_not_the_nearest_effect(tmp_path, seed):
    """A 10 % sensor scale error (beyond ``sensor_scale``'s 5 %) used to be named ``sphere_radius``
    (dr = 4.2-4.5 mm, within its 20 %), which explains only a part of it. Now nothing is named
    and ``unexplained`` says both: the scale it would need, and that the radius is only the nearest."""
    res, _ = run(tmp_path, {"sensor_scale": 0.1}, seed)
    assert res["effects"] == [] and res["outliers"] == []
    assert re.search(r"sensor_scale would need s = 0\.(09|10)\d*, beyond", res["unexplained"])
    assert re.search(r"sphere_radius \(dr = [\d.]+\) is only the nearest effect", res["unexplained"])


def test_catalogue_is_open_and_documented():
    for effect in effects.catalogue():
        assert effect.NAME in effects.MODULES and effect.DOC and effect.PARAMS
        assert effect.KIND in ("data", "centre", "discrete", "structural", "robot")
    with pytest.raises(ValueError, match="unknown effect"):
        effects.get("gravity")


def test_effect_corrections_are_derived_exactly():
    """Each data effect's generated Jacobian against central differences of its correction."""
    xs = np.array([[3.0, -10.0, 235.0], [-2.0, -4.0, 260.0], [1.0, 12.0, 220.0]])
    for effect in effects.catalogue("data"):
        p0 = np.full(len(effect.PARAMS), 0.002)
        _, jac = effects.correct(effect.NAME, xs, 29.97, p0)
        h = 1e-7
        for k in range(len(p0)):
            step = np.zeros_like(p0)
            step[k] = h
            up, _ = effects.correct(effect.NAME, xs, 29.97, p0 + step)
            down, _ = effects.correct(effect.NAME, xs, 29.97, p0 - step)
            np.testing.assert_allclose(jac[:, :, k], (up - down) / (2 * h), rtol=1e-6, atol=1e-6)
        zero, _ = effects.correct(effect.NAME, xs, 29.97, np.zeros(len(effect.PARAMS)))
        np.testing.assert_allclose(zero, xs, atol=1e-12)  # parameters zero: no effect


def test_thesis_real_diagnosis_and_cli(tmp_path, capsys):
    assert main(["diagnose", "--json", "--figures", str(tmp_path)]) == EXIT_OK
    res = json.loads(capsys.readouterr().out)
    for key in ("effects", "outliers", "not_identifiable", "rms_before_mm", "rms_after_mm", "heldout_rms_before_mm",
                "heldout_rms_after_mm", "sensor_pose", "sensor_matrix"):
        assert key in res
    assert [e["name"] for e in res["effects"]] == ["sphere_center"]
    shift = np.array(list(res["effects"][0]["parameters"].values()))
    assert np.linalg.norm(shift) > 5 and "x+22.5" in res["outliers"]
    assert res["heldout_rms_after_mm"] < res["heldout_rms_before_mm"] / 5
    assert (tmp_path / "residuals.png").is_file() and (tmp_path / "gap.png").is_file()
