"""calibrate is the search: the pose under the model the data choose, or no pose.

After the stages (:mod:`handeye.app.engine.calibrate`) have fitted the requested model, the
discrepancy search of ``handeye diagnose`` (:func:`handeye.app.engine.diagnose.diagnose`: the
catalogue's score tests, each candidate confirmed by an F test, Delta BIC and a held-out error,
plausibility, the robot effects compared as alternatives) runs on the same data, at the same
level and stated noise, from calibrate's pose. Its outcome decides calibrate's:

- it names no effect: the requested model is the one the data choose; the result stands;
- it names catalogue effects: the result is the fit *with* them (the same as ``handeye calibrate
  --effects NAMES``), each effect named with its sd and a warning saying the search chose it; a
  fit with them that fails (an implausible value, no convergence) is refused;
- the nearest effect to the discrepancy lies beyond the catalogue's physical range (a pairing
  shift, profiles of no sphere, a scale of ten per cent): "unexplained structure", refused
  (exit 1) with the search's evidence.

The model is the user's where ``--effects`` is given (``none`` for no effect) or a profile
residual model is asked for (``--model measurement|points``: the effects need the centre
residual); the search then checks it instead of choosing: where the search's model differs
(or ``--keep-all`` keeps samples the search excludes), a pose the search puts more than
:data:`handeye.app.engine.levels.AGREE_SD` of the reported pose's own sd away (Mahalanobis
distance on 6 dof) is refused (exit 1). Poses of one model are not compared: they differ only
by the samples each excludes or flips back, and a 1-sd limit would refuse good data for that.

A sphere on a positioner is searched at the axes the result stands on (set up, or calibrated by
``--unknowns ...+positioner``: :func:`handeye.app.engine.cell_stage.dataset_at`). Where the search
finds the set-up axes off, the positioner's own test refuses next
(:func:`handeye.app.engine.positioner_effect.with_positioner_hint`, naming ``--unknowns
...+positioner``); where it names data effects on top of calibrated axes, the cell stage fits them
together with the axes (:func:`handeye.app.engine.cell_stage.fit`: a 0.2 % sensor scale had put a
calibrated-axes pose 0.66 mm, 42 sd, from the truth; refused since; now 0.10 mm, 2.5 sd, the scale
0.00196 +- 0.00009); a sphere centre or robot effect beside them whose pose lies beyond ``AGREE_SD`` of
the result's sd is refused (:func:`_beside_axes`), within it a warning names it.

So calibrate does not exit 0 with a model its search replaces. Data of more than ``ROW_CHUNK`` samples
are searched on that many spread over the rows (:func:`searched_samples`; a warning says so), the model
chosen fitted to all. Left to other checks: a held sensor (the cell stage's own test of held parts), the
closed-form methods and a fit that did not converge.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from handeye.app.engine import cell_stage, diagnose
from handeye.app.engine.agreement import UNEXPLAINED, same_pose
from handeye.app.engine.describe import STRUCTURE_WARNING, command_argument
from handeye.app.engine.levels import AGREE_SD, AMBIGUOUS, AT_NOISE, POWER_WARN_GROWTH
from handeye.model.common.rotation import chart_shift, pose_distance
from handeye.model.fit.calibration import ROW_CHUNK
from handeye.model.fit.extended import spread
from handeye.model.fit.power import SHIFT_FLOOR, WIDEN_SD

#: Effects the search names that are not a model the stages can take: sign flips are samples; the
#: positioner's axes are the cell stage's (``--unknowns ...+positioner``).
NOT_A_MODEL = ("sign_flip", "positioner_axes")
#: How the warning of models the search could not tell apart begins (:func:`with_rivals`).
RIVALS_WARNING = "the robot's errors are not settled: other models"
#: How the warning of a widened uncertainty begins (:func:`with_power`).
POWER_WARNING = "the data lack the power to see every effect (few samples, much noise): the 1 sd is widened"


def searchable(request, dataset, result):
    """Whether the search decides or checks this result (module docstring: what is left to other checks)."""
    return (result.converged and "sensor" in request.parts.split("+")
            and bool(np.all(np.isfinite(result.sensor2flange))))


def search(request, dataset, result):
    """The discrepancy search on the data of ``result``, from its pose (its sphere centre the
    start of a free one)."""
    data = dataset
    if request.unknowns == "sensor+sphere":
        data = dataclasses.replace(dataset, sphere_centre=np.asarray(result.sphere_centre, float))
    return diagnose.diagnose(data, alpha=request.alpha, start=result.sensor_pose_kuka, sigma=request.sigma,
                             centre_unknown=request.unknowns == "sensor+sphere", detail=request.story)


def chosen(request, dataset, result, refit):
    """The result under the model the data choose (module docstring).

    Parameters
    ----------
    request : handeye.app.engine.request.CalibrationRequest
        Checked.
    dataset : handeye.model.datasets.dataset.Dataset
    result : handeye.app.present.results.CalibrationResult
        Of the stages on ``request`` (handeye's frame).
    refit : callable
        ``refit(request, dataset)``: the stages on another (unchecked) request.

    Returns
    -------
    handeye.app.present.results.CalibrationResult
    """
    if not searchable(request, dataset, result):
        return result
    searched = searched_samples(cell_stage.dataset_at(result, dataset))
    try:
        found = search(request, searched, result)
    except (np.linalg.LinAlgError, FloatingPointError) as exc:
        return _unchecked_result(result, f"the search failed numerically ({exc})")
    decided = _decided(request, dataset, result, refit, found, searched)
    return dataclasses.replace(decided, search=found) if request.story else decided


def _decided(request, dataset, result, refit, found, searched):
    """The result the search's finding ``found`` (on the samples ``searched``) decides (module docstring)."""
    if found.beyond_catalogue:
        return result.refused("unexplained structure, not a calibration: the discrepancy search finds the residuals "
                               f"structured beyond what the catalogue's effects can be: {'; '.join(found.beyond_catalogue)}"
                               f" ({_command('diagnose', dataset, request)} prints its steps)")
    if any(e.name == "positioner_axes" for e in found.effects) and "positioner" not in request.parts:
        return result  # held axes that are off: the positioner's own test refuses next, naming the option
    names = _model_of(found)
    if names and request.cell and not request.chosen and not set(names) <= set(cell_stage.DATA_EFFECTS):
        result = _beside_axes(result, found, names, dataset, request)  # a centre or robot effect beside the axes
    elif names and not request.chosen:  # the model the data choose: the same model as the search's from here
        result = _with_effects(request, dataset, result, refit, names, found)
    elif len(searched) < len(dataset) and names_differ(found, request):  # its model fitted to every sample decides
        result = _against_search(result, _on_every_sample(request, dataset, found, refit), dataset, request)
    elif names_differ(found, request) or (found.outliers and not request.outliers and len(searched) == len(dataset)):
        result = _against_search(result, found, dataset, request)  # another model, or samples --keep-all keeps
    if len(dataset) > ROW_CHUNK:
        return dataclasses.replace(result, warnings=[*result.warnings, _subsample_note(len(dataset))])
    result = with_rivals(result, found.robot_rivals)
    return with_power(result, _statement(result, found, cell_stage.dataset_at(result, dataset)))


def with_rivals(result, rivals):
    """``result`` with its sd widened to hold the poses of the models the search could not tell from its own
    (``rivals``: ``(label, sensor2flange)``, :func:`handeye.app.engine.robot_choice.compare`'s, within a BIC of
    :data:`~handeye.app.engine.levels.AMBIGUOUS`): each rival's shift ``s`` adds ``s s^T / WIDEN_SD^2`` to the
    pose's covariance, so that every rival lies within :data:`~handeye.model.fit.power.WIDEN_SD` of the added
    sd (as a suggested bend's pose does); shifts within the floor's third are no widening. A robot's length error
    the search took for a taught centre off (an independent generator's UR10e, 0.13 mm of noise) had exited 0
    0.34 mm, 7 sd, from the truth; its rival, the length error, lay 0.30 mm away."""
    if not rivals or not result.converged or result.covariance is None:
        return result
    base, added, said = np.asarray(result.sensor2flange, float), np.zeros((6, 6)), []
    for label, pose in rivals:
        pose = np.asarray(pose, float)
        shift = chart_shift(pose, base)
        d = pose_distance(pose, base, result.covariance, result.parameter_names)
        if d["translation_mm"] <= SHIFT_FLOOR[0] / WIDEN_SD and d["rotation_deg"] <= SHIFT_FLOOR[1] / WIDEN_SD:
            continue
        added += np.outer(shift, shift) / WIDEN_SD**2
        said.append(f"{label} at {d['translation_mm']:.2g} mm / {d['rotation_deg']:.2g} deg"
                    + (f" ({d['sd']:.2g} sd)" if d["sd"] is not None else ""))
    if not said:
        return result
    uncertainty = result.uncertainty.widened(added, ("tx", "ty", "tz", "wx", "wy", "wz"))
    return dataclasses.replace(result, uncertainty=uncertainty, warnings=[*result.warnings, (
        f"{RIVALS_WARNING}, {', '.join(said)} from this pose, explain the data about as well (a BIC within "
        f"{AMBIGUOUS:g}); the 1 sd is widened to hold each within {WIDEN_SD:g} sd (poses that differ more in reach "
        "and arm configuration would tell them apart: handeye plan --robot)")])


def searched_samples(dataset):
    """The samples the search runs on: every one, or beyond :data:`ROW_CHUNK` (the search holds the whole
    Jacobian) that many spread evenly over the rows (a pose tour's order: every part of it) -- its tests then
    see an effect of a size that moves the pose by a tenth of the 0.2 mm / 0.05 deg a result may miss
    (their power grows as the square root of the samples), and the model it chooses is fitted to every
    sample (chunk by chunk)."""
    if len(dataset) <= ROW_CHUNK:
        return dataset
    return dataset.subset(spread(np.ones(len(dataset), bool), ROW_CHUNK))


def _subsample_note(n):
    """The warning of a search that ran on a subsample (:func:`searched_samples`)."""
    return (f"the discrepancy search ran on {ROW_CHUNK:,} of the {n:,} samples, spread evenly over the rows (it holds "
            "the whole Jacobian); its model is fitted to every sample (its exclusions, of the subsample, are not "
            "compared); the sd is not widened by what it could not see (no power statement beyond that size)")


def _statement(result, found, data):
    """What the data could not see at ``result``'s pose: the search's statement at its fit for a result
    with effects, else the plain chain's at the result's own pose and samples
    (:func:`handeye.app.engine.diagnose.held_power`: what the held verdict of a saved file recomputes)."""
    if result.effects or not result.converged:
        return found.power
    try:
        return diagnose.held_power(data, cell_stage.mask_of(result), result.sensor2flange, result.sphere_centre,
                                   "sphere" in result.unknowns.split("+"))
    except (np.linalg.LinAlgError, FloatingPointError, ValueError):
        return found.power  # the plain chain not evaluable at the pose: the search's statement at its fit


def with_power(result, statement):
    """``result`` with what its data could not see (a
    :class:`~handeye.app.present.result_parts.PowerStatement`): its uncertainty widened by the effects
    the statement says could move the pose beyond the floor unseen, and a warning saying which where
    that grows a sd by more than :data:`POWER_WARN_GROWTH`; a refused result unchanged."""
    if statement is None or not result.converged:
        return result
    uncertainty = result.uncertainty.with_power(statement)
    before, after = (u.std for u in (result.uncertainty, uncertainty))
    growth = 1.0 if before is None or before.sensor_translation_mm is None else float(np.nanmax(
        np.concatenate([after.sensor_translation_mm, after.sensor_rotation_deg])
        / np.maximum(np.concatenate([before.sensor_translation_mm, before.sensor_rotation_deg]), 1e-300)))
    warnings = result.warnings + ([f"{POWER_WARNING} (up to {growth:.2g} x): {statement.text}"]
                                  if growth > POWER_WARN_GROWTH else [])
    return dataclasses.replace(result, uncertainty=uncertainty, warnings=warnings)


def _unchecked_result(result, why):
    """``result`` with a warning that the search did not check it (and why)."""
    return dataclasses.replace(result, warnings=[*result.warnings, f"the model is not checked by the discrepancy "
                                                                   f"search: {why}"])


def _with_effects(request, dataset, result, refit, names, found):
    """The fit with the effects the search named (a warning says it chose them, and why)."""
    # resolved reset: checked again by the refit, from the parts asked (a cell's, not its conditional unknowns)
    asked = dataclasses.replace(request, effects=names, unknowns=request.parts)
    fitted = refit(asked, dataset)
    steps = ", ".join(f"{s.step}: RMS {s.rms_mm:.3g} mm" for s in found.steps)
    note = (f"the data choose the model with {', '.join(names)}: the discrepancy search names "
            f"{'it' if len(names) == 1 else 'them'} ({steps}); calibrated with "
            f"{'it' if len(names) == 1 else 'them'}, the same as `{_command('calibrate', dataset, request)} "
            f"--effects {','.join(names)}`" + (f"; {found.configuration}" if found.configuration else ""))
    kept = [w for w in fitted.warnings if not w.startswith(STRUCTURE_WARNING)]  # the search decided
    return dataclasses.replace(fitted, warnings=[note, *kept])


def _beside_axes(result, found, names, dataset, request):
    """A calibration of the positioner's axes beside which the search names effects other than data effects
    (which the cell stage fits with the axes: :func:`_with_effects`): refused where the
    search's pose (with them, at the calibrated axes) lies beyond :data:`~handeye.app.engine.levels.AGREE_SD` of the
    result's own sd; else kept, with a warning naming them (a 0.007 % scale on a clean cell, 3 of its sd,
    moves the pose by a fraction of its sd)."""
    named = "; ".join(f"{e.name} ({_values(e)})" for e in found.effects if e.name in names)
    d = pose_distance(np.asarray(found.sensor2flange, float), np.asarray(result.sensor2flange, float),
                      result.covariance, result.parameter_names)
    kept = [w for w in result.warnings if not w.startswith(STRUCTURE_WARNING)]  # the search decided
    far = f"{d['translation_mm']:.3g} mm and {d['rotation_deg']:.3g} deg from this one" + (
        f", {d['sd']:.2f} sd of its own" if d["sd"] is not None else " (it has no sd to compare with)")
    if same_pose(d):
        return dataclasses.replace(result, warnings=[*kept, f"at the positioner's calibrated axes the discrepancy search "
                                                             f"names {named}; with it the pose is {far}: within its sd"])
    return dataclasses.replace(result, warnings=kept).refused(
        f"not a calibration: at the positioner's calibrated axes the discrepancy search names {named}, which the cell "
        f"stage cannot estimate together with the axes; with {'it' if len(names) == 1 else 'them'} the pose is {far} "
        f"(more than {AGREE_SD:g}); `{_command('diagnose', dataset, request)}` prints the search")


def _values(effect):
    """``k = v +- sd, ...`` of a named effect."""
    sd = effect.std or {}
    return ", ".join(f"{k} = {v:.4g}" + (f" +- {sd[k]:.2g}" if sd.get(k) else "") for k, v in effect.parameters.items())


def _on_every_sample(request, dataset, found, refit):
    """The search's model (its effects) fitted to every sample (``refit``), in ``found``'s place: a search on a
    subsample (:func:`searched_samples`) has a pose that scatters about the full fit's by its own sd, which the
    1-sd rule of one model fitted twice would take for a contradiction."""
    names = _model_of(found)
    asked = dataclasses.replace(request, effects=names, chosen=True, model="centre" if names else request.model,
                                unknowns=request.parts)
    fitted = refit(asked, dataset)
    if not fitted.converged:
        return found
    return dataclasses.replace(found, sensor2flange=np.asarray(fitted.sensor2flange, float), outliers=[])


def _against_search(result, found, dataset, request):
    """``result`` refused when the search's pose is not its own (:func:`handeye.app.engine.agreement.same_pose`)."""
    cov, names = result.covariance, result.parameter_names
    if cov is None or names is None or not np.all(np.isfinite(cov)):
        return result
    d = pose_distance(np.asarray(found.sensor2flange, float), np.asarray(result.sensor2flange, float), cov, names)
    if same_pose(d):
        return result
    named = ", ".join(e.name for e in found.effects) or "no effect"
    kept = f" and the {len(found.outliers)} samples it excludes" if found.outliers and not request.outliers else ""
    advice = ("calibrate without --effects fits the model it chooses" if request.effects or request.chosen and
              request.model in (None, "centre") else "calibrate --model centre fits the model it chooses")
    advice = "without --keep-all its exclusions apply" if kept and not names_differ(found, request) else advice
    return result.refused(f"not a calibration: the discrepancy search (with {named}{kept}) puts the pose "
                           f"{d['translation_mm']:.3g} mm and {d['rotation_deg']:.3g} deg from this one, {d['sd']:.2f} sd "
                           f"of its own (more than {AGREE_SD:g}): these data contradict this model; "
                           f"`{_command('diagnose', dataset, request)}` prints the search; {advice}")


def _model_of(found):
    """The effects of the search's model (the named ones a fit can take)."""
    return tuple(e.name for e in found.effects if e.name not in NOT_A_MODEL)


def names_differ(found, request):
    """Whether the search's model (its named effects) is not the request's."""
    return set(_model_of(found)) != set(request.effects)


def _command(verb, dataset, request):
    """``handeye VERB DATASET`` with the request's unknowns when the centre is free."""
    free = "" if request.parts == "sensor" else f" --unknowns {request.parts}"
    return f"handeye {verb} {command_argument(dataset)}{free}"


def unexplained(result, dataset, request):
    """``result`` refused (exit 1, "unexplained structure") where the user stated the centre noise
    (``[noise] centre_mm`` or ``--sigma``), the fit is tested against it (unweighted centres), and the model
    the search chose leaves residuals beyond it: the noise test fails at its level and the chi2 per dof
    exceeds :data:`AT_NOISE` (diagnose's line of "nothing beyond the nominal noise"). The fit's own sd
    then scales with a misfit that is structure, not noise (a wrist flip's joint offset with no joints
    given: 8 of 32 rows excluded, the rest 11 x the stated 0.03 mm, exit 0 5-6 sd from the truth).
    A fit whitened by each row's covariance is not judged so: its circle part is estimated from the
    profile's own scatter, which real profiles exceed (RobCalibrator's scans with ``robot_mm`` stated:
    4.6-14 x); without a stated noise the fit estimates it. Neither is refused here."""
    test = getattr(result, "noise_test", None)
    if not result.converged or test is None or test.passed or test.whitened or test.ratio**2 <= AT_NOISE:
        return result
    if not (request.sigma_stated or "centre_mm" in dataset.noise_stated):
        return result
    names = [e.name for e in result.effects or []]
    if "sphere" in result.unknowns.split("+") and "sphere" not in (request.parts or "").split("+"):
        names.insert(0, "sphere_center")  # the search freed the centre
    chosen = ", ".join(names) or "the base model"
    return result.refused(
        f"not a calibration: {UNEXPLAINED}: under the model the discrepancy search chose ({chosen}) the "
        f"residuals are {test.ratio:.3g} x the stated {test.nominal} (chi2 = {test.statistic:.4g} on {test.dof} dof, "
        f"p = {test.p_value:.2g}); no effect of the catalogue explains them, and the pose's sd, scaled by the misfit, "
        f"does not bound what it does to the pose; `{_command('diagnose', dataset, request)}` prints the search "
        "(if the noise is larger than stated, correct [noise]: without it the noise is estimated from the fit)")
