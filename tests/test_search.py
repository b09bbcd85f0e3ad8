"""calibrate is the search (app/engine/search.py): the model the data choose, or a refusal; the
user's model (--effects, --model measurement|points) checked, never changed; the cases the
search leaves to other checks said in a warning."""
import indep_mounts as im
import numpy as np
import pytest

import handeye
from handeye.app.command.cli import EXIT_NOT_CONVERGED, EXIT_OK, main
from handeye.app.engine import calibrate as engine
from handeye.app.engine import search
from handeye.model.chain.pose import transform_from_pose
from handeye.model.common.rotation import pose_distance, transform_distance
from handeye.model.fit import extended


@pytest.fixture(scope="module")
def scale_cell(tmp_path_factory):
    """A profiled cell whose sensor reads 0.2 % long: the plain model is wrong by many sd."""
    made = handeye.simulate(tmp_path_factory.mktemp("search") / "scale", seed=2, n_poses=20, profiles=True,
                            effect="sensor_scale=0.002")
    return made.path, transform_from_pose(made.dataset.truth["sensor_pose"])


def test_the_default_calibrates_the_model_the_search_chooses(scale_cell):
    folder, truth = scale_cell
    r = handeye.calibrate(folder, no_loo=True)
    assert r.converged and [e.name for e in r.effects] == ["sensor_scale"]
    assert r.warnings[0].startswith("the data choose the model with sensor_scale")
    dt, dr = transform_distance(r.sensor2flange, truth)
    assert dt < 0.15 and dr < 0.05
    said = handeye.diagnose(folder).against_calibrate
    assert said.startswith("the same pose as `handeye calibrate`'s: the search chose its model (sensor_scale)")
    assert "(0.00 sd of calibrate's)" in said  # the search's own fit: the same model on the same centres


@pytest.mark.parametrize("options", [["--effects", "none"], ["--model", "measurement"]])
def test_the_users_model_is_checked_not_changed(scale_cell, capsys, options):
    """--effects none and a profile residual model are the user's: refused where the search puts
    the pose beyond 1 sd, the advice naming what lets calibrate choose."""
    folder, _ = scale_cell
    assert main(["calibrate", str(folder), "--no-loo", *options]) == EXIT_NOT_CONVERGED
    out = capsys.readouterr().out
    assert "not a calibration: the discrepancy search (with sensor_scale)" in out
    assert ("calibrate without --effects" if options[0] == "--effects" else "calibrate --model centre") in out


def test_the_engine_reads_effects_none_as_the_users_model(scale_cell):
    data = handeye.load_dataset(scale_cell[0])
    assert not engine.calibrate(data, effects="none", loo=False).converged
    assert engine.calibrate(data, loo=False).converged


def test_a_score_is_of_the_requested_model(scale_cell):
    """The data's own calibration of a score is the requested model's: where the search replaces
    it, there is no verdict (not a verdict against a fit of another model)."""
    folder, truth = scale_cell
    scored = handeye.calibrate(folder, sensor_pose=handeye.calibrate(folder, no_loo=True, effects="none").sensor_pose,
                               no_loo=True)
    assert not scored.converged and scored.error.startswith("no verdict: the data's own calibration is refused")


def test_sign_flips_beside_an_effect_are_not_a_reason_to_refuse(tmp_path):
    """The search flips samples back, the fit with its effects excludes them: poses of one model are
    not compared (a 1-sd limit refused such cells at 1.0-1.3 sd)."""
    made = handeye.simulate(tmp_path / "f", seed=5, effect=["sphere_radius=0.2", "sign_flip=x-45,y+45"])
    r = handeye.calibrate(made.path, no_loo=True)
    assert r.converged and "sphere_radius" in [e.name for e in r.effects]


@pytest.mark.slow(sibling="test_the_default_calibrates_the_model_the_search_chooses")
def test_data_beyond_the_searchs_size_are_searched_on_a_spread_subsample(scale_cell, monkeypatch):
    """More samples than the search holds (its limit lowered to 14 of 20 here; 16,384 by default): the search
    runs on 14 spread over the rows, names the scale, and the fit with it runs on all 20 -- chunk by chunk,
    its sd and identifiability from the normal equations (the extended model's limit lowered to 16). Before,
    a 0.2 % scale of 30,000 samples exited 0 0.48 mm (200 sd) from the truth, "not checked by the search",
    and ``--effects`` on them stopped with a traceback."""
    folder, truth = scale_cell
    monkeypatch.setattr(search, "ROW_CHUNK", 14)
    whole = handeye.calibrate(folder, no_loo=True)  # the fit with the effect on the full arrays
    monkeypatch.setattr(extended, "ROW_CHUNK", 16)
    r = handeye.calibrate(folder, no_loo=True)
    assert r.converged and [e.name for e in r.effects] == ["sensor_scale"] and r.n_used == 20
    assert any(w.startswith("the discrepancy search ran on 14 of the 20 samples") for w in r.warnings)
    dt, dr = transform_distance(r.sensor2flange, truth)
    assert dt < 0.15 and dr < 0.05
    np.testing.assert_allclose(r.sensor2flange, whole.sensor2flange, atol=1e-6)  # the same fit, chunked
    for part in ("sensor_translation_mm", "sensor_rotation_deg"):
        np.testing.assert_allclose(getattr(r.uncertainty.std, part), getattr(whole.uncertainty.std, part), rtol=1e-6)
    ident = [x.identifiability for x in (r, whole)]
    np.testing.assert_allclose(ident[0].singular_values, ident[1].singular_values, rtol=1e-6)


def test_clean_data_keep_the_requested_model(tmp_path):
    made = handeye.simulate(tmp_path / "c", seed=1, n_poses=16, profiles=True)
    r = handeye.calibrate(made.path, no_loo=True)
    assert r.converged and not r.effects and r.model == "measurement"
    assert main(["calibrate", str(made.path), "--no-loo", "--effects", "none"]) == EXIT_OK
    dt, _ = transform_distance(r.sensor2flange, transform_from_pose(made.dataset.truth["sensor_pose"]))
    assert np.isfinite(dt) and dt < 0.2


@pytest.mark.parametrize("mount", ["eye_in_hand", "eye_to_hand"])
def test_a_scale_of_the_centres_three_coordinates_is_named_and_fitted(tmp_path, mount):
    """An independent generator's 0.5 % scale of the centres (x, y and z, as a 3-D sensor's): not a line
    scanner's ``sensor_scale``; before ``centre_scale`` was in the catalogue every such cell exited 0
    at 1.0-1.2 mm and 20-53 sd from the truth. Now the search names it and the pose is the truth's."""
    made = im.make(tmp_path / mount, mount, 1, effect="sensor_scale")
    r = handeye.calibrate(made["folder"], no_loo=True)
    assert r.converged and [e.name for e in r.effects] == ["centre_scale"]
    s, sd = r.effects[0].parameters["s"], r.effects[0].std["s"]
    assert abs(s - (im.SENSOR_SCALE - 1)) < 4 * sd
    dt, dr = transform_distance(r.sensor2flange, made["sensor"])
    assert dt < 0.25 and dr < 0.08


@pytest.fixture(scope="module")
def positioner_scale(tmp_path_factory):
    """A sphere on a positioner, the sensor reading 0.2 % long; the set-up axes exact (``held``) or
    off by the simulator's default error."""
    root = tmp_path_factory.mktemp("positioner")
    return {name: handeye.simulate(root / name, seed=4, sphere_mount="positioner", effect="sensor_scale=0.002", **extra)
            for name, extra in (("held", {"positioner_error": (0.0, 0.0)}), ("off", {}))}


def test_a_positioner_cell_is_searched_too(positioner_scale):
    """At exact set-up axes the search chooses the scale (before: exit 0 at 0.52 mm, 58 sd)."""
    made = positioner_scale["held"]
    r = handeye.calibrate(made.path, no_loo=True)
    assert r.converged and [e.name for e in r.effects] == ["sensor_scale"]
    dt, dr = transform_distance(r.sensor2flange, transform_from_pose(made.dataset.truth["sensor_pose"]))
    assert dt < 0.2 and dr < 0.08


@pytest.mark.slow(sibling="test_a_positioner_cell_is_searched_too")
def test_calibrated_axes_with_an_effect_beside_them_are_fitted_together(positioner_scale):
    """The search names the scale beside the calibrated axes; the cell stage fits it with them (before: exit 0 at
    0.66 mm, 42 sd; then refused): at the truth, the scale within 3 of its sd, the axes calibrated, the command
    that gives the same named."""
    made = positioner_scale["off"]
    r = handeye.calibrate(made.path, unknowns="sensor+positioner", no_loo=True)
    assert r.converged and [e.name for e in r.effects] == ["sensor_scale"] and r.positioner.calibrated
    (scale,) = r.effects
    assert abs(scale.parameters["s"] - 0.002) < 3 * scale.std["s"]
    assert "sensor_scale.s" in r.parameter_names and "e1_tilt1" in r.parameter_names
    truth = transform_from_pose(made.dataset.truth["sensor_pose"])
    assert pose_distance(r.sensor2flange, truth, r.covariance, r.parameter_names)["sd"] < 4
    assert "--unknowns sensor+positioner --effects sensor_scale" in r.warnings[0]  # the command that gives the same
