"""The robot's own errors beyond joint offsets (model/robot/robot_errors.py; effects ``link_lengths`` and
``joint_compliance``): exact derivatives, the effects' geometry checked by hand, simulate writes
them, diagnose names them with their values on the right parameters, calibrate --effects reports
them with 1 sd, export folds lengths into the model, and a clean robot names none."""
from __future__ import annotations

import json

import numpy as np
import pytest

import handeye
from handeye.app.command.cli import EXIT_BAD_INPUT, main
from handeye.app.public import api
from handeye.model.robot import robot_errors, robots
from handeye.model.simulation import simulate_mounts


def _values(model, rng, scale=0.3):
    return {n: rng.normal(0, scale, len(robot_errors.param_names(model, n))) for n in robot_errors.NAMES}


@pytest.mark.parametrize("name", robots.builtin_names())
def test_derivatives_of_every_robot_error_against_central_differences(name):
    """Each parameter's exact derivative (product rule) against central differences of the
    perturbed forward kinematics, with every error non-zero at once (1e-6 relative: differences of
    positions of ~1e3 mm carry ~1e-8 of rounding)."""
    model, rng = robots.load(name), np.random.default_rng(0)
    q, values = rng.uniform(-80, 80, (5, 6)), _values(model, rng)
    _, derivatives = robot_errors.perturbed(model, q, values)
    for effect, full in values.items():
        for k in range(len(full)):
            step = np.zeros_like(full)
            step[k] = 1e-5
            up = robot_errors.perturbed(model, q, values | {effect: full + step})[0]
            down = robot_errors.perturbed(model, q, values | {effect: full - step})[0]
            numeric = (up - down) / 2e-5
            assert np.abs(numeric - derivatives[effect][:, k]).max() < 1e-6 * max(1.0, np.abs(numeric).max()), (effect, k)


@pytest.mark.parametrize("name", robots.builtin_names())
def test_zero_errors_are_the_nominal_model(name):
    model = robots.load(name)
    q = np.random.default_rng(1).uniform(-90, 90, (4, 6))
    zero = {n: np.zeros(len(robot_errors.param_names(model, n))) for n in robot_errors.NAMES}
    np.testing.assert_allclose(robot_errors.perturbed(model, q, zero)[0], model.flange2base(q), atol=1e-9)
    np.testing.assert_allclose(robots.offset_derivatives(model, q, np.zeros(6))[0], model.flange2base(q), atol=1e-9)


def test_length_names_are_the_data_sheets_nonzero_lengths():
    assert robot_errors.param_names(robots.load("kr60ha"), "link_lengths") == (
        "j2_x", "j2_z", "j3_x", "j4_x", "j4_z", "j5_x", "j6_x")
    assert robot_errors.param_names(robots.load("ur10e"), "link_lengths") == ("d1", "a2", "a3", "d4", "d5", "d6")


def test_a_length_error_moves_the_flange_by_hand():
    """KR 60 HA at A1 = 0, A2 = -90 (upper arm up), A3 = 90: the 850 mm arm j3_x points up (base
    +z), so +1 mm of it lifts the flange 1 mm; UR10e at zero: a2 (-612.7 mm) lies along base x, so
    +1 mm of a2 moves the flange +1 mm in x."""
    kr = robots.load("kr60ha")
    q = np.array([[0.0, -90.0, 90.0, 0.0, 0.0, 0.0]])
    names = robot_errors.param_names(kr, "link_lengths")
    err = np.zeros(len(names))
    err[names.index("j3_x")] = 1.0
    moved = robot_errors.perturbed(kr, q, {"link_lengths": err})[0] - kr.flange2base(q)
    np.testing.assert_allclose(moved[0, :3, 3], [0, 0, 1], atol=1e-9)
    ur = robots.load("ur10e")
    names = robot_errors.param_names(ur, "link_lengths")
    err = np.zeros(len(names))
    err[names.index("a2")] = 1.0
    moved = robot_errors.perturbed(ur, np.zeros((1, 6)), {"link_lengths": err})[0] - ur.flange2base(np.zeros((1, 6)))
    np.testing.assert_allclose(moved[0, :3, 3], [1, 0, 0], atol=1e-9)


def test_gravity_lever_and_sag_by_hand():
    """KR 60 HA with A1 = 0: A2 turns about base y through the shoulder (350, 0, 815), so the lever
    of the flange about it is its x beyond the shoulder, (p_x - 350) / 1000 m, whatever A2..A6 are
    (zero when the flange is straight above or below the shoulder). Stretched forward (all zero) a
    positive gain sags the flange: down by reach * sin(gain * lever), nothing sideways."""
    kr = robots.load("kr60ha")
    q = np.random.default_rng(2).uniform(-60, 60, (20, 6))
    q[:, 0] = 0.0
    np.testing.assert_allclose(robot_errors.levers(kr, q)[:, 0], (kr.flange2base(q)[:, 0, 3] - 350.0) / 1000.0, atol=1e-12)
    stretched = np.zeros((1, 6))
    lever = robot_errors.levers(kr, stretched)[0, 0]
    reach = kr.flange2base(stretched)[0, 0, 3] - 350.0
    sag = robot_errors.perturbed(kr, stretched, {"joint_compliance": np.array([0.02, 0.0])})[0] - kr.flange2base(stretched)
    assert lever > 1.5 and abs(sag[0, 1, 3]) < 1e-9
    assert sag[0, 2, 3] == pytest.approx(-reach * np.sin(np.radians(0.02 * lever)), rel=1e-3) and sag[0, 2, 3] < -0.5


def _cell(folder, robot, effects, seed=0):
    api.simulate(folder, robot=robot, effect=list(effects), seed=seed)
    return folder


def _within(effect, truth, sd=3.0):
    """Every estimated parameter within ``sd`` of its truth (0 where none was planted)."""
    for param, value in effect.parameters.items():
        assert abs(value - truth.get(param, 0.0)) < sd * effect.std[param], (effect.name, param, value, truth)


def test_diagnose_names_link_lengths_with_their_values(tmp_path):
    """KR 60 HA, the 850 mm upper arm 0.4 mm long and the 145 mm elbow offset 0.3 mm short: named
    on those (3 sd); j2_z (absorbed by the centre's z), j6_x (along the last axis: the sensor's
    translation) and j5_x (along A4's axis, as j4_x) said to be absorbed; the gap shrinks to the
    noise."""
    d = handeye.diagnose(_cell(tmp_path / "ll", "kr60ha", ["link_lengths=j3_x:0.4,j4_z:-0.3"], seed=1))
    named = {e.name: e for e in d.effects}
    assert list(named) == ["link_lengths"], list(named)
    assert {"j3_x", "j4_z"} <= set(named["link_lengths"].parameters)
    _within(named["link_lengths"], {"j3_x": 0.4, "j4_z": -0.3})
    assert {"link_lengths.j2_z", "link_lengths.j6_x", "link_lengths.j5_x"} <= set(d.not_identifiable)
    assert d.chi2_dof_after < 2.0 and d.chi2_dof_before > 2.0


def test_diagnose_names_joint_compliance_with_its_gains(tmp_path):
    d = handeye.diagnose(_cell(tmp_path / "jc", "kr60ha", ["joint_compliance=j2:0.03,j3:0.02"], seed=2))
    named = {e.name: e for e in d.effects}
    assert list(named) == ["joint_compliance"], list(named)
    _within(named["joint_compliance"], {"j2": 0.03, "j3": 0.02})
    assert d.chi2_dof_after < 2.0 < 10 * 2.0 < d.chi2_dof_before


def test_calibrate_reports_both_with_1_sd_and_export_folds_the_lengths_in(tmp_path):
    """UR10e with a2 0.3 mm long and a shoulder sag of 0.03 deg/m: the centre model alone would name
    the sphere centre (the sag looks like it), --effects with both keeps the given centre, reports
    the values within 3 sd and fits to the noise; the exported model TOML is the nominal one with
    the calibrated lengths (its FK equals the perturbed FK), the sag said in its comment."""
    folder = _cell(tmp_path / "ur", "ur10e", ["joint_compliance=j2:0.03", "link_lengths=a2:0.3"], seed=3)
    res = handeye.calibrate(folder, effects="joint_compliance,link_lengths", out=tmp_path / "cal.json")
    assert res.converged and [e.name for e in res.effects] == ["joint_compliance", "link_lengths"]
    named = {e.name: e for e in res.effects}
    _within(named["joint_compliance"], {"j2": 0.03})
    _within(named["link_lengths"], {"a2": 0.3})
    assert res.rms_mm < 0.06 and any("d1 not estimated" in w for w in res.warnings)
    doc = json.loads((tmp_path / "cal.json").read_text())
    text = handeye.export(tmp_path / "cal.json", format="robot-toml").text
    assert "gravity deflection not in the model" in text and "a2 +0.3" in text
    (tmp_path / "model.toml").write_text(text)
    ur = robots.load("ur10e")
    names = robot_errors.param_names(ur, "link_lengths")
    lengths = [e for e in doc["effects"] if e["name"] == "link_lengths"][0]["parameters"]
    full = np.array([lengths.get(n, 0.0) for n in names])
    q = np.random.default_rng(4).uniform(-120, 120, (5, 6))
    np.testing.assert_allclose(robots.load(tmp_path / "model.toml").flange2base(q),
                               robot_errors.perturbed(ur, q, {"link_lengths": full})[0], atol=1e-6)


def test_a_clean_robot_names_no_robot_effect(tmp_path):
    for seed, robot in ((5, "kr60ha"), (6, "ur10e")):
        d = handeye.diagnose(_cell(tmp_path / f"clean{seed}", robot, [], seed=seed))
        assert not [e.name for e in d.effects if e.name in robot_errors.NAMES], (robot, [e.name for e in d.effects])


def test_simulate_refuses_unknown_parameters_and_robot_effects_without_a_robot(tmp_path, capsys):
    assert main(["simulate", "--out", str(tmp_path / "a"), "--robot", "ur10e", "--effect", "link_lengths=j3_x:0.2"]) \
        == EXIT_BAD_INPUT
    assert "j3_x not a parameter of the UR10e" in capsys.readouterr().err
    assert main(["simulate", "--out", str(tmp_path / "b"), "--effect", "joint_compliance=j2:0.02"]) == EXIT_BAD_INPUT
    assert "joint_compliance needs --robot" in capsys.readouterr().err
    assert main(["simulate", "--out", str(tmp_path / "c"), "--robot", "kr60ha", "--effect", "link_lengths=j3_x:50"]) \
        == EXIT_BAD_INPUT
    assert "|VALUE| <= 20" in capsys.readouterr().err


def test_the_truth_of_robot_errors_reads_back(tmp_path):
    folder = _cell(tmp_path / "t", "kr60ha", ["link_lengths=j3_x:0.4", "joint_compliance=j2:0.01"], seed=7)
    truth = handeye.load_dataset(folder).truth
    assert truth["link_lengths"] == {"j3_x": 0.4} and truth["joint_compliance"] == {"j2": 0.01}


def test_a_fixed_sensor_with_the_robot_holding_the_sphere_names_joint_offsets(tmp_path):
    """Eye-to-hand: the robot's corrected flange enters inverted (d inv(F) = -inv(F) dF inv(F));
    A2/A3 offsets named within 3 sd. A6's offset turns the sphere (on the flange axis) about
    itself: its column passes the gate in direction but is tiny, said as too weakly seen."""
    folder = tmp_path / "e2h"
    api.simulate(folder, robot="kr60ha", sensor_mount="world", sphere_mount="flange",
                 effect=["joint_offsets=j2:0.05,j3:-0.03"])
    d = handeye.diagnose(folder)
    named = {e.name: e for e in d.effects}
    assert list(named) == ["joint_offsets"] and "j6" not in named["joint_offsets"].parameters
    _within(named["joint_offsets"], {"j2": 0.05, "j3": -0.03})
    assert any(s.startswith("joint_offsets.j6: too weakly seen here") for s in d.absorbed_explained)


def test_robot_effects_that_explain_alike_are_said_not_chosen_silently(tmp_path):
    """The IRB 4600 holding the sphere before a fixed sensor: every pose near one place, so A2/A3
    offsets and length errors with a shoulder sag explain the data alike. diagnose keeps the
    simplest (the offsets, the truth here) and says the alternative with how far its sensor pose
    lies; the comparison is in the JSON too."""
    folder = tmp_path / "irb"
    far = ",".join(f"{v:g}" for v in simulate_mounts.WORLD_SENSOR)  # 1.75 m out: the arm stretched, poses alike
    api.simulate(folder, robot="irb4600", sensor_mount="world", sphere_mount="flange", truth=far,
                 effect=["joint_offsets=j2:0.05,j3:-0.03"])
    d = handeye.diagnose(folder)
    assert [e.name for e in d.effects] == ["joint_offsets"]
    assert d.robot_alternatives and "which robot errors is not settled" in d.robot_alternatives
    assert "link_lengths" in d.robot_alternatives and "sensor pose" in d.robot_alternatives
    assert d.to_dict()["robot_alternatives"] == d.robot_alternatives
    assert "which robot errors is not settled" in d.summary()


def test_robot_effects_are_not_offered_with_the_sphere_on_a_positioner(tmp_path):
    from handeye.model import effects

    folder = tmp_path / "pos"
    api.simulate(folder, robot="kr60ha", sphere_mount="positioner", n_poses=12)
    data = handeye.load_dataset(folder)
    assert data.joints is not None and not any(e.available(data) for e in effects.catalogue("robot"))
    with pytest.raises(handeye.InputError, match="link_lengths: not with the sphere on a positioner"):
        handeye.calibrate(folder, effects="link_lengths", unknowns="sensor+sphere")


def test_robot_errors_beyond_a_controllers_model_are_not_named():
    """A fitted offset of 3 deg, a length 12 mm off or a sag of 0.8 deg/m is no robot error a
    controller's nominal model leaves: it absorbs something else and is said, with the names."""
    from handeye.model import effects

    assert "j3 = 3, beyond joint zero offsets of at most 2 deg" in effects.implausible(
        "joint_offsets", np.array([0.1, 3.0]), 25.0, names=("j2", "j3"))
    assert "a wrong [robot] model" in effects.implausible("link_lengths", np.array([12.0]), 25.0, names=("a2",))
    assert effects.implausible("joint_compliance", np.array([0.8, 0.0]), 25.0, names=("j2", "j3")) is not None
    assert effects.implausible("joint_compliance", np.array([0.05, 0.02]), 25.0, names=("j2", "j3")) is None


@pytest.mark.parametrize("name", robots.builtin_names())
def test_what_no_pose_set_separates_is_found_from_the_chain(name):
    """A first-joint offset and a length before the first joint's turn change the flange by a
    constant transform on the base side; a last-joint offset and a length along the last axis by one
    on the flange side: for every built-in robot exactly these four, and no sag gain."""
    model = robots.load(name)
    lengths = robot_errors.always_absorbed(model, "link_lengths")
    assert robot_errors.always_absorbed(model, "joint_offsets") == {"j1": "base", "j6": "flange"}
    assert sorted(lengths.values()) == ["base", "flange"] and len(lengths) == 2
    assert robot_errors.always_absorbed(model, "joint_compliance") == {}


def test_diagnose_says_which_robot_parameters_no_pose_set_separates(tmp_path):
    d = handeye.diagnose(_cell(tmp_path / "jo", "ur10e", ["joint_offsets=j2:0.05"], seed=8))
    said = dict(zip(d.absorbed_by, d.absorbed_explained))
    for param in ("joint_offsets.j1", "joint_offsets.j6", "link_lengths.d1", "link_lengths.d6"):
        assert "no choice of poses can separate it" in said[param], said[param]


def test_a_model_file_is_copied_into_the_simulated_dataset(tmp_path, monkeypatch):
    """simulate --robot FILE writes the file into the dataset (robot_model.toml), so the dataset
    loads from any working folder; a model file with an unknown key is named, exit 2."""
    text = (robots.ROBOTS_DIR / "ur10e.toml").read_text()
    (tmp_path / "arm.toml").write_text(text.replace('name = "UR10e"', 'name = "my arm"'))
    monkeypatch.chdir(tmp_path)
    api.simulate("sim", robot="arm.toml", n_poses=8, center="600,-300,100")
    monkeypatch.chdir("/")
    data = handeye.load_dataset(tmp_path / "sim")
    assert data.robot_model.name == "my arm" and (tmp_path / "sim" / "robot_model.toml").is_file()
    (tmp_path / "typo.toml").write_text(text.replace("alpha =", "alhpa ="))
    assert main(["simulate", "--out", str(tmp_path / "t"), "--robot", str(tmp_path / "typo.toml")]) == EXIT_BAD_INPUT


def test_simulate_names_a_parameter_given_twice(tmp_path, capsys):
    assert main(["simulate", "--out", str(tmp_path / "a"), "--robot", "ur10e", "--effect",
                 "link_lengths=a2:0.4,a2:0.1"]) == EXIT_BAD_INPUT
    assert "a2 given twice" in capsys.readouterr().err
    assert main(["simulate", "--out", str(tmp_path / "b"), "--robot", "ur10e", "--effect", "link_lengths=a7:0.1"]) \
        == EXIT_BAD_INPUT
    err = capsys.readouterr().err
    assert "a7 not a parameter of the UR10e; its parameters are d1, a2" in err and "--poses" not in err


def test_a_robot_error_the_centre_check_would_blame_is_named_beside_it(tmp_path):
    """A KR 60 HA's upper arm 0.4 mm long looks, to the centre model, like a centre taught off: the
    refusal (exit 2) names the robot's lengths as the other explanation when the joints are there,
    and a calibration with the centre free warns that the residuals have a robot effect's shape."""
    folder = _cell(tmp_path / "a", "kr60ha", ["link_lengths=j3_x:0.4"], seed=0)
    with pytest.raises(handeye.InputError, match="or the robot's own errors are: with link_lengths"):
        handeye.calibrate(folder)
    held = handeye.calibrate(folder, unknowns="sensor+sphere", effects="none")  # the centre free, no robot effect
    assert any("structure the model lacks: link_lengths" in w for w in held.warnings), held.warnings
    assert not held.converged and "link_lengths" in held.message  # and the search puts its pose elsewhere
    freed = handeye.calibrate(folder, unknowns="sensor+sphere")  # the model the search chooses
    assert freed.converged and [e.name for e in freed.effects][-1] == "link_lengths", freed.warnings
    fixed = handeye.calibrate(folder, effects="link_lengths")
    assert fixed.converged and abs(fixed.effects[0].parameters["j3_x"] - 0.4) < 3 * fixed.effects[0].std["j3_x"]


@pytest.mark.slow(sibling="test_a_robot_error_the_centre_check_would_blame_is_named_beside_it")
def test_joint_angles_on_a_positioner_cell_are_said_to_leave_the_robot_unmodelled(tmp_path):
    folder = tmp_path / "pos"
    api.simulate(folder, robot="kr60ha", sphere_mount="positioner", n_poses=12, effect=["link_lengths=j3_x:0.4"])
    d = handeye.diagnose(folder)
    assert "not modelled with the sphere on a positioner" in d.unexplained


def test_truth_names_robot_parameters_of_its_model(tmp_path):
    folder = _cell(tmp_path / "t", "ur10e", [], seed=1)
    setup = folder / "setup.toml"
    setup.write_text(setup.read_text() + "link_lengths = { zz = 0.4 }\n")
    with pytest.raises(handeye.InputError, match="zz is not a parameter of the UR10e"):
        handeye.load_dataset(folder)


def test_repeated_effect_options_add_up_and_a_repeat_is_named(tmp_path, capsys):
    made = api.simulate(tmp_path / "r", robot="ur10e", n_poses=6,
                        effect=["link_lengths=a2:0.3", "link_lengths=d4:0.2"])
    assert made.dataset.truth["link_lengths"] == {"a2": 0.3, "d4": 0.2}
    assert main(["simulate", "--out", str(tmp_path / "x"), "--robot", "ur10e", "--effect", "link_lengths=a2:0.3",
                 "--effect", "link_lengths=a2:0.1"]) == EXIT_BAD_INPUT
    assert "a2 given twice" in capsys.readouterr().err


def test_a_robot_effect_beside_the_radius_is_no_centre_correction(tmp_path):
    """The search named link_lengths with sphere_radius on an independent generator's UR10e cell, and the report's
    note on the radius's sd corrected the centres by every fitted effect, the robot's too: exit 3 (AttributeError).
    Only data effects correct the centres."""
    import types

    from handeye.app.engine import describe

    data = handeye.simulate(tmp_path / "c", robot="ur10e", profiles=True, seed=2).dataset
    mask = np.ones(len(data), bool)
    fit = types.SimpleNamespace(params={"link_lengths": np.zeros(3), "sphere_radius": np.array([0.01])})
    y, ids = describe._corrected_y(data, mask, fit, data.sphere_diameter / 2)
    only = types.SimpleNamespace(params={"sphere_radius": np.array([0.01])})
    np.testing.assert_array_equal(y, describe._corrected_y(data, mask, only, data.sphere_diameter / 2)[0])
    assert len(ids) == len(data)
