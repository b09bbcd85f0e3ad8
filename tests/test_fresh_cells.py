"""Cells of a fresh independent generator (tests/indep_fresh.py: written by a helper from the README alone, its own
rotations, UR kinematics, circle fit and pose designs) that found what the other generators had not (2026-12-08).

Judged as tests/verdict_rates.py judges: an exit 0 is wrong beyond 3 reported sd in a component *and* beyond
0.2 mm / 0.05 deg from the truth."""
from __future__ import annotations

import json
import pathlib
import sys

import numpy as np
import pytest

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))

import indep_fresh  # noqa: E402
from verdict_rates import FAR_SD  # noqa: E402

import handeye  # noqa: E402
from handeye.model.common.rotation import rotvec_from_matrix  # noqa: E402


def _cell(tmp_path, cls, seed, legacy=False):
    out = str(tmp_path / f"{cls}-{seed}")
    truth = indep_fresh.generate(cls, seed, out, legacy_order=legacy)
    return out, truth


def _away(result, truth):
    """``(z per component, mm, deg)`` of the result's pose from the truth, in the result's chart and sd."""
    x, t = np.asarray(result.sensor2flange, float), np.asarray(truth["X"], float)
    shift = np.r_[t[:3, 3] - x[:3, 3], rotvec_from_matrix(x[:3, :3].T @ t[:3, :3])]
    sd = np.sqrt(np.diag(np.asarray(result.covariance, float))[:6])
    return shift / sd, float(np.linalg.norm(shift[:3])), float(np.degrees(np.linalg.norm(shift[3:])))


def test_a_link_length_taken_for_a_taught_centre_is_in_the_sd(tmp_path):
    """UR10e with joints, profiles, 30 poses on a grid at 0.13 mm of point noise, a2 0.58 mm long, the centre taught
    right: the search frees the centre (its offset absorbs the length error) and had exited 0 0.34 mm, 7 sd, from
    the truth. The robot's errors are now compared with a named centre too (robot_choice.compare): the length
    error explains the data about as well (BIC -0.7), at a pose 0.34 mm away, and the sd holds it (search.with_rivals)."""
    out, truth = _cell(tmp_path, "link_lengths", 4)
    r = handeye.calibrate(out, unknowns=truth["unknowns"])
    z, mm, deg = _away(r, truth)
    assert not (r.converged and np.max(np.abs(z)) > 3 and (mm > 0.2 or deg > 0.05)), (z, mm, deg)
    assert any(w.startswith("the robot's errors are not settled") for w in r.warnings), r.warnings


def test_samples_a_joint_offset_moves_are_no_gross_errors(tmp_path):
    """UR5e with joints, 17 poses in three orientations, 0.14 mm of point noise, j5 0.085 deg off: the five samples of
    one orientation were excluded as gross errors (F 129-244) and calibrate exited 0 3.4 sd (a component) from the
    truth. Kept as an alternative (configuration_group._many_excluded), the search names joint_offsets and every
    one passes the outlier test."""
    out, truth = _cell(tmp_path, "joint_offsets", 21)
    r = handeye.calibrate(out, unknowns=truth["unknowns"])
    z, mm, deg = _away(r, truth)
    assert r.converged and np.max(np.abs(z)) < 3, (z, mm, deg)
    assert "joint_offsets" in {e.name for e in r.effects or []} and not r.excluded, (r.effects, r.excluded)


@pytest.fixture(scope="module")
def radius_beside_lengths(tmp_path_factory):
    """UR10e, a3 0.59 mm short (the generator's first draw order): the search names link_lengths with
    sphere_radius."""
    out, truth = _cell(tmp_path_factory.mktemp("fresh"), "link_lengths", 6, legacy=True)
    return handeye.calibrate(out, unknowns=truth["unknowns"]), truth


def test_a_robot_effect_named_beside_the_radius_is_no_crash(radius_beside_lengths):
    """The report's note on the radius's sd corrected the centres by the robot effect too (exit 3,
    AttributeError); only data effects correct the centres."""
    r, _ = radius_beside_lengths
    assert {"link_lengths", "sphere_radius"} <= {e.name for e in r.effects or []}
    json.dumps(r.to_dict())  # every part of it reads


@pytest.mark.xfail(strict=True, reason="known: the radius named beside the true length error absorbs part of it; "
                                       "exit 0 0.34 mm, 3.9 sd in ty, from the truth (found 2026-12-08)")
def test_a_radius_named_beside_a_length_error_keeps_the_pose_within_its_sd(radius_beside_lengths):
    r, truth = radius_beside_lengths
    z, mm, deg = _away(r, truth)
    assert not (r.converged and np.max(np.abs(z)) > 3 and (mm > 0.2 or deg > 0.05)), (z, mm, deg)


#: cells per class of the slow test: the robot classes fewer (the generator's inverse kinematics of a UR takes ~20 s
#: a cell: 12 link-length cells were 278 s of the full suite's time; tests/test_robots_indep.py holds more robot cells)
CELLS = {"clean": 12, "diameter": 12, "taught": 12, "gross": 12, "joint_offsets": 4, "link_lengths": 3}


@pytest.mark.slow(sibling="test_a_link_length_taken_for_a_taught_centre_is_in_the_sd")
@pytest.mark.parametrize("cls", list(CELLS))
def test_no_exit_0_away_from_the_truth(tmp_path, cls):
    """Cells of each class (:data:`CELLS`): no exit 0 beyond :data:`verdict_rates.FAR_SD` (4.5 sd: no chance puts a
    right answer there) and the floor, at most two beyond 3 sd (a right sd crosses 3 in a component of 1.6 % of
    cells; the fresh generator's link_lengths seed 10 does, at 3.02 sd, 0.59 mm); clean: no exit but 0."""
    crossed = []
    for seed in range(CELLS[cls]):
        out, truth = _cell(tmp_path, cls, seed)
        try:
            r = handeye.calibrate(out, unknowns=truth["unknowns"])
        except handeye.InputError as exc:
            assert cls != "clean", f"seed {seed}: {exc}"
            continue
        assert r.converged or cls != "clean", (seed, r.message)
        if r.converged:
            z, mm, deg = _away(r, truth)
            floor = mm > 0.2 or deg > 0.05
            assert not (np.max(np.abs(z)) > FAR_SD and floor), (seed, z, mm, deg)
            crossed += [(seed, float(np.max(np.abs(z))), mm)] if np.max(np.abs(z)) > 3 and floor else []
    assert len(crossed) <= 2, crossed
