"""The verdict of a saved calibration with catalogue effects, recomputed at its pose and effects.

A ``calibrate --out`` file whose model has data effects (``--effects``, or the effects the search
chose: ``sensor_scale``, ``sphere_radius``, ``centre_scale``, ...) is of the extended model
(:mod:`handeye.model.fit.extended`), not of the plain chain the held-pose path scores. Here the file's
pose, sphere centre and effect parameters are held in that model, in the samples' own metric
(:func:`handeye.model.datasets.observations.centre_metric`, what the fit with effects weighs by), and:

- the residuals (the centres corrected by the file's effects, through the chain), their RMS (mm per
  sphere centre, unweighted: what the file's ``rms_mm`` is) and the noise test, as the fit with effects
  reports them (:func:`handeye.app.engine.describe.noise_test`);
- the data's own minimum of that model, fitted from the held point with every block free (pose, centre
  when the file frees it, effects), and the F test of the held point against it: ``F = ((S_h - S_m) / p)
  / (S_m / (m - p))`` on all ``p`` parameters the file holds; the data *contradict* the file when
  ``p < P_HELD`` and the RMS is larger by ``HELD_FACTOR`` (:func:`handeye.app.engine.score.held_test`, the rule for any part held,
  :mod:`handeye.app.engine.cell_stage`);
- the distance of the held pose from that minimum (mm, deg, and in the minimum's sd).

Robot effects are held with the parameters the file names (those its calibration estimated); the
positioner's axes are held where the caller puts the data (its axes). A file whose effects this path cannot
read (an unknown name, a parameter missing or not a number, a robot effect on data without joints) is no
calibration of these data: :class:`UnreadEffects`, which the caller names as a hand-edited or foreign field.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from handeye.app.engine.describe import noise_test
from handeye.app.engine.held_chain import held_at
from handeye.app.engine.score import held_test
from handeye.model import effects as catalogue
from handeye.model.common.rotation import pose_distance


@dataclasses.dataclass(frozen=True)
class HeldEffects:
    """The extended model held at a file's pose, centre and effects (module docstring).

    Attributes
    ----------
    residuals : ndarray, shape (N, 3)
        Every sample's corrected sphere centre through the chain minus the sphere centre, mm.
    rms_mm, max_mm : float
        RMS and largest ``|e_i|`` over the samples used, mm per sphere centre (unweighted).
    covariance : ndarray, shape (6, 6)
        Of the sensor pose (local chart, mm and rad) with the effects free, ``s^2 (J^T J)^-1`` at the held point.
    noise : handeye.app.present.result_parts.NoiseTest or None
    contradicted : bool
    distance : dict
        The data's minimum from the held pose: mm, deg, sd.
    """

    residuals: np.ndarray
    rms_mm: float
    max_mm: float
    covariance: np.ndarray
    noise: object
    contradicted: bool
    distance: dict


class UnreadEffects(ValueError):
    """The file's ``effects`` cannot be held on these data (why, in words)."""


#: Named effects that are no parameters of the extended model's effects: sign flips are samples; the
#: positioner's axes are the data's (the caller holds them); the sphere centre is held as the file's own
#: (its offset named as an effect frees it: :func:`centre_freed`).
NOT_HELD = ("sign_flip", "positioner_axes", "sphere_center")


def centre_freed(doc):
    """Whether the file's calibration estimated the sphere centre: its unknowns free it, or it names the
    centre's offset as an effect."""
    named = [e.get("name") for e in doc.get("effects") or [] if isinstance(e, dict)]
    return "sphere" in str(doc.get("unknowns") or "sensor").split("+") or "sphere_center" in named


def file_effects(doc, data):
    """The file's catalogue effects on ``data``: ``({name: parameters (k,)}, {robot effect: indices of its
    parameters the file estimated})``, each effect's parameters in the catalogue's order (a robot effect's:
    the ones the file names); raises :class:`UnreadEffects` naming what cannot be read."""
    effects = doc.get("effects")
    if not isinstance(effects, list) or not all(isinstance(e, dict) for e in effects):
        raise UnreadEffects(f"effects {str(effects)[:60]!r} is not a list of named effects")
    values, robot_free = {}, {}
    for effect in effects:
        name, given = effect.get("name"), effect.get("parameters")
        if name in NOT_HELD:
            continue
        if not isinstance(name, str) or name not in catalogue.MODULES or not isinstance(given, dict):
            raise UnreadEffects(f"effect {str(name)[:40]!r} is not one of the catalogue's with its parameters")
        known = catalogue.get(name)
        if known.KIND == "robot" and not known.available(data):
            raise UnreadEffects(f"effect {name!r} needs the joint angles, which {data.name} lacks")
        names = known.params(data.robot_model) if known.KIND == "robot" else known.PARAMS
        keys = list(given) if known.KIND == "robot" else list(names)
        try:
            values[name] = np.array([float(given[k]) for k in keys])
            if known.KIND == "robot":
                robot_free[name] = [list(names).index(k) for k in keys]
        except (KeyError, TypeError, ValueError):
            raise UnreadEffects(f"effect {name!r} parameters {str(given)[:60]} are not {', '.join(names)} as numbers") from None
        if not np.all(np.isfinite(values[name])):
            raise UnreadEffects(f"effect {name!r} has a parameter that is not finite")
        why = catalogue.implausible(name, values[name], data.sphere_radius_mm, names=keys)
        if why is not None:
            raise UnreadEffects(why)
    return values, robot_free


def recompute(data, mask, sensor2flange, centre, held, stated):
    """The :class:`HeldEffects` of a file's calibration.

    Parameters
    ----------
    data : handeye.model.datasets.dataset.Dataset
    mask : ndarray of bool, shape (N,)
        The samples the file used.
    sensor2flange : ndarray, shape (4, 4)
        The file's pose (handeye's frame, its mount's), mm.
    centre : ndarray, shape (3,)
        The file's sphere centre, mm.
    held : tuple
        ``(file_effects, centre_free)``: :func:`file_effects` of the file, and whether its unknowns free the
        centre.
    stated : float
        The stated noise the file's calibration ran with, mm per component.
    """
    (effects, robot_free), centre_free = held
    chain = held_at(data, mask, (sensor2flange, centre), centre_free, effects, stated)
    prob, structure, x = chain.prob, chain.structure, chain.x
    prob.robot_free.update(robot_free)
    with np.errstate(all="ignore"):
        e = prob.residuals(structure, x, effects)
        jtj, _, ssr = prob.normal_equations(structure, x, effects, mask)
        best = prob.fit(structure, mask, x, effects)
    m, p = 3 * int(mask.sum()), jtj.shape[0]
    if not (np.isfinite(ssr) and np.all(np.isfinite(jtj))):
        raise UnreadEffects("the chain with the file's effects is not finite on these data")
    cov = ssr / max(m - p, 1) * np.linalg.pinv(jtj)
    norms = np.linalg.norm(prob.raw(e), axis=1)
    return HeldEffects(prob.raw(e), float(np.sqrt(np.mean(norms[mask] ** 2))), float(norms[mask].max()), cov[:6, :6],
                       noise_test(ssr, m - p, stated, False, [], ""), held_test(ssr, best.ssr, m, p, p)[2],
                       pose_distance(sensor2flange, prob.transform(best.x), best.covariance(mask), best.names))

