"""A CalibrationResult made of parts behaves as the flat record it replaced: pickling (joblib
workers return results), copies, attribute access and ``dir``."""
from __future__ import annotations

import copy
import pickle

import pytest
from conftest import simulate

from handeye.app.engine.calibrate import calibrate
from handeye.app.present.result_parts import FLAT
from handeye.model.datasets.dataset import load


@pytest.fixture(scope="module")
def result(tmp_path_factory):
    folder = simulate(tmp_path_factory.mktemp("sim") / "d", seed=3, n=12)
    return calibrate(load(folder), loo=False)


def test_pickle_round_trip_keeps_every_attribute(result):
    back = pickle.loads(pickle.dumps(result))
    assert back.to_json() == result.to_json()
    for name in FLAT:
        assert type(getattr(back, name)) is type(getattr(result, name)), name
    assert copy.deepcopy(result).to_json() == result.to_json()


def test_flat_attributes_are_listed_and_unknown_ones_raise(result):
    assert {"rms_mm", "excluded", "std", "effects"} <= set(dir(result))
    assert not hasattr(result, "no_such_field")
    assert not hasattr(result, "__array_interface__")  # numpy probes dunders: no recursion, no part lookup
    bare = object.__new__(type(result))  # as unpickling sees it before the state is set
    with pytest.raises(AttributeError):
        bare.rms_mm
