"""The uncertainty a corrected depth bend adds to the pose (:mod:`handeye.model.geometry.profile_bend`).

A dataset whose profiles bend along the sensor's depth (a linearity error) is loaded with the bend
corrected, its centres rebuilt from the corrected profiles; the calibration then fits them as any
others. The correction is estimated, not known: its coefficients ``beta`` have a covariance ``C``
(a jackknife over the profiles), and every rebuilt centre moves with them (``dc_i / dbeta``, the
circle fit's implicit derivative). Held at the calibrated pose, a change ``delta`` of ``beta``
moves the residuals by ``de``, and the least-squares pose by ``-(J^T J)^-1 J^T de`` (the alias
matrix of the omitted-variable bias, as :mod:`handeye.model.fit.power` takes it, ``J`` the plain
chain's Jacobian in the centres' metric). Over ``delta = sqrt(l_k) v_k`` (``C``'s eigenpairs) these
shifts ``s_k`` give the added covariance ``sum_k s_k s_k^T``: the pose's sd then includes what the
correction does not know. Where the correction moved the centres, the result says so: its bend,
the pose's move, and the sd it added.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from handeye.app.engine import cell_stage
from handeye.model import effects as catalogue
from handeye.model.fit.held import held_at


def _held(dataset, result):
    """The chain held at ``result``'s pose, centre and data effects (:func:`handeye.model.fit.held.held_at`),
    the samples it used, and the effects' parameters."""
    mask = cell_stage.mask_of(result)
    named = [e for e in result.effects or [] if catalogue.get(e.name).KIND == "data"]
    params = {e.name: np.array([e.parameters[p] for p in catalogue.get(e.name).PARAMS], float) for e in named}
    chain = held_at(dataset, mask, result.sensor2flange, result.sphere_centre, "sphere" in result.unknowns.split("+"),
                    tuple(params))
    return chain, mask, params


def widening(chain, mask, params, bend):
    """``(shifts (k, p), move (p,), names)``: the pose's shifts over ``bend``'s covariance eigen-directions,
    and its shift had the bend not been corrected (module docstring). ``chain``: the chain held at the pose
    (:func:`handeye.model.fit.held.held_at`); ``mask``: the samples the pose is of; ``params``: the held data
    effects' parameters (name -> array)."""
    e, jac, _ = chain.prob.evaluate(chain.structure, chain.x, params)
    flat = jac[mask].reshape(-1, jac.shape[2])

    def shift(change):
        moved = np.array(chain.dataset.centre_in_sensor, float)
        moved[list(bend.rows)] += change
        other = chain.with_centres(moved)
        e_k, _, _ = other.prob.evaluate(other.structure, other.x, params)
        return np.linalg.lstsq(flat, -(e_k - e)[mask].ravel(), rcond=None)[0]

    values, vectors = np.linalg.eigh(bend.covariance)
    shifts = [shift(bend.dcentre @ (np.sqrt(max(lam, 0.0)) * v)) for lam, v in zip(values, vectors.T)]
    return np.array(shifts), shift(-bend.moved), chain.prob.names(chain.structure)


def widened(record, chain, mask, bend):
    """An :class:`~handeye.app.present.result_parts.UncertaintyRecord` of a pose held (a saved calibration's,
    :mod:`handeye.app.engine.held_verdict`) widened as :func:`with_bend` widens a calibration's: the same
    covariance from the same data; unchanged without an applied bend."""
    if bend is None or not bend.applied:
        return record
    shifts, _, names = widening(chain, mask, {}, bend)
    return record.widened(shifts.T @ shifts, names)


def with_bend(result, dataset):
    """``result`` with the uncertainty of the dataset's applied bend added to its covariance (module
    docstring) and a line saying it; unchanged without an applied bend or a converged fit."""
    bend = getattr(dataset, "bend", None)
    if bend is None or not bend.applied or not result.converged or result.uncertainty.covariance is None:
        return result
    data = cell_stage.dataset_at(result, dataset)
    try:
        chain, mask, params = _held(data, result)
        shifts, move, names = widening(chain, mask, params, bend)
    except (np.linalg.LinAlgError, FloatingPointError, ValueError):
        return dataclasses.replace(result, warnings=[*result.warnings, _note(bend, None, None)])
    uncertainty = result.uncertainty.widened(shifts.T @ shifts, names)
    return dataclasses.replace(result, uncertainty=uncertainty, warnings=[*result.warnings, _note(bend, shifts, move)])


def _size(shifts):
    """The largest translation (mm) and rotation (deg) of a set of pose shifts' covariance's 1-sd ellipsoid."""
    return (float(np.sqrt(np.max(np.linalg.eigvalsh(shifts[:, :3].T @ shifts[:, :3])))),
            float(np.degrees(np.sqrt(np.max(np.linalg.eigvalsh(shifts[:, 3:6].T @ shifts[:, 3:6]))))))


def _note(bend, shifts, move):
    lo, hi = bend.depths
    head = (f"the profiles bend along the sensor's depth by {bend.bend_mm:.3g} mm over {lo:.0f}-{hi:.0f} mm "
            f"(a linearity error of the sensor: F = {bend.f:.3g} on degree {bend.degree}); every profile was "
            f"corrected and its centre rebuilt before the fit")
    if shifts is None:
        return head + "; the correction's uncertainty could not be carried into the sd"
    (mm, deg), (move_mm, move_deg) = _size(shifts), _size(move[None])
    return head + (f": it moved the pose by {move_mm:.2g} mm / {move_deg:.2g} deg; the 1 sd includes the "
                   f"correction's own uncertainty (up to {mm:.2g} mm / {deg:.2g} deg)")
