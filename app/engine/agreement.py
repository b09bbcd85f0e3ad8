"""One answer per dataset: the diagnosis reports calibrate's pose where its search chose calibrate's model.

``handeye diagnose`` runs ``handeye calibrate`` on the same data, with the same options, and tells the story of
its discrepancy search (:mod:`handeye.app.engine.diagnose`; the search, from calibrate's pose, keeps each step's
figures: :attr:`~handeye.app.engine.request.CalibrationRequest.story`); only where calibrate ran no search (it
stopped on bad input, its fit did not converge or ended at a pose that is not finite, or the search failed
numerically) does diagnose run one of its own. Calibrate *is* that search
(:mod:`handeye.app.engine.search`): it ends in the model the search chooses, fitted in calibrate's own residual
model (for profile data the measured circles, the exact likelihood, where the search fits the sphere centres
rebuilt from them in their first-order metric) and to every sample (the search runs on
:data:`~handeye.model.fit.calibration.ROW_CHUNK` of them spread over the rows where there are more). So where
the search names the model calibrate fitted, the diagnosis's pose, 1-sd and named effects' values are calibrate's
(:func:`at_calibration`) wherever the search's own fit could only be the cruder one: it lies within
:data:`~handeye.app.engine.levels.AGREE_SD` of calibrate's sd, or it ran on a subsample (whose pose scatters by its
own sd), or it fitted another residual model within :data:`~handeye.app.engine.levels.METRIC_SD` of calibrate's
sd (the rebuilt centres' first-order metric where calibrate fits the measured circles or the profile points: on
10 poses of a 1-inch ball the two put the pose 1.55 sd apart, and the circles are the exact likelihood). The
search's own fit stays in the story (its steps, residuals and RMS) and the sentence :func:`against_calibrate` says
how far it lies. Where the models differ, or the search's fit of the same
model in the same metric on the same samples lies beyond 1 sd (two fits of one problem: one of them wrong), or in
the other metric beyond 3 sd, the diagnosis keeps its own pose and the sentence says why the two differ.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from handeye.app.engine.levels import AGREE_FLOOR, AGREE_SD, METRIC_SD
from handeye.model.common.rotation import pose_distance


def same_pose(distance):
    """Whether a :func:`handeye.model.common.rotation.pose_distance` (with its ``sd``) is the same pose
    (:data:`~handeye.app.engine.levels.AGREE_SD`, :data:`~handeye.app.engine.levels.AGREE_FLOOR`); without an
    sd, only the floor decides."""
    tiny = distance["translation_mm"] <= AGREE_FLOOR[0] and distance["rotation_deg"] <= AGREE_FLOOR[1]
    return tiny or (distance["sd"] is not None and distance["sd"] <= AGREE_SD)


#: What calibrate's refusal of structure beyond a stated noise says (:func:`handeye.app.engine.search.unexplained`);
#: diagnose reports it as beyond the catalogue (:func:`at_calibration`): one verdict.
UNEXPLAINED = "unexplained structure"


def model_of(effects):
    """The names of what a result's model fits besides the pose (``effects``: NamedEffects or None): every
    named effect but flipped samples (a diagnosis's ``positioner_axes`` too: calibrate with
    ``--unknowns sensor[+sphere]`` holds the axes)."""
    return frozenset(e.name for e in effects or () if e.name != "sign_flip")


def at_calibration(result, own, searched, n):
    """The diagnosis ``result`` with calibrate's pose where the search chose calibrate's model (module docstring).

    Parameters
    ----------
    result : handeye.app.present.diagnosis_results.DiagnosisResult
        Of the user's frame (``in_user_frame``), as ``own``.
    own : handeye.app.present.results.CalibrationResult or Exception
        ``handeye.calibrate`` on the same data and options; an InputError where it stopped.
    searched, n : int
        Samples the search ran on, and of the data.

    Returns
    -------
    DiagnosisResult
        With ``against_calibrate`` said, and calibrate's ``sensor2flange``, ``sensor_pose`` (KUKA),
        ``sensor_pose_as``, ``std``, ``sphere_centre`` and effect values where the models are one.
    """
    note = "" if searched == n else (f"; the search ran on {searched:,} of the {n:,} samples, spread evenly over "
                                     "the rows (it holds the whole Jacobian)")
    if isinstance(own, Exception):
        return dataclasses.replace(result, against_calibrate=f"calibrate refuses these data: {own}{note}")
    if not own.converged and UNEXPLAINED in own.message:  # calibrate's rule of a stated noise: one verdict
        result = dataclasses.replace(result, beyond_catalogue=(*result.beyond_catalogue, own.message))
    if not (own.converged and model_of(own.effects) == model_of(result.effects)):
        return dataclasses.replace(result, against_calibrate=against_calibrate(result, own) + note)
    d = pose_distance(np.asarray(result.sensor2flange, float), np.asarray(own.sensor2flange, float), own.covariance,
                      own.parameter_names)
    if not same_pose(d) and searched == n and (own.model == "centre" or not _within_metric(d)):  # two fits: kept
        return dataclasses.replace(result, against_calibrate=against_calibrate(result, own) + note)
    said = (f"the same pose as `handeye calibrate`'s: the search chose its model "
            f"({', '.join(sorted(model_of(own.effects))) or 'no effect'}), and this is calibrate's fit of it "
            f"({_how(own)}); the search's own fit lies {_far(d)} from it"
            + (f", within {AGREE_SD:g} sd" if same_pose(d) else
               f" (it fits the sphere centres rebuilt from the {own.model} model's data, to first order)" if searched == n
               else "") + note + _exclusions(result, own))
    values = {e.name: e for e in own.effects or ()}
    named = [dataclasses.replace(e, parameters=values[e.name].parameters, std=values[e.name].std)
             if e.name in values else e for e in result.effects]
    return dataclasses.replace(
        result, sensor2flange=np.asarray(own.sensor2flange, float), sensor_pose=np.asarray(own.sensor_pose_kuka, float),
        sensor_pose_as=np.asarray(own.sensor_pose, float), std=own.std, effects=named,
        sphere_centre=np.asarray(own.sphere_centre, float), against_calibrate=said)


def _within_metric(distance):
    """Whether two fits of one model in two metrics (rebuilt centres, measured circles) lie within
    :data:`~handeye.app.engine.levels.METRIC_SD` of calibrate's sd."""
    return distance["sd"] is not None and distance["sd"] <= METRIC_SD


def _how(own):
    """How calibrate fitted the model: its residual model and the samples it kept."""
    model = "the sphere centres" if own.model == "centre" else f"the {own.model} model"
    return model + ("" if own.n_used is None else f", the {own.n_used:,} samples it kept")


def _exclusions(result, own):
    """``; they exclude different samples (...)`` where the search's exclusions are not calibrate's, else ''."""
    left_out = set(result.outliers) ^ set(own.outliers)
    return f"; they exclude different samples ({', '.join(sorted(left_out)[:6])})" if left_out else ""


def _far(d):
    """``x mm and y deg (z sd of calibrate's)`` of a :func:`pose_distance`."""
    return (f"{d['translation_mm']:.3f} mm and {d['rotation_deg']:.4f} deg" +
            ("" if d["sd"] is None else f" ({d['sd']:.2f} sd of calibrate's)"))


def against_calibrate(result, own):
    """Whether the diagnosis's pose is calibrate's (``own``, the same unknowns) within 1 sd, and
    if not, why: the effects named (calibrate fits none unless ``--effects``), the residual model
    (diagnose fits sphere centres; calibrate its default model), the samples excluded."""
    if not own.converged:
        verb = "refuses these data" if own.message.startswith(("not a calibration", "unexplained")) else \
            "did not converge on these data"
        return f"calibrate {verb} ({own.message}); nothing to compare"
    d = pose_distance(np.asarray(result.sensor2flange, float), np.asarray(own.sensor2flange, float), own.covariance,
                      own.parameter_names)
    if same_pose(d):
        return f"the same pose as `handeye calibrate`'s within {AGREE_SD:g} sd ({_far(d)} apart)"
    why = _why(result, own)
    return (f"{_far(d)} from `handeye calibrate`'s pose: " + ("; ".join(why) if why else
            "the two fits differ though they have the same model and samples (report it)"))


def _why(result, own):
    """Why the diagnosis's own fit differs from calibrate's: the effects it names (where calibrate's model has
    others), the residual model, the samples excluded."""
    why = []
    named = [e.name for e in result.effects if e.name != "sign_flip"]
    if named and model_of(result.effects) != model_of(own.effects):
        why.append(f"diagnose corrects the data by the effects it names ({', '.join(named)}), calibrate does not "
                   f"(calibrate --effects {','.join(named)} does)")
    if own.model != "centre":
        why.append(f"the search fits the sphere centres, calibrate the {own.model} model (calibrate --model centre "
                   "fits what the search fits)")
    if _exclusions(result, own):
        why.append(_exclusions(result, own)[2:])
    return why
