"""A robot configuration group as one of the search's alternatives (a step of diagnose).

Samples the outlier test excludes are gross errors only when they are no group: where they coincide
with a configuration group of the robot (:func:`handeye.model.robot.configuration.coinciding`: the
poses with the wrist flipped, the elbow down, the wrist centre behind axis 1), they share something
the others do not -- a robot error that acts differently in that configuration (a j5 zero offset
changes sign under a wrist flip), or another setup. The alternative "the group kept" is then
fitted by the search itself: the group's samples reinstated, the catalogue searched again on every
sample (with joint angles the robot's effects are candidates: ``joint_offsets``, ``link_lengths``,
``joint_compliance``), and the final outlier test run (:mod:`handeye.app.engine.diagnose`). It
replaces the exclusion by the rules every alternative meets: each effect it names is confirmed by
the search's F test, Delta BIC and held-out error, and each sample of the group kept passes the
deletion test at the family-wise level, as any reinstated sample must. Otherwise the group stays
excluded and the result says so as structure no catalogue effect explains (``beyond_catalogue``):
calibrate refuses it (exit 1) with the evidence, instead of exiting 0 as if the group were gross
errors.

:func:`deferred` tells calibrate's stages (:func:`handeye.app.engine.calibrate.verify`) to leave such
an exclusion to the search, which runs on every result it can check.
"""
from __future__ import annotations

import copy

import numpy as np

from handeye.app.engine.levels import AT_NOISE
from handeye.model import effects
from handeye.model.common.statistics import f_survival
from handeye.model.fit.calibration import ROW_CHUNK
from handeye.model.robot import configuration


def deferred(dataset, mask, request):
    """The coincidence (:class:`~handeye.model.robot.configuration.Coincidence`) of the samples the
    screening excluded (``mask``: used) with a configuration group when the search will judge it
    (the sensor is estimated and the data are within its size), else None."""
    if "sensor" not in request.parts.split("+") or len(dataset) > ROW_CHUNK:
        return None
    return configuration.coinciding(dataset, ~np.asarray(mask, bool), request.alpha)


def _named(prob, structure, fit):
    """``"joint_offsets (j5 = 0.4 +- 0.01)"``-like text of the effects in ``structure``."""
    names = ["sphere_center"] * bool(structure.centre and "cx" in fit.names) + list(structure.data_effects)
    parts = []
    for name in names:
        if name == "sphere_center":
            parts.append("sphere_center")
            continue
        values = ", ".join(f"{p} = {v:.3g}" for p, v in zip(prob.params_of(name), np.ravel(fit.params[name])))
        parts.append(f"{name} ({values})")
    return "; ".join(parts) or "no effect"


def _group_test(run, structure, fit, members):
    """The group's samples against the model fitted without them (the deletion test of the group as a
    whole, Chow's F): ``(F, p)`` of the rise in SSR the group brings, on its 3 per sample degrees of
    freedom, against the residual variance without it. Each sample's own deletion test is not enough:
    a group that does not fit inflates the variance every test divides by (a j5 offset without joint
    angles: RMS 2.8 mm with the group kept, every deletion test passed)."""
    mask = run.mask & ~members
    without = run.prob.fit(structure, mask, fit.x, fit.params)
    k, dof = fit.m - without.m, without.m - without.p
    if k <= 0 or dof <= 0:
        return float("inf"), 0.0
    f_stat = max((fit.ssr - without.ssr) / k, 0.0) / (without.ssr / dof)
    return float(f_stat), float(f_survival(f_stat, k, dof))


def _void_trials(run, fit):
    """Forget the candidates found implausible while the group was out (``run.implausible``) when the
    model with the group kept leaves nothing beyond the nominal noise (:data:`AT_NOISE`): they were
    fitted to samples that lacked the configuration that tells the effect apart (a j5 offset seen from
    one wrist only looked like an upward gravity sag)."""
    if fit.sigma2 / run.prob.sigma ** 2 < AT_NOISE:
        run.implausible.clear()


def _reinstated(run, structure, fit, allowed):
    """Said in ``run.configuration`` when the screening's first exclusions were a configuration group
    that the search has reinstated, every one, with the effects it named."""
    if run.screening is None:
        return
    first = configuration.coinciding(run.prob.d, ~run.screening.inliers, run.alpha)
    if first is None or np.any(first.group.members & allowed & ~run.mask):
        return
    f_stat, p = _group_test(run, structure, fit, first.group.members & allowed)
    said = first.said().replace("excluded samples", "samples the screening excluded first")
    if p < run.alpha:
        run.configuration = (f"{said}; reinstated with {_named(run.prob, structure, fit)}, the group does not fit as a "
                             f"whole (F = {f_stat:.3g}, p = {p:.2g})")
        run.implausible.append(run.configuration)
        return
    _void_trials(run, fit)
    run.configuration = (f"{said}; kept: with {_named(run.prob, structure, fit)} every sample of the group passes the "
                         f"outlier test, and the group as a whole (F = {f_stat:.3g}, p = {p:.2g})")


def examine(run, structure, fit, allowed, steps):
    """The group kept as an alternative (module docstring).

    Parameters
    ----------
    run : handeye.app.engine.diagnose.Procedure
        After the search and the final outlier test; its ``mask`` the samples used.
    structure, fit : the search's model and fit on ``run.mask``.
    allowed : ndarray of bool, shape (N,)
        Samples that may be reinstated (not rows that contradict themselves).
    steps : tuple
        diagnose's ``(search, final_outliers, summaries)``: ``search(run, structure, fit)``,
        ``final_outliers(prob, structure, fit, mask, alpha, allowed)`` and ``summaries(prob,
        structure, fit, mask, heldout)``.

    Returns
    -------
    tuple or None
        ``(structure, fit, mask, flips, outliers)`` with the group kept, or None (``run.configuration``
        and, when the group stays out, ``run.implausible`` say why).
    """
    found = configuration.coinciding(run.prob.d, ~run.mask, run.alpha)
    if found is None:
        _reinstated(run, structure, fit, allowed)
        return _many_excluded(run, structure, fit, allowed, steps)
    members = found.group.members & allowed
    saved, kept, (f_stat, p), passed = _kept(run, structure, fit, members, allowed, steps)
    if passed:
        _void_trials(run, kept[1])
        run.configuration = (f"{found.said()}; kept: with {_named(run.prob, kept[0], kept[1])} every sample of the "
                             f"group passes the outlier test, and the group as a whole (F = {f_stat:.3g}, p = {p:.2g})")
        run.steps.append({"step": f"configuration group kept ({found.group.label})",
                          **steps[2](run.prob, kept[0], kept[1], run.mask, run.detail)})
        return kept
    _restore(run, saved)
    robot = [e.NAME for e in effects.catalogue("robot") if e.available(run.prob.d)]
    tried = (f"with the group kept, the search ({', '.join(robot)} among its candidates) names "
             f"{_named(run.prob, kept[0], kept[1])}, and the group does not fit: the outlier test excludes "
             f"{int(np.sum(members & ~kept[2]))} of them, the group as a whole F = {f_stat:.3g}, p = {p:.2g}" if robot else
             "without joint angles and a [robot] model the robot's effects that act by configuration (a j5 zero offset "
             f"changes sign under a wrist flip) cannot be tested, and kept the group does not fit (F = {f_stat:.3g}, "
             f"p = {p:.2g})")
    run.configuration = f"{found.said()}; {tried}"
    run.implausible.append(run.configuration)
    return None


#: Excluded samples are kept as an alternative without a configuration group when they are at least this
#: many and this share of the samples, and the robot's effects are candidates (joints given): the signature of
#: a robot error in a group of poses the joints do not mark (an independent generator's UR5e, j5 0.085 deg off:
#: the five samples of one of three orientations excluded as gross errors, exit 0 3.4 sd from the truth).
MANY_EXCLUDED = (3, 0.2)


def _many_excluded(run, structure, fit, allowed, steps):
    """The excluded samples kept as :func:`examine` keeps a configuration group, where they are many
    (:data:`MANY_EXCLUDED`) and the robot's effects are candidates: kept when the search names what explains
    them and each passes the outlier test (the group as a whole too); else they stay excluded as gross errors,
    nothing said (no group marks them as one)."""
    members = ~run.mask & allowed
    n = int(members.sum())
    if (n < MANY_EXCLUDED[0] or n < MANY_EXCLUDED[1] * len(run.mask)
            or not any(e.available(run.prob.d) for e in effects.catalogue("robot"))):
        return None
    saved, kept, (f_stat, p), passed = _kept(run, structure, fit, members, allowed, steps)
    if passed and kept[0].data_effects:
        run.configuration = (f"the {n} samples the outlier test excluded are no gross errors: with "
                             f"{_named(run.prob, kept[0], kept[1])} every one passes the outlier test, and the group as "
                             f"a whole (F = {f_stat:.3g}, p = {p:.2g})")
        run.steps.append({"step": f"{n} excluded samples kept", **steps[2](run.prob, kept[0], kept[1], run.mask,
                                                                            run.detail)})
        return kept
    _restore(run, saved)
    return None


def _kept(run, structure, fit, members, allowed, steps):
    """The alternative "``members`` kept" fitted by the search itself (``steps``: :func:`examine`'s): the samples
    reinstated, the catalogue searched on every sample, the final outlier test run. Returns ``(saved, kept, (F, p),
    passed)``: the run's state before it (for :func:`_restore`), the final outlier test's result, the group's test,
    and whether every member passes the outlier test and the group as a whole."""
    search, final_outliers, _ = steps
    saved = (run.mask, copy.deepcopy(run.steps), copy.deepcopy(run.tested), dict(run.absorbed), list(run.implausible),
             dict(run.prob.robot_free))
    run.mask = run.mask | members
    trial_structure, trial = search(run, structure, run.prob.fit(structure, run.mask, fit.x, fit.params))
    kept = final_outliers(run.prob, trial_structure, trial, run.mask.copy(), run.alpha, allowed)
    run.mask = kept[2]
    f_stat, p = _group_test(run, kept[0], kept[1], members)
    return saved, kept, (f_stat, p), bool(not np.any(members & ~kept[2]) and p >= run.alpha)


def _restore(run, saved):
    """The run's state as :func:`_kept` found it."""
    run.mask, run.steps, run.tested, run.absorbed, run.implausible = saved[:5]
    run.prob.robot_free.clear()
    run.prob.robot_free.update(saved[5])
