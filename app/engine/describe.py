"""What a final fit says: residuals, uncertainty, leave-one-out, the noise and effect tests,
and the fit with catalogue effects (fields of :class:`handeye.app.present.results.CalibrationResult`).

:mod:`handeye.app.engine.calibrate` solves; this module describes what it solved, on the samples it
used and on every sample. Nothing here prints.
"""
from __future__ import annotations

import dataclasses
import pathlib
import shlex

import numpy as np

from handeye.app.common.errors import CalibrationInputError
from handeye.app.engine import effect_size, robot_choice, robust
from handeye.app.engine.levels import GROSS_ERROR_Z, NOISE_ALPHA  # the verdict's levels, one place
from handeye.app.present.residual_table import ResidualTable, SampleResidual
from handeye.app.present.result_parts import (
    EffectsRecord,
    FitRecord,
    NamedEffect,
    NoiseTest,
    PositionerRecord,
    ScreeningRecord,
    UncertaintyRecord,
)
from handeye.app.present.results import RMS_PER_CENTRE, CalibrationResult
from handeye.model import effects as catalogue
from handeye.model.chain import conventions
from handeye.model.chain.pose import pose_from_transform
from handeye.model.common.rotation import nearest_transform
from handeye.model.common.statistics import chi2_survival, covariance, covariance_normal
from handeye.model.datasets import observations
from handeye.model.datasets.dataset import DATA_DIR
from handeye.model.design import identifiability, robot_gate
from handeye.model.fit import extended
from handeye.model.fit.calibration import CalibrationModel
from handeye.model.geometry import circle
from handeye.model.readers.setup_file import NOISE_CENTRE_MM

#: How the warning of a failed noise test begins (:func:`noise_test`; an output that recomputes
#: the test, :mod:`handeye.app.engine.held_verdict`, writes its own instead of a saved one).
NOISE_WARNING = "the residuals are larger than the assumed noise"


def gross_error_warnings(ids, norms):
    """Flag residuals far above the rest (median + GROSS_ERROR_Z * 1.4826 MAD); never excludes."""
    med = float(np.median(norms))
    spread = 1.4826 * float(np.median(np.abs(norms - med)))
    limit = med + GROSS_ERROR_Z * max(spread, 1e-9)
    return [f"measurement {i!r} has residual {n:.2f} mm, above {limit:.2f} mm (median {med:.2f} mm + "
            f"{GROSS_ERROR_Z:g} robust sd): a gross error is likely (misprint, wrong side, bad profile); "
            "the whole calibration is pulled by it -- check or remove that sample" for i, n in zip(ids, norms) if n > limit]


def rms(values):
    values = np.asarray(values, float)
    values = values[np.isfinite(values)]
    return float(np.sqrt(np.mean(values**2))) if values.size else None


def _noise_model_text(local):
    rows = {"centre": "reconstructed centres", "measurement": "measured circles", "points": "profile points"}[local.kind]
    if local.kind == "points":
        weights = ("equal weights; covariance cluster-robust over the profiles (a robot pose error moves a whole "
                   "profile), sigma = sqrt(SSR/(m - p)) is the point scatter")
        return f"residual: {rows}; {weights}"
    if local.whiten is None:
        weights = "independent components with one common variance sigma^2, estimated as SSR/(m - p)"
    else:
        weights = ("each row whitened by its covariance (circle or sphere fit + robot repeatability); sigma_scale, estimated as "
                   "sqrt(SSR/(m - p)), should be near 1 and scales the covariance")
    return (f"residual: {rows}; {weights}; covariance sigma^2 (J^T J)^-1 on the local chart "
            "(rotation about the sensor's axes)")




def command_argument(dataset):
    """The dataset as a command to paste names it: an embedded dataset by its name (not the
    installed folder's path), a folder by the path it was given; quoted for the shell.

    An embedded name shadowed by a folder of that name in the current directory (which the
    command would read instead) is given by its full path.
    """
    path = pathlib.Path(dataset.path)
    return shlex.quote(dataset.name if path.parent == DATA_DIR and not pathlib.Path(dataset.name).exists() else str(path))


def diagnose_advice(dataset, centre_given=True):
    """``run `handeye diagnose DATASET``` as a command to paste; where the setup gives no sphere
    centre, with ``--unknowns sensor+sphere`` (the centre estimated with the pose there too)."""
    return f"run `handeye diagnose {command_argument(dataset)}" + ("`" if centre_given else " --unknowns sensor+sphere`")


def noise_test(ssr, dof, sigma, whitened, warnings, advice):
    """The fit against the stated noise (chi-square); a warning giving ``advice`` (the diagnose
    command, :func:`diagnose_advice`) when it fails."""
    if dof <= 0:
        return None
    statistic = float(ssr if whitened else ssr / sigma**2)
    ratio = float(np.sqrt(statistic / dof))
    p_value = float(chi2_survival(statistic, dof))
    nominal = ("noise (each row whitened by its stated covariance, so sd 1)" if whitened
               else f"{sigma:g} mm per component of a sphere centre")
    passed = not (p_value < NOISE_ALPHA and ratio > 1)
    if not passed:
        warnings.append(
            f"{NOISE_WARNING}: sd {ratio:.1f} x the {nominal} assumed (chi2 = {statistic:.4g} on {dof} dof, "
            f"p = {p_value:.2g}): the noise is larger than assumed ([noise] centre_mm in setup.toml or --sigma sets "
            f"it; without either, {NOISE_CENTRE_MM:g} mm), or the model lacks an effect; {advice} to see the discrepancy "
            "search's steps and what it tried")
    return NoiseTest(statistic, int(dof), p_value, ratio, nominal, passed, bool(whitened))


@dataclasses.dataclass(frozen=True)
class Described:
    """What the final fit is described from (:func:`effect_tests`, :func:`describe_fit`,
    :func:`with_effects`).

    Attributes
    ----------
    dataset : handeye.model.datasets.dataset.Dataset
    mask : ndarray of bool, shape (N,)
        Samples used.
    fit : handeye.app.engine.fitting.Verdict
        The final fit.
    request : handeye.app.engine.request.Request
        Checked: the effects, unknowns, level, leave-one-out and outlier switches, stated noise
        and convention.
    warnings : list of str
        Appended to.
    centre_given : bool
        The setup gave the sphere centre (else it was estimated: advice says to write it).
    """

    dataset: object
    mask: np.ndarray
    fit: object
    request: object
    warnings: list
    centre_given: bool = True


#: How the score tests' warning begins (calibrate's search replaces it with its own outcome).
STRUCTURE_WARNING = "the residuals show structure the model lacks"


def effect_tests(final):
    """Score tests of the catalogue's effects at the fit ``final`` (a :class:`Described`); a warning
    naming diagnose for a significant one that matters, whose fit moves the pose beyond the promise's floor
    (:mod:`handeye.app.engine.effect_size`: at 10^6 samples the test detects what moves it a micrometre;
    the test uses the fit's own scale, not the stated noise)."""
    dataset, fit, request, warnings = final.dataset, final.fit, final.request, final.warnings
    tests = robot_gate.score_effects(dataset, final.mask, fit.sensor, fit.centre, request.unknowns, skip=request.effects)
    at = effect_size.At(dataset, final.mask, fit.sensor, fit.centre, request.unknowns, tuple(request.effects))
    significant = [t for t in tests if t.p_bonferroni < request.alpha and effect_size.matters(at, t.name)]
    if significant:
        names = ", ".join(f"{t.name} (score {t.score:.3g}, Bonferroni p = {t.p_bonferroni:.2g})" for t in significant)
        warnings.append(f"{STRUCTURE_WARNING}: {names}; "
                        f"{diagnose_advice(dataset, final.centre_given)} to confirm and name it, then `handeye calibrate "
                        f"{command_argument(dataset)} --effects {significant[0].name}`")
    return tests


def with_effects(final, base):
    """The final fit with catalogue effects (the extended model, :mod:`handeye.model.fit.extended`).

    ``final`` is the :class:`Described` (its request names the effects, the stated noise and the
    convention); ``base`` is the :class:`~handeye.app.present.result_parts.FitRecord` of the fit
    without them. Returns the parts ``(FitRecord, UncertaintyRecord, Identifiability, list of
    NamedEffect, unknowns)`` of the fit with them; appends to ``final.warnings``."""
    dataset, mask, names = final.dataset, final.mask, final.request.effects
    structure = extended.Structure(centre=final.fit.local.unknowns == "sensor+sphere", data_effects=names)
    prob = extended.Samples(dataset, metric=observations.centre_metric(dataset, final.fit.sensor, final.fit.centre, mask,
                                                                       9 if structure.centre else 6))
    _choose_joints(final, prob, structure)
    efit, jac = _fit_with_effects(final, prob, structure)
    stuck = _not_a_minimum(dataset, mask, efit, names, prob.radius)
    if stuck is None:
        std, corr = efit.uncertainty(mask)
    else:  # the fit stopped against a bound, where the linearised sd means nothing
        std, corr = np.full(efit.p, np.nan), np.full((efit.p, efit.p), np.nan)
        jac = np.where(np.isfinite(jac), jac, 0.0)
    named = _named_effects(final, efit, std, stuck, final.centre_given and structure.centre)
    converged, message = _effects_verdict(final, efit, base, stuck)
    ident = identifiability.analyse(jac, efit.names, rows=efit.m)
    final.warnings.append(f"calibrated with the effects {', '.join(names) or 'sphere_center'} on the centre residual; "
                          "no leave-one-out error (the effects are fitted to every sample used)")
    sensor = prob.transform(efit.x)
    fitted = dataclasses.replace(
        base, sensor2flange=sensor, sphere_centre=np.asarray(prob.centre(structure, efit.x), float),
        sensor_pose_kuka=pose_from_transform(sensor), sensor_pose=conventions.pose_from(final.request.convention, sensor),
        converged=converged, message=message, **_effects_fit_fields(final, prob, efit))
    uncertainty = UncertaintyRecord.of_fit(corr * np.outer(std, std), efit.names, efit.m - efit.p,
                                           sigma_mm=float(np.sqrt(efit.sigma2)))
    return fitted, uncertainty, ident, named, "sensor+sphere" if structure.centre else "sensor"


def _choose_joints(final, prob, structure):
    """With robot effects (``joint_offsets``, ``link_lengths``, ``joint_compliance``): the
    parameters these poses separate from the sensor pose, the centre and the effects before it
    (:func:`handeye.model.design.robot_gate.gate_robot_effects`); the others are said in a warning; an
    effect with none: CalibrationInputError."""
    left = robot_gate.gate_robot_effects(prob, structure, final.mask, final.fit.sensor, final.fit.centre)
    for name, left_out in left.items():
        if not prob.robot_free[name]:
            raise CalibrationInputError(f"{final.dataset.path / 'measurements.csv'}: --effects {name}: these poses "
                                        "separate none of its parameters from the sensor pose and the sphere centre")
        if left_out:
            final.warnings.append(f"{name}: " + "; ".join(
                f"{j} not estimated (" + (f"too weakly seen: {who[0]})" if who[0].startswith("1 sd ")
                                          else f"absorbed by {', '.join(who)})") for j, who in left_out.items()))


def _fit_with_effects(final, prob, structure):
    """The extended fit ``structure`` of ``prob`` from the final fit, and its Jacobian of the used
    samples (many samples, fitted chunk by chunk: its triangular factor R, ``R^T R = J^T J``); a
    CalibrationInputError when the effects cannot be fitted on these data."""
    dataset, mask, fit = final.dataset, final.mask, final.fit
    with np.errstate(all="ignore"):
        efit = prob.fit(structure, mask, prob.point(structure, fit.sensor, fit.centre))
    jac = efit.jac[mask].reshape(-1, efit.p) if efit.jac is not None else efit.r_factor(mask)
    on_plane = np.any(dataset.centre_in_sensor[mask, 1] == 0)
    if not np.all(np.isfinite(efit.x)) or (on_plane and not np.all(np.isfinite(jac))):
        raise CalibrationInputError(
            f"{dataset.path / 'measurements.csv'}: --effects {','.join(final.request.effects)} cannot be fitted on these "
            "data: the effect has no derivative where a measured centre lies on the laser plane (ys = 0)")
    return efit, jac


def _named_effects(final, efit, std, stuck, centre_named):
    """The fitted effects as NamedEffect (with their 1 sd ``std``), the sphere centre's offset first
    when ``centre_named``."""
    dataset, mask, radius = final.dataset, final.mask, final.dataset.sphere_radius_mm
    index = {n: k for k, n in enumerate(efit.names)}
    named = [NamedEffect(n, dict(zip(_effect_params(n, efit), efit.params[n].tolist())),
                         {p: _finite_or_none(std[index[f"{n}.{p}"]]) for p in _effect_params(n, efit)},
                         _effect_sd_note(dataset, mask, efit, n, radius, stuck)) for n in final.request.effects]
    if centre_named:
        delta = efit.x[12:15] - dataset.sphere_centre
        named.insert(0, NamedEffect("sphere_center", dict(zip(("dx", "dy", "dz"), delta.tolist())),
                                    dict(zip(("dx", "dy", "dz"), std[6:9].tolist()))))
    return named


def _effects_verdict(final, efit, base, stuck):
    """(converged, message) of the fit with effects: not converged when an effect is implausible
    (appended to the warnings: an official-looking calibration it is not) or the fit did not converge."""
    names, radius = final.request.effects, final.dataset.sphere_radius_mm
    circles = circles_shown(final.dataset, final.mask) if "sphere_radius" in names else None
    implausible = [why for n in names
                   if (why := catalogue.implausible(n, efit.params[n], radius, circles, _effect_params(n, efit)))]
    if stuck is not None:
        implausible.append(stuck)
    if implausible:
        final.warnings.extend(implausible)
        return False, "; ".join(implausible)
    if not efit.converged:
        return False, f"the fit with the effects did not converge: {efit.message}"
    return base.converged, base.message


#: What the fit with effects weighs its residuals by, with and without centres rebuilt from profiles.
EFFECTS_METRIC = {False: "unweighted",
                  True: "each centre rebuilt from its profile whitened by its circle fit's covariance plus the chain's "
                        "isotropic part (observations.centre_metric), in mm at the samples' typical sd"}


def _effects_fit_fields(final, prob, efit):
    """The residual fields of the FitRecord of the fit with effects (its noise test appends to the warnings);
    ``prob`` the extended model's samples (their metric)."""
    dataset, mask, weighted = final.dataset, final.mask, prob.whiten is not None
    e = prob.raw(efit.e)
    norms = np.linalg.norm(e, axis=1)
    rms = float(np.sqrt(np.mean(norms[mask] ** 2)))
    return dict(
        n_used=int(mask.sum()), rms_mm=rms, max_residual_mm=float(norms[mask].max()),
        cost_mm2=float(0.5 * efit.ssr),
        residuals=ResidualTable(dataset.ids, dataset.rows, e, norms, mask),
        noise_model=("residual: reconstructed centres corrected by the effects, " + EFFECTS_METRIC[weighted] +
                     "; independent components with one common variance sigma^2 = SSR/(m - p); covariance "
                     "sigma^2 (J^T J)^-1 on the local chart"),
        rms_what=("RMS over the samples used of |e_i|, the distance (mm) of sample i's sphere centre, corrected by the "
                  "effects and carried through the calibrated chain, from the sphere centre: per sphere centre, "
                  "unweighted (the fit with the effects minimises it in the samples' metric where centres were rebuilt "
                  "from profiles, else as it is)"),
        objective={"model": "centre", "residual": "sphere centres corrected by the effects, through the chain (3 "
                   "components, mm)", "weighted": weighted, "rows": int(mask.sum()), "cost": float(0.5 * efit.ssr),
                   "rms": rms, "unit": "mm", "rms_unweighted_mm": rms,
                   "what": f"sphere centres corrected by the effects, {EFFECTS_METRIC[weighted]}: RMS of |e_i| per "
                           "sphere centre (unweighted), mm",
                   "short": "the unweighted RMS per sphere centre of the centres corrected by the effects"},
        noise_test=noise_test(efit.ssr, efit.m - efit.p, final.request.sigma, False, final.warnings,
                              diagnose_advice(dataset, final.centre_given)))


#: The fit with effects is a minimum when every column of its Jacobian is orthogonal to the
#: residual: |J_k^T e| <= EFFECT_COS |J_k| |e| (a regular fit: below 1e-7; one stopped against
#: the sphere_radius bound: 1e-4 to 1e-2, or an infinite derivative).
EFFECT_COS = 1e-5


def _finite_or_none(value):
    return float(value) if np.isfinite(value) else None


def circles_shown(dataset, mask):
    """What the data show of the sphere: per sample its id, the radius of the circle its laser
    plane cut (a profile's geometric circle fit with its 1 sd; for a used sample given as a
    centre without a profile ``sqrt(R^2 - ys^2)``, sd 0) -- ``(ids, r, sd)`` for
    :func:`handeye.model.effects.implausible`. Every profile counts, excluded or not (a gross
    error of the robot pose leaves its circle a circle of the sphere)."""
    radius = dataset.sphere_radius_mm
    ids, r, sd = [], [], []
    profiles = dataset.profiles or (None,) * len(dataset)
    for k, (ident, pts) in enumerate(zip(dataset.ids, profiles)):
        if pts is not None:
            try:
                c = circle.fit_circle(pts[:, 0], pts[:, 1], observations.CIRCLE_FIT)
                cov = circle.circle_covariance(pts[:, 0], pts[:, 1], c)
            except circle.CircleFitError:
                continue
            ids.append(ident), r.append(c.r), sd.append(float(np.sqrt(max(cov[2, 2], 0.0))))
        elif mask[k]:
            ids.append(ident), r.append(float(np.sqrt(max(radius**2 - dataset.centre_in_sensor[k, 1] ** 2, 0.0)))),
            sd.append(0.0)
    return ids, np.array(r), np.array(sd)


def _corrected_y(dataset, mask, extended, radius):
    """|y| of each used sample's centre corrected by the fitted data effects, and their ids."""
    xs = dataset.centre_in_sensor[mask]
    with np.errstate(all="ignore"):
        for name, params in extended.params.items():
            if catalogue.get(name).KIND == "data":  # a robot effect corrects the flange, not the centres
                xs, _ = catalogue.correct(name, xs, radius, params)
    return np.abs(xs[:, 1]), [i for i, u in zip(dataset.ids, mask) if u]


def _not_a_minimum(dataset, mask, extended, names, radius):
    """Why the fit with effects is not a minimum (text), or None: a Jacobian column not
    orthogonal to the residual (:data:`EFFECT_COS`) or not finite. For ``sphere_radius`` this
    is the fit stopped against the bound ``R + dr >= r_i`` (a corrected y of 0): the data ask
    for a sphere smaller than a circle measured on it."""
    e = extended.e[mask].ravel()
    cos = extended.gradient_cosines(mask)
    worst = float(np.max(np.where(np.isfinite(cos), cos, np.inf)))
    if worst <= EFFECT_COS or not np.linalg.norm(e) > 0:
        return None
    if "sphere_radius" in names:
        y, ids = _corrected_y(dataset, mask, extended, radius)
        k = int(np.nanargmin(y))
        r = float(np.sqrt(max(radius**2 - dataset.centre_in_sensor[mask][k, 1] ** 2, 0.0)))
        dr = float(extended.params["sphere_radius"][0])
        return (f"sphere_radius: the fit stops at dr = {dr:.4g} mm, a sphere radius of {radius + dr:.4f} mm, against "
                f"the {r:.4f} mm circle of sample {ids[k]!r} (its corrected y is {y[k]:.2g} mm): the data ask for a "
                "sphere smaller than a circle measured on it, which cannot be; not a minimum (the gradient does not "
                f"vanish: cosine {worst:.2g}), so no sd either: the radius absorbs something else (a sphere centre "
                "offset, a wrong [profile] side or a gross error?); it is not named")
    return (f"the fit with the effects {', '.join(names)} is not a minimum (a Jacobian column is not orthogonal to "
            f"the residual: cosine {worst:.2g} > {EFFECT_COS:g}); its sd would mean nothing")


def _effect_sd_note(dataset, mask, extended, name, radius, stuck):
    """What the 1 sd of effect ``name`` is and why it is the size it is (text), or None."""
    if name != "sphere_radius":
        return None
    if stuck is not None:
        return "no sd: the fit is not a minimum (see the message)"
    y, ids = _corrected_y(dataset, mask, extended, radius)
    k = int(np.nanargmin(y))
    dr = float(extended.params["sphere_radius"][0])
    gain = (radius + dr) / y[k]
    return (f"1 sd of the linearised fit, sigma (J^T J)^-1 with sigma = {np.sqrt(extended.sigma2):.4g} mm per "
            f"component: small against the residual because a radius change dr moves each reconstructed centre's y by "
            f"(R + dr)/|y| dr, up to {gain:.3g} x for sample {ids[k]!r} (|y| = {y[k]:.3g} mm, its laser plane "
            "near the sphere's equator); within about 10 % of a Monte Carlo on simulated data while the planes stay "
            "about 1 mm or more from the equator (tests/test_effect_sd.py); nearer, y's own noise grows like r/|y| "
            "and the sd is optimistic (the Monte Carlo's is 1.4 x at 0.5 mm on a 25.4 mm sphere)")


def _effect_params(name, efit):
    """The parameters an effect has in the fit (``joint_offsets``: its estimated joints only)."""
    return tuple(n.split(".", 1)[1] for n in efit.names if n.startswith(f"{name}."))


def describe_fit(final):
    """Residuals, uncertainty, identifiability and leave-one-out error of the final fit (``final``
    a :class:`Described`, its request's ``loo``, ``outliers`` and ``sigma``): ``(dict of FitRecord
    fields, UncertaintyRecord, Identifiability)``; appends to ``final.warnings``."""
    dataset, mask, fit, warnings = final.dataset, final.mask, final.fit, final.warnings
    loo, outliers_on, sigma = final.request.loo, final.request.outliers, final.request.sigma
    advice = diagnose_advice(dataset, final.centre_given)
    warnings.extend(filter(None, [robot_choice.unmodelled(dataset)]))
    local, sensor, centre = fit.local, fit.sensor, fit.centre
    e = _all_residuals(dataset, local.unknowns, sensor, centre)
    norms = np.linalg.norm(e, axis=1)
    final = local.point_from(sensor, centre)
    ident, cov, ssr = _fit_statistics(local, final)
    if not ident.full_rank:
        warnings.append(f"at the solution the data do not determine: {ident.describe_null()}")
    elif ident.observability["O2"] < identifiability.WEAK:
        warnings.append(
            f"the poses constrain one direction badly (inverse condition number {ident.observability['O2']:.2g} < "
            f"{identifiability.WEAK:g}): {ident.describe_weakest()}; add poses that move it (handeye plan)")
    loo_errors = _final_loo(dataset, mask, local, final, centre) if loo else np.full(len(mask), np.nan)
    if not outliers_on:
        warnings += gross_error_warnings(dataset.ids, norms)
    stats = dict(
        n_used=int(mask.sum()), rms_mm=float(np.sqrt(np.mean(norms[mask] ** 2))), max_residual_mm=float(norms[mask].max()),
        cost_mm2=float(0.5 * np.sum(norms[mask] ** 2)),
        residuals=ResidualTable(dataset.ids, dataset.rows, e, norms, mask, loo_errors),
        loo_error_mm=rms(loo_errors) if loo else None, loo=_loo_description(local, int(mask.sum())) if loo else None,
        rms_what=RMS_PER_CENTRE, objective=_objective(local, final), hessian_eigenvalues=fit.hess_eig,
        noise_model=_noise_model_text(local),
        noise_test=None if local.kind == "points" else noise_test(ssr, local.n_meas * local.m - local.n, sigma,
                                                                   local.whiten is not None, warnings, advice))
    uncertainty = UncertaintyRecord.of_fit(cov.matrix, local.names, cov.dof,
                                           sigma_mm=cov.sigma if local.whiten is None else None,
                                           sigma_scale=cov.sigma if local.whiten is not None else None)
    return stats, uncertainty, ident


def _all_residuals(dataset, unknowns, sensor, centre):
    """Residuals (N, 3) of every sample at the fit (the model of every sample freed after)."""
    allm = CalibrationModel.from_dataset(dataset, "local", unknowns, sphere_centre=centre)
    return allm.residuals(allm.point_from(sensor, centre))


def _fit_statistics(local, final):
    """Identifiability, covariance and sum of squares of the final model ``local`` at ``final``:
    above :data:`~handeye.model.design.identifiability.TALL` rows (independent ones) from the
    Jacobian's triangular factor and the normal equations, summed chunk by chunk."""
    if local.groups is None and local.n_meas > identifiability.TALL:
        rows = local.n_meas * local.m
        ident = identifiability.analyse(local.jacobian_r(final), local.names, rows=rows)
        jtj, _, ssr = local.normal_equations(final)
        return ident, covariance_normal(jtj, ssr, rows), float(ssr)
    r_used, j_used = local.residual(final), local.jacobian(final)
    ident = identifiability.analyse(j_used, local.names)
    cov = covariance(r_used, j_used, None if local.groups is None else np.repeat(local.groups, local.m))
    return ident, cov, float(r_used @ r_used)


def _final_loo(dataset, mask, local, final, centre):
    """Leave-one-out errors (N,) of the final fit: ``local`` (the final model of the samples in
    ``mask``: its residual kind, weights and unknowns) refitted without each sample, from
    ``final``; the error is sample i's sphere centre through the refitted chain
    (:func:`handeye.app.engine.robust.leave_one_out`). NaN for the samples not used."""
    if local.kind == "centre" and local.whiten is None and local.groups is None and local.rotation == "local":
        predictor = local  # its own centres: one evaluation per chunk, no second model of the samples
    else:
        predictor = CalibrationModel(dataset.motions()[mask], dataset.centre_in_sensor[mask], centre, "local",
                                     local.unknowns)
    out = np.full(len(mask), np.nan)
    out[mask] = robust.leave_one_out(local, final, None, predictor)
    return out


#: The rows of each residual model, in words (one row: m components).
_ROWS = {"centre": ("sphere centre", "sphere centres through the chain (3 components, mm)"),
         "measurement": ("circle", "circles (xc, zc, r) measured in the laser plane (3 components, mm)"),
         "points": ("profile point", "profile points' distances from the sphere surface (1 component, mm)")}


def _objective(local, final):
    """What the final fit minimised and its RMS (:attr:`CalibrationResult.objective`) at the
    point ``final`` of ``local`` (the final model, local chart)."""
    per, rows = _ROWS[local.kind]
    weighted = local.whiten is not None
    raw = local.residuals(final).reshape(local.n_meas, -1)
    unweighted = float(np.sqrt(np.mean(np.sum(raw**2, axis=1))))
    residual = local.residual(final)
    ssr = float(residual @ residual)
    if weighted:
        what = (f"{rows}, each whitened by its covariance (circle or sphere fit + robot repeatability): RMS of |W_i e_i| per "
                f"{per}, in units of its stated sd (about sqrt({local.m}) = {np.sqrt(local.m):.2f} when the noise is as "
                "stated)")
        short = f"the weighted RMS per {per} (whitened {rows.split(' (')[0]})"
    else:
        what = f"{rows}, unweighted: RMS of |e_i| per {per}, mm"
        short = f"the unweighted RMS per {per} ({rows.split(' (')[0]})"
    return {"model": local.kind, "residual": rows, "weighted": weighted, "rows": int(local.n_meas), "cost": 0.5 * ssr,
            "rms": float(np.sqrt(ssr / local.n_meas)), "unit": "sd" if weighted else "mm",
            "rms_unweighted_mm": unweighted, "what": what, "short": short}


def _loo_description(local, n_used):
    """How the final fit's leave-one-out error was made (:attr:`CalibrationResult.loo`)."""
    per = _ROWS[local.kind][0]
    weights = "weighted as the fit" if local.whiten is not None else "unweighted"
    method = ("exact refit per sample in closed form (each an absolute orientation: the cross-covariance of every "
              "sample downdated by the one left out, one batched SVD; handeye.app.engine.loo.closed_form_errors)"
              if robust.loo_in_closed_form(local, local) else
              "exact refit per sample (all at once: damped Gauss-Newton, or Newton where the residuals are large, "
              "from the full fit, whose first step is the deletion formula; handeye.app.engine.loo)"
              if n_used <= robust.LOO_EXACT_UP_TO else
              "deletion formula (the exact update of the linearised fit); samples of high leverage refitted exactly")
    return {"model": local.kind, "weighted": local.whiten is not None, "unknowns": local.unknowns, "method": method,
            "what": (f"the final model (--model {local.kind}: {per} rows, {weights}, unknowns {local.unknowns}) refitted "
                     "without each used sample; the error is that sample's sphere centre carried through the refitted "
                     "chain against the refitted sphere centre, |T1_i T2_(-i) xs_i - c_(-i)| (mm): comparable across "
                     "models; loo_error_mm is its RMS over the samples used")}


def kuka_pose(sensor2flange):
    """KUKA pose (mm, deg) of a 4x4; NaN when it is not finite (a numerical failure)."""
    t = np.asarray(sensor2flange, float)
    return pose_from_transform(t) if np.all(np.isfinite(t)) else np.full(6, np.nan)


def _fit_record(prep, verified):
    """The :class:`FitRecord` of the verified fit, before its residuals are described."""
    fit, request = verified.fit, prep.request
    result, convention = fit.result, request.convention
    finite = np.all(np.isfinite(fit.sensor))
    return FitRecord(
        sensor2flange=fit.sensor, sensor_pose_kuka=kuka_pose(fit.sensor),
        sensor_pose=(conventions.pose_from(convention, fit.sensor) if finite
                     else np.full(len(conventions.columns(convention)), np.nan)),
        sphere_centre=fit.centre, converged=fit.converged and verified.refusal is None, status=int(result.status),
        message=fit.message if verified.refusal is None else f"{verified.refusal} (the solver: {fit.message})",
        iterations=int(result.iterations), evaluations={"f": result.nfev, "jacobian": result.njev, "hessian": result.nhev},
        history=np.array([kuka_pose(nearest_transform(fit.model.sensor2flange(x))) for x in result.history]).reshape(-1, 6),
        solver_point=np.asarray(result.x, float),
        solver_extra={k: v for k, v in result.extra.items() if k in ("rank_deficient_steps", "return_status")})


def result(prep, screened, verified, warnings):
    """The :class:`CalibrationResult` of the stages' records (:mod:`handeye.app.engine.calibrate`)."""
    request, dataset, mask = prep.request, prep.dataset, screened.mask
    warnings = [*prep.warnings, *screened.warnings, *warnings, *verified.warnings]
    base = _fit_record(prep, verified)
    start = prep.start_pose
    # a positioner's axes as set up (held: the stages work at these axes)
    positioner = PositionerRecord(dataset.mounts.axes, dataset.mounts.axes) if dataset.mounts.sphere == "positioner" else None
    header = dict(
        dataset=dataset.name, dataset_path=str(dataset.path), dataset_sha256=dataset.content_hash(),
        method=request.method, rotation=request.rotation, unknowns=request.unknowns, model=prep.kind,
        robot_sigma_mm=request.robot_sigma if prep.kind != "centre" or dataset.profiles is not None else None,
        start_pose=conventions.convert(start, "kuka", request.convention) if request.convention != "kuka" else start,
        start_pose_kuka=start, start_used=verified.start_used, convention=request.convention,
        columns=conventions.columns(request.convention), global_check=verified.global_check,
        screening=ScreeningRecord(list(screened.excluded), screened.before), warnings=warnings,
        sensor_mount=dataset.mounts.sensor, sphere_mount=dataset.mounts.sphere, positioner=positioner,
        robot_model=None if getattr(dataset, "robot_model", None) is None else dataset.robot_model.spec)
    fit = verified.fit
    if fit.local is None:  # numerical failure: nothing to describe, but the same complete type
        residuals = [SampleResidual(i, int(r), np.full(3, np.nan), float("nan"), bool(u))
                     for i, r, u in zip(dataset.ids, dataset.rows, mask)]
        return CalibrationResult(fit=dataclasses.replace(base, residuals=residuals, n_used=int(mask.sum())), **header)
    final = Described(dataset, mask, fit, request, warnings, prep.centre_given)
    tests = effect_tests(final)
    if request.effects:
        fitted, uncertainty, ident, named, unknowns = with_effects(final, base)
        return CalibrationResult(**dict(header, model="centre", unknowns=unknowns), fit=fitted, uncertainty=uncertainty,
                                 identifiability=ident, catalogue=EffectsRecord(tests, named))
    stats, uncertainty, ident = describe_fit(final)
    return CalibrationResult(**header, fit=dataclasses.replace(base, **stats), uncertainty=uncertainty,
                             identifiability=ident, catalogue=EffectsRecord(tests, None))
