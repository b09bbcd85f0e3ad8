"""Calibrating other parts of the cell than the sensor alone: the sphere, the positioner's axes.

``--unknowns`` names the parts estimated (``sensor``, ``sphere``, ``positioner``, ``+``-joined).
``sensor`` and ``sensor+sphere`` are the seed's problems and go through the stages of
:mod:`handeye.app.engine.calibrate` alone. Any other set takes one more stage, here:

1. The stages run on the *conditional* problem: the positioner at its current axes (nominal
   first), the sensor estimated even when it is known (so that screening, the global check and
   leave-one-out see the data as they are).
2. The one chain model (:class:`handeye.model.fit.extended.Samples`, its blocks freed by a
   :class:`~handeye.model.fit.extended.Structure`) fits the requested parts together on the samples kept,
   holding the others (a known sensor from ``[sensor] pose`` or ``--calibration``; a known
   centre from ``[sphere] center``), after checking that the poses and axis angles determine every
   requested parameter (else :class:`CalibrationInputError` names what they cannot separate).
3. With the positioner free, the stages run again at the refined axes (screening against the
   better model) and the cell fit is repeated from there, until the samples kept stop changing
   (at most :data:`PASSES` runs).

The result is the conditional result with the cell fit's pose, centre, covariance,
identifiability, residual table (every sample at the cell fit, in the sphere mount's frame), noise
test and a :class:`~handeye.app.present.result_parts.PositionerRecord`; screening, the global
check and leave-one-out errors are the last conditional run's (at the refined axes). A held part
that the data contradict (the cell fit fails the noise test that the conditional fit, estimating
it, passed) is refused: not converged, exit 1, with both tests in the message.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from handeye.app.common.errors import CalibrationInputError
from handeye.app.engine.levels import FAR_ON_FLANGE_MM, HELD_FACTOR, P_HELD, SURELY_FAR_MM  # the verdict's levels, one place
from handeye.app.engine.request import DATA_EFFECTS  # the cell fit fits them with the parts
from handeye.app.present.residual_table import ResidualTable
from handeye.app.present.result_parts import PositionerRecord, Uncertainty
from handeye.model import effects as catalogue
from handeye.model.chain import conventions
from handeye.model.chain.mounts import inverse_transforms
from handeye.model.chain.pose import pose_from_transform, transform_from_pose
from handeye.model.common.statistics import f_survival
from handeye.model.design import identifiability
from handeye.model.fit.cell import PARTS, corrected_centres, normals
from handeye.model.fit.extended import Samples, Structure

#: Most runs of the conditional stages with the positioner free: the first at the set-up axes,
#: then at the refined ones until the samples kept stop changing.
PASSES = 4


@dataclasses.dataclass(frozen=True)
class CellFit:
    """The cell fit: the one chain model's fit (its samples, structure and :class:`~handeye.model.fit.extended.Fit`
    on the samples of ``mask``), its parts, covariance on the free step, identifiability."""

    prob: Samples
    structure: Structure
    fit: object
    mask: np.ndarray
    sensor: np.ndarray
    centre: np.ndarray
    axes: tuple
    covariance: np.ndarray | None
    sigma: float
    ident: object

    @property
    def x(self):
        return self.fit.x

    @property
    def params(self):
        """The data effects fitted with the parts: name -> parameters."""
        return self.fit.params

    @property
    def names(self):
        """The free step's coordinates (:func:`handeye.model.fit.cell.step_names` of the free blocks)."""
        return self.fit.names

    @property
    def n(self):
        return self.fit.p

    def residual(self):
        """The residuals (mm) of the samples fitted, stacked (3 m,)."""
        return self.fit.e[self.mask].ravel()


@dataclasses.dataclass(frozen=True)
class Start:
    """Where a cell fit starts (a :class:`CellFit` serves too): the sensor 4x4 and the centre (3,) in their mounts'
    frames (mm), the data effects fitted with the parts (name -> parameters)."""

    sensor: np.ndarray
    centre: np.ndarray
    params: dict = dataclasses.field(default_factory=dict)


def structure_of(dataset, free, axes=None, effects=()):
    """The one chain model's blocks for the ``free`` parts (``axes``: with the positioner free, the names of
    the axes estimated, None: all) and the data ``effects`` fitted with them."""
    turning = (tuple(dataset.mounts.axis_names) if axes is None else tuple(axes)) if "positioner" in free else ()
    return Structure(centre="sphere" in free, data_effects=tuple(effects), sensor="sensor" in free, axes=turning)


def check_determined(jac, names, path):
    """Raise CalibrationInputError when the poses and angles leave a requested parameter free
    (the Jacobian's columns do not depend on the measured centres' noise: exact)."""
    ident = identifiability.analyse(jac, names, rtol=1e-7)
    if not ident.full_rank:
        raise CalibrationInputError(
            f"{path / 'measurements.csv'}: the poses and axis angles cannot separate (rank {ident.rank} of "
            f"{ident.n}): {ident.describe_null()}. Vary every positioner axis over at least three angles, "
            "and the robot's orientation about two axes, or hold one of the parts (--unknowns)")
    return ident


def turning_axes(dataset, least=3):
    """Names of the positioner axes that take at least ``least`` distinct angles (the others' errors
    are constant: the sphere centre absorbs them, and they cannot be estimated)."""
    if dataset.axis_angles is None:
        return ()
    return tuple(name for name, col in zip(dataset.mounts.axis_names, np.asarray(dataset.axis_angles).T)
                 if len(np.unique(np.round(col, 6))) >= least)


def fit(dataset, free, start, mask, axes=None):
    """Fit the ``free`` parts (and the data effects ``start.params`` names) from ``start`` (:class:`Start`), on the
    samples of ``mask`` (``axes``: with the positioner free, the axes estimated; None: all)."""
    mask = np.asarray(mask, bool)
    effects = {name: np.asarray(v, float) for name, v in (start.params or {}).items()}
    prob, structure = Samples(dataset), structure_of(dataset, free, axes, tuple(effects))
    x0 = prob.point(structure, start.sensor, start.centre)
    names = prob.names(structure)
    check_determined(prob.evaluate(structure, x0, effects)[1][mask].reshape(-1, len(names)), names, dataset.path)
    fitted = prob.fit(structure, mask, x0, effects)
    jac = fitted.jac[mask].reshape(-1, fitted.p) if fitted.jac is not None else fitted.r_factor(mask)
    sigma = float(np.sqrt(fitted.ssr / max(fitted.m - fitted.p, 1)))
    ident = identifiability.analyse(jac, fitted.names)
    cov = sigma**2 * np.linalg.inv(jac.T @ jac) if ident.full_rank else None
    return CellFit(prob, structure, fitted, mask, prob.transform(fitted.x), prob.centre(structure, fitted.x),
                   prob.axes(structure, fitted.x) if "positioner" in free else (), cov, sigma, ident)


def _block_sd(fitted, part_names):
    """1-sd of the named step coordinates (zeros where a part was held)."""
    if fitted.covariance is None:
        return np.full(len(part_names), np.nan)
    sd, names = np.sqrt(np.clip(np.diag(fitted.covariance), 0, None)), fitted.names
    return np.array([sd[names.index(n)] if n in names else 0.0 for n in part_names])


def positioner_record(fitted, nominal, calibrated):
    """The axes with their 1-sd from the cell fit's covariance (module docstring of model/fit/cell.py)."""
    axes = fitted.axes or nominal
    if not calibrated or fitted.covariance is None:
        return PositionerRecord(axes, nominal, calibrated=calibrated)
    names, cov = fitted.names, fitted.covariance
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
    if not solved(result) or (not result.converged and "positioner" not in free):
        return dataclasses.replace(result, unknowns=request.parts)
    held = None if "sensor" in free else known_sensor(request, dataset)
    centre = result.sphere_centre if "sphere" in free else dataset.sphere_centre  # held: the setup's
    effects = data_effects(result)  # fitted with the parts, from the conditional fit's values
    fitted = fit(dataset, free, Start(result.sensor2flange if held is None else held, centre, effects), mask_of(result))
    for _ in range(PASSES - 1 if "positioner" in free else 0):
        dataset = dataclasses.replace(dataset, mounts=dataset.mounts.at(fitted.axes))  # the fitted axes: the next start
        mask = mask_of(result)
        result = stages(request, dataset)
        if not solved(result):
            break
        fitted = fit(dataset, free, fitted, mask_of(result))
        if np.array_equal(mask, mask_of(result)):
            break
    return compose(request, dataset, result, fitted, free, nominal)


def data_effects(result):
    """The data effects (:mod:`handeye.model.effects`, kind ``data``) a result calibrated: name -> parameters."""
    return {e.name: np.array(list(e.parameters.values()), float) for e in result.effects or ()
            if e.name in DATA_EFFECTS}


def solved(result):
    """A finite conditional solution (it may still be refused: at set-up axes far from the true ones
    the conditional fit can "explain nothing"; the cell fit starts from it all the same)."""
    return result.rms_mm is not None and bool(np.all(np.isfinite(result.sensor2flange)))


def final_residuals(dataset, result, fitted):
    """The residual table and its statistics at the cell fit (every sample, in the sphere mount's frame;
    the leave-one-out errors stay the conditional fit's)."""
    data = dataclasses.replace(dataset, mounts=dataset.mounts.at(fitted.axes)) if fitted.axes else dataset
    corrected = corrected_centres(data.centre_in_sensor, data.sphere_radius_mm, fitted.params)[0]
    xs = np.column_stack([corrected, np.ones(len(data))])
    e = (data.motions() @ fitted.sensor @ xs[..., None])[:, :3, 0] - fitted.centre
    norms, used = np.linalg.norm(e, axis=1), mask_of(result)
    loo = getattr(result.residuals, "loo", None)
    loo = [getattr(r, "loo", float("nan")) for r in result.residuals] if loo is None else loo
    return {"residuals": ResidualTable(data.ids, data.rows, e, norms, used, loo),
            "rms_mm": float(np.sqrt(np.mean(norms[used] ** 2))), "max_residual_mm": float(norms[used].max()),
            "cost_mm2": float(0.5 * np.sum(norms[used] ** 2))}


def reversed_axes(fitted, nominal):
    """Warnings for fitted axes that point against their set-up direction (the same rotations with the
    angles counted the other way round: right, but the setup's sign is not the controller's)."""
    turns = ((axis, float(np.degrees(np.arccos(np.clip(axis.direction @ nom.direction, -1.0, 1.0)))))
             for axis, nom in zip(fitted.axes, nominal))
    return [f"positioner axis {axis.name} points {turn:.1f} deg from its direction in [positioner] axes: its angles count "
            "the other way round (negate its direction in setup.toml, or check the controller's sign of that axis)"
            for axis, turn in turns if turn > 90.0]


def held_contradicted(dataset, request, fitted, free, mask):
    """The cell fit tested against the stated noise, and its held parts against the data:
    ``(NoiseTest, refusal or None)``. A held part (the sensor, the centre or the axes given) is
    contradicted when the same cell model with it estimated fits significantly and clearly better
    (F test below :data:`P_HELD`, RMS lower by :data:`HELD_FACTOR`): the pose at it is wrong."""
    from handeye.app.engine.describe import noise_test

    r = fitted.residual()
    test = noise_test(float(r @ r), len(r) - fitted.n, request.sigma, False, [], "")
    turning = turning_axes(dataset) if dataset.mounts.sphere == "positioner" else ()
    every = tuple(p for p in PARTS if p != "positioner" or turning)
    held = [p for p in every if p not in free]
    if not held:
        return test, None
    try:
        loose = fit(dataset, every, fitted, mask, axes=turning or None)  # the same effects, every part free
    except CalibrationInputError:
        return test, None  # the data cannot estimate what is held: nothing to contradict it
    q = loose.residual()
    k, dof = loose.n - fitted.n, len(q) - loose.n
    ssr_held, ssr_free = float(r @ r), float(q @ q)
    if dof <= 0 or ssr_free <= 0 or ssr_held < HELD_FACTOR**2 * ssr_free:
        return test, None
    p_value = f_survival(((ssr_held - ssr_free) / k) / (ssr_free / dof), k, dof)
    if p_value >= P_HELD:
        return test, None
    given = {"sensor": "the sensor pose given ([sensor] pose or --calibration)", "sphere": "the [sphere] center given",
             "positioner": "the [positioner] axes given"}
    return test, (f"not a calibration: what is held contradicts the data -- with {' and '.join(given[p] for p in held)}, "
                  f"the RMS is {np.sqrt(ssr_held / len(mask[mask]) ):.3g} mm per centre; estimating it too, "
                  f"{np.sqrt(ssr_free / len(mask[mask])):.3g} mm (F test p = {p_value:.2g}): another cell's, an old or a "
                  "mistyped value? Estimate it (--unknowns) or correct it")


def compose(request, dataset, result, fitted, free, nominal):
    """The conditional result with the cell fit's parts (module docstring)."""
    sensor = fitted.sensor
    test, refusal = held_contradicted(dataset, request, fitted, free, mask_of(result))
    fit_part = dataclasses.replace(
        result.fit, **final_residuals(dataset, result, fitted), sensor2flange=sensor,
        sensor_pose_kuka=pose_from_transform(sensor), sensor_pose=conventions.pose_from(request.convention, sensor),
        sphere_centre=fitted.centre, noise_test=test,
        converged=result.converged and fitted.fit.converged and fitted.ident.full_rank and refusal is None,
        message=refusal or f"{result.message}; then the cell fit of {request.parts} "
                           f"({'converged' if fitted.fit.converged else 'NOT converged'}: {fitted.fit.message})")
    held = "sensor" not in free
    trans = None if held else _block_sd(fitted, ["tx", "ty", "tz"])
    rot = None if held else np.degrees(_block_sd(fitted, ["wx", "wy", "wz"]))
    centre_sd = _block_sd(fitted, ["cx", "cy", "cz"]) if "sphere" in free else None
    cov = fitted.covariance
    corr = None if cov is None else cov / np.sqrt(np.outer(np.diag(cov), np.diag(cov)))
    unc = dataclasses.replace(result.uncertainty, std=Uncertainty(trans, rot, centre_sd), sigma_mm=fitted.sigma,
                              parameter_names=tuple(fitted.names), covariance=cov, correlation=corr,
                              dof=None, t_factor=None)  # the cell fit's sd: not Student-t scaled (yet)
    warnings = list(result.warnings) + ([refusal] if refusal else [])
    if held:
        warnings.append("the sensor pose is held at the one given (its sd is not in this result's; add it from its "
                        "own calibration); start and screening used a sensor pose estimated from these data")
    warnings += reversed_axes(fitted, nominal)
    if not fitted.ident.full_rank:
        warnings.append(f"at the solution the data do not determine: {fitted.ident.describe_null()}")
    positioner = positioner_record(fitted, nominal, "positioner" in free) if dataset.mounts.sphere == "positioner" else None
    out = dataclasses.replace(result, unknowns=request.parts, fit=fit_part, uncertainty=unc,
                              identifiability=fitted.ident, warnings=warnings, positioner=positioner)
    return _with_fitted_effects(out, fitted, dataset.sphere_centre)


def _with_fitted_effects(result, fitted, given_centre):
    """``result`` with the effects' values and 1-sd of the cell fit, which fitted them with the parts: the data
    effects', and ``sphere_center`` (the fitted centre's offset from ``given_centre``, the setup's)."""
    if not result.effects:
        return result
    sd = np.sqrt(np.clip(np.diag(fitted.covariance), 0, None)) if fitted.covariance is not None else None
    names = fitted.names
    values = {name: dict(zip(catalogue.get(name).PARAMS, p.tolist())) for name, p in fitted.params.items()}
    columns = {name: [f"{name}.{k}" for k in v] for name, v in values.items()}
    if "cx" in names and given_centre is not None:
        values["sphere_center"] = dict(zip(("dx", "dy", "dz"), (fitted.centre - given_centre).tolist()))
        columns["sphere_center"] = ["cx", "cy", "cz"]
    named = [dataclasses.replace(e, parameters=values[e.name], std=None if sd is None else {
        k: float(sd[names.index(c)]) for k, c in zip(values[e.name], columns[e.name])})
        if e.name in values else e for e in result.effects]
    return dataclasses.replace(result, catalogue=dataclasses.replace(result.catalogue, calibrated=named))


def _other_mount_fits_better(dataset):
    """Whether the other cell of the same data (the flange poses inverted: the sensor fixed and
    the sphere on the flange, or the other way round) fits about as well or better: the centre
    model's global minimum, centre free, RMS not above :data:`HELD_FACTOR` times this cell's. A
    long-stand-off sensor really on the flange (a real FANUC cell: 874 mm) fits clearly worse the
    other way (1.04 against 0.18 mm)."""
    from handeye.model.fit import global_fit

    if dataset.mounts.sphere == "positioner":
        return True  # no simple other cell to compare: keep the warning
    motions = np.asarray(dataset.motions())
    try:
        here = global_fit.centre_minima(motions, dataset.centre_in_sensor, None).best.cost
        other = global_fit.centre_minima(inverse_transforms(motions), dataset.centre_in_sensor, None).best.cost
    except global_fit.GlobalFitError:
        return True
    return bool(other < HELD_FACTOR**2 * here)  # not clearly worse


def with_mount_plausibility(result, dataset):
    """A warning when what the result puts on the flange lies farther than :data:`FAR_ON_FLANGE_MM`
    from it and the other cell of the same data fits clearly better: a sensor "on the flange" a
    metre away is a sensor fixed in the cell (and the other way round), since the same data fit
    both cells with the flange poses inverted."""
    if not solved(result):
        return result
    setup = dataset.path / "setup.toml"
    if dataset.mounts.sensor == "flange" and np.linalg.norm(result.sensor2flange[:3, 3]) > FAR_ON_FLANGE_MM:
        what = (f"the sensor's origin lies {np.linalg.norm(result.sensor2flange[:3, 3]):.0f} mm from the flange: if the "
                f"sensor is fixed in the cell and the robot carries the sphere, set [sensor] mount = \"world\" and "
                f"[sphere] mount = \"flange\" in {setup} (and write the flange poses as the robot reports them)")
    elif dataset.mounts.sphere == "flange" and np.linalg.norm(result.sphere_centre) > FAR_ON_FLANGE_MM:
        what = (f"the sphere's centre lies {np.linalg.norm(result.sphere_centre):.0f} mm from the flange: is the sphere "
                f"fixed in the cell and the sensor on the flange? ([sensor] and [sphere] mount in {setup})")
    else:
        return result
    far = np.linalg.norm(result.sensor2flange[:3, 3] if dataset.mounts.sensor == "flange" else result.sphere_centre)
    if far <= SURELY_FAR_MM and not _other_mount_fits_better(dataset):
        return result
    return dataclasses.replace(result, warnings=[*result.warnings, what])


def dataset_at(result, dataset):
    """The dataset with the positioner's axes the result calibrated (unchanged otherwise): what the
    result's chain is, for figures and checks of the centres through it."""
    positioner = getattr(result, "positioner", None)
    if positioner is None or not positioner.calibrated:
        return dataset
    return dataclasses.replace(dataset, mounts=dataset.mounts.at(positioner.axes))
