"""Every result type speaks one protocol: to_dict, to_json, summary, save, _repr_html_."""
import dataclasses
import json

import numpy as np
import pytest

import handeye
from handeye.app.present.protocol import ResultProtocol


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("protocol")
    sim = handeye.simulate(tmp / "sim", n_poses=12, profiles=True)
    cal = handeye.calibrate(sim.path, no_loo=True)
    saved = tmp / "cal.json"
    cal.save(saved)
    return {
        "calibration": cal,
        "closed form": handeye.calibrate("thesis-real", method="kim-cho"),
        "diagnosis": handeye.diagnose("thesis-sim"),
        "simulation": sim,
        "plan": handeye.plan(n=8),
        "export": handeye.export(saved, format="ur"),
        "cloud": handeye.cloud(sim.path, calibration=saved),
        "validation": handeye.validate(sim.path, calibration=saved),
    }


@pytest.mark.parametrize("kind", ["calibration", "closed form", "diagnosis", "simulation", "plan", "export", "cloud",
                                  "validation"])
def test_every_result_has_the_protocol(results, kind, tmp_path):
    res = results[kind]
    assert isinstance(res, ResultProtocol)
    as_dict = res.to_dict()
    assert isinstance(as_dict, dict) and as_dict
    assert json.loads(res.to_json()) == json.loads(json.dumps(as_dict, default=_plain))
    text = res.summary()
    assert isinstance(text, str) and text.strip()
    table = res._repr_html_()
    assert table.startswith("<table>") and "<tr>" in table and table.count("<tr>") <= 80
    res.save(tmp_path / "r.json")
    assert json.loads((tmp_path / "r.json").read_text()) == json.loads(res.to_json())


def _plain(value):
    if isinstance(value, np.generic):
        return value.item()
    if dataclasses.is_dataclass(value):
        return dataclasses.asdict(value)
    raise TypeError(type(value))


def test_the_result_is_made_of_typed_parts_and_keeps_its_flat_names():
    res = handeye.calibrate("thesis-sim", no_loo=True)
    from handeye.app.present.result_parts import EffectsRecord, FitRecord, ScreeningRecord, UncertaintyRecord

    assert isinstance(res.fit, FitRecord) and isinstance(res.uncertainty, UncertaintyRecord)
    assert isinstance(res.screening, ScreeningRecord) and isinstance(res.catalogue, EffectsRecord)
    assert res.rms_mm == res.fit.rms_mm and res.excluded is res.screening.excluded
    assert res.std is res.uncertainty.std and res.effect_tests is res.catalogue.tests
    assert res.to_dict()["global"] == res.global_check.to_dict()
    with pytest.raises(AttributeError, match="no_such"):
        res.no_such
    copy = dataclasses.replace(res, provenance={"x": 1})
    assert copy.rms_mm == res.rms_mm and copy.provenance == {"x": 1}


def test_public_functions_take_their_options_by_keyword():
    """The inputs (dataset, calibration) may be positional; every option is keyword-only."""
    import inspect

    for name in ("calibrate", "diagnose", "simulate", "plan", "export", "cloud", "validate"):
        params = inspect.signature(getattr(handeye, name)).parameters.values()
        positional = [p.name for p in params if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)]
        assert set(positional) <= {"dataset", "calibration", "out"} and len(positional) <= 2, (name, positional)


def test_a_checked_request_is_a_plain_record_bound_to_its_dataset():
    import pickle

    from handeye.app.engine import calibrate as engine
    from handeye.app.engine.request import CalibrationRequest

    sim, real = handeye.load_dataset("thesis-sim"), handeye.load_dataset("thesis-real")
    with pytest.raises(TypeError):
        CalibrationRequest(resolved="x")  # only checked() resolves a request
    with pytest.raises(ValueError, match="checked request"):
        engine.run(CalibrationRequest(), sim)
    request = CalibrationRequest(options={"max_iter": 50}, loo=False).checked(sim)
    assert pickle.loads(pickle.dumps(request)) == request  # to a worker and back
    request.solver_options["max_iter"] = 1  # a copy: the request stays as checked
    assert request.options == {"max_iter": 50} and request.method == "ipopt" and request.sigma == sim.noise_centre_mm
    with pytest.raises(ValueError, match="checked against"):
        engine.run(request, real)
    assert engine.run(request, sim).converged
