"""calibrate and diagnose talk: calibrate tests its fit against the stated noise and the catalogue,
points to diagnose, and calibrates with the effects diagnose names; diagnose decides sign flips by
a proper test and reports the pose in the dataset's convention with its uncertainty."""
import json

import numpy as np
import pytest

import handeye
from handeye.app.command import cli
from handeye.model.chain.pose import transform_from_pose
from handeye.model.common.rotation import rotvec_from_matrix


def _errors_in_sd(r, truth):
    e = np.concatenate([r.sensor2flange[:3, 3] - truth[:3, 3],
                        np.degrees(rotvec_from_matrix(truth[:3, :3].T @ r.sensor2flange[:3, :3]))])
    return np.abs(e) / np.concatenate([r.std.sensor_translation_mm, r.std.sensor_rotation_deg])


@pytest.mark.slow(sibling="test_screening_with_effects_keeps_clean_samples_and_excludes_a_gross_error")
def test_a_hidden_scale_error_warns_is_named_and_is_calibrated(tmp_path):
    s = handeye.simulate(tmp_path / "scale", seed=11, effect="sensor_scale=0.002")
    truth = transform_from_pose(s.dataset.truth["sensor_pose"])
    plain = handeye.calibrate(s.path, no_loo=True, effects="none")
    assert _errors_in_sd(plain, truth).max() > 10  # the plain model is wrong by many of its own sd ...
    assert not plain.converged and "sensor_scale" in plain.message  # ... and refused: the search names the scale
    d = handeye.diagnose(s.path)
    assert [e.name for e in d.effects] == ["sensor_scale"]
    chosen = handeye.calibrate(s.path, no_loo=True)  # without --effects: the model the search chooses
    assert chosen.converged and [e.name for e in chosen.effects] == ["sensor_scale"]
    assert _errors_in_sd(chosen, truth).max() < 4 and chosen.warnings[0].startswith("the data choose the model")
    assert "within 1 sd" in d.against_calibrate
    r = handeye.calibrate(s.path, no_loo=True, effects="sensor_scale")
    (scale,) = r.effects
    assert scale.name == "sensor_scale" and abs(scale.parameters["s"] - 0.002) < 4 * scale.std["s"]
    assert _errors_in_sd(r, truth).max() < 4 and r.noise_test.passed
    assert not any("structure" in w for w in r.warnings)
    assert r.to_dict()["effects"][0]["name"] == "sensor_scale"


def test_the_noise_test_against_the_stated_noise(tmp_path):
    clean = handeye.calibrate("thesis-sim", no_loo=True)
    assert clean.noise_test is None or clean.noise_test.passed
    real = handeye.calibrate("thesis-real", no_loo=True)
    assert not real.noise_test.passed and real.noise_test.ratio > 5
    assert any("assumed noise" in w and "handeye diagnose" in w for w in real.warnings)
    loose = handeye.calibrate("thesis-real", no_loo=True, sigma=5.0)  # a user who states 5 mm
    assert loose.noise_test.passed and loose.noise_test.nominal.startswith("5 mm")
    s = handeye.simulate(tmp_path / "n", seed=3, n_poses=20)
    setup = s.path / "setup.toml"
    setup.write_text(setup.read_text() + "\n[noise]\ncentre_mm = 0.001\n")
    tight = handeye.calibrate(s.path, no_loo=True)
    assert not tight.noise_test.passed and "0.001 mm" in tight.noise_test.nominal


def test_effects_are_checked():
    with pytest.raises(handeye.InputError, match="--effects"):
        handeye.calibrate("thesis-sim", effects="base_frame")
    with pytest.raises(handeye.InputError, match="centre residual"):
        handeye.calibrate("thesis-sim", effects="sensor_scale", model="measurement")


@pytest.mark.parametrize("component_sd", [2.5, 3.0])
def test_a_sign_flip_with_an_ordinary_large_component_is_named(tmp_path, component_sd):
    s = handeye.simulate(tmp_path / "f", seed=21)
    ref = handeye.calibrate(s.path, no_loo=True, keep_all=True)
    sigma = ref.sigma_mm
    csv = s.path / "measurements.csv"
    lines = csv.read_text().splitlines()
    k = 7  # the eighth sample: a large but ordinary noise component along the base x axis, then its y flipped
    cells = lines[k + 1].split(",")
    f2b = transform_from_pose([float(v) for v in cells[1:7]])
    r12 = f2b[:3, :3] @ ref.sensor2flange[:3, :3]
    residual = np.array(ref.residuals[k].vector)
    wanted = np.array([component_sd * sigma, residual[1], residual[2]])
    xs = np.array([float(v) for v in cells[7:10]]) + r12.T @ (wanted - residual)
    xs[1] = -xs[1]
    cells[7:10] = [repr(float(v)) for v in xs]
    lines[k + 1] = ",".join(cells)
    csv.write_text("\n".join(lines) + "\n")
    d = handeye.diagnose(s.path)
    flips = [e for e in d.effects if e.name == "sign_flip"]
    assert flips and flips[0].parameters["ids"] == [cells[0]], d.summary()
    assert cells[0] not in d.outliers


def test_diagnose_reports_the_pose_in_the_datasets_convention_and_saves(tmp_path, capsys):
    s = handeye.simulate(tmp_path / "ur", seed=2, convention="ur", n_poses=20)
    out = tmp_path / "d.json"
    assert cli.main(["diagnose", str(s.path), "--sigma", "0.03", "--out", str(out), "--json"]) == cli.EXIT_OK
    saved = json.loads(out.read_text())
    assert saved["sensor_pose_as"]["convention"] == "ur" and len(saved["sensor_pose_as"]["pose"]) == 6
    assert saved["nominal_sigma_mm"] == 0.03 and saved["provenance"]["options"]["sigma"] == 0.03
    assert all(v > 0 for v in saved["std"]["sensor_translation_mm"])
    text = handeye.diagnose("thesis-real").summary()
    assert "base_frame: not measurable here" in text and "1 sd: translation mm" in text


def _shift_x(path, index, mm):
    """Shift the flange x of measurement ``index`` by ``mm``: a planted gross error."""
    lines = (path / "measurements.csv").read_text().splitlines()
    cells = lines[index + 1].split(",")
    cells[1] = repr(float(cells[1]) + mm)
    lines[index + 1] = ",".join(cells)
    (path / "measurements.csv").write_text("\n".join(lines) + "\n")


def test_screening_with_effects_keeps_clean_samples_and_excludes_a_gross_error(tmp_path, capsys):
    """With --effects the outlier tests judge samples against the model with the effects: the
    plain centre model lacks the scale, and screening on it excluded 3 of 36 clean samples."""
    s = handeye.simulate(tmp_path / "my cell", seed=4, effect="sensor_scale=0.003")
    r = handeye.calibrate(s.path, no_loo=True, effects="sensor_scale")
    (scale,) = r.effects
    assert r.n_used == 36 and not r.excluded
    assert abs(scale.parameters["s"] - 0.003) < scale.std["s"]
    assert cli.main(["calibrate", str(s.path), "--effects", "sensor_scale"]) == cli.EXIT_OK
    capsys.readouterr()
    _shift_x(s.path, 14, 5.0)
    r = handeye.calibrate(s.path, no_loo=True, effects="sensor_scale")
    assert r.n_used == 35 and [e.id for e in r.excluded] == [s.dataset.ids[14]]
    assert abs(r.effects[0].parameters["s"] - 0.003) < 2 * r.effects[0].std["s"]
    assert cli.main(["calibrate", str(s.path), "--effects", "sensor_scale"]) == cli.EXIT_OK


def test_screening_without_effects_is_unchanged(tmp_path):
    """The model held as asked (--effects none) screens on the plain centre model, as before (the
    same 3 exclusions) and is refused: the search adds the scale. The default path calibrates
    with the scale the search chooses, and keeps the 36 clean samples."""
    s = handeye.simulate(tmp_path / "my cell", seed=4, effect="sensor_scale=0.003")
    r = handeye.calibrate(s.path, no_loo=True, effects="none")
    assert r.n_used == 33 and len(r.excluded) == 3
    assert not r.converged and "sensor_scale" in r.message
    chosen = handeye.calibrate(s.path, no_loo=True)
    assert chosen.converged and [e.name for e in chosen.effects] == ["sensor_scale"] and chosen.n_used == 36
