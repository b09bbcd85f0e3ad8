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
from handeye.model.datasets import observations
from handeye.model.fit.extended import Samples, Structure


class _Held:
    """The plain chain held at a result's pose: the pose shift of a change of the centres."""

    def __init__(self, dataset, result):
        self.mask = cell_stage.mask_of(result)
        centre_free = "sphere" in result.unknowns.split("+")
        pose = np.asarray(result.sensor2flange, float)
        centre = np.asarray(result.sphere_centre if result.sphere_centre is not None else dataset.sphere_centre, float)
        self.held = dataclasses.replace(dataset, sphere_centre=centre)
        self.metric = observations.centre_metric(self.held, pose, centre, self.mask, 9 if centre_free else 6)
        self.structure = Structure(centre=centre_free)
        prob = Samples(self.held, metric=self.metric)
        self.x = prob.point(self.structure, pose, centre)
        self.e, jac, _ = prob.evaluate(self.structure, self.x, {})
        self.jac = jac[self.mask].reshape(-1, jac.shape[2])
        self.names = prob.names(self.structure)

    def shift(self, rows, change):
        """The least-squares pose's shift (p,) when the centres of ``rows`` change by ``change`` (k, 3; mm)."""
        moved = np.array(self.held.centre_in_sensor, float)
        moved[list(rows)] += change
        e, _, _ = Samples(dataclasses.replace(self.held, centre_in_sensor=moved),
                          metric=self.metric).evaluate(self.structure, self.x, {})
        return np.linalg.lstsq(self.jac, -(e - self.e)[self.mask].ravel(), rcond=None)[0]


def _shifts(dataset, result, bend):
    """``(shifts (k, p), move (p,), names)``: the pose's shifts over ``bend``'s covariance eigen-directions,
    and its shift had the bend not been corrected."""
    held = _Held(dataset, result)
    values, vectors = np.linalg.eigh(bend.covariance)
    shifts = [held.shift(bend.rows, bend.dcentre @ (np.sqrt(max(lam, 0.0)) * v)) for lam, v in zip(values, vectors.T)]
    return np.array(shifts), held.shift(bend.rows, -bend.moved), held.names


def with_bend(result, dataset):
    """``result`` with the uncertainty of the dataset's applied bend added to its covariance (module
    docstring) and a line saying it; unchanged without an applied bend or a converged fit."""
    bend = getattr(dataset, "bend", None)
    if bend is None or not bend.applied or not result.converged or result.uncertainty.covariance is None:
        return result
    data = cell_stage.dataset_at(result, dataset)
    try:
        shifts, move, names = _shifts(data, result, bend)
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
