"""Calibrating other parts of the cell than the sensor alone: the sphere, the positioner's axes.

``--unknowns`` names the parts estimated (``sensor``, ``sphere``, ``positioner``, ``+``-joined).
``sensor`` and ``sensor+sphere`` are the seed's problems and go through the stages of
:mod:`handeye.app.engine.calibrate` alone. Any other set takes one more stage, here:

1. The stages run on the *conditional* problem: the positioner at its current axes (nominal
   first), the sensor estimated even when it is known (so that screening, the global check and
   leave-one-out see the data as they are).
2. :class:`handeye.model.cell.CellModel` fits the requested parts together on the samples kept,
   holding the others (a known sensor from ``[sensor] pose`` or ``--calibration``; a known
   centre from ``[sphere] center``), after checking that the poses and axis angles determine every
   requested parameter (else :class:`CalibrationInputError` names what they cannot separate).
3. With the positioner free, the stages run again at the refined axes (screening against the
   better model) and the cell fit is repeated from there, until the samples kept stop changing
   (at most :data:`PASSES` runs).

The result is the conditional result with the cell fit's pose, centre, covariance,
identifiability, residual table (every sample at the cell fit, in the sphere mount's frame) and a
:class:`PositionerRecord`; screening, the global check, leave-one-out errors and the noise test
are the last conditional run's (at the refined axes).
"""
from __future__ import annotations

import dataclasses

import numpy as np

from handeye import solvers
from handeye.app.errors import CalibrationInputError
from handeye.model import conventions, identifiability
from handeye.model.cell import CellModel, pack, unpack
from handeye.model.pose import pose_from_transform, transform_from_pose

#: Iteration limit of the cell fit (Levenberg-Marquardt from the conditional fit: a few steps).
MAX_ITER = 200
#: Most runs of the conditional stages with the positioner free: the first at the set-up axes,
#: then at the refined ones until the samples kept stop changing.
PASSES = 4


@dataclasses.dataclass(frozen=True)
class PositionerRecord:
    """The positioner's axes as calibrated (or held), robot base frame, all angles zero.

    Attributes
    ----------
    axes : tuple of handeye.model.mounts.Axis
    nominal : tuple of handeye.model.mounts.Axis
        The axes of ``setup.toml``.
    point_sd : ndarray, shape (k, 3) or None
        1-sd of each axis's point, mm (it moves normal to the axis; along it is no parameter).
    direction_sd : ndarray, shape (k, 3) or None
        1-sd of each unit direction's components.
    tilt_sd_deg : ndarray, shape (k,) or None
        1-sd of the direction's tilt, degrees (root of the two normal variances' sum).
    calibrated : bool
    """

    axes: tuple
    nominal: tuple
    point_sd: np.ndarray | None = None
    direction_sd: np.ndarray | None = None
    tilt_sd_deg: np.ndarray | None = None
    calibrated: bool = False

    def to_dict(self):
        out = []
        for j, (axis, nom) in enumerate(zip(self.axes, self.nominal)):
            entry = axis.to_dict()
            entry["nominal"] = nom.to_dict()
            entry["point_sd"] = None if self.point_sd is None else [float(v) for v in self.point_sd[j]]
            entry["direction_sd"] = None if self.direction_sd is None else [float(v) for v in self.direction_sd[j]]
            entry["tilt_sd_deg"] = None if self.tilt_sd_deg is None else float(self.tilt_sd_deg[j])
            entry["calibrated"] = self.calibrated
            out.append(entry)
        return out


@dataclasses.dataclass(frozen=True)
class CellFit:
    """The cell fit: point, parts, covariance on the free step, identifiability."""

    model: CellModel
    x: np.ndarray
    sensor: np.ndarray
    centre: np.ndarray
    axes: tuple
    covariance: np.ndarray | None
    sigma: float
    ident: object
    converged: bool
    iterations: int
    message: str


def cell_model(dataset, free):
    """The cell model of a dataset: with the positioner free, the flange poses and the axis angles;
    otherwise the carrier motions (the positioner, if any, at its current axes)."""
    if "positioner" in free:
        return CellModel(np.asarray(dataset.flange2base()), dataset.centre_in_sensor, dataset.axis_angles,
                         dataset.mounts.axis_names, free)
    return CellModel(np.asarray(dataset.motions()), dataset.centre_in_sensor, np.zeros((len(dataset), 0)), (), free)


def check_determined(model, x, path):
    """Raise CalibrationInputError when the poses and angles leave a requested parameter free
    (the Jacobian's columns do not depend on the measured centres' noise: exact)."""
    ident = identifiability.analyse(model.jacobian(x), model.names, rtol=1e-7)
    if not ident.full_rank:
        raise CalibrationInputError(
            f"{path / 'measurements.csv'}: the poses and axis angles cannot separate (rank {ident.rank} of "
            f"{ident.n}): {ident.describe_null()}. Vary every positioner axis over at least three angles, "
            "and the robot's orientation about two axes, or hold one of the parts (--unknowns)")
    return ident


def fit(dataset, free, sensor, centre, mask):
    """Fit the ``free`` parts from the sensor 4x4 and centre given, on the samples of ``mask``."""
    model = cell_model(dataset, free)
    model = model.subset(np.asarray(mask, bool))
    axes = dataset.mounts.axes if "positioner" in free else ()
    x0 = pack(sensor, centre, axes)
    check_determined(model, x0, dataset.path)
    problem = solvers.Problem(n=model.n, residual=model.residual, jacobian=model.jacobian, retract=model.retract)
    res = solvers.solve(problem, x0, "lm", {"max_iter": MAX_ITER})
    r, jac = model.residual(res.x), model.jacobian(res.x)
    dof = max(len(r) - model.n, 1)
    sigma = float(np.sqrt(r @ r / dof))
    ident = identifiability.analyse(jac, model.names)
    cov = sigma**2 * np.linalg.inv(jac.T @ jac) if ident.full_rank else None
    s, c, ax = unpack(res.x, model.axis_names)
    return CellFit(model, res.x, s, c, ax if axes else (), cov, sigma, ident, bool(res.converged),
                   int(res.iterations), str(res.message))


def _block_sd(fitted, part_names):
    """1-sd of the named step coordinates (zeros where a part was held)."""
    names = fitted.model.names
    if fitted.covariance is None:
        return np.full(len(part_names), np.nan)
    sd = np.sqrt(np.clip(np.diag(fitted.covariance), 0, None))
    return np.array([sd[names.index(n)] if n in names else 0.0 for n in part_names])


def positioner_record(fitted, nominal, calibrated):
    """The axes with their 1-sd from the cell fit's covariance (module docstring of model/cell.py)."""
    from handeye.model.cell import normals

    axes = fitted.axes or nominal
    if not calibrated or fitted.covariance is None:
        return PositionerRecord(axes, nominal, calibrated=calibrated)
    names, cov = fitted.model.names, fitted.covariance
    point_sd, dir_sd, tilt = [], [], []
    for axis in axes:
        e = np.column_stack(normals(axis.direction))
        idx = [names.index(f"{axis.name}_{k}") for k in ("tilt1", "tilt2", "shift1", "shift2")]
        c_tilt, c_shift = cov[np.ix_(idx[:2], idx[:2])], cov[np.ix_(idx[2:], idx[2:])]
        point_sd.append(np.sqrt(np.clip(np.diag(e @ c_shift @ e.T), 0, None)))
        dir_sd.append(np.sqrt(np.clip(np.diag(e @ c_tilt @ e.T), 0, None)))
        tilt.append(np.degrees(np.sqrt(max(np.trace(c_tilt), 0.0))))
    return PositionerRecord(axes, nominal, np.array(point_sd), np.array(dir_sd), np.array(tilt), True)


def known_sensor(request, dataset):
    """The held sensor pose (4x4): ``--calibration``/``sensor_pose`` of the request, else ``[sensor] pose``."""
    pose = request.sensor_pose if request.sensor_pose is not None else dataset.sensor_pose
    return transform_from_pose(np.asarray(pose, float))


def mask_of(result):
    """Samples the conditional result used."""
    return np.asarray(result.residuals.used if hasattr(result.residuals, "used") else
                      [r.used for r in result.residuals], bool)


def extend(request, dataset, stages):
    """The cell stage (module docstring): ``stages(request, dataset)`` runs the conditional stages."""
    free = tuple(request.parts.split("+"))
    nominal = dataset.mounts.axes
    result = stages(request, dataset)
    if not _solved(result) or (not result.converged and "positioner" not in free):
        return dataclasses.replace(result, unknowns=request.parts)
    held = None if "sensor" in free else known_sensor(request, dataset)
    fitted = fit(dataset, free, result.sensor2flange if held is None else held, result.sphere_centre, mask_of(result))
    for _ in range(PASSES - 1 if "positioner" in free else 0):
        dataset = dataclasses.replace(dataset, mounts=refined_mounts(dataset, fitted))
        mask = mask_of(result)
        result = stages(request, dataset)
        if not _solved(result):
            break
        fitted = fit(dataset, free, fitted.sensor, fitted.centre, mask_of(result))
        if np.array_equal(mask, mask_of(result)):
            break
    return compose(request, dataset, result, fitted, free, nominal)


def _solved(result):
    """A finite conditional solution (it may still be refused: at set-up axes far from the true ones
    the conditional fit can "explain nothing"; the cell fit starts from it all the same)."""
    return result.rms_mm is not None and bool(np.all(np.isfinite(result.sensor2flange)))


def refined_mounts(dataset, fitted):
    """The mounts with the fitted axes as the cell fit's start (refining from where it stopped)."""
    return dataset.mounts.with_axes([a.point for a in fitted.axes], [a.direction for a in fitted.axes])


def final_residuals(dataset, result, fitted):
    """The residual table and its statistics at the cell fit (every sample, in the sphere mount's frame;
    the leave-one-out errors stay the conditional fit's)."""
    from handeye.app.present.results import ResidualTable

    data = dataclasses.replace(dataset, mounts=refined_mounts(dataset, fitted)) if fitted.axes else dataset
    xs = np.column_stack([data.centre_in_sensor, np.ones(len(data))])
    e = (data.motions() @ fitted.sensor @ xs[..., None])[:, :3, 0] - fitted.centre
    norms, used = np.linalg.norm(e, axis=1), mask_of(result)
    loo = getattr(result.residuals, "loo", None)
    if loo is None:
        loo = [getattr(r, "loo", float("nan")) for r in result.residuals]
    return {"residuals": ResidualTable(data.ids, data.rows, e, norms, used, loo),
            "rms_mm": float(np.sqrt(np.mean(norms[used] ** 2))), "max_residual_mm": float(norms[used].max()),
            "cost_mm2": float(0.5 * np.sum(norms[used] ** 2))}


def compose(request, dataset, result, fitted, free, nominal):
    """The conditional result with the cell fit's parts (module docstring)."""
    from handeye.app.present.results import Uncertainty

    sensor = fitted.sensor
    kuka = pose_from_transform(sensor)
    fit_part = dataclasses.replace(
        result.fit, **final_residuals(dataset, result, fitted), sensor2flange=sensor, sensor_pose_kuka=kuka,
        sensor_pose=conventions.pose_from(request.convention, sensor), sphere_centre=fitted.centre,
        converged=result.converged and fitted.converged and fitted.ident.full_rank,
        message=f"{result.message}; cell fit of {request.parts}: {fitted.message} ({fitted.iterations} iterations)")
    trans = _block_sd(fitted, ["tx", "ty", "tz"])
    rot = np.degrees(_block_sd(fitted, ["wx", "wy", "wz"]))
    centre_sd = _block_sd(fitted, ["cx", "cy", "cz"]) if "sphere" in free else None
    cov = fitted.covariance
    corr = None if cov is None else cov / np.sqrt(np.outer(np.diag(cov), np.diag(cov)))
    unc = dataclasses.replace(result.uncertainty, std=Uncertainty(trans, rot, centre_sd), sigma_mm=fitted.sigma,
                              parameter_names=tuple(fitted.model.names), covariance=cov, correlation=corr)
    warnings = list(result.warnings)
    if "sensor" not in free:
        warnings.append("the sensor pose is held at the one given (its sd is not in this result's; add it from its "
                        "own calibration)")
    if not fitted.ident.full_rank:
        warnings.append(f"at the solution the data do not determine: {fitted.ident.describe_null()}")
    positioner = None
    if dataset.mounts.sphere == "positioner":
        positioner = positioner_record(fitted, nominal, "positioner" in free)
    return dataclasses.replace(result, unknowns=request.parts, fit=fit_part, uncertainty=unc,
                               identifiability=fitted.ident, warnings=warnings, positioner=positioner)



def with_positioner_hint(result, dataset, parts):
    """A result with the positioner held at its set-up axes and residuals beyond the stated noise
    says that the axes may be the missing effect, and how to calibrate them."""
    test = result.noise_test
    if dataset.mounts.sphere != "positioner" or "positioner" in (parts or "") or test is None or test.passed:
        return result
    more = "+".join(p for p in ("sensor", "sphere", "positioner") if p in (parts or "").split("+") or p == "positioner")
    hint = (f"the positioner's axes are held as set up ([positioner] axes in {dataset.path / 'setup.toml'}); residuals "
            f"{test.ratio:.3g} x the stated noise may be their error: calibrate them with --unknowns {more}")
    return dataclasses.replace(result, warnings=[*result.warnings, hint])


def dataset_at(result, dataset):
    """The dataset with the positioner's axes the result calibrated (unchanged otherwise): what the
    result's chain is, for figures and checks of the centres through it."""
    positioner = getattr(result, "positioner", None)
    if positioner is None or not positioner.calibrated:
        return dataset
    return dataclasses.replace(dataset, mounts=dataset.mounts.with_axes(
        [a.point for a in positioner.axes], [a.direction for a in positioner.axes]))
