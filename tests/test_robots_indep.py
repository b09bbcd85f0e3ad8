"""handeye's robot kinematics and its ``joint_offsets`` effect, against data it did not generate.

The data come from tests/indep_robots.py (numpy only, its own forward kinematics from the robots' published
data: the KR 60 HA URDF of ROS-Industrial, Universal Robots' DH parameters; its own inverse kinematics).

(a) The generator checks itself, with nothing from handeye: its FK at known configurations, its rotations,
    its IK, the chain closing at the truth, the sphere in the sensor's range at every pose.
(b) handeye loads the datasets (its own nominal FK of j1..j6 must reproduce the reported poses; here also
    compared directly, to 1e-6 mm), and ``handeye.diagnose`` names ``joint_offsets`` with the hidden offsets
    of joints 2-5 within 3 sd, the fit ending at the noise level; on clean data it names nothing.
(c) ``slow``: over 100 clean datasets the false-positive rate of naming ``joint_offsets`` (<= 10 %), and over
    40 datasets with offsets how often exactly the offset joints are named and the values' 3-sd coverage.
"""
import ast
import pathlib

import indep_robots as ir
import numpy as np
import pytest

import handeye

IDENTIFIABLE = ("j2", "j3", "j4", "j5")


# ----------------------------------------------------------------------------- (a) the generator itself
def test_generator_is_independent_of_handeye():
    """tests/indep_robots.py imports numpy and the standard library only."""
    tree = ast.parse(pathlib.Path(ir.__file__).read_text())
    names = {a.name.split(".")[0] for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
    names |= {n.module.split(".")[0] for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) and n.module}
    assert names <= {"__future__", "csv", "math", "pathlib", "tomllib", "numpy"}, names


@pytest.mark.parametrize("model, joints, position, z_axis", [
    ("kr60ha", (0, 0, 0, 0, 0, 0), (2190.0, 0.0, 960.0), (1, 0, 0)),      # stretched out: flange z along +x
    ("kr60ha", (0, -90, 90, 0, 0, 0), (1340.0, 0.0, 1810.0), (1, 0, 0)),  # KUKA home
    ("kr60ha", (0, -90, 90, 0, 90, 0), (1340.0 - 170.0, 0.0, 1810.0 - 170.0), (0, 0, -1)),  # looking down
    ("ur10e", (0, 0, 0, 0, 0, 0), (-1184.25, -290.7, 60.85), (0, -1, 0)),
    ("ur5e", (0, 0, 0, 0, 0, 0), (-817.2, -232.9, 62.8), (0, -1, 0)),
])
def test_forward_kinematics_at_known_configurations(model, joints, position, z_axis):
    """Own FK: the published zero and home positions (mm) and the flange's z axis."""
    T = ir.forward(model, joints)
    assert np.allclose(T[:3, 3], position, atol=1e-9)
    assert np.allclose(T[:3, 2], z_axis, atol=1e-12)
    assert np.allclose(T[:3, :3].T @ T[:3, :3], np.eye(3), atol=1e-12)


def test_kuka_a1_turns_clockwise_seen_from_above():
    """KUKA's A1 is positive clockwise from above (the URDF's axis is -z): A1 = 90 puts the arm at -y."""
    assert np.allclose(ir.forward("kr60ha", (90, 0, 0, 0, 0, 0))[:3, 3], (0.0, -2190.0, 960.0), atol=1e-9)


def test_rotation_helpers_round_trip():
    """Rotation vectors (also at 180 deg) and KUKA angles back to the matrices they came from."""
    rng = np.random.default_rng(3)
    for _ in range(200):
        R = ir.rodrigues(rng.normal(size=3), rng.uniform(-180, 180))
        w = ir.rotation_vector(R)
        assert np.allclose(ir.rodrigues(w, np.degrees(np.linalg.norm(w))), R, atol=1e-9)
        a, b, c = ir.kuka_angles(R)
        assert np.allclose(ir.rot_z(a) @ ir.rot_y(b) @ ir.rot_x(c), R, atol=1e-12)
    for axis in ((1, 0, 0), (0, 1, 1), (1, -2, 3)):
        R = ir.rodrigues(axis, 180.0)
        w = ir.rotation_vector(R)
        assert np.isclose(np.linalg.norm(w), np.pi) and np.allclose(ir.rodrigues(w, 180.0), R, atol=1e-9)


@pytest.mark.parametrize("model", ir.MODELS)
def test_inverse_kinematics_reaches_its_target(model):
    """Own IK: from the working configuration to a pose 20 deg and 100 mm away, to 1e-6 mm."""
    target = ir.forward(model, np.add(ir.WORKING[model], (10, -8, 12, 15, -10, 20)))
    q = ir.inverse_kinematics(model, target, ir.WORKING[model])
    assert q is not None
    assert np.allclose(ir.forward(model, q), target, atol=1e-6)


@pytest.mark.parametrize("model", ir.MODELS)
def test_chain_closes_at_the_truth_and_the_sensor_sees_the_sphere(tmp_path, model):
    """F(q + delta) X p = c to the noise; the reported F(q) misses by the offsets; files read back."""
    truth = ir.make(tmp_path / model, model, seed=5, n=30, offsets={"j2": 0.05, "j3": -0.03}, noise=0.02)
    true_chain = ir.chain_residuals(truth)
    assert np.sqrt(np.mean(true_chain**2)) == pytest.approx(0.02, rel=0.3)
    assert np.sqrt(np.mean(ir.chain_residuals(truth, true_robot=False) ** 2)) > 0.1
    p = truth["points"]
    assert np.all(np.abs(p[:, :2]) < 40) and np.all((p[:, 2] > 180) & (p[:, 2] < 300))
    assert np.ptp(truth["joints"][:, 1:5], axis=0).min() > 15.0  # joints 2-5 move: the offsets show
    back = ir.read(tmp_path / model)
    assert back["setup"]["robot"] == {"convention": ir.CONVENTION[model], "model": model}
    assert np.allclose(back["joints"], truth["joints"]) and np.allclose(back["xs"], truth["measured"])
    flanges = [ir.pose_row(F, ir.CONVENTION[model]) for F in truth["flanges"]]
    assert np.allclose(back["poses"], flanges)


# ----------------------------------------------------------------------------- (b) handeye on these data
@pytest.mark.parametrize("model, convention", [("kr60ha", None), ("ur5e", None), ("ur10e", None),
                                               ("ur10e", "kuka")])
def test_handeye_loads_and_its_nominal_kinematics_agree(tmp_path, model, convention):
    """handeye accepts the datasets (its FK of j1..j6 = the reported poses within 5 mm / 0.5 deg) and its
    nominal FK equals this generator's to 1e-6 mm over the whole joint space."""
    truth = ir.make(tmp_path / model, model, seed=2, n=20, convention=convention)
    data = handeye.load_dataset(tmp_path / model)
    assert np.allclose(data.joints, truth["joints"])
    from handeye.model import robots  # the kinematics under test (not public API; the load above is)

    q = np.random.default_rng(0).uniform(-180, 180, (500, 6))
    theirs = robots.load(model).flange2base(q)
    ours = np.array([ir.forward(model, row) for row in q])
    assert np.abs(theirs[:, :3, 3] - ours[:, :3, 3]).max() < 1e-6
    assert np.abs(theirs[:, :3, :3] - ours[:, :3, :3]).max() < 1e-12


def joint_offsets(result):
    """The ``joint_offsets`` effect of a diagnosis, or None."""
    return next((e for e in result.effects if e.name == "joint_offsets"), None)


@pytest.mark.parametrize("model, offsets", [
    ("kr60ha", {"j2": 0.05, "j3": -0.03, "j5": 0.02}),
    ("ur10e", {"j2": 0.02, "j3": 0.04, "j4": -0.1}),
])
def test_diagnose_names_joint_offsets_within_3_sd(tmp_path, model, offsets):
    """Hidden offsets on joints 2-5: ``joint_offsets`` named, every estimated joint within 3 sd of the
    truth (0 where none is hidden), j1 and j6 masked, chi2/dof after < 2."""
    ir.make(tmp_path / model, model, seed=11, offsets=offsets, noise=0.02)
    result = handeye.diagnose(tmp_path / model)
    effect = joint_offsets(result)
    assert effect is not None, [e.name for e in result.effects]
    assert set(effect.parameters) <= set(IDENTIFIABLE) and set(offsets) <= set(effect.parameters)
    for name, value in effect.parameters.items():
        assert abs(value - offsets.get(name, 0.0)) < 3 * effect.std[name], (name, value, effect.std[name])
    assert result.chi2_dof_after < 2.0


def test_diagnose_names_nothing_on_clean_data(tmp_path):
    """No offsets hidden: no ``joint_offsets`` (nor anything else) named."""
    ir.make(tmp_path / "clean", "kr60ha", seed=1000, noise=0.02)
    result = handeye.diagnose(tmp_path / "clean")
    assert joint_offsets(result) is None, [(e.name, e.parameters) for e in result.effects]


# ----------------------------------------------------------------------------- (c) the rates
def _draw_offsets(rng):
    """1-3 of joints 2-5, each off by 0.02-0.1 deg with a random sign."""
    joints = rng.choice(IDENTIFIABLE, size=rng.integers(1, 4), replace=False)
    return {str(j): float(rng.choice([-1.0, 1.0]) * rng.uniform(0.02, 0.1)) for j in joints}


def _score_offsets(result, offsets):
    """(exactly the offset joints are named beyond 3 sd, values within 3 sd, values estimated)."""
    effect = joint_offsets(result)
    if effect is None:
        return False, 0, len(offsets)
    named = {k for k, v in effect.parameters.items() if abs(v) > 3 * effect.std[k]}
    inside = sum(abs(v - offsets.get(k, 0.0)) < 3 * effect.std[k] for k, v in effect.parameters.items())
    return named == set(offsets), inside, len(effect.parameters)


@pytest.mark.slow(sibling="test_diagnose_names_nothing_on_clean_data")
def test_joint_offset_rates_over_seeds(tmp_path):
    """100 clean datasets (50 per robot): joint_offsets named in <= 10 %; 40 with offsets (20 per robot):
    exactly the offset joints named in >= 90 %, >= 95 % of the values within 3 sd."""
    false_positives = clean = 0
    for model in ("kr60ha", "ur10e"):
        for seed in range(50):
            ir.make(tmp_path / f"c-{model}-{seed}", model, seed=1000 + seed)
            false_positives += joint_offsets(handeye.diagnose(tmp_path / f"c-{model}-{seed}")) is not None
            clean += 1
    rng = np.random.default_rng(7)
    right = inside = estimated = runs = 0
    for model in ("kr60ha", "ur10e"):
        for seed in range(20):
            offsets = _draw_offsets(rng)
            ir.make(tmp_path / f"o-{model}-{seed}", model, seed=2000 + seed, offsets=offsets)
            ok, k, m = _score_offsets(handeye.diagnose(tmp_path / f"o-{model}-{seed}"), offsets)
            right, inside, estimated, runs = right + ok, inside + k, estimated + m, runs + 1
    print(f"\njoint_offsets false positives {false_positives}/{clean}; right joints named {right}/{runs}; "
          f"values within 3 sd {inside}/{estimated}")
    assert false_positives <= 0.10 * clean
    assert right >= 0.90 * runs
    assert inside >= 0.95 * estimated
