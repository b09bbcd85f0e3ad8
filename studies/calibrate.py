"""One calibration run: dataset in, checked, solved, reported as plain data.

The pipeline is: check the request (method and parametrisation fit together, enough
measurements), check that the robot poses determine every unknown (structural
identifiability, :func:`model.identifiability.structural`), solve with the chosen method,
and return a JSON-ready dict. Nothing here prints.
"""
from __future__ import annotations

import math

import numpy as np

import solvers
from model import identifiability
from model.calibration import ROTATIONS, UNKNOWNS, CalibrationModel
from model.dataset import GUESS_LIMITS
from model.pose import pose_from_transform, transform_from_pose
from studies.problems import calibration_problem

METHODS = ("ipopt", "gn", "lm", "tr", "dogleg", "newton")

#: Which rotation parametrisations each method can use.
SUPPORTED = {
    "ipopt": ("matrix", "euler"),
    "gn": ("local", "euler"),
    "lm": ("local", "euler"),
    "tr": ("local", "euler"),
    "dogleg": ("local", "euler"),
    "newton": ("local", "euler"),
}
#: Parametrisation used when none is asked for.
DEFAULT_ROTATION = {"ipopt": "matrix"}

#: Within this many degrees of B = +-90 the Euler angles A and C are nearly one rotation.
GIMBAL_WARN_DEG = 1.0


class CalibrationInputError(ValueError):
    """The request cannot be calibrated as asked (bad option, too few or degenerate poses)."""


def parse_pose(text, what="--start"):
    """Parse ``'X,Y,Z,A,B,C'`` (mm, degrees) into a pose; raises CalibrationInputError."""
    parts = [p.strip() for p in str(text).split(",")]
    if len(parts) != 6:
        raise CalibrationInputError(f"{what}: needs six comma-separated numbers X,Y,Z,A,B,C, got {text!r}")
    try:
        pose = np.array([float(p) for p in parts])
    except ValueError:
        raise CalibrationInputError(f"{what}: not a number in {text!r}") from None
    if not np.all(np.isfinite(pose)):
        raise CalibrationInputError(f"{what}: values must be finite, got {text!r}")
    for name, v, lim in zip("ABC", pose[3:], GUESS_LIMITS):
        if abs(v) > lim:
            raise CalibrationInputError(f"{what}: angle {name} = {v} out of range [-{lim:g}, {lim:g}] degrees")
    return pose


def min_measurements(unknowns):
    """Fewest measurements with more equations (3 each) than unknowns (6 or 9)."""
    n = 6 if unknowns == "sensor" else 9
    return n // 3 + 1


def check_request(dataset, unknowns, method, rotation):
    """Validate the combination; returns the rotation parametrisation to use."""
    if method not in METHODS:
        raise CalibrationInputError(f"--method: unknown {method!r}; choose one of {', '.join(METHODS)}")
    if unknowns not in UNKNOWNS:
        raise CalibrationInputError(f"--unknowns: unknown {unknowns!r}; choose one of {', '.join(UNKNOWNS)}")
    rotation = rotation or DEFAULT_ROTATION.get(method, "local")
    if rotation not in ROTATIONS:
        raise CalibrationInputError(f"--rotation: unknown {rotation!r}; choose one of {', '.join(ROTATIONS)}")
    if rotation not in SUPPORTED[method]:
        raise CalibrationInputError(
            f"--rotation {rotation} does not work with --method {method} (it supports {', '.join(SUPPORTED[method])}):"
            + (" the matrix entries need the orthogonality constraints only IPOPT handles" if rotation == "matrix" else "")
            + (" IPOPT has no retraction for the local parametrisation" if rotation == "local" else "")
        )
    need = min_measurements(unknowns)
    if len(dataset) < need:
        raise CalibrationInputError(
            f"{dataset.path / 'measurements.csv'}: {len(dataset)} measurement(s); unknowns {unknowns!r} "
            f"need at least {need} (3 equations each for {3 * need - 3} unknowns, plus redundancy)"
        )
    return rotation


def check_identifiable(dataset, unknowns, start_transform):
    """Raise CalibrationInputError when the robot poses leave an unknown undetermined."""
    probe = CalibrationModel(dataset.flange2base(), dataset.centre_in_sensor, dataset.sphere_centre, "local", unknowns)
    ident = identifiability.structural(probe, probe.point_from(start_transform))
    if not ident.full_rank:
        raise CalibrationInputError(
            f"{dataset.path / 'measurements.csv'}: the robot poses do not determine every unknown "
            f"(rank {ident.rank} of {ident.n}); undetermined direction(s): {ident.describe_null()}. "
            "Measure from poses with rotations about at least two different axes"
            + (", and not only translations (they cannot separate the sensor offset from the sphere centre)"
               if unknowns == "sensor+sphere" else "")
        )
    return ident


def _projected(transform):
    """The transform with its rotation block replaced by the nearest rotation (SVD)."""
    out = np.array(transform, dtype=float)
    if np.all(np.isfinite(out)):
        u, _, vt = np.linalg.svd(out[:3, :3])
        out[:3, :3] = u @ np.diag([1.0, 1.0, np.linalg.det(u @ vt)]) @ vt
    return out


#: A residual this many robust standard deviations above the median is flagged.
GROSS_ERROR_Z = 10.0


def _gross_error_warnings(ids, norms):
    """Flag residuals far above the rest (median + GROSS_ERROR_Z * 1.4826 MAD); never excludes."""
    med = float(np.median(norms))
    spread = 1.4826 * float(np.median(np.abs(norms - med)))
    limit = med + GROSS_ERROR_Z * max(spread, 1e-9)
    out = []
    for i, n in zip(ids, norms):
        if n > limit:
            out.append(
                f"measurement {i!r} has residual {n:.2f} mm, above {limit:.2f} mm (median {med:.2f} mm + "
                f"{GROSS_ERROR_Z:g} robust sd): a gross error is likely (misprint, wrong side, bad profile); "
                "the whole calibration is pulled by it -- check or remove that sample"
            )
    return out


def _orthogonality(rot):
    return float(np.linalg.norm(rot.T @ rot - np.eye(3))), float(np.linalg.det(rot))


def calibrate(dataset, unknowns="sensor", method="ipopt", rotation=None, start=None, options=None):
    """Calibrate the sensor pose on the flange from a dataset.

    Parameters
    ----------
    dataset : model.dataset.Dataset
    unknowns : {'sensor', 'sensor+sphere'}
    method : {'ipopt', 'gn', 'lm', 'tr', 'dogleg', 'newton'}
    rotation : {'matrix', 'local', 'euler'} or None
        None: ``matrix`` for IPOPT, ``local`` otherwise.
    start : array_like, shape (6,), optional
        Start sensor pose (KUKA, mm and degrees); default the dataset's ``start_pose``.
    options : dict, optional
        Solver options (:class:`solvers.Options`).

    Returns
    -------
    dict
        JSON-ready: ``sensor_pose``, ``sensor_matrix``, ``sphere_center``, ``rms_mm``,
        ``max_residual_mm``, ``residuals``, ``iterations``, ``converged``, ``status``,
        ``message``, ``method``, ``rotation``, ``unknowns``, ``identifiability``,
        ``hessian_eigenvalues`` (of the cost in the local chart: all positive at a minimum), ``warnings``,
        ``history`` (sensor poses of the iterates) and ``solver_point`` (the solver's own final
        point, e.g. the raw Euler angles before normalisation).
    """
    rotation = check_request(dataset, unknowns, method, rotation)
    start_pose = np.asarray(dataset.start_pose if start is None else start, dtype=float)
    start_t = transform_from_pose(start_pose)
    check_identifiable(dataset, unknowns, start_t)
    model = CalibrationModel(dataset.flange2base(), dataset.centre_in_sensor, dataset.sphere_centre, rotation, unknowns)
    problem = calibration_problem(model)
    x0 = model.point_from_pose(start_pose)
    result = solvers.solve(problem, x0, method=method, options=options)
    warnings = []
    rot_raw = model.sensor_rotation(result.x)
    converged = bool(result.converged)
    status, message = result.status, result.message
    if rotation == "matrix":
        orth, det = _orthogonality(rot_raw)
        if det <= 0:
            converged, message = False, f"{message}; but det R = {det:.3g} <= 0: a reflection, not a rotation"
        if orth > 1e-6:
            warnings.append(f"R^T R - I has norm {orth:.2e}; R is reported projected onto SO(3)")
    sensor = _projected(model.sensor2flange(result.x))  # a no-op but for 'matrix'
    if not np.all(np.isfinite(sensor)):
        converged, message = False, "numerical failure: non-finite result"
    pose = pose_from_transform(sensor)
    if abs(abs(pose[4]) - 90.0) < GIMBAL_WARN_DEG:
        warnings.append(
            f"B = {pose[4]:.4f} deg is within {GIMBAL_WARN_DEG:g} deg of the Euler singularity: A and C are "
            "nearly one rotation and are not separately meaningful; compare transforms, not angles"
        )
    centre = model.sphere_centre(result.x)
    check = CalibrationModel(model.flange2base, model.centre_in_sensor, centre, "local", unknowns)
    e = check.residuals(check.point_from(sensor, centre))
    norms = np.linalg.norm(e, axis=1)
    warnings += _gross_error_warnings(dataset.ids, norms)
    # judged in the local chart, free of the Euler singularity and of the matrix constraints
    final = check.point_from(sensor, centre)
    ident = identifiability.analyse(check.jacobian(final), check.names)
    hess_eig = np.linalg.eigvalsh(check.cost_hessian(final))
    if converged and hess_eig[0] < -1e-9 * max(1.0, abs(hess_eig[-1])):
        converged = False
        message = (f"{message}; but the cost Hessian has a negative eigenvalue ({hess_eig[0]:.3g}): a saddle "
                   "point, not a minimum (local Newton converges to any stationary point)")
    if not ident.full_rank:
        warnings.append(f"at the solution the data do not determine: {ident.describe_null()}")
    history = [pose_from_transform(_projected(model.sensor2flange(x))).tolist() for x in result.history]
    return {
        "dataset": dataset.name,
        "method": method,
        "rotation": rotation,
        "unknowns": unknowns,
        "start_pose": start_pose.tolist(),
        "sensor_pose": pose.tolist(),
        "sensor_matrix": sensor.tolist(),
        "sphere_center": centre.tolist(),
        "rms_mm": float(math.sqrt(np.mean(norms**2))),
        "max_residual_mm": float(norms.max()),
        "residuals": [
            {"id": i, "row": r, "vector": v.tolist(), "norm": float(n)}
            for i, r, v, n in zip(dataset.ids, dataset.rows, e, norms)
        ],
        "cost_mm2": float(0.5 * np.sum(norms**2)),
        "iterations": int(result.iterations),
        "evaluations": {"f": result.nfev, "jacobian": result.njev, "hessian": result.nhev},
        "converged": converged,
        "status": int(status),
        "message": message,
        "identifiability": ident.as_dict(),
        "hessian_eigenvalues": hess_eig.tolist(),
        "warnings": warnings,
        "history": history,
        "solver_point": result.x.tolist(),
        "solver_extra": {k: v for k, v in result.extra.items() if k in ("rank_deficient_steps", "return_status")},
    }
