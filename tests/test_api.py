"""The public Python API: `import handeye`, the CLI's options as keywords, typed results whose
`to_dict()` is the CLI's JSON, every exit a complete result, one bad-input error class."""
import inspect
import json

import numpy as np
import pytest

import handeye
from handeye.app.command import cli
from handeye.app.common.errors import CalibrationInputError
from handeye.app.engine import calibrate as engine
from handeye.app.present.diagnosis_results import DiagnosisResult
from handeye.app.present.results import CalibrationResult
from handeye.app.public import api
from handeye.model.chain import conventions
from handeye.model.datasets import dataset, observations
from handeye.model.design import planning
from handeye.model.fit import classics, closed_form
from handeye.model.geometry import circle
from handeye.model.simulation import simulate


def _cli_json(capsys, *argv):
    code = cli.main(list(argv))
    out, err = capsys.readouterr()
    return code, json.loads(out), err


def _strip_timing(d):
    d = json.loads(json.dumps(d))
    if d.get("closed_form"):
        d["closed_form"].pop("time_ms")
    return d


def test_calibrate_matches_the_cli_json(capsys):
    r = handeye.calibrate("thesis-sim")
    assert isinstance(r, CalibrationResult) and r.sensor2flange.shape == (4, 4) and r.converged
    code, cli_json, _ = _cli_json(capsys, "calibrate", "thesis-sim", "--json")
    assert code == cli.EXIT_OK
    assert json.loads(json.dumps(r.to_dict())) == cli_json  # same keys, same values, JSON-serialisable


def test_closed_form_result_is_the_same_type_and_matches_the_cli(capsys):
    r = handeye.calibrate("thesis-real", method="kim-cho", unknowns="sensor+sphere")
    code, cli_json, _ = _cli_json(capsys, "calibrate", "--method", "kim-cho", "--unknowns", "sensor+sphere", "--json")
    # the baseline lies 1.8 mm / 0.71 deg from the data's own calibration, 31 of its sd: no calibration, exit 1
    assert code == cli.EXIT_NOT_CONVERGED and isinstance(r, CalibrationResult) and not r.converged
    assert _strip_timing(r.to_dict()) == _strip_timing(cli_json)
    ls = handeye.calibrate("thesis-sim", method="lm").to_dict()
    # one schema: the same keys, the dataset named the same way, status an int or None
    assert set(cli_json) == set(ls)
    assert cli_json["dataset"] == "thesis-real" and ls["dataset"] == "thesis-sim"
    assert cli_json["status"] is None and isinstance(ls["status"], int)
    assert cli_json["closed_form"]["least_squares_from_here"]["converged"] in (True, False)


def test_summary_is_the_cli_text(capsys):
    r = handeye.calibrate("thesis-sim", method="lm")
    assert cli.main(["calibrate", "thesis-sim", "--method", "lm"]) == cli.EXIT_OK
    assert capsys.readouterr().out.rstrip("\n") == r.summary()
    html = r._repr_html_()
    assert html.startswith("<table>") and "converged" in html and "sensor pose (kuka" in html


def test_keywords_are_the_cli_options_with_the_cli_defaults():
    parser = cli.build_parser()
    sub = next(a for a in parser._actions if a.dest == "command").choices
    cases = {"calibrate": api.calibrate, "diagnose": api.diagnose, "simulate": api.simulate, "plan": api.plan}
    for command, function in cases.items():
        params = inspect.signature(function).parameters
        for action in sub[command]._actions:
            if action.dest in ("help", "json"):
                continue
            assert action.dest in params, f"handeye {command} {action.option_strings}: no keyword {action.dest}"
            default = params[action.dest].default
            if default is not inspect.Parameter.empty:
                cli_default = action.default
                assert (list(default) if isinstance(default, tuple) else default) == cli_default, (command, action.dest)


def test_start_in_the_datasets_convention_as_text_or_numbers():
    kuka = handeye.calibrate("thesis-sim", method="lm", start="75,75,55,0.01,-90.1,0.01", no_loo=True)
    numbers = handeye.calibrate("thesis-sim", method="lm", start=(75, 75, 55, 0.01, -90.1, 0.01), no_loo=True)
    assert np.array_equal(kuka.start_pose, numbers.start_pose)
    ur_start = conventions.convert(kuka.start_pose, "kuka", "ur")
    ur = handeye.calibrate("thesis-sim", method="lm", start=ur_start, convention="ur", no_loo=True)
    assert np.allclose(ur.start_pose[:3], kuka.start_pose[:3])
    assert ur.convention == "ur" and ur.columns == ("x", "y", "z", "rx", "ry", "rz")
    assert np.allclose(ur.sensor_pose, conventions.pose_from("ur", ur.sensor2flange))
    assert np.allclose(ur.sensor2flange, kuka.sensor2flange, atol=1e-9)


def test_every_bad_input_is_an_input_error_and_nothing_else_is():
    for cls in (dataset.DatasetError, conventions.ConventionError, observations.ObservationError,
                simulate.SimulationError, circle.CircleFitError, closed_form.ClosedFormError,
                classics.MissingMotions, planning.PlanningError, CalibrationInputError):
        assert issubclass(cls, handeye.InputError) and issubclass(cls, ValueError), cls
    with pytest.raises(handeye.InputError, match="--alpha"):
        handeye.calibrate("thesis-sim", alpha=2)
    with pytest.raises(handeye.InputError, match="--max-iter"):
        handeye.calibrate("thesis-sim", max_iter=0)
    with pytest.raises(handeye.InputError, match="closed form"):
        handeye.calibrate("thesis-sim", method="kim-cho", start="1,2,3,4,5,6")
    with pytest.raises(handeye.InputError, match="options"):
        engine.calibrate(handeye.load_dataset("thesis-sim"), method="lm", options={"no_such_option": 1})
    with pytest.raises(handeye.InputError, match="no dataset folder"):
        handeye.load_dataset("no-such-dataset")


def test_cli_maps_exactly_input_errors_to_exit_2(capsys, monkeypatch):
    def bad_input(*args, **kwargs):
        raise handeye.InputError("a bad option")

    def bug(*args, **kwargs):
        raise ValueError("a bug that happens to be a ValueError")

    monkeypatch.setattr(api, "calibrate", bad_input)
    assert cli.main(["calibrate", "thesis-sim"]) == cli.EXIT_BAD_INPUT
    monkeypatch.setattr(api, "calibrate", bug)
    assert cli.main(["calibrate", "thesis-sim"]) == cli.EXIT_INTERNAL
    assert "internal error" in capsys.readouterr().err


def test_a_non_finite_solve_builds_the_complete_result_and_exits_1(capsys, break_solver):
    """The early exit of a numerical failure: same type, same keys, a report, exit 1 (not 3)."""
    complete = set(handeye.calibrate("thesis-sim", method="lm", no_loo=True, keep_all=True).to_dict())
    break_solver()
    r = handeye.calibrate("thesis-sim", method="lm", no_loo=True, keep_all=True)
    assert not r.converged and r.std is None and r.identifiability is None and r.rms_mm is None
    assert set(r.to_dict()) == complete
    json.dumps(r.to_dict())
    assert "NOT CONVERGED" in r.summary()
    assert cli.main(["calibrate", "thesis-sim", "--method", "lm", "--no-loo", "--keep-all"]) == cli.EXIT_NOT_CONVERGED


def test_diagnose_plan_and_simulate_from_python(tmp_path, capsys):
    sim = handeye.simulate(tmp_path / "sim", seed=2, n_poses=12, effect=["sensor_scale=0.002"])
    assert len(sim.ids) + len(sim.dropped) == 12 and sim.dataset.name == "sim"
    d = handeye.diagnose(sim.path)
    assert isinstance(d, DiagnosisResult)
    code, cli_json, _ = _cli_json(capsys, "diagnose", str(sim.path), "--json")
    assert code == cli.EXIT_OK and json.loads(json.dumps(d.to_dict())) == cli_json
    assert d.summary().startswith("handeye diagnose") and d._repr_html_().startswith("<table>")
    p = handeye.plan(n=6, out=tmp_path / "plan.csv")
    code, cli_json, _ = _cli_json(capsys, "plan", "--n", "6", "--json")
    assert json.loads(json.dumps(p.to_dict())) == cli_json
    ids, poses = dataset.read_pose_list(tmp_path / "plan.csv")
    assert ids == p.ids and np.allclose(poses, p.poses, atol=1e-4)


def test_out_writes_the_result_with_provenance(tmp_path):
    r = handeye.calibrate("thesis-sim", method="lm", no_loo=True, out=tmp_path / "r.json")
    saved = json.loads((tmp_path / "r.json").read_text())
    assert saved["provenance"]["options"]["method"] == "lm" and saved["provenance"]["dataset_sha256"] == r.dataset_sha256
    assert saved["sensor_matrix"] == r.to_dict()["sensor_matrix"]


def test_a_simulation_that_drops_every_pose_is_refused(tmp_path):
    with pytest.raises(handeye.InputError, match="every pose was dropped"):
        handeye.simulate(tmp_path / "none", n_poses=4, effect=["sensor_scale=1.002"])  # a 100 % scale error
    assert not (tmp_path / "none" / "measurements.csv").exists()


def test_output_paths_are_checked_before_the_work(tmp_path, capsys):
    missing = tmp_path / "no-such-folder" / "x.png"
    with pytest.raises(handeye.InputError, match="--plot"):
        handeye.calibrate("thesis-sim", plot=missing)
    assert cli.main(["calibrate", "thesis-sim", "--plot", str(missing)]) == cli.EXIT_BAD_INPUT
    assert cli.main(["calibrate", "thesis-sim", "--out", str(tmp_path)]) == cli.EXIT_BAD_INPUT  # a folder
    assert cli.main(["diagnose", "thesis-sim", "--plot", str(missing)]) == cli.EXIT_BAD_INPUT
    assert cli.main(["plan", "--out", str(missing)]) == cli.EXIT_BAD_INPUT
    assert "--plot" in capsys.readouterr().err


def test_arguments_of_the_wrong_kind_are_input_errors(tmp_path):
    for bad in (None, 123):
        with pytest.raises(handeye.InputError, match="dataset"):
            handeye.calibrate(bad)
    one = handeye.simulate(tmp_path / "one", n_poses=8, effect="sphere_center=0.1,0,0")  # one effect as a string
    assert one.effects and "sphere_center" in one.effects


def test_screening_never_speaks_of_a_negative_count():
    """With fewer samples than the screening's minimum, it keeps them all and says so sensibly."""
    from handeye.app.engine import robust
    from handeye.model.chain.pose import transform_from_pose

    d = handeye.load_dataset("thesis-real").subset(np.arange(31) < 3)
    s = robust.screen(d, "sensor", transform_from_pose(handeye.load_dataset("thesis-real").start_pose))
    assert s.inliers.sum() <= 3 and "-1" not in s.note


def test_more_bad_arguments_are_input_errors(tmp_path, capsys):
    """What a review found exiting 3 (or silently accepted): each is bad input now."""
    assert cli.main(["calibrate", "thesis-sim", "--convention", "ur", "--start=nan,0,0,0,0,0"]) == cli.EXIT_BAD_INPUT
    assert cli.main(["simulate", "--out", str(tmp_path / "s"), "--seed", "-1"]) == cli.EXIT_BAD_INPUT
    assert "finite" in capsys.readouterr().err
    with pytest.raises(handeye.InputError, match="--unknowns"):
        handeye.calibrate("thesis-sim", method="kim-cho", unknowns="sphere", keep_all=True)
    with pytest.raises(handeye.InputError, match="--start"):
        handeye.calibrate("thesis-sim", start=[1, 2, 3, "a", 5, 6])
    for kwargs in ({"seed": 1.5}, {"n_poses": "4"}, {"truth": [1, 2, "x", 0, 0, 0]}):
        with pytest.raises(handeye.InputError):
            handeye.simulate(tmp_path / "t", **kwargs)
    folder = tmp_path / "listconv"
    handeye.simulate(folder, n_poses=8)
    setup = (folder / "setup.toml").read_text()
    (folder / "setup.toml").write_text('[robot]\nconvention = ["kuka"]\n' + setup)
    with pytest.raises(handeye.InputError, match="convention"):
        handeye.load_dataset(folder)


def test_a_non_finite_solve_in_another_convention_and_its_plot(tmp_path, break_solver):
    break_solver()
    r = handeye.calibrate("thesis-sim", method="lm", no_loo=True, keep_all=True, convention="abb",
                          plot=tmp_path / "p.png")
    assert len(r.sensor_pose) == len(r.columns) == 7 and r.n_used == len(r.residuals)
    assert (tmp_path / "p.png").stat().st_size > 0


def test_the_sphere_centre_is_optional_when_it_is_an_unknown(tmp_path, capsys):
    sim = handeye.simulate(tmp_path / "c", seed=4, n_poses=20, center="900,150,400", diameter=50.8)
    setup = sim.path / "setup.toml"
    setup.write_text("\n".join(line for line in setup.read_text().splitlines() if not line.startswith("center")) + "\n")
    assert handeye.load_dataset(sim.path).sphere_centre is None
    with pytest.raises(handeye.InputError, match=r"\[sphere\] center.*sensor\+sphere"):
        handeye.calibrate(sim.path)
    r = handeye.calibrate(sim.path, unknowns="sensor+sphere", no_loo=True)
    assert r.converged and np.linalg.norm(r.sphere_centre - [900, 150, 400]) < 0.5
    assert any("no sphere centre" in w for w in r.warnings)
    k = handeye.calibrate(sim.path, unknowns="sensor+sphere", method="kim-cho")
    assert np.linalg.norm(k.sphere_centre - [900, 150, 400]) < 1.0
    assert cli.main(["diagnose", str(sim.path)]) == cli.EXIT_BAD_INPUT
