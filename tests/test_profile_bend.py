"""A sensor's depth linearity measured from the profiles' shape (model/geometry/profile_bend.py, app/engine/bend.py).

The bends here are written by the tests themselves (a cubic in depth, not ``simulate``'s sine), added to the
clean profiles of simulated cells; ``simulate --linearity`` (its sine) is the second, independent shape."""
import tomllib

import numpy as np
import pytest

import handeye
from handeye.app.outputs.verdict import shorten
from handeye.model.chain.pose import transform_from_pose
from handeye.model.common.rotation import pose_distance
from handeye.model.datasets import dataset
from handeye.model.geometry import profile_bend


def _cubic(z, size_mm, lo=190.0, hi=270.0):
    """A bend of ``size_mm`` peak to peak over lo..hi: a cubic, neither the sine of ``simulate`` nor a Legendre term."""
    u = (np.asarray(z, float) - lo) / (hi - lo)
    shape = u**3 - 0.4 * u
    grid = np.linspace(0, 1, 201) ** 3 - 0.4 * np.linspace(0, 1, 201)
    return size_mm * shape / (grid.max() - grid.min())


@pytest.fixture(scope="module")
def clean_cell(tmp_path_factory):
    folder = tmp_path_factory.mktemp("bend") / "cell"
    handeye.simulate(out=folder, profiles=True, seed=5, no_start=True)
    return folder


def test_a_written_bend_is_recovered_within_its_sd(clean_cell):
    ds = dataset.load(clean_cell)
    assert ds.bend is not None and not ds.bend.applied  # clean profiles: nothing to correct
    bent = [np.column_stack([p[:, 0], p[:, 1] + _cubic(p[:, 1], 0.08)]) for p in ds.profiles]
    bend = profile_bend.estimate(bent, ds.sphere_diameter / 2, ds.side)
    assert bend.applied and bend.p_value < profile_bend.ALPHA
    z = np.concatenate([p[:, 1] for p in bent])
    grid = np.linspace(np.percentile(z, 5), np.percentile(z, 95), 25)  # where the profiles lie
    truth = _cubic(grid, 0.08) - np.mean(_cubic(z, 0.08))
    sd = bend.correction_sd(grid)
    error = bend.correction(grid) - truth
    assert np.max(np.abs(error)) < 0.01, error  # a tenth of a 0.08 mm bend
    assert np.max(np.abs(error) / np.maximum(sd, 1e-4)) < 5, (error, sd)
    # the correction undoes it: corrected profiles are circles again (their fit's F against a bend is noise)
    again = profile_bend.estimate([bend.corrected(p) for p in bent], ds.sphere_diameter / 2, ds.side)
    assert not again.applied, again.to_dict()


@pytest.mark.parametrize("seed", range(4))
def test_clean_profiles_are_never_corrected(tmp_path, seed):
    folder = tmp_path / "cell"
    handeye.simulate(out=folder, profiles=True, seed=100 + seed, n_poses=12, motions="about-sphere")
    bend = dataset.load(folder).bend
    assert bend is not None and not bend.applied, bend.to_dict()


def test_a_steep_bend_is_not_a_linearity(clean_cell):
    """Few profiles of a small sphere can trade a bend against the circles (a real 1-inch ball: 5 mm over 34 mm
    of depth): beyond MAX_SLOPE the bend is reported, never applied."""
    ds = dataset.load(clean_cell)
    bent = [np.column_stack([p[:, 0], p[:, 1] + 0.1 * (p[:, 1] - 230.0)]) for p in ds.profiles]  # a 10 % slope
    bend = profile_bend.estimate(bent, ds.sphere_diameter / 2, ds.side)
    assert bend.slope > profile_bend.MAX_SLOPE and not bend.applied


def _away(folder, r):
    truth = transform_from_pose(tomllib.loads((folder / "setup.toml").read_text())["truth"]["sensor_pose"])
    return pose_distance(truth, np.asarray(r.sensor2flange, float), r.covariance, r.parameter_names)


def test_simulated_linearity_is_corrected_and_said(tmp_path, monkeypatch):
    """``simulate --linearity 0.0016`` (the data sheet's): uncorrected the pose lay 2.1 mm from the truth; the
    correction takes at least four fifths of that away, and the result says what it did."""
    folder = tmp_path / "cell"
    handeye.simulate(out=folder, profiles=True, linearity=0.0016, seed=0, no_start=True)
    r = handeye.calibrate(folder)
    assert r.converged
    note = [w for w in r.warnings if "bend" in w and "along the sensor's depth" in w]
    assert len(note) == 1 and "moved the pose by" in note[0], r.warnings
    # what an export's header keeps of it (verdict.shorten: the first clauses within 160 characters) says it all
    assert "corrected" in shorten(note[0]) and "moved the pose by" in shorten(note[0]), shorten(note[0])
    assert r.cleaning["bend"]["applied"] and r.cleaning["bend"]["degree"] >= 2
    monkeypatch.setattr(profile_bend, "MIN_BEND_MM", np.inf)  # the same data, the bend left in
    plain = handeye.calibrate(folder)
    assert not any("every profile was corrected" in w for w in plain.warnings)
    suggested = [w for w in plain.warnings if "an uncorrected" in w and "depth bend" in w]  # its move is in the sd
    assert len(suggested) == 1 and "would move the pose" in shorten(suggested[0]), suggested
    assert _away(folder, r)["translation_mm"] < 0.2 * _away(folder, plain)["translation_mm"]
