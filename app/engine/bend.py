"""The uncertainty a depth bend of the profiles adds to the pose (:mod:`handeye.model.geometry.profile_bend`):
one corrected, or one the profiles suggest but do not make clear.

A dataset whose profiles bend along the sensor's depth (a linearity error) is loaded with the bend
corrected, its centres rebuilt from the corrected profiles; the calibration then fits them as any
others. The correction is estimated, not known: its coefficients ``beta`` have a covariance ``C``
(a jackknife over the profiles), and every rebuilt centre moves with them (``dc_i / dbeta``, the
circle fit's implicit derivative). Held at the calibrated pose, a change ``delta`` of ``beta``
moves the residuals by ``de``, and the least-squares pose by ``-(J^T J)^-1 J^T de`` (the alias
matrix of the omitted-variable bias, as :mod:`handeye.model.fit.power` takes it, ``J`` the chain's Jacobian
with the data effects the calibration holds, in the centres' metric). Over ``delta = sqrt(l_k) v_k`` (``C``'s eigenpairs) these
shifts ``s_k`` give the added covariance ``sum_k s_k s_k^T``. That covers the profiles' scatter, not the shape
the polynomial misses (measured: up to a fifth of the correction's move, and more on other bends), so
:data:`~handeye.app.engine.levels.BEND_DOUBT` of the move (the pose's shift had the bend been left in) is
added as 1 sd in every direction of its block. Where the correction moved the centres, the result says so: its bend,
the pose's move, and the sd it added.

Where BIC chooses a bend but the tests do not make it clear (not applied), the bend the profiles could have
missed (their own information about a stretch and a curvature, :func:`unseen`) widens the sd as
:mod:`handeye.model.fit.power` widens it for the catalogue's effects: beyond the floor only. A saved
calibration's covariance is recomputed the same way (:func:`widened`), so a file is compared with its own.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from handeye.app.engine import cell_stage
from handeye.app.engine.held_chain import held_at
from handeye.app.engine.levels import BEND_DOUBT
from handeye.model import effects as catalogue
from handeye.model.fit import power
from handeye.model.geometry import profile_bend


def _held(dataset, result):
    """The chain held at ``result``'s pose, centre and data effects (:func:`handeye.app.engine.held_chain.held_at`),
    the samples it used, and the effects' parameters."""
    mask = cell_stage.mask_of(result)
    named = [e for e in result.effects or [] if catalogue.get(e.name).KIND == "data"]
    params = {e.name: np.array([e.parameters[p] for p in catalogue.get(e.name).PARAMS], float) for e in named}
    chain = held_at(dataset, mask, (result.sensor2flange, result.sphere_centre), "sphere" in result.unknowns.split("+"),
                    tuple(params))
    return chain, mask, params


def _shifter(chain, mask, params):
    """``shift(rows, change)``: the least-squares pose's shift (p,) at the held chain when the centres of
    ``rows`` change by ``change`` (k, 3; mm, sensor frame), to first order (the residual's change held at the
    pose, projected on the Jacobian)."""
    e, jac, _ = chain.prob.evaluate(chain.structure, chain.x, params)
    flat = jac[mask].reshape(-1, jac.shape[2])

    def shift(rows, change):
        moved = np.array(chain.dataset.centre_in_sensor, float)
        moved[list(rows)] += change
        other = chain.with_centres(moved)
        e_k, _, _ = other.prob.evaluate(other.structure, other.x, params)
        return np.linalg.lstsq(flat, -(e_k - e)[mask].ravel(), rcond=None)[0]

    return shift


def widening(shift, bend):
    """``(shifts (k, p), move (p,))``: the pose's shifts over ``bend``'s covariance eigen-directions, and its shift
    had the bend not been corrected (module docstring); ``shift``: the held chain's (:func:`_shifter`)."""
    values, vectors = np.linalg.eigh(bend.covariance)
    shifts = [shift(bend.rows, bend.dcentre @ (np.sqrt(max(lam, 0.0)) * v)) for lam, v in zip(values, vectors.T)]
    return np.array(shifts), shift(bend.rows, -bend.moved)


def unseen(shift, bend, covariance):
    """The :class:`~handeye.model.fit.power.Missable` depth bend of degree
    :data:`~handeye.model.geometry.profile_bend.SEEN_DEGREE` the profiles' test (at its level
    :data:`~handeye.model.geometry.profile_bend.ALPHA`) could have missed, or None without the profiles'
    information; ``shift``: the held chain's (:func:`_shifter`), ``covariance``: the pose's, on its parameters."""
    if bend.seen is None:
        return None
    info, dcentre = bend.seen
    step = 1e-3  # mm of a Legendre coefficient: the map is linear
    alias = np.column_stack([shift(bend.rows, dcentre[:, :, j] * step) / step for j in range(info.shape[0])])
    lam = power.detectable_noncentrality(info.shape[0], profile_bend.ALPHA)
    return power.missable_seen("a depth bend", "mm", alias, info, covariance, lam)


def _on(names, record):
    """``record``'s covariance (an UncertaintyRecord's, by parameter name) on ``names`` (the others unknown)."""
    index = {n: k for k, n in enumerate(record.parameter_names)}
    known = [k for k, n in enumerate(names) if n in index]
    theirs = [index[names[k]] for k in known]
    cov = np.diag([1e300] * len(names))
    cov[np.ix_(known, known)] = np.asarray(record.covariance)[np.ix_(theirs, theirs)]
    return cov


def _added(chain, mask, params, bend, record):
    """``(covariance added or None, its parameter names, note)``: what ``bend`` adds to the uncertainty
    ``record`` of the pose the chain is held at -- an applied bend's (:func:`widening`, :func:`_covariance`),
    or a suggested one's (:func:`_suspected`); None where it adds nothing."""
    shift, names = _shifter(chain, mask, params), chain.prob.names(chain.structure)
    if bend.applied:
        shifts, move = widening(shift, bend)
        return _covariance(shifts, move), names, _note(bend, shifts, move)
    if not bend.degree:
        return None, names, ""
    added, note = _suspected(shift, bend, _on(names, record))
    return added, names, note


def widened(record, chain, mask, bend):
    """An :class:`~handeye.app.present.result_parts.UncertaintyRecord` of a pose held (a saved calibration's,
    :mod:`handeye.app.engine.held_verdict`) widened as :func:`with_bend` widens a calibration's: the same
    covariance from the same data; unchanged without a bend."""
    if bend is None:
        return record
    added, names, _ = _added(chain, mask, {}, bend, record)
    return record if added is None else record.widened(added, names)


def with_bend(result, dataset):
    """``result`` with the uncertainty of the dataset's bend added to its covariance (module docstring: an
    applied one's, or a suggested one's) and a line saying it; unchanged without either or a converged fit."""
    bend = getattr(dataset, "bend", None)
    if bend is None or not result.converged or result.uncertainty.covariance is None:
        return result
    try:
        chain, mask, params = _held(cell_stage.dataset_at(result, dataset), result)
        added, names, note = _added(chain, mask, params, bend, result.uncertainty)
    except (np.linalg.LinAlgError, FloatingPointError, ValueError):
        return result if not bend.applied else dataclasses.replace(
            result, warnings=[*result.warnings, _note(bend, None, None)])
    if added is None:
        return result
    return dataclasses.replace(result, uncertainty=result.uncertainty.widened(added, names),
                               warnings=[*result.warnings, note])


def _suspected(shift, bend, covariance):
    """``(covariance added or None, note)`` of a bend BIC suggests but the tests do not make clear: the pose its
    correction would give lies within :data:`~handeye.model.fit.power.WIDEN_SD` of the added sd (along that
    move), and the bend the profiles could have missed (:func:`unseen`) where it moves the pose beyond the
    floor (:attr:`~handeye.model.fit.power.Missable.widening`); the note says both."""
    missed = unseen(shift, bend, covariance)
    beyond = missed is not None and missed.beyond_floor
    move = shift(bend.rows, bend.moved) if bend.moved is not None else np.zeros(len(covariance))
    move_mm, move_deg = _size(move[None])
    if move_mm <= power.SHIFT_FLOOR[0] / power.WIDEN_SD and move_deg <= power.SHIFT_FLOOR[1] / power.WIDEN_SD \
            and not beyond:
        return None, ""
    note = (f"an uncorrected {bend.bend_mm:.3g} mm depth bend of the profiles (sensor linearity): correcting it would "
            f"move the pose {move_mm:.2g} mm / {move_deg:.2g} deg, within {power.WIDEN_SD:g} of its 1 sd; the profiles "
            f"suggest it, but the tests do not make it clear ({bend.reason})")
    if beyond:
        note += f"; the profiles could have missed {missed.text()}, also in the sd"
    return np.outer(move, move) / power.WIDEN_SD**2 + (missed.widening if beyond else 0.0), note


def _covariance(shifts, move):
    """What a corrected bend adds to the pose's covariance (parameters of ``shifts``' columns): the jackknife's
    shifts, and :data:`~handeye.app.engine.levels.BEND_DOUBT` of the correction's move, per block (translation
    mm, rotation rad) in every direction."""
    doubt = np.zeros(len(move))
    doubt[:3] = BEND_DOUBT * np.linalg.norm(move[:3])
    doubt[3:6] = BEND_DOUBT * np.linalg.norm(move[3:6])
    return shifts.T @ shifts + np.diag(doubt**2)


def _size(shifts):
    """The largest translation (mm) and rotation (deg) of a set of pose shifts' covariance's 1-sd ellipsoid."""
    return (float(np.sqrt(np.max(np.linalg.eigvalsh(shifts[:, :3].T @ shifts[:, :3])))),
            float(np.degrees(np.sqrt(np.max(np.linalg.eigvalsh(shifts[:, 3:6].T @ shifts[:, 3:6]))))))


def _note(bend, shifts, move):
    lo, hi = bend.depths
    head = (f"a sensor linearity error corrected, the profiles bending {bend.bend_mm:.3g} mm along the sensor's depth "
            f"over {lo:.0f}-{hi:.0f} mm")
    why = (f"(F = {bend.f:.3g} on degree {bend.degree}; every profile was corrected and its centre rebuilt before the "
           "fit)")
    if shifts is None:
        return f"{head} {why}; the correction's uncertainty could not be carried into the sd"
    (mm, deg), (move_mm, move_deg) = _size(shifts), _size(move[None])
    return head + (f", which moved the pose by {move_mm:.2g} mm / {move_deg:.2g} deg; the 1 sd includes the "
                   f"correction's scatter over the profiles (up to {mm:.2g} mm / {deg:.2g} deg) and {BEND_DOUBT:g} of "
                   f"that move ({BEND_DOUBT * move_mm:.2g} mm / {BEND_DOUBT * move_deg:.2g} deg: what the correction's "
                   f"polynomial may miss, measured) {why}")
