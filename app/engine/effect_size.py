"""Whether a significant effect matters: how far fitting it moves the pose, against the promise's floor.

A score test at a fixed level detects ever smaller effects as the samples grow: on a clean cell of 10^6
measurements (0.02 mm, the centre model) ``sensor_scale`` and ``sphere_radius`` score 25 (Bonferroni
p = 2e-6), an errors-in-variables bias of the test itself (their columns are functions of the measured
centre, which carries the noise: its z grows as sqrt(n) sigma, measured 1.4, 3.6, 5.0 and 7.1 at 10^5 x
0.02 mm, 10^5 x 0.06 mm, 10^6 x 0.02 mm and 10^5 x 0.1 mm), whose fitted size moves the pose by about a
micrometre. Such an effect cannot make the answer wrong: a pose
is wrong only beyond 3 sd *and* beyond :data:`handeye.model.fit.power.SHIFT_FLOOR` (0.2 mm / 0.05 deg,
issue 39). So the warning of structure (:func:`handeye.app.engine.describe.effect_tests`) names a
significant data effect only where the model with it puts the pose beyond that floor (robot effects and the
sphere centre, whose tests carry no such bias, as before); the size is measured by
the model with the effect, to first order, at any number of samples (:func:`pose_shift`).
"""
from __future__ import annotations

import dataclasses

import numpy as np

from handeye.model import effects as catalogue
from handeye.model.fit import extended
from handeye.model.fit.power import SHIFT_FLOOR


@dataclasses.dataclass(frozen=True)
class At:
    """The fit a test was made at: its ``dataset``, used samples ``mask`` (N,), ``sensor2flange`` (4, 4),
    sphere ``centre`` (base, mm), ``unknowns`` and the data effects already in its model (``effects``)."""

    dataset: object
    mask: np.ndarray
    sensor2flange: np.ndarray
    centre: np.ndarray
    unknowns: str = "sensor"
    effects: tuple = ()


def biased(name):
    """Whether the score test of catalogue effect ``name`` carries the bias that grows with n: a data effect,
    whose columns are functions of the measured centre (a robot effect's are of the joints, the sphere
    centre's constant: a significant test of those is structure at any n)."""
    return catalogue.get(name).KIND == "data"


def pose_shift(at, name):
    """``(mm, deg)``: how far the model with effect ``name`` puts the pose from the model without it, on the
    same samples, to first order: the pose part of a Gauss-Newton step of the model with it, less that of
    the model without it, both at the fit (one pass over the samples each, chunked above
    :data:`~handeye.model.fit.calibration.ROW_CHUNK`: the alias of the score test's effect). None for an
    effect whose test is not :func:`biased` (never dismissed), one in the model already, or a step that is
    not finite."""
    if not biased(name):
        return None
    prob, mask = extended.Samples(at.dataset), np.asarray(at.mask, bool)
    base = extended.Structure(centre=at.unknowns == "sensor+sphere",
                              data_effects=tuple(e for e in at.effects if catalogue.get(e).KIND == "data"))
    wider = dataclasses.replace(base, data_effects=base.data_effects + (name,))
    if name in base.data_effects:
        return None
    with np.errstate(all="ignore"):
        x, params = prob.point(base, at.sensor2flange, at.centre), {}
        if base.data_effects:  # their values: the fit with them
            fit = prob.fit(base, mask, x)
            x, params = fit.x, fit.params
        steps = [_step(prob, s, x if s.centre == base.centre else prob.point(s, prob.transform(x), prob.centre(base, x)),
                       params, mask) for s in (base, wider)]
    if steps[0] is None or steps[1] is None:
        return None
    delta = steps[1][:6] - steps[0][:6]
    return float(np.linalg.norm(delta[:3])), float(np.degrees(np.linalg.norm(delta[3:6])))


def _step(prob, structure, x, params, mask):
    """The Gauss-Newton step of ``structure`` at ``x`` (its effects at ``params``, a new one at zero)."""
    full = {n: np.asarray(params.get(n, np.zeros(len(prob.params_of(n)))), float) for n in structure.data_effects}
    try:
        jtj, jtr, _ = prob.normal_equations(structure, x, full, mask)
        step = np.linalg.lstsq(jtj, -jtr, rcond=None)[0]
    except (np.linalg.LinAlgError, ValueError):
        return None
    return step if np.all(np.isfinite(step)) else None


def matters(at, name):
    """Whether effect ``name``, fitted, moves the pose beyond :data:`~handeye.model.fit.power.SHIFT_FLOOR`
    (or its test is not :func:`biased`, or its size cannot be measured here: then it is not dismissed)."""
    shift = pose_shift(at, name)
    return shift is None or shift[0] > SHIFT_FLOOR[0] or shift[1] > SHIFT_FLOOR[1]
