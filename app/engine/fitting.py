"""The final fit: one observation model built once, solved from a start and judged.

A solver's return string is not a verdict: :func:`judge` checks the first-order conditions
and the Hessian at the returned point on the local chart (free of the Euler singularity and of
the matrix constraints), polishes a solver that stopped next to a minimum by trust-region
Newton, and says what it did. :class:`FinalFit` holds the model and its problem (built once
per calibration) and solves from any start: the user's, the closed form's, or a minimum of
the centre model (:mod:`handeye.app.engine.guarantee`).
"""
from __future__ import annotations

import dataclasses

import numpy as np

from handeye import solvers
from handeye.app.engine import guarantee
from handeye.app.engine.problems import calibration_problem
from handeye.model.chain.pose import pose_from_transform
from handeye.model.common.rotation import nearest_transform, transform_distance
from handeye.model.fit.closed_form import ClosedFormError, closed_form_estimate

#: A converged point must be stationary on the local chart too: |grad| <= LOCAL_GTOL max(1, f).
LOCAL_GTOL = 1e-4
#: Iterations of the trust-region Newton polish of a solver that stopped early, and how far
#: (mm, deg) the polish may move its point: farther, the solver did not stop next to a minimum,
#: and the closed-form restart decides instead.
POLISH_ITER = 50
POLISH_MAX_MM = 1.0
POLISH_MAX_DEG = 1.0


@dataclasses.dataclass
class Verdict:
    """A solver result judged: final transform and centre, convergence, local-chart diagnostics.

    Attributes
    ----------
    model : handeye.model.fit.calibration.CalibrationModel
        The model solved (the request's parametrisation).
    result : handeye.solvers.OptimizeResult
    sensor : ndarray, shape (4, 4)
        Sensor in flange (mm), projected onto SE(3).
    centre : ndarray, shape (3,)
        Sphere centre in the base (mm).
    converged : bool
        First-order conditions and a positive semi-definite Hessian on the local chart.
    message : str
    notes : list of str
    local : CalibrationModel or None
        The same rows on the local chart; None after a numerical failure.
    hess_eig : ndarray or None
        Eigenvalues of the cost Hessian on the local chart.
    """

    model: object
    result: object
    sensor: np.ndarray
    centre: np.ndarray
    converged: bool
    message: str
    notes: list
    local: object = None
    hess_eig: np.ndarray | None = None


def _matrix_checks(model, result, converged, message, notes):
    if model.rotation == "matrix":
        rot = model.sensor_rotation(result.x)
        orth, det = float(np.linalg.norm(rot.T @ rot - np.eye(3))), float(np.linalg.det(rot))
        if det <= 0:
            converged, message = False, f"{message}; but det R = {det:.3g} <= 0: a reflection, not a rotation"
        if orth > 1e-6:
            notes.append(f"R^T R - I has norm {orth:.2e}; R is reported projected onto SO(3)")
    return converged, message


def _polished(local, final, sensor, result):
    """(point, message, note) after a trust-region Newton polish (exact Hessian, on the local chart:
    the minimum to machine precision when ``final`` is in its basin), or None when it did not
    converge or moved too far."""
    polished = solvers.solve(calibration_problem(local), final, "tr", {"max_iter": POLISH_ITER})
    converged = polished.converged and np.all(np.isfinite(polished.x))
    dt, dr = transform_distance(local.sensor2flange(polished.x), sensor) if converged else (np.inf, np.inf)
    if dt > POLISH_MAX_MM or dr > POLISH_MAX_DEG:
        return None
    note = (f"{result.method} stopped before its convergence test ({result.message}) {dt:.2g} mm and {dr:.2g} deg from "
            f"the minimum; polished by trust-region Newton on the local chart ({polished.iterations} iterations), where "
            "the first-order conditions hold")
    message = (f"first-order conditions met on the local chart after a trust-region Newton polish "
               f"({result.method} had stopped early: {result.message})")
    return polished.x, message, note


def judge(model, result, polish=True):
    """Final transform, convergence verdict and local-chart diagnostics of a solver result.

    The verdict is the first-order conditions at the returned point on the local chart (and a
    positive semi-definite Hessian), not the solver's return string alone: a solver that stops
    early (IPOPT's ``Search_Direction_Becomes_Too_Small`` next to the minimum) is polished by
    trust-region Newton when ``polish``, and the message says so.
    """
    notes = []
    converged, message = _matrix_checks(model, result, bool(result.converged), result.message, notes)
    sensor = nearest_transform(model.sensor2flange(result.x))  # a no-op but for 'matrix'
    centre = model.sphere_centre(result.x)
    if not (np.all(np.isfinite(sensor)) and np.all(np.isfinite(centre))):
        return Verdict(model, result, sensor, centre, False, "numerical failure: non-finite result", notes)
    local = model.with_rotation("local", centre)
    final = local.point_from(sensor, centre)
    if not converged and polish and (done := _polished(local, final, sensor, result)) is not None:
        final, message, note = done
        notes.append(note)
        converged, sensor, centre = True, local.sensor2flange(final), local.sphere_centre(final)
    hess_eig = np.linalg.eigvalsh(local.cost_hessian(final))
    grad_local = float(np.max(np.abs(local.gradient(final))))
    if converged and grad_local > LOCAL_GTOL * max(1.0, local.cost(final)):
        converged, message = False, (f"{message}; but the gradient on the local chart is {grad_local:.3g}: stationary only "
                                     f"in the {model.rotation} chart, which is singular here (gimbal lock), not a minimum")
    elif converged and hess_eig[0] < -1e-9 * max(1.0, abs(hess_eig[-1])):
        converged, message = False, (f"{message}; but the cost Hessian has a negative eigenvalue ({hess_eig[0]:.3g}): "
                                     "a saddle point, not a minimum (local Newton converges to any stationary point)")
    return Verdict(model, result, sensor, centre, converged, message, notes, local, hess_eig)


class FinalFit:
    """The final fit of a calibration: its observation model and problem, built once.

    Parameters
    ----------
    used : handeye.model.datasets.dataset.Dataset
        The samples kept after screening (with a sphere centre: the known one, or the start
        value of a free one).
    model : handeye.model.fit.calibration.CalibrationModel
        The final residual model of those samples (the request's parametrisation and weights).
    request : handeye.app.engine.request.CalibrationRequest
        Checked (:meth:`~handeye.app.engine.request.CalibrationRequest.checked`).
    kind : {'centre', 'measurement', 'points'}
    """

    def __init__(self, used, model, request, kind):
        self.used, self.model, self.request, self.kind = used, model, request, kind
        self.problem = calibration_problem(model)

    def solve(self, start_pose, centre=None):
        """The judged fit from a KUKA start pose (mm, deg) and, for a free centre, a start centre."""
        x0 = self.model.point_from_pose(start_pose, centre)
        result = solvers.solve(self.problem, x0, method=self.request.method, options=self.request.solver_options)
        return judge(self.model, result, polish=self.request.polish)

    def from_minimum(self, sensor2flange, centre, exact=False):
        """The fit from a centre-model minimum; with ``exact`` the minimum itself when the
        solver ends next to it (the SVD solution of the unweighted centre model is exact)."""
        centre = None if self.request.unknowns == "sensor" else centre
        verdict = self.solve(pose_from_transform(sensor2flange), centre)
        if exact and verdict.local is not None and verdict.converged:
            dt, dr = transform_distance(verdict.sensor, sensor2flange)
            if dt <= guarantee.SAME_MM and dr <= guarantee.SAME_DEG:
                verdict = dataclasses.replace(verdict, sensor=np.array(sensor2flange, float))
        return verdict


def closed_form_pose(dataset, unknowns):
    """KUKA pose (mm, deg) of the closed-form estimate (the centre free with ``sensor+sphere``,
    and when the known centre leaves it undetermined)."""
    centre = None if unknowns == "sensor+sphere" else dataset.sphere_centre
    try:
        t, _ = closed_form_estimate(dataset.motions(), dataset.centre_in_sensor, centre)
    except ClosedFormError:
        if centre is not None:
            raise
        t, _ = closed_form_estimate(dataset.motions(), dataset.centre_in_sensor, dataset.sphere_centre)
    return pose_from_transform(t)
