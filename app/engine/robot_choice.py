"""Which of the robot's errors: the robot effects compared as alternatives (a step of diagnose).

A robot's zero offsets, length errors and gravity sag move the flange in similar ways: over a
narrow range of configurations their columns are nearly parallel, and the forward search of
:mod:`handeye.app.engine.diagnose`, which takes the most significant candidate first, can name
one for another. Once the search has named any robot effect -- or a ``sphere_center`` where the joints are
given (a robot's length error seen as a taught centre off: an independent generator's UR10e, a2 0.58 mm long at
0.13 mm of noise, exited 0 0.34 mm, 7 sd, from the truth with the centre freed) -- every non-empty combination of the
robot effects the dataset can show is fitted in its place (each with its parameters chosen by the
identifiability gate, :func:`handeye.model.design.robot_gate.gate_robot_effects`), with and without a
``sphere_center`` the search named before them (a centre offset named first may be a robot error
seen from poses that do not yet have the robot in the model), and scored by BIC
``m ln(SSR / m) + p ln m`` (Schwarz 1978). The searched model is kept unless another scores
lower by :data:`POSITIVE` or more (Kass & Raftery 1995: "positive" evidence), predicts held-out
samples better (5-fold) and, when it holds the searched one, passes the search's F test for its
extra parameters (:func:`_replaces`); then the lowest is. Combinations within
:data:`AMBIGUOUS` of the kept one explain the data about as well (a BIC difference below 10 is
not "very strong" evidence): those that are not supersets of it are said, with how far the
sensor pose moves between the two, instead of claiming to know which. (Keeping the simplest of
the near ones instead named an upward gravity sag for a length error beside a centre offset the
data preferred by 8.4, found by the independent generator's test.)
"""
from __future__ import annotations

import dataclasses
import itertools

import numpy as np

from handeye.app.engine.levels import AMBIGUOUS, POSITIVE  # the verdict's levels, one place
from handeye.model import effects
from handeye.model.common.rotation import transform_distance
from handeye.model.common.statistics import f_survival
from handeye.model.design.robot_gate import gate_robot_effects


@dataclasses.dataclass(frozen=True)
class Candidate:
    """One combination of robot effects, fitted: its structure, fit, free parameters and BIC."""

    names: tuple
    centre: bool
    structure: object
    fit: object
    free: dict
    bic: float


def _bic(fit):
    return float(fit.m * np.log(max(fit.ssr, 1e-300) / fit.m) + fit.p * np.log(fit.m))


def _implausible(prob, fit, names):
    """Whether a fitted robot effect is beyond its physical limit (:func:`handeye.model.effects.implausible`)."""
    return any(effects.implausible(n, fit.params[n], prob.radius, names=prob.params_of(n)) is not None for n in names)


def _fitted(prob, structure, mask, names, free_centre, start):
    """The structure with the robot effects ``names`` in place of its own and the centre free or
    not, gated and fitted from ``start`` (sensor2flange, centre); None when one of them has no
    estimable parameter or the fit fails."""
    sensor, centre = start
    others = tuple(n for n in structure.data_effects if effects.get(n).KIND != "robot")
    trial = dataclasses.replace(structure, centre=free_centre, data_effects=others + tuple(names))
    gate_robot_effects(prob, trial, mask, sensor, centre if free_centre else None)
    if any(not prob.robot_free[n] for n in names):
        return None
    with np.errstate(all="ignore"):
        fit = prob.fit(trial, mask, prob.point(trial, sensor, centre if free_centre else None))
    if not (np.isfinite(fit.ssr) and fit.converged) or _implausible(prob, fit, names):
        return None
    return Candidate(tuple(names), free_centre, trial, fit, {n: prob.robot_free[n] for n in names}, _bic(fit))


def _replaces(prob, mask, searched, other, alpha):
    """Whether ``other`` replaces the searched combination: a BIC lower by :data:`POSITIVE`, a
    lower 5-fold held-out error, and, when it holds the searched one (more parameters of the same
    kinds), the F test of its extra parameters at ``alpha`` -- the search's own standard for adding
    an effect (on 9 poses BIC and the held-out error alone let fifteen robot parameters fit 27
    residuals where four were true)."""
    if other is searched or other.bic >= searched.bic - POSITIVE:
        return False
    nested = set(searched.names) <= set(other.names) and other.centre >= searched.centre
    if nested:
        k, dof = other.fit.p - searched.fit.p, other.fit.m - other.fit.p
        if k <= 0 or dof <= 0:
            return False
        f = (searched.fit.ssr - other.fit.ssr) / k / (other.fit.ssr / dof)
        if f <= 0 or f_survival(f, k, dof) >= alpha:
            return False
    prob.robot_free.update(other.free)
    new = prob.heldout_rms(other.structure, mask, other.fit)
    prob.robot_free.update(searched.free)
    return new < prob.heldout_rms(searched.structure, mask, searched.fit)


def compare(prob, structure, fit, mask, alpha, centre_unknown=False):
    """Choose among the robot effects (module docstring).

    Parameters
    ----------
    prob : handeye.model.fit.extended.Samples
    structure : handeye.model.fit.extended.Structure
        The searched model; unchanged without a robot effect.
    fit : handeye.model.fit.extended.Fit
    mask : ndarray of bool, shape (N,)
    alpha : float
        Level of the F test a combination holding the searched one must pass (diagnose's).
    centre_unknown : bool
        The centre is estimated in every model (``--unknowns sensor+sphere``): no combination
        without it is tried.

    Returns
    -------
    structure, fit
        The searched combination, or one with a BIC lower by :data:`POSITIVE` (``prob.robot_free``
        set for it).
    note : str or None
        The alternatives within :data:`AMBIGUOUS`, said; None when there are none.
    rivals : tuple of (str, ndarray (4, 4))
        Those alternatives' labels and sensor poses (the calibration's sd is widened to hold them:
        :func:`handeye.app.engine.search.with_rivals`).
    """
    named = [n for n in structure.data_effects if effects.get(n).KIND == "robot"]
    available = [e.NAME for e in effects.catalogue("robot") if e.available(prob.d)]
    if not named and not (structure.centre and not centre_unknown and available):
        return structure, fit, None, ()
    kept_free = {n: prob.robot_free[n] for n in named}
    start = (prob.transform(fit.x), prob.centre(structure, fit.x))
    combos = [names for r in range(1, len(available) + 1) for names in itertools.combinations(available, r)]
    tried = [c for centre in dict.fromkeys((structure.centre, structure.centre and centre_unknown)) for names in combos
             if (c := _fitted(prob, structure, mask, names, centre, start)) is not None]
    searched = Candidate(tuple(named), structure.centre, structure, fit, kept_free, _bic(fit))
    prob.robot_free.update(kept_free)
    if _implausible(prob, fit, named):  # refitted beside outliers since the search checked it
        if not tried:
            return (*_without_robot(prob, structure, fit, mask), None, ())
        searched = min(tried, key=lambda c: c.bic)
    lowest = min(tried, key=lambda c: c.bic, default=searched)
    best = lowest if _replaces(prob, mask, searched, lowest, alpha) else searched
    prob.robot_free.update(best.free)
    rivals = {(c.names, c.centre): c for c in tried + [searched]
              if c.bic - best.bic < AMBIGUOUS and (set(c.names), c.centre) != (set(best.names), best.centre)
              and not (set(best.names) <= set(c.names) and c.centre >= best.centre)}
    near = sorted(rivals.values(), key=lambda c: c.bic)
    return (best.structure, best.fit, _said(prob, best, near, mask),
            tuple((_label(c), prob.transform(c.fit.x)) for c in near))


def _without_robot(prob, structure, fit, mask):
    """The structure without its robot effects, refitted: ``(structure, fit)``."""
    kept = tuple(n for n in structure.data_effects if effects.get(n).KIND != "robot")
    reduced = dataclasses.replace(structure, data_effects=kept)
    with np.errstate(all="ignore"):
        return reduced, prob.fit(reduced, mask, fit.x, {n: fit.params[n] for n in kept})


def _said(prob, best, rivals, mask):
    if not rivals:
        return None
    sd = float(np.linalg.norm(best.fit.uncertainty(mask)[0][:3]))  # the kept pose's translation, 1 sd (3-D)
    parts = []
    for c in sorted(rivals, key=lambda c: c.bic):
        dt, dr = transform_distance(prob.transform(best.fit.x), prob.transform(c.fit.x))
        parts.append(f"{_label(c)} (BIC {c.bic - best.bic:+.1f}; sensor pose {float(dt):.3g} mm / "
                     f"{float(dr):.3g} deg from this one, {float(dt) / max(sd, 1e-12):.2g} times its 1 sd)")
    return (f"which robot errors is not settled: {_label(best)} explains the residuals, but "
            f"{'; '.join(parts)} about as well -- these poses do not tell them apart (a BIC difference below "
            f"{AMBIGUOUS:g}), and where the sensor pose moves by more than its sd between them, the sd does not "
            "hold; poses that differ more in reach and arm configuration would (handeye plan --robot)")


def _label(c):
    return "+".join(("sphere_center",) * c.centre + c.names)


def unmodelled(dataset):
    """What to say when a dataset has the robot's joint angles but its cell does not let the robot's
    errors be modelled (the sphere on a positioner), or None."""
    if (getattr(dataset, "joints", None) is None or getattr(dataset, "robot_model", None) is None
            or any(e.available(dataset) for e in effects.catalogue("robot"))):
        return None
    return ("the robot's own errors (joint offsets, lengths, sag) are not modelled with the sphere on a positioner: "
            "the turning axes and the sphere centre absorb them in part, so a centre offset or axes named here may be "
            "a robot error, and the pose is only as right as the robot's nominal kinematics")
