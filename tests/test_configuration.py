"""Robot configuration groups and the nominal-model gate (issue 39, item 4), on data handeye did not generate.

The data come from tests/indep_config.py (numpy only: an IRB 4600-like arm from the published URDF chain,
its own FK and IK; 32 poses, 8 of them with the wrist flipped; 0.03 mm noise).

(a) The generator checks itself: its FK at zero, a wrist flip reaches the same flange, its IK.
(b) Configuration groups (:mod:`handeye.model.robot.configuration`): from the joints and from ABB's cfx;
    a coincidence needs several excluded samples, most of them in one group, improbable by chance.
(c) The nominal gate (:mod:`handeye.model.robot.nominal_gate`): a constant flange turn of -0.35 deg (a
    controller's calibrated model) absorbed and said; a joint order or a sign slip refused, naming it.
(d) calibrate: a j5 zero offset (which a wrist flip reverses) makes the screening exclude the flipped
    poses; with joints the verdict names the group, keeps it with joint_offsets and exits 0 at the truth;
    with a cfx column and no joints it refuses naming the group; clean cells with both wrists are
    calibrated at the truth with nothing said (``slow``, as the rates over seeds (tests/config_rates.py; the
    README quotes 20 seeds per class)).
"""
import ast
import pathlib

import config_rates as cr
import indep_config as ic
import numpy as np
import pytest

import handeye
from handeye.model.common.rotation import transform_distance
from handeye.model.readers.tables import DatasetError
from handeye.model.robot import configuration, nominal_gate, robots


# ----------------------------------------------------------------------------- (a) the generator
def test_generator_is_independent_of_handeye():
    """tests/indep_config.py imports numpy and the standard library only."""
    tree = ast.parse(pathlib.Path(ic.__file__).read_text())
    names = {a.name.split(".")[0] for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
    names |= {n.module.split(".")[0] for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) and n.module}
    assert names <= {"__future__", "csv", "math", "pathlib", "numpy"}, names


def test_generator_kinematics():
    """Own FK at zero (the IRB 4600-60/2.05's 175 + 960 + 135 mm reach, 495 + 900 + 175 mm height, the
    flange's z forward), a flipped wrist reaches the same flange, IK back to the angles."""
    T = ic.forward(np.zeros(6))
    assert np.allclose(T[:3, 3], (1270.0, 0.0, 1570.0), atol=1e-9) and np.allclose(T[:3, 2], (1, 0, 0), atol=1e-12)
    q = np.array([10.0, 25.0, 5.0, 20.0, 50.0, -30.0])
    assert np.allclose(ic.forward(ic.flipped(q)), ic.forward(q), atol=1e-9) and ic.flipped(q)[4] == -50.0
    assert np.allclose(ic.inverse_kinematics(ic.forward(q), q + 3.0), q, atol=1e-6)
    assert np.allclose(handeye.model.robot.robots.load("irb4600").flange2base(q[None])[0], ic.forward(q), atol=1e-9)


# ----------------------------------------------------------------------------- (b) configuration groups
class _Data:
    def __init__(self, joints=None, cfx=None):
        self.joints, self.configuration = joints, cfx
        self.robot_model = robots.load("irb4600") if joints is not None else None


def test_groups_from_joints_and_from_cfx():
    """The wrist groups by the sign of j5 (from the joints, else from cfx bit 0); the 8 flipped of 32
    excluded coincide with their group; 3 excluded of which 2 flipped do not (chance)."""
    cell = ic.draw_cell(1)
    flip = cell["flip"]
    for data, label in ((_Data(cell["joints"]), "j5 < 0 (the wrist flipped)"),
                        (_Data(cfx=flip.astype(int)), "j5 < 0 (the wrist flipped, cfx bit 0)")):
        wrist = [g for g in configuration.groups(data) if g.kind == "wrist"]
        assert [g.label for g in wrist] == [label, wrist[1].label] and np.array_equal(wrist[0].members, flip)
        found = configuration.coinciding(data, flip, 0.01)
        assert found.group.label == label and found.shared == 8 and found.p < 1e-5
        assert found.said().startswith("the 8 excluded samples are the 8 with j5 < 0")
        few = np.zeros(32, bool)
        few[np.flatnonzero(flip)[:2]] = few[np.flatnonzero(~flip)[0]] = True
        assert configuration.coinciding(data, few, 0.01) is None
    assert configuration.groups(_Data()) == []


# ----------------------------------------------------------------------------- (c) the nominal gate
def test_a_constant_flange_turn_is_absorbed_and_said():
    """-0.35 deg about the flange's z between the reported poses and the nominal FK (the issue's IRB 4600):
    refused before at the 0.5 deg gate beside other differences; now absorbed into the model, said with
    its size, and the corrected model reproduces the reported poses."""
    cell = ic.draw_cell(2, n=12, flipped_n=4, flange_turn=-0.35)
    model = robots.check_reported(robots.load("irb4600"), cell["joints"], cell["reported"], "m.csv")
    assert "by a constant transform, 0.35 deg about (0.00, 0.00, -1.00) at the flange" in model.absorbed
    assert np.allclose(model.flange2base(cell["joints"]), cell["reported"], atol=1e-9)
    clean = ic.draw_cell(2, n=12, flipped_n=4)
    assert robots.check_reported(robots.load("irb4600"), clean["joints"], clean["reported"], "m.csv").absorbed == ""
    found = nominal_gate.constants(robots.load("irb4600").flange2base(cell["joints"]), cell["reported"])
    assert found.agrees() and np.isclose(np.degrees(np.arctan2(found.flange[1, 0], found.flange[0, 0])), -0.35)


def test_a_calibrated_controller_model_beyond_the_old_gate_is_absorbed():
    """The issue's case: the controller's model turns the flange -0.35 deg and has its own small zero
    offsets (j1 0.25, j2 0.05, j3 -0.05, j4 0.1, j5 0.05 deg): 7.4 mm / 0.59 deg from the nominal model
    (refused before at 5 mm / 0.5 deg); the constants at the flange and the base absorb most of it and
    what depends on the pose (0.46 mm / 0.075 deg) is within the gate."""
    cell = ic.draw_cell(2, n=12, flipped_n=4)
    turn = ic.transform(ic.rodrigues((0, 0, 1), -0.35), np.zeros(3))
    reported = np.array([ic.forward(q + (0.25, 0.05, -0.05, 0.1, 0.05, 0.0)) @ turn for q in cell["joints"]])
    nominal = robots.load("irb4600")
    dpos, dang = transform_distance(nominal.flange2base(cell["joints"]), reported)
    assert dpos.max() > 5.0 and dang.max() > 0.5  # beyond the old gate
    model = robots.check_reported(nominal, cell["joints"], reported, "m.csv")
    assert "0.36 deg about" in model.absorbed and "at the flange and 0.213 deg" in model.absorbed
    assert "up to 0.46 mm / 0.075 deg depend on the pose" in model.absorbed


@pytest.mark.parametrize("slip, said", [({"order": [0, 1, 2, 5, 4, 3]}, "read from the file's columns j1,j2,j3,j6,j5,j4"),
                                        ({"signs": [1, 1, 1, 1, -1, 1]}, "with the sign of j5 reversed")])
def test_a_joint_order_or_sign_slip_is_refused_naming_it(tmp_path, slip, said):
    """Joint columns in another order or with another sign leave pose-dependent differences no constant
    transform absorbs: exit 2, naming the reading under which the model agrees."""
    ic.make(tmp_path, 3, n=12, flipped_n=4, **slip)
    with pytest.raises(DatasetError, match="still depend on the pose") as err:
        handeye.load_dataset(tmp_path)
    assert said in str(err.value)


# ----------------------------------------------------------------------------- (d) calibrate
def test_a_wrist_flip_group_is_named_and_kept_with_joint_offsets(tmp_path):
    """A 0.4 deg j5 offset on narrow poses: the screening excludes the 8 flipped poses; the verdict says
    they are the 8 with the wrist flipped, keeps them with joint_offsets (j5 within 3 sd) and exits 0 at
    the truth. (Before: exit 1, "two calibrations".)"""
    out = cr.outcome("j5", 1, tmp_path)
    assert out["exit"] == 0 and out["at_truth"] and out["named"], out["text"]
    assert "the 8 samples the screening excluded first are the 8 with j5 < 0 (the wrist flipped)" in out["text"]


@pytest.mark.slow(sibling="test_a_wrist_flip_group_is_named_and_kept_with_joint_offsets")
def test_clean_cells_with_both_wrists_and_a_cfx_group_without_joints(tmp_path):
    """Clean cells with both wrists, joints given: exit 0 at the truth, nothing excluded or said. A j5
    offset without joints but with a cfx column: refused (exit 1), naming the group."""
    clean = cr.outcome("clean", 4, tmp_path / "clean")
    assert clean["exit"] == 0 and clean["at_truth"] and not clean["alarm"], clean["text"]
    grouped = cr.outcome("j5-cfx", 1, tmp_path / "cfx")
    assert grouped["exit"] == 1 and grouped["named"], grouped["text"]


@pytest.mark.slow(sibling="test_a_wrist_flip_group_is_named_and_kept_with_joint_offsets")
def test_configuration_rates_over_seeds(tmp_path):
    """Over 4 seeds per class (the README: 20): clean cells exit 0 at the truth with no alarm; j5 offsets
    with joints exit 0 at the truth naming the group; with a cfx column and no joints they are refused;
    a constant flange turn is absorbed and said at the truth; a joint order slip is named (exit 2)."""
    got = cr.rates(["clean", "j5", "j5-cfx", "turn", "order"], 4, tmp_path)
    assert got["clean"]["exit0_truth"] == 4 and got["clean"]["alarms"] == 0, got
    assert got["j5"]["exit0_truth"] == 4 and got["j5"]["named"] == 4, got
    assert got["j5-cfx"]["refused"] == 4 and got["j5-cfx"]["named"] == 4, got
    assert got["turn"]["exit0_truth"] == 4 and got["turn"]["named"] == 4, got
    assert got["order"]["exit2"] == 4 and got["order"]["named"] == 4, got


def test_a_wrist_flip_without_joints_or_cfx_is_never_an_exit_0(tmp_path):
    """A j5 offset with neither joints nor cfx: no group can be told. Seeds 4 and 14 (of 20) were the two where
    the "two calibrations" check did not fire (the excluded rows fit each other no better than 2 x the used
    ones) and calibrate exited 0 5.3 and 6.3 sd from the truth with residuals 11-12 x the stated 0.03 mm. The
    stated noise makes that misfit structure: exit 1, "unexplained structure"."""
    for seed in (4, 14):
        out = cr.outcome("j5-nojoints", seed, tmp_path / str(seed))
        assert out["exit"] == 1 and "unexplained structure" in out["text"], out["text"]
        assert "x the stated 0.03 mm" in out["text"], out["text"]
