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
  ``p < P_HELD`` and the RMS is larger by ``HELD_FACTOR`` (the rule for any part held,
  :mod:`handeye.app.engine.cell_stage`);
- the distance of the held pose from that minimum (mm, deg, and in the minimum's sd).

Robot effects (their parameters are the ones the poses separate, a choice the file does not record) and
the positioner's axes stay beyond this path: the caller says so.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from handeye.app.engine.cell_stage import HELD_FACTOR, P_HELD
from handeye.app.engine.describe import noise_test
from handeye.model import effects as catalogue
from handeye.model.common.rotation import pose_distance
from handeye.model.common.statistics import f_survival
from handeye.model.datasets import observations
from handeye.model.fit.extended import Samples, Structure


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


def file_effects(doc):
    """The file's catalogue effects as ``{name: parameters (k,)}`` in the catalogue's parameter order, or None
    when one of them is beyond this path (a robot effect, the positioner's axes, an unknown name, a missing
    parameter); sign flips are data, not effects here."""
    out = {}
    for effect in doc.get("effects") or []:
        name = effect.get("name") if isinstance(effect, dict) else None
        if name == "sign_flip":
            continue
        try:
            known = catalogue.get(name)
            values = np.array([float(effect["parameters"][p]) for p in known.PARAMS])
        except (KeyError, TypeError, ValueError):
            return None
        if known.KIND != "data" or not np.all(np.isfinite(values)):
            return None
        out[name] = values
    return out


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
        ``(effects, centre_free)``: :func:`file_effects` of the file, and whether its unknowns free the centre.
    stated : float
        The stated noise the file's calibration ran with, mm per component.
    """
    effects, centre_free = held
    structure = Structure(centre=bool(centre_free), data_effects=tuple(effects))
    n_pose = 9 if centre_free else 6
    prob = Samples(data, stated, observations.centre_metric(data, sensor2flange, centre, mask, n_pose))
    x = prob.point(structure, sensor2flange, centre)
    e, jac, _ = prob.evaluate(structure, x, effects)
    flat = jac[mask].reshape(-1, jac.shape[2])
    ssr, m, p = float(np.sum(e[mask] ** 2)), 3 * int(mask.sum()), jac.shape[2]
    with np.errstate(all="ignore"):
        best = prob.fit(structure, mask, x, effects)
    cov = ssr / max(m - p, 1) * np.linalg.pinv(flat.T @ flat)
    raw = prob.raw(e)
    norms = np.linalg.norm(raw, axis=1)
    return HeldEffects(raw, float(np.sqrt(np.mean(norms[mask] ** 2))), float(norms[mask].max()), cov[:6, :6],
                       noise_test(ssr, m - p, stated, False, [], ""), _contradicted(ssr, best.ssr, m, p),
                       pose_distance(sensor2flange, prob.transform(best.x), best.sigma2 * np.linalg.pinv(
                           best.jac[mask].reshape(-1, p).T @ best.jac[mask].reshape(-1, p)), best.names))


def _contradicted(held, minimum, m, p):
    """The held point's sum of squares ``held`` against the data's ``minimum`` (module docstring)."""
    dof = m - p
    if dof <= 0 or not minimum > 0 or not np.isfinite(held):
        return False
    f = max(held - minimum, 0.0) / p / (minimum / dof)
    return bool(f_survival(f, p, dof) < P_HELD and np.sqrt(held / minimum) > HELD_FACTOR)
