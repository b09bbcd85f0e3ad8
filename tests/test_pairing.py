"""Pairing shifts (issue 39): each pose paired with its neighbour's measurement is a setup slip that
calibrate and diagnose name (exit 2, app/engine/slips.py), and "explains nothing" is measured on the
motion the sensor sees for every mount (app/engine/guarantee.py, motion_seen).

The cells come from tests/indep_pairing.py, an independent generator (smooth tours and shuffled orders,
the three mounts, centres given or profiles): a shifted cell must never exit 0 away from the truth (more
than 3 reported sd *and* more than 0.2 mm / 0.05 deg); the same cells unshifted exit 0 at the truth.
"""
from __future__ import annotations

import ast
import math
import pathlib

import indep_mounts as im
import indep_pairing as ip
import numpy as np
import pytest
import shards as sh

import handeye
from handeye.app.command import cli
from handeye.app.common.errors import InputError
from handeye.app.engine import guarantee
from handeye.model.datasets.dataset import load
from handeye.model.fit import global_fit

#: "away from the truth": beyond this many reported sd, and beyond these (mm, deg)
AWAY_SD, AWAY_MM, AWAY_DEG = 3.0, 0.2, 0.05


def _unknowns(truth):
    if truth["mount"] == "positioner":
        return "sensor+sphere+positioner"
    return "sensor" if truth["centre_known"] else "sensor+sphere"


def _away(result, truth):
    """Whether a result lies away from the truth (module docstring): per component of the sensor's
    translation (its mount's frame) and rotation (about the sensor's axes), in reported sd."""
    T, X = np.asarray(result.sensor2flange, float), truth["sensor"]
    dt = T[:3, 3] - X[:3, 3]
    R = X[:3, :3].T @ T[:3, :3]
    angle = math.degrees(math.acos(min(1.0, max(-1.0, (np.trace(R) - 1) / 2))))
    w = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    w = w / max(np.linalg.norm(w), 1e-300) * angle  # deg, about the sensor's axes
    sd = np.concatenate([result.std.sensor_translation_mm, result.std.sensor_rotation_deg])
    z = float(np.max(np.abs(np.concatenate([dt, w])) / np.maximum(sd, 1e-300)))
    return z > AWAY_SD and (np.linalg.norm(dt) > AWAY_MM or angle > AWAY_DEG), z, float(np.linalg.norm(dt)), angle


def outcome(truth):
    """``(kind, detail)`` of ``handeye.calibrate`` on a generated cell: 'named' (exit 2 naming the pairing
    shift), 'input' (exit 2, another reason), 'refused' (exit 1), 'truth' (exit 0 at the truth), 'away'
    (exit 0 away from it: the one wrong outcome)."""
    try:
        result = handeye.calibrate(truth["folder"], unknowns=_unknowns(truth), no_loo=True)
    except InputError as exc:
        return ("named" if "pairing shift" in str(exc) else "input"), str(exc)[:300]
    if not result.converged:
        return "refused", (result.message or "")[:300]
    away, z, dt, dr = _away(result, truth)
    return ("away" if away else "truth"), f"{z:.1f} sd, {dt:.3g} mm, {dr:.3g} deg"


# ----------------------------------------------------------------------------- the generator itself
def test_generator_is_independent_of_handeye():
    """tests/indep_pairing.py imports numpy, the standard library and tests/indep_mounts.py only."""
    tree = ast.parse(pathlib.Path(ip.__file__).read_text())
    names = {a.name.split(".")[0] for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
    names |= {n.module.split(".")[0] for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) and n.module}
    assert names <= {"__future__", "math", "pathlib", "numpy", "indep_mounts"}, names


@pytest.mark.parametrize("mount", ip.MOUNTS)
def test_tours_are_smooth_and_the_shift_moves_the_measurements(tmp_path, mount):
    """Every step 2-10 deg and 5-30 mm relative to the sphere's mount; own rotations agree with
    indep_mounts'; the file holds n - 1 rows whose measurement is the next pose's."""
    R = ip.turn([1.0, 2.0, -0.5], 37.0)
    np.testing.assert_allclose(R, im.rodrigues([1.0, 2.0, -0.5], 37.0), atol=1e-12)
    assert ip.angle_between(np.eye(3), R) == pytest.approx(37.0)
    truth = ip.make(tmp_path / "c", mount, seed=7, n=12, shift=1)
    steps = ip.step_sizes(truth["flanges"], truth["angles"], truth["axes"])
    assert np.all((steps[:, 0] >= 2.0 - 1e-9) & (steps[:, 0] <= 10.0 + 1e-9)), steps[:, 0]
    assert np.all((steps[:, 1] >= 5.0) & (steps[:, 1] <= 30.0)), steps[:, 1]
    read = im.read(truth["folder"])
    assert len(read["ids"]) == 11
    np.testing.assert_allclose(read["measured"], truth["points"][1:], atol=0.6)  # the next pose's, with noise
    assert all(im.in_view(p) for p in truth["points"])


# ----------------------------------------------------------------------------- the slip, named
def test_a_shifted_tour_is_named_by_calibrate_and_diagnose(tmp_path, capsys):
    """The issue's case (sensor fixed in the cell, sphere on the flange, a smooth tour, each pose with the
    next row's measurement): exit 2 naming the direction and the fix, from calibrate and from diagnose;
    the tour unshifted exits 0 at the truth."""
    shifted = ip.make(tmp_path / "s", "eye_to_hand", seed=3, n=20, shift=1, centre_known=True)
    for verb in ("calibrate", "diagnose"):
        assert cli.main([verb, str(shifted["folder"])]) == cli.EXIT_BAD_INPUT
        err = capsys.readouterr().err
        assert "pairing shift" in err and "belongs to the pose below it" in err and "down one row" in err, err
    good = ip.make(tmp_path / "g", "eye_to_hand", seed=3, n=20, shift=0, centre_known=True)
    kind, detail = outcome(good)
    assert kind == "truth", detail


def test_the_other_direction_and_profiles_are_named(tmp_path):
    """Each pose with the previous row's measurement, the measurements as profile files, the sensor on
    the flange: named with the other direction."""
    truth = ip.make(tmp_path / "p", "eye_in_hand", seed=11, n=16, shift=-1, profiles=True, centre_known=True)
    with pytest.raises(InputError, match="pairing shift, each row's measurement belongs to the pose above it") as exc:
        handeye.calibrate(truth["folder"], no_loo=True)
    assert "profile column" in str(exc.value) and "up one row" in str(exc.value)


def test_paired_moves_the_sensors_fields_and_keeps_the_robots(tmp_path):
    """Dataset.paired: poses, axis angles, ids and rows stay; centres, profiles and their records move."""
    truth = ip.make(tmp_path / "q", "positioner", seed=2, n=8, profiles=True)
    d = load(truth["folder"])
    up = d.paired(1)
    assert len(up) == 7 and up.ids == d.ids[:7] and up.rows == d.rows[:7]
    np.testing.assert_array_equal(up.flange_poses, d.flange_poses[:7])
    np.testing.assert_array_equal(up.axis_angles, d.axis_angles[:7])
    np.testing.assert_array_equal(up.centre_in_sensor, d.centre_in_sensor[1:])
    assert up.profiles[0] is d.profiles[1] and up.cleaning[0] is d.cleaning[1] and up.reconstructed == d.reconstructed[1:]
    down = d.paired(-1)
    assert down.ids == d.ids[1:] and down.raw_profiles[0] is d.raw_profiles[0]
    np.testing.assert_array_equal(down.motions(), d.motions()[1:])


# ----------------------------------------------------------------------------- explains nothing
class _Moved:
    """A dataset's carrier motions in another frame of the sphere's mount (``W M_i``)."""

    def __init__(self, d, W):
        self._m = W @ d.motions()

    def motions(self):
        return self._m


def test_the_motion_the_sensor_sees_is_its_line_of_sight_moving(tmp_path):
    """On a tour of a sensor fixed in the cell: motion_seen is the RMS over poses and over the line of
    sight (sampled here) of its points' distance from their mean place in the sphere mount's frame; the same
    in any frame of that mount; a fraction of the carrier motions' (the inverted poses') own spread."""
    truth = ip.make(tmp_path / "e", "eye_to_hand", seed=5, n=16, centre_known=True)
    d = load(truth["folder"])
    X, c = truth["sensor"], truth["sphere_center"]
    T = d.motions() @ X
    seen = np.array([np.linalg.solve(t, np.append(c, 1.0))[:3] for t in T])
    s = np.linspace(0.0, 1.0, 2001)
    line = np.einsum("nab,kb->nka", T[:, :3, :3], s[:, None] * seen.mean(0)) + T[:, None, :3, 3]
    dev = line - line.mean(axis=0)
    sampled = math.sqrt(np.trapezoid(np.mean(np.sum(dev**2, axis=2), axis=0), s))
    assert guarantee.motion_seen(d, X, c) == pytest.approx(sampled, rel=1e-5)
    W = im.transform(im.rodrigues([0.3, -1.0, 0.2], 70.0), [400.0, -900.0, 120.0])
    moved = guarantee.motion_seen(_Moved(d, W), X, (W @ np.append(c, 1.0))[:3])
    assert moved == pytest.approx(guarantee.motion_seen(d, X, c), rel=1e-9)
    carrier = d.motions()[:, :3, 3]
    assert guarantee.motion_seen(d, X, c) < float(np.sqrt(np.mean(np.sum((carrier - carrier.mean(0)) ** 2, 1)))) / 3


def test_explains_nothing_refuses_a_shifted_tour_and_keeps_rotations_about_the_sphere(tmp_path):
    """The shifted tour's global minimum is refused on the motion the sensor sees (it passed on the
    inverted poses' translations); rotations about the sphere with a robot error the model lacks are not
    (the observed point barely moves there, the sensor's line of sight does)."""
    shifted = load(ip.make(tmp_path / "s", "eye_to_hand", seed=3, n=20, shift=1, centre_known=True)["folder"])
    basin = global_fit.centre_minima(shifted.motions(), shifted.centre_in_sensor, shifted.sphere_centre)
    message = guarantee.explains_nothing(shifted, basin, shifted.noise_centre_mm)
    assert message is not None and "motion the sensor sees" in message
    out = tmp_path / "about"
    assert cli.main(["simulate", "--out", str(out), "--motions", "about-sphere", "--translations", "3", "--robot", "kr60ha",
                     "--effect", "joint_offsets=j3:0.05"]) == 0
    d = load(out)
    basin = global_fit.centre_minima(d.motions(), d.centre_in_sensor, d.sphere_centre)
    rms = math.sqrt(2 * basin.best.cost / len(d))
    assert rms > 10 * d.noise_centre_mm  # above the noise: only the motion decides
    assert guarantee.explains_nothing(d, basin, d.noise_centre_mm) is None


# ----------------------------------------------------------------------------- the rates
#: (mount, profiles) classes of the rate check; per class SHIFTED cells (shift +1/-1, tour/shuffled
#: alternating) and CLEAN cells, seeds from 5000.
CLASSES = [(m, p) for m in ip.MOUNTS for p in (False, True)]
SHIFTED, CLEAN = 10, 10


def _cells(mount, profiles, tmp_path):
    out = []
    for k in range(SHIFTED + CLEAN):
        seed = 5000 + 100 * ip.MOUNTS.index(mount) + 50 * profiles + k
        shift = 0 if k >= SHIFTED else (1, -1)[k % 2]
        order = "shuffled" if k < SHIFTED and k % 3 == 2 else "tour"
        truth = ip.make(tmp_path / f"c{k}", mount, seed, n=20, shift=shift, order=order, profiles=profiles)
        kind, detail = outcome(truth)
        out.append(dict(seed=seed, shift=shift, order=order, profiles=profiles, kind=kind, detail=detail))
    return out


def test_a_few_cells_of_the_rate_check(tmp_path):
    """The rate check's cheap sibling: a shifted cell of profiles with the sphere on the flange (the mount
    whose shifted tours exited 0 away from the truth) is named; a clean cell of profiles exits 0 at the truth."""
    for mount, shift, allowed in (("eye_to_hand", -1, ("named",)), ("eye_in_hand", 0, ("truth",))):
        truth = ip.make(tmp_path / f"c{shift}", mount, 5300 + shift, n=16, shift=shift, profiles=True)
        kind, detail = outcome(truth)
        assert kind in allowed, (shift, kind, detail)


def _wrong(cell):
    """A shifted cell that exits 0 away from the truth; a clean cell named a pairing shift or refused as
    explaining nothing (this work's false alarms), or with centres given anything but exit 0 at the truth
    (clean profile cells may be refused or a few sd off for other reasons: below)."""
    if cell["shift"]:
        return cell["kind"] == "away"
    ours = cell["kind"] == "named" or "explains nothing" in cell["detail"]
    return ours or (not cell["profiles"] and cell["kind"] != "truth")


@pytest.mark.slow(sibling="test_a_few_cells_of_the_rate_check")
@pytest.mark.parametrize("mount, profiles", CLASSES, ids=[f"{m}-{'profiles' if p else 'centres'}" for m, p in CLASSES])
def test_shifted_cells_never_exit_0_away_from_the_truth(tmp_path, tmp_path_factory, mount, profiles):
    """Over the six classes (60 shifted cells, shuffled in a third; 60 clean ones): no shifted cell exits 0
    away from the truth; no clean cell is named a pairing shift or refused as explaining nothing (0 false
    alarms of this work), and every clean cell of centres given exits 0 at the truth. The rates are
    printed: the shift named; clean profile cells that exit 0 a few sd off or whose good rows the
    screening excludes as gross errors and two_groups then refuses (before this work too, the same
    cells: the reconstructed centres' y is 2-3 x noisier than their x, z and than ``[noise] centre_mm``,
    which the isotropic centre model does not see -- issue 39's circle-fit covariance and deletion test,
    not a pairing question). A shard per class (tests/shards.py); the shard that completes the set
    asserts the rates."""
    part = _cells(mount, profiles, tmp_path)
    assert not [c for c in part if _wrong(c)], [c for c in part if _wrong(c)]
    parts = sh.pool(tmp_path_factory, "pairing-shifts", CLASSES.index((mount, profiles)), len(CLASSES), part)
    if parts is None:
        return
    cells = [c for p in parts for c in p]
    shifted = [c for c in cells if c["shift"]]
    clean = [c for c in cells if not c["shift"]]
    named = sum(c["kind"] == "named" for c in shifted)
    print(f"\npairing shifts: {named} of {len(shifted)} shifted cells named, "
          f"{sum(c['kind'] == 'away' for c in shifted)} exit 0 away from the truth; clean: "
          f"{sum(c['kind'] == 'truth' for c in clean)} of {len(clean)} exit 0 at the truth, "
          f"{sum(_wrong(c) for c in clean)} false alarms of this work; profile cells: "
          f"{sum(c['kind'] == 'away' for c in clean)} exit 0 a few sd off, "
          f"{sum(c['kind'] in ('refused', 'input') for c in clean)} refused for other reasons")
    assert len(shifted) >= 30 and sum(not c["profiles"] for c in clean) >= 30
    assert not [c for c in cells if _wrong(c)]


def test_a_constant_step_tour_shifted_fits_exactly_one_step_off():
    """The module docstring's limit (app/engine/slips.py), numerically: every pose the previous one times
    one fixed motion D, each pose with the next row's centre: the centre model fits exactly at D X, so no
    test can tell the shift (nor is it claimed)."""
    X = im.transform(im.rodrigues([0.2, 1.0, -0.4], 35.0), [60.0, -40.0, 150.0])
    D = im.transform(im.rodrigues([1.0, -0.3, 0.5], 6.0), [8.0, 3.0, -5.0])
    M = [im.transform(im.rodrigues([0.0, 1.0, 0.0], 180.0), [900.0, 100.0, 600.0])]
    for _ in range(11):
        M.append(M[-1] @ D)
    M = np.array(M)
    c = (M[0] @ X @ np.array([5.0, -10.0, 230.0, 1.0]))[:3]
    seen = np.array([np.linalg.solve(m @ X, np.append(c, 1.0))[:3] for m in M])
    best = global_fit.centre_minima(M[:-1], seen[1:], c).best
    assert best.cost < 1e-12
    np.testing.assert_allclose(best.sensor2flange, D @ X, atol=1e-6)
