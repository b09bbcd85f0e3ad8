"""Model discrepancy: find where model and data disagree, name the missing effect, add it,
show the gap shrink (``handeye diagnose``).

The procedure combines three traditions: a residual check (like a Bayesian discrepancy term
it *finds* a gap), a catalogue of named candidate effects (like sparse model discovery it
*names* terms), and an identifiability gate (like robot-calibration practice it refuses what
the poses cannot separate):

0. For a sphere on a positioner, the set-up axes are tested first as the missing effect
   (:mod:`handeye.app.engine.positioner_effect`); when named, the rest runs at the refined axes.
1. Robust first fit; gross outliers screened with a robust scale (:mod:`handeye.app.engine.robust`);
   rows whose centre columns contradict their own profile excluded for good, as in calibrate.
2. Least-squares fit of the current model; residuals per sample and component, RMS, chi2/dof
   against a stated noise level, 5-fold held-out prediction error.
3. For every candidate of the catalogue (:mod:`handeye.model.effects`): its Jacobian columns at the
   fit; the identifiability gate -- the part of the columns orthogonal to the current model's
   must keep at least ``GATE`` of their size, otherwise the effect is "absorbed by" the current
   parameters that reproduce it, and never named; the score (Lagrange multiplier) test
   ``S = r^T A (A^T A)^-1 A^T r / sigma^2 ~ chi2_k`` with a Bonferroni correction over the
   candidates tested.
4. The best candidate is confirmed by refitting the extended model: the F test of the
   reduction in SSR, Delta BIC < 0 and a lower 5-fold held-out error must all agree. A
   candidate whose fitted values are beyond its physical range (:func:`handeye.model.effects.implausible`)
   is not named, and neither is a later one that it fits significantly better
   (:func:`_only_nearest`): a discrepancy beyond the catalogue's range stays unexplained.
5. Repeat until nothing significant remains; every accepted effect is re-tested for removal.
6. Final outlier test on the structured model: an excluded sample is named a ``sign_flip``
   when, with its y negated, every component of its residual returns within 3 sigma; it is
   reinstated when its deletion test is no longer significant; otherwise it is an outlier.
7. Report: named effects with parameters, standard errors and correlations; RMS and chi2/dof
   before and after, on fitted and held-out data; absorbed effects; excluded samples; what
   remains.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from handeye.app.engine import configuration_group, effect_size, positioner_effect, robot_choice, robust, set_aside
from handeye.app.engine.held_chain import held_at
from handeye.app.engine.levels import AT_NOISE
from handeye.app.engine.prepare import resolve_start
from handeye.app.present.diagnosis_results import DiagnosisResidual, DiagnosisResult, Step
from handeye.app.present.result_parts import NamedEffect, PowerStatement, Uncertainty, cleaning_summary
from handeye.model import effects
from handeye.model.chain import conventions
from handeye.model.chain.pose import pose_from_transform, transform_from_pose
from handeye.model.common.rotation import pose_distance
from handeye.model.common.statistics import deletion_statistics, f_survival, prediction_test
from handeye.model.datasets import observations
from handeye.model.design.robot_gate import robot_free
from handeye.model.fit import power
from handeye.model.fit.extended import GATE, Fit, Samples, ScoreTest, Structure, candidate_columns
from handeye.model.fit.score_tests import gate, score_test

#: Family-wise level of the effect tests and of the outlier tests: the screening's (one value).
ALPHA = robust.ALPHA

@dataclasses.dataclass
class Procedure:
    """The state of one run of :func:`diagnose`, shared by its steps.

    Attributes
    ----------
    prob : Samples
        The samples and their model.
    mask : ndarray of bool, shape (N,)
        Samples fitted (changed in place by the outlier test).
    alpha : float
        Family-wise level of the tests.
    screening : handeye.app.engine.robust.Screening
    before : dict
        :func:`_summaries` of the base model.
    before_norms : ndarray, shape (N,)
        The base model's residual norms.
    absorbed, tested, steps, implausible
        The record so far: effects absorbed by others (name -> who), the rounds of score tests,
        the steps taken, why a candidate's fit was implausible.
    robot_alternatives : str or None
        Other robot effects as good as those named (:mod:`handeye.app.engine.robot_choice`).
    robot_rivals : tuple of (str, ndarray (4, 4))
        Their labels and sensor poses.
    configuration : str or None
        Excluded samples that are a configuration group (:mod:`handeye.app.engine.configuration_group`).
    """

    prob: Samples
    mask: np.ndarray
    alpha: float
    screening: robust.Screening
    before: dict
    before_norms: np.ndarray
    absorbed: dict = dataclasses.field(default_factory=dict)
    tested: list = dataclasses.field(default_factory=list)
    steps: list = dataclasses.field(default_factory=list)
    implausible: list = dataclasses.field(default_factory=list)
    robot_alternatives: str | None = None
    robot_rivals: tuple = ()
    centre_unknown: bool = False
    configuration: str | None = None
    detail: bool = True


def _summaries(prob, structure, fit, mask, heldout=True):
    """A step's figures; without ``heldout`` its 5-fold held-out RMS is NaN (not computed)."""
    return {
        "rms_mm": _rms(prob, fit, mask),
        "chi2_dof": float(fit.sigma2 / prob.sigma**2),
        "sigma_mm": float(np.sqrt(fit.sigma2)),
        "heldout_rms_mm": prob.heldout_rms(structure, mask, fit, raw=True) if heldout else float("nan"),
    }


def diagnose(dataset, alpha=ALPHA, start=None, sigma=None, centre_unknown=False, detail=True):
    """Run the procedure (module docstring) on a dataset.

    Parameters
    ----------
    dataset : handeye.model.datasets.dataset.Dataset
    alpha : float
        Family-wise level of the effect and outlier tests.
    start : array_like, shape (6,), optional
        Start sensor pose (KUKA, mm, deg); default as :func:`handeye.app.engine.prepare.resolve_start`.
    sigma : float, optional
        Nominal noise per residual component (mm) for chi2/dof; default the dataset's
        ``[noise] centre_mm``.
    centre_unknown : bool
        The sphere centre is estimated with the pose (``--unknowns sensor+sphere``): free in the
        base model and in every model after it (never tested, named or removed as an effect);
        ``dataset.sphere_centre`` is its start.
    detail : bool
        Without it (calibrate's search, :mod:`handeye.app.engine.search`) the same decisions,
        but the steps' held-out RMS (NaN) and the structural effects' identifiability
        (``absorbed_by``) -- the report's figures -- are not computed (~40 % of the time).

    Returns
    -------
    handeye.app.present.diagnosis_results.DiagnosisResult
    """
    unknowns = "sensor+sphere" if centre_unknown else "sensor"
    start_pose, _ = resolve_start(dataset, unknowns, start)
    screening = robust.screen(dataset, unknowns, transform_from_pose(start_pose), alpha=alpha)
    mask, inconsistent = set_aside.exclude_inconsistent(dataset, unknowns, screening.inliers.copy(), [])
    allowed = ~np.isin(dataset.rows, [e.row for e in inconsistent])  # never reinstated
    structure = Structure(centre=centre_unknown)
    prob, fit = _base_fit(dataset, sigma, structure, mask, screening.robust_sensor2flange)
    before = _summaries(prob, structure, fit, mask, detail)
    run = Procedure(prob, mask, alpha, screening, before, np.linalg.norm(prob.raw(fit.e), axis=1),
                    centre_unknown=centre_unknown, detail=detail)
    run.steps.append({"step": "base model", **before})
    axes = _positioner_axes(run, fit, sigma)
    if axes is not None:  # the rest runs at the refined axes
        dataset, prob = axes.dataset, run.prob
        fit = prob.fit(structure, mask, fit.x)
        run.steps.append({"step": "+ positioner_axes", **_summaries(prob, structure, fit, mask, detail)})
    for _ in range(3):  # effects, then discrete samples, until neither changes the other
        structure, fit = _search(run, structure, fit)
        previous = (mask.copy(), structure.flips)
        structure, fit, mask, flips, outliers = _final_outliers(prob, structure, fit, mask, alpha, allowed)
        run.mask = mask
        if not (np.array_equal(previous[0], mask) and previous[1] == structure.flips):
            run.steps.append({"step": _outlier_step_label(dataset, previous, mask, structure.flips),
                          **_summaries(prob, structure, fit, mask, detail)})
        structure, fit = _backward(prob, structure, fit, mask, alpha, centre_unknown)
        if np.array_equal(previous[0], mask) and previous[1] == structure.flips:
            break
    kept = configuration_group.examine(run, structure, fit, allowed, (_search, _final_outliers, _summaries))
    structure, fit, mask, flips, outliers = kept or (structure, fit, mask, flips, outliers)
    structure, fit = _robot_choice(run, structure, fit)
    unseen = power_statement(run, structure, fit)
    if detail:
        _absorbed_structural(run, structure, fit, mask)
    result = _report(run, structure, fit, flips, outliers)
    result = dataclasses.replace(result, power=unseen)
    if axes is not None:
        result = dataclasses.replace(result, effects=[axes.effect, *result.effects])
    if run.implausible:
        beyond = tuple(dict.fromkeys(run.implausible))
        result = dataclasses.replace(result, unexplained="; ".join(beyond) + ". " + result.unexplained,
                                     beyond_catalogue=beyond)
    return dataclasses.replace(result, inconsistent=inconsistent) if inconsistent else result


def _base_fit(dataset, sigma, structure, mask, sensor2flange):
    """The samples in their own metric and the base model's fit on ``mask`` from ``sensor2flange``: the
    metric (:func:`handeye.model.datasets.observations.centre_metric`) is taken at an unweighted fit first
    where centres were rebuilt from profiles, their covariance the circle fit's, not equal and isotropic."""
    prob = Samples(dataset, sigma)
    fit = prob.fit(structure, mask, prob.point(structure, sensor2flange))
    metric = observations.centre_metric(dataset, prob.transform(fit.x), prob.centre(structure, fit.x), mask,
                                        fit.p)
    if metric is None:
        return prob, fit
    prob = Samples(dataset, sigma, metric)
    return prob, prob.fit(structure, mask, fit.x)


def _robot_choice(run, structure, fit):
    """The robot effects compared as alternatives (:func:`handeye.app.engine.robot_choice.compare`);
    a step recorded when another combination replaces the searched one."""
    chosen, new, run.robot_alternatives, run.robot_rivals = robot_choice.compare(run.prob, structure, fit, run.mask,
                                                                                 run.alpha, run.centre_unknown)
    if set(chosen.data_effects) != set(structure.data_effects) or chosen.centre != structure.centre:
        robot = [n for n in chosen.data_effects if effects.get(n).KIND == "robot"]
        label = "+".join(("sphere_center",) * (chosen.centre and not run.centre_unknown) + tuple(robot))
        run.steps.append({"step": f"robot effects: {label}", **_summaries(run.prob, chosen, new, run.mask, run.detail)})
    return chosen, new


def _absorbed_structural(run, structure, fit, mask):
    """The structural effects, checked against the sensor pose and the sphere centre: those the
    current parameters reproduce are recorded in ``run.absorbed``."""
    prob = run.prob
    with_centre = _extend(structure, "sphere_center")
    full = prob.fit(with_centre, mask, fit.x, fit.params)
    for effect in effects.catalogue("structural"):
        cols = candidate_columns(prob, with_centre, full, mask, effect.NAME)
        frac, who = gate(full.jac[mask].reshape(-1, full.p), cols, full.names)
        if frac < GATE:
            run.absorbed[effect.NAME] = who


def _positioner_axes(run, fit, sigma):
    """Step 0 for a sphere on a positioner: are the set-up axes the missing effect
    (:mod:`handeye.app.engine.positioner_effect`)? When named, ``run`` continues at the refined
    axes (its samples' model replaced, a step recorded) and the finding is returned."""
    dataset = run.prob.d
    if dataset.mounts.sphere != "positioner":
        return None
    found = positioner_effect.examine(dataset, run.mask, run.prob.transform(fit.x), run.prob.sigma, run.alpha)
    if found is None:
        return None
    run.prob = Samples(found.dataset, sigma, run.prob.metric)
    return found


def _continuous(prob):
    """The catalogue's continuous candidates on these samples: data and centre effects, and the robot
    effects the dataset allows (joints given)."""
    return [e.NAME for e in effects.catalogue() if (e.KIND in ("data", "centre") and effects.fittable(e.NAME, prob.d))
            or (e.KIND == "robot" and e.available(prob.d))]


def power_statement(run, structure, fit):
    """What the data could not see at the final fit (:mod:`handeye.model.fit.power`): per continuous
    candidate not in ``structure`` and separable from it (the gate), the size its score test would
    detect with :data:`~handeye.model.fit.power.POWER` at the search's level (``run.alpha`` over the
    candidates, Bonferroni, as :func:`_search` tests them) and the shift it would cause if missed;
    and the gross error the final outlier test (its level over the samples) could miss on the sample
    where it moves the pose most (:func:`handeye.model.fit.power.missable_sample`).

    Returns
    -------
    handeye.app.present.result_parts.PowerStatement
    """
    prob, mask = run.prob, run.mask
    jac = fit.jac[mask].reshape(-1, fit.p)
    columns = {}
    for name in _continuous(prob):
        if name in structure.data_effects or (name == "sphere_center" and structure.centre) or (
                effects.get(name).KIND == "robot" and not prob.robot_free.get(name, True)):
            continue
        cols = candidate_columns(prob, structure, fit, mask, name)
        if np.all(np.isfinite(cols)) and gate(jac, cols, fit.names, absorbers=False)[0] >= GATE:
            columns[name] = cols
    level = run.alpha / max(len(columns), 1)
    setting = power.Setting(fit.sigma2, level, fit.m - fit.p)
    found = [power.missable(name, getattr(effects.get(name), "UNIT", ""), jac, cols, setting)
             for name, cols in columns.items()]
    used = [prob.d.ids[i] for i in np.flatnonzero(mask)]
    samples = dataclasses.replace(setting, level=run.alpha / prob.n)
    found.append(power.missable_sample(fit.jac[mask], samples, used))
    found = sorted((m for m in found if m is not None), key=lambda m: -max(m.shift_mm / power.SHIFT_FLOOR[0],
                                                                          m.shift_deg / power.SHIFT_FLOOR[1]))
    return PowerStatement(tuple(found), tuple(fit.names), level)


def held_power(dataset, mask, sensor2flange, centre, centre_unknown, alpha=ALPHA):
    """The :func:`power_statement` of a pose held (a saved calibration's, :mod:`handeye.app.engine.held_verdict`)
    on the samples of ``mask``: the plain chain (the sphere centre free with ``centre_unknown``) evaluated
    at the pose, never fitted. ``centre``: the sphere centre (robot base or its mount's frame, mm)."""
    chain = held_at(dataset, mask, (sensor2flange, centre), centre_unknown)
    prob, structure, x = chain.prob, chain.structure, chain.x
    e, jac, _ = prob.evaluate(structure, x, {})
    fit = Fit(x, {}, e, jac, prob.names(structure), float(np.sum(e[mask] ** 2)), 3 * int(mask.sum()), jac.shape[2])
    held = Procedure(prob, np.asarray(mask, bool), alpha, None, {}, np.linalg.norm(e, axis=1),
                     centre_unknown=bool(centre_unknown), detail=False)
    return power_statement(held, structure, fit)


def _search(run, structure, fit):
    """Steps 3-5: test every continuous candidate, confirm the best, repeat (``run`` the
    :class:`Procedure`, its record extended)."""
    prob, mask, alpha = run.prob, run.mask, run.alpha
    absorbed, tested, steps, implausible = run.absorbed, run.tested, run.steps, run.implausible
    continuous = _continuous(prob)
    for _ in range(len(continuous)):
        jac_cur = fit.jac[mask].reshape(-1, fit.p)
        candidates = []
        for name in continuous:
            if name in structure.data_effects or (name == "sphere_center" and structure.centre):
                continue
            if effects.get(name).KIND == "robot":
                for param, who in robot_free(prob, structure, fit, mask, name).items():
                    absorbed[f"{name}.{param}"] = who
                if not prob.robot_free[name]:
                    continue
            cols = candidate_columns(prob, structure, fit, mask, name)
            if not np.all(np.isfinite(cols)):
                continue  # not testable here (e.g. a centre reconstructed exactly on the equator)
            frac, who = gate(jac_cur, cols, fit.names)
            if frac < GATE:
                absorbed[name] = who
                continue
            absorbed.pop(name, None)
            stat, p = score_test(fit, mask, cols)
            candidates.append((p, name, stat, frac))
        if not candidates:
            break
        m_tests = len(candidates)
        candidates.sort()
        tested.append([{"name": nm, "score": st, "p_bonferroni": min(p * m_tests, 1.0), "gate": fr}
                       for p, nm, st, fr in candidates])
        accepted, beyond = None, []
        for p, name, _, _ in candidates:
            if p * m_tests >= alpha:
                break
            trial = _extend(structure, name)
            new = prob.fit(trial, mask, fit.x, fit.params)
            why = effects.implausible(name, new.params.get(name, []), prob.radius, names=prob.params_of(name))
            if why is not None:
                implausible.append(why)
                beyond.append((name, new))
                continue
            why = _only_nearest(run, fit, name, new, beyond)
            if why is not None:
                implausible.append(why)
                continue
            if _confirmed(run, structure, fit, trial, new):
                accepted = (name, trial, new)
                break
        if accepted is None:
            break
        name, structure, fit = accepted
        structure, fit = _backward(prob, structure, fit, mask, alpha, run.centre_unknown)
        steps.append({"step": f"+ {name}", **_summaries(prob, structure, fit, mask, run.detail)})
    return _swapped(run, structure, fit)


def _swapped(run, structure, fit):
    """The named data effects, each exchanged for an unnamed one of as many parameters where that
    fits clearly better (an SSR lower by one unit of the residual variance, a chi-square of one),
    or as well (within one unit) and the other comes first in the catalogue's order (its physical
    prior); its value physical. Equal-size models: the lower SSR is the lower BIC. One at a time, the forward
    search can take the wrong one of effects that span nearly the same: a line scanner's
    ``sensor_scale`` is, to first order, ``centre_scale`` plus a ``sphere_radius`` of R s."""
    prob, mask = run.prob, run.mask
    order = [e.NAME for e in effects.catalogue() if e.KIND == "data" and effects.fittable(e.NAME, prob.d)]
    for _ in range(len(order)):
        best, unit = None, fit.ssr / max(fit.m - fit.p, 1)
        for name in (n for n in structure.data_effects if n in order):
            for other in (o for o in order if o not in structure.data_effects):
                if len(effects.get(other).PARAMS) != len(effects.get(name).PARAMS):
                    continue
                trial = dataclasses.replace(structure, data_effects=tuple(
                    other if n == name else n for n in structure.data_effects))
                with np.errstate(all="ignore"):  # a trial may leave its domain (a root of a negative): rejected steps
                    new = prob.fit(trial, mask, fit.x, {k: v for k, v in fit.params.items() if k != name})
                bar = fit.ssr + (unit if order.index(other) < order.index(name) else -unit)  # no cycle
                if (new.ssr < bar and (best is None or new.ssr < best[2].ssr) and np.all(np.isfinite(new.jac[mask]))
                        and effects.implausible(other, new.params.get(other, []), prob.radius) is None):
                    best = (f"{name} -> {other}", trial, new)
        if best is None:
            return structure, fit
        label, structure, fit = best
        run.steps.append({"step": f"swap {label}", **_summaries(prob, structure, fit, mask, run.detail)})
    return structure, fit


def _only_nearest(run, base, name, new, beyond):
    """Why candidate ``name`` (fit ``new``) is only the nearest effect to a discrepancy beyond the
    catalogue's range, or None.

    ``beyond`` holds ``(name, fit)`` of the candidates whose fitted values were implausible
    (:func:`handeye.model.effects.implausible`). When one of them explains the data significantly
    better than ``new`` -- the F statistic of the SSR that ``new`` leaves beyond it, on its own
    parameters, at the run's level -- ``new`` absorbs part of an effect it does not describe
    (a 10 % sensor scale error fitted as a radius error): the discrepancy is left unexplained.

    Parameters
    ----------
    run : Procedure
    base : Fit
        The current model's fit, which both candidates extend.
    name : str
    new : Fit
    beyond : list of (str, Fit)

    Returns
    -------
    str or None
    """
    for other, fit in beyond:
        k = max(fit.p - base.p, 1)
        dof = fit.m - fit.p
        if dof <= 0 or fit.ssr >= new.ssr:
            continue
        f_stat = ((new.ssr - fit.ssr) / k) / (fit.ssr / dof)
        p_f = f_survival(f_stat, k, dof)
        if p_f < run.alpha:
            values = ", ".join(f"{k} = {v:.4g}" for k, v in zip(run.prob.params_of(name), np.ravel(new.params.get(name, []))))
            return (f"{name} ({values}) is only the nearest effect: {other} beyond its range fits significantly better "
                    f"(RMS {_rms(run.prob, new, run.mask):.3g} against {_rms(run.prob, fit, run.mask):.3g} mm, F = {f_stat:.3g}, "
                    f"p = {p_f:.2g}), so {name} is not named")
    return None


def _rms(prob, fit, mask):
    """RMS per sphere centre of ``fit``'s residuals on the samples of ``mask``, mm (unweighted)."""
    return float(np.sqrt(np.mean(np.sum(prob.raw(fit.e[mask], mask) ** 2, axis=1))))


def _outlier_step_label(dataset, previous, mask, flips):
    """What the final outlier test changed, said: a step that raises the RMS says that it
    reinstates samples (more data, not a worse model)."""
    before_mask, before_flips = previous
    new_flips = sorted(set(flips) - set(before_flips))
    back = [i for i in np.where(mask & ~before_mask)[0] if i not in new_flips]
    changes = (("sign_flip", new_flips), ("reinstated", back), ("excluded", np.where(~mask & before_mask)[0]))
    return "outliers: " + "; ".join(f"{what} " + ",".join(dataset.ids[i] for i in rows) for what, rows in changes if len(rows))


def _extend(structure, name):
    if name == "sphere_center":
        return dataclasses.replace(structure, centre=True)
    return dataclasses.replace(structure, data_effects=structure.data_effects + (name,))


def _reduce(structure, name):
    if name == "sphere_center":
        return dataclasses.replace(structure, centre=False)
    return dataclasses.replace(structure, data_effects=tuple(e for e in structure.data_effects if e != name))


def _confirmed(run, base_structure, base, structure, new):
    """F test, Delta BIC and held-out error must agree that ``new`` improves on ``base`` (``run`` the
    :class:`Procedure`), and a data effect must move the pose beyond :data:`~handeye.model.fit.power.SHIFT_FLOOR`:
    its test's bias grows with n (:mod:`handeye.app.engine.effect_size`; 16,000 clean centres at 0.15 mm: a
    0.01 % scale, which moves the pose 0.025 mm), and one within the floor cannot make the answer wrong."""
    prob, mask, alpha = run.prob, run.mask, run.alpha
    k = new.p - base.p
    if new.ssr >= base.ssr or new.m - new.p <= 0:
        return False
    f_stat = ((base.ssr - new.ssr) / k) / (new.ssr / (new.m - new.p))
    p_f = f_survival(f_stat, k, new.m - new.p)
    d_bic = new.m * np.log(new.ssr / base.ssr) + k * np.log(new.m)
    moved = pose_distance(prob.transform(new.x), prob.transform(base.x))
    matters = (not any(effect_size.biased(n) for n in set(structure.data_effects) - set(base_structure.data_effects))
               or moved["translation_mm"] > power.SHIFT_FLOOR[0] or moved["rotation_deg"] > power.SHIFT_FLOOR[1])
    return (p_f < alpha and d_bic < 0 and matters
            and prob.heldout_rms(structure, mask, new) < prob.heldout_rms(base_structure, mask, base))


def _backward(prob, structure, fit, mask, alpha, centre_unknown=False):
    """Re-test every accepted effect for removal (F test); a centre estimated from the start
    (``centre_unknown``) is not an effect and stays."""
    names = (["sphere_center"] if structure.centre and not centre_unknown else []) + list(structure.data_effects)
    for name in names:
        reduced = _reduce(structure, name)
        smaller = prob.fit(reduced, mask, fit.x, {k: v for k, v in fit.params.items() if k != name})
        k = fit.p - smaller.p
        f_stat = ((smaller.ssr - fit.ssr) / k) / (fit.ssr / (fit.m - fit.p))
        if f_survival(max(f_stat, 0.0), k, fit.m - fit.p) >= alpha:
            return reduced, smaller
    return structure, fit


def _final_outliers(prob, structure, fit, mask, alpha, allowed=None):
    """Sign flips and outliers among the excluded samples, on the structured model; a sample
    not ``allowed`` (a row that contradicts itself) is never flipped or reinstated."""
    flips = set(structure.flips)
    allowed = np.ones(prob.n, bool) if allowed is None else allowed
    for _ in range(prob.n):
        changed = False
        predict = prediction_test(fit.e, fit.jac, mask)
        for i in np.where(~mask & allowed)[0]:
            flipped = dataclasses.replace(structure, flips=frozenset(flips | {i}))
            e_flip, j_flip, _ = prob.evaluate(flipped, fit.x, fit.params, rows=[i])
            # the flipped sample must be consistent with the fit of the others: its externally
            # studentised prediction statistic, Bonferroni over the samples, not significant
            _, pval = predict(e_flip[0], j_flip[0])
            if min(pval * prob.n, 1.0) >= alpha:
                flips.add(i)
                structure = flipped
                mask[i] = True
                changed = True
                fit = prob.fit(structure, mask, fit.x, fit.params)  # the next candidate against this fit
                predict = prediction_test(fit.e, fit.jac, mask)
        _, pval = deletion_statistics(fit.e, fit.jac, mask)
        adj = np.minimum(pval * prob.n, 1.0)
        back = np.where(~mask & allowed & (adj >= alpha))[0]
        bad = np.where(mask & (adj < alpha))[0]
        together = prob.n > robust.LOO_EXACT_UP_TO  # many samples: all at once (linear, not quadratic)
        if len(back):
            mask[back if together else back[np.argmax(adj[back])]] = True
            changed = True
        elif len(bad) and mask.sum() > max(prob.n // 2 + 1, 4):
            room = int(mask.sum()) - max(prob.n // 2 + 1, 4)
            mask[bad[np.argsort(adj[bad])][:room] if together else bad[np.argmin(adj[bad])]] = False
            changed = True
        fit = prob.fit(structure, mask, fit.x, fit.params)
        if not changed:
            break
    outliers = [int(i) for i in np.where(~mask)[0]]
    return structure, fit, mask, sorted(flips), outliers


def _report(run, structure, fit, flips, outliers):
    """The :class:`DiagnosisResult` of the final ``structure`` and ``fit`` (``run`` the :class:`Procedure`)."""
    prob, mask, before = run.prob, run.mask, run.before
    after = _summaries(prob, structure, fit, mask, run.detail)
    d = prob.d
    std, corr = fit.uncertainty(mask)
    index = {name: k for k, name in enumerate(fit.names)}
    named, all_cols = [], []
    if structure.centre and not run.centre_unknown:
        ks = [index["cx"], index["cy"], index["cz"]]
        delta = fit.x[12:15] - d.sphere_centre
        named.append(NamedEffect("sphere_center", dict(zip(("dx", "dy", "dz"), delta.tolist())),
                                 dict(zip(("dx", "dy", "dz"), std[ks].tolist()))))
        all_cols += ks
    for name in structure.data_effects:
        pnames = prob.params_of(name)
        ks = [index[f"{name}.{p}"] for p in pnames]
        named.append(NamedEffect(name, dict(zip(pnames, fit.params[name].tolist())),
                                 dict(zip(pnames, std[ks].tolist()))))
        all_cols += ks
    if flips:
        named.append(NamedEffect("sign_flip", {"ids": [d.ids[i] for i in flips]}, None))
    sensor = prob.transform(fit.x)
    return DiagnosisResult(
        centre_fitted=bool(structure.centre), convention=d.convention, columns=conventions.columns(d.convention),
        sensor_pose_as=conventions.pose_from(d.convention, sensor),
        std=Uncertainty(std[:3], np.degrees(std[3:6]), std[6:9] if structure.centre else None),
        dataset=d.name, effects=named, outliers=[d.ids[i] for i in outliers], absorbed_by=run.absorbed,
        rms_before_mm=before["rms_mm"], rms_after_mm=after["rms_mm"],
        heldout_rms_before_mm=before["heldout_rms_mm"], heldout_rms_after_mm=after["heldout_rms_mm"],
        chi2_dof_before=before["chi2_dof"], chi2_dof_after=after["chi2_dof"],
        nominal_sigma_mm=prob.sigma, sigma_after_mm=after["sigma_mm"],
        sensor_pose=pose_from_transform(sensor), sensor2flange=sensor,
        sphere_centre=np.asarray(prob.centre(structure, fit.x), float),
        effect_correlations={"names": [fit.names[k] for k in all_cols],
                             "matrix": np.round(corr[np.ix_(all_cols, all_cols)], 4).tolist()},
        steps=[Step(**s) for s in run.steps], tests=[[ScoreTest(**c) for c in round_] for round_ in run.tested],
        residuals=[DiagnosisResidual(i, float(b), float(a), bool(u))
                   for i, b, a, u in zip(d.ids, run.before_norms, np.linalg.norm(prob.raw(fit.e), axis=1), mask)],
        screened_out_first=[e.id for e in run.screening.excluded],
        unexplained=". ".join(t.rstrip(".") for t in (_unexplained(after, prob.sigma), robot_choice.unmodelled(d)) if t),
        robot_alternatives=run.robot_alternatives, robot_rivals=run.robot_rivals, configuration=run.configuration,
        always_absorbed=tuple(sorted(prob.robot_always)),
        cleaning=cleaning_summary(d))


def _unexplained(after, sigma):
    ratio = after["chi2_dof"]
    if ratio < AT_NOISE:
        return f"nothing beyond the nominal noise: chi2/dof {ratio:.2f} at sigma = {sigma:g} mm"
    return (f"residual scatter sigma = {after['sigma_mm']:.3f} mm is {np.sqrt(ratio):.1f} x the nominal {sigma:g} mm: "
            "an effect outside the catalogue (or a larger noise than assumed) remains")
