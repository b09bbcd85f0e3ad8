"""Model discrepancy: find where model and data disagree, name the missing effect, add it,
show the gap shrink (``handeye diagnose``).

The procedure combines three traditions: a residual check (like a Bayesian discrepancy term
it *finds* a gap), a catalogue of named candidate effects (like sparse model discovery it
*names* terms), and an identifiability gate (like robot-calibration practice it refuses what
the poses cannot separate):

1. Robust first fit; gross outliers screened with a robust scale (:mod:`handeye.app.robust`);
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
   reduction in SSR, Delta BIC < 0 and a lower 5-fold held-out error must all agree.
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

from handeye import solvers
from handeye.app import robust
from handeye.app.calibrate import resolve_start
from handeye.app.diagnosis_results import DiagnosisResidual, DiagnosisResult, ScoreTest, Step
from handeye.app.results import NamedEffect
from handeye.model import effects
from handeye.model.calibration import CalibrationModel
from handeye.model.pose import pose_from_transform, transform_from_pose
from handeye.model.statistics import chi2_survival, deletion_statistics, f_survival, prediction_test

#: Family-wise level of the effect tests and of the outlier tests: the screening's (one value).
ALPHA = robust.ALPHA
#: Fraction of an effect's columns that must lie outside the current model's span.
GATE = 1e-3
#: Nominal noise per residual component (mm) for chi2/dof when the dataset states none
#: (``[noise] centre_mm``; ``--sigma``): the tests themselves use the estimated sigma.
NOMINAL_SIGMA = 0.05
FOLDS = 5


@dataclasses.dataclass
class Structure:
    """What the model contains besides the sensor pose."""

    centre: bool = False
    data_effects: tuple = ()
    flips: frozenset = frozenset()


@dataclasses.dataclass
class Fit:
    x: np.ndarray  # local point: t2, R2 (9), [c]
    params: dict  # effect name -> array of parameters
    e: np.ndarray  # (N, 3) residuals of all samples
    jac: np.ndarray  # (N, 3, p) Jacobian of all samples: theta then effect parameters
    names: list
    ssr: float
    m: int
    p: int
    converged: bool = True
    message: str = ""

    @property
    def sigma2(self):
        return self.ssr / max(self.m - self.p, 1)

    def uncertainty(self, mask):
        """1-sd (step units: mm, rad, effect units) and correlation of every parameter, from
        ``sigma^2 (J^T J)^+`` over the samples in ``mask``."""
        jac = self.jac[mask].reshape(-1, self.p)
        cov = self.sigma2 * np.linalg.pinv(jac.T @ jac)
        std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
        scale = np.where(std > 0, std, 1.0)
        return std, cov / np.outer(scale, scale)


class Samples:
    """The dataset's samples with a structure: residuals, Jacobians, fits."""

    def __init__(self, dataset, sigma=None):
        self.d = dataset
        self.sigma = float(sigma if sigma is not None else getattr(dataset, "noise_centre_mm", NOMINAL_SIGMA))
        self.f2b = dataset.flange2base()
        self.radius = dataset.sphere_diameter / 2
        self.n = len(dataset)

    def measured(self, structure):
        xs = self.d.centre_in_sensor.copy()
        for i in structure.flips:
            xs[i, 1] = -xs[i, 1]
        return xs

    def evaluate(self, structure, x, params, rows=None):
        """Residuals (N, 3) and Jacobian (N, 3, p) at point x with effect parameters (of the
        samples ``rows`` only, when given)."""
        xs = self.measured(structure)
        f2b = self.f2b
        if rows is not None:
            xs, f2b = xs[rows], f2b[rows]
        cols = []
        for name in structure.data_effects:
            with np.errstate(invalid="ignore", divide="ignore"):  # non-finite trial steps are rejected
                xs, dxs = effects.correct(name, xs, self.radius, params[name])
            cols.append(dxs)
        unknowns = "sensor+sphere" if structure.centre else "sensor"
        model = CalibrationModel(f2b, xs, self.d.sphere_centre, "local", unknowns)
        e, j = model.residual_and_jacobian(x)
        r12 = f2b[:, :3, :3] @ model.sensor_rotation(x)
        extra = [np.einsum("nij,njk->nik", r12, c) for c in cols]
        return e, np.concatenate([j] + extra, axis=2) if extra else j, model

    def names(self, structure):
        base = ["tx", "ty", "tz", "wx", "wy", "wz"] + (["cx", "cy", "cz"] if structure.centre else [])
        for name in structure.data_effects:
            base += [f"{name}.{p}" for p in effects.get(name).PARAMS]
        return base

    def fit(self, structure, mask, x0, params0=None):
        """Least squares of the structure on the samples in ``mask``."""
        params0 = {n: np.zeros(len(effects.get(n).PARAMS)) for n in structure.data_effects} | (params0 or {})
        keys = list(structure.data_effects)
        sizes = [len(effects.get(n).PARAMS) for n in keys]
        retract_model = self._chart(structure.centre)
        n_pt = len(x0)
        n_theta = retract_model.n

        def split(z):
            x = z[:n_pt]
            params, k = {}, n_pt
            for key, size in zip(keys, sizes):
                params[key] = z[k : k + size]
                k += size
            return x, params

        def residual(z):
            x, params = split(z)
            return self.evaluate(structure, x, params)[0][mask].ravel()

        def jacobian(z):
            x, params = split(z)
            return self.evaluate(structure, x, params)[1][mask].reshape(-1, n_theta + sum(sizes))

        def retract(z, delta):
            return np.concatenate([retract_model.retract(z[:n_pt], delta[:n_theta]), z[n_pt:] + delta[n_theta:]])

        z0 = np.concatenate([x0] + [params0[k] for k in keys])
        problem = solvers.Problem(n=n_theta + sum(sizes), residual=residual, jacobian=jacobian, retract=retract)
        solved = solvers.solve(problem, z0, "lm", {"max_iter": 200})
        x, params = split(solved.x)
        e, jac, _ = self.evaluate(structure, x, params)
        ssr = float(np.sum(e[mask] ** 2))
        return Fit(x, params, e, jac, self.names(structure), ssr, 3 * int(mask.sum()), jac.shape[2],
                   bool(solved.converged), solved.message)

    def _chart(self, centre_free):
        """A one-row local-chart model: the point layout and retraction of a structure."""
        return CalibrationModel(self.f2b[:1], self.d.centre_in_sensor[:1], self.d.sphere_centre, "local",
                                "sensor+sphere" if centre_free else "sensor")

    def point(self, structure, sensor2flange, centre=None):
        return self._chart(structure.centre).point_from(sensor2flange, self.d.sphere_centre if centre is None else centre)

    def heldout_rms(self, structure, mask, fit):
        """RMS prediction error (mm) of held-out samples, 5-fold cross-validation over ``mask``."""
        idx = np.where(mask)[0]
        folds = np.array_split(np.random.default_rng(0).permutation(idx), min(FOLDS, len(idx)))
        errs = []
        for fold in folds:
            train = mask.copy()
            train[fold] = False
            f = self.fit(structure, train, fit.x, fit.params)
            errs.append(np.sum(f.e[fold] ** 2, axis=1))
        return float(np.sqrt(np.mean(np.concatenate(errs))))

    def transform(self, x):
        return self._chart(False).sensor2flange(x[:12])

    def centre(self, structure, x):
        return x[12:15] if structure.centre else self.d.sphere_centre


#: Above this many rows the orthonormal basis of the Jacobian's columns is CholeskyQR2 (two
#: Cholesky passes of the normal equations: matrix products, several times faster than
#: Householder QR on (3 million, p), and as orthogonal for a condition number below ~1e7).
CHOLESKY_QR_ABOVE = 30_000


def _projection(jac_cur):
    """Orthonormal basis (m, p) of the columns of ``jac_cur`` (m, p)."""
    if len(jac_cur) <= CHOLESKY_QR_ABOVE:
        return np.linalg.qr(jac_cur)[0]
    q = jac_cur
    for _ in range(2):
        try:
            r = np.linalg.cholesky(q.T @ q).T
        except np.linalg.LinAlgError:
            return np.linalg.qr(jac_cur)[0]
        d = np.abs(np.diag(r))
        if not np.all(np.isfinite(r)) or d.min() <= 1e-7 * d.max():  # ill-conditioned: Householder
            return np.linalg.qr(jac_cur)[0]
        q = q @ np.linalg.inv(r)
    return q


def _gate(jac_cur, cand, names):
    """Fraction of the candidate's columns outside the current span, and who absorbs it."""
    norms = np.linalg.norm(cand, axis=0)
    scaled = cand / np.where(norms > 0, norms, 1.0)
    q = _projection(jac_cur)
    perp = scaled - q @ (q.T @ scaled)
    s_perp = np.linalg.svd(perp, compute_uv=False)
    s_full = np.linalg.svd(scaled, compute_uv=False)
    frac = float(s_perp[-1] / max(s_full[-1], 1e-300))
    coef, *_ = np.linalg.lstsq(jac_cur, scaled, rcond=None)
    weight = np.abs(coef) * np.linalg.norm(jac_cur, axis=0)[:, None]
    # strongest first; weights equal to 6 digits (a frame shift absorbed by cx, cy, cz alike)
    # keep the parameters' order, so the list does not follow the last bits of the solve
    strength = np.round(weight.max(axis=1) / max(weight.max(), 1e-300), 6)
    top = np.argsort(-strength, kind="stable")
    absorbers = [names[k] for k in top if strength[k] > 0.1][:6]
    return frac, absorbers


def _candidate_columns(prob, structure, fit, mask, name):
    """Jacobian columns (rows of the samples in mask) of a candidate effect at the fit."""
    effect = effects.get(name)
    xs = prob.measured(structure)
    for eff in structure.data_effects:
        xs, _ = effects.correct(eff, xs, prob.radius, fit.params[eff])
    model = CalibrationModel(prob.f2b, xs, prob.centre(structure, fit.x), "local",
                             "sensor+sphere" if structure.centre else "sensor")
    r2 = model.sensor_rotation(fit.x)
    r12 = prob.f2b[:, :3, :3] @ r2
    if effect.KIND == "centre":
        cols = -np.broadcast_to(np.eye(3), (prob.n, 3, 3))
    elif effect.KIND == "data":
        with np.errstate(invalid="ignore", divide="ignore"):
            _, dxs = effects.correct(name, xs, prob.radius, np.zeros(len(effect.PARAMS)))
        cols = np.einsum("nij,njk->nik", r12, dxs)
    else:
        t2 = fit.x[:3]
        u = np.einsum("ij,nj->ni", r2, xs) + t2
        q = np.einsum("nij,nj->ni", prob.f2b[:, :3, :3], u) + prob.f2b[:, :3, 3]
        cols = effect.columns({"q": q, "u": u, "R1": prob.f2b[:, :3, :3], "R1R2": r12, "xs": xs})
    return cols[mask].reshape(-1, cols.shape[2])


def _score(fit, mask, cand):
    jac_cur = fit.jac[mask].reshape(-1, fit.p)
    r = fit.e[mask].ravel()
    q = _projection(jac_cur)
    a = cand - q @ (q.T @ cand)
    g = a.T @ r
    stat = float(g @ np.linalg.lstsq(a.T @ a, g, rcond=None)[0]) / fit.sigma2
    return stat, chi2_survival(stat, cand.shape[1])


def _score_robust(fit, mask, cand):
    """The score test with a variance robust to unequal noise between samples (a reconstructed
    centre's y is noisier where the laser plane passes near the sphere's centre): the score's
    variance is summed over the samples (cluster-robust), with the small-sample factor m / (m - p)."""
    jac_cur = fit.jac[mask].reshape(-1, fit.p)
    r = fit.e[mask].ravel()
    q = _projection(jac_cur)
    a = cand - q @ (q.T @ cand)
    g = a.T @ r
    per_sample = np.einsum("nik,ni->nk", a.reshape(-1, 3, a.shape[1]), r.reshape(-1, 3))
    m = len(r)
    v = per_sample.T @ per_sample * m / max(m - fit.p, 1)
    stat = float(g @ np.linalg.lstsq(v, g, rcond=None)[0])
    return stat, chi2_survival(stat, cand.shape[1])


def score_effects(dataset, mask, sensor2flange, centre, unknowns="sensor", skip=()):
    """Score tests of the catalogue's continuous effects at a calibration (step 3 alone).

    Parameters
    ----------
    dataset : handeye.model.dataset.Dataset
    mask : ndarray of bool, shape (N,)
        The samples the calibration used.
    sensor2flange : ndarray, shape (4, 4)
    centre : ndarray, shape (3,)
        Sphere centre in the base, mm.
    unknowns : {'sensor', 'sensor+sphere'}
    skip : sequence of str
        Data effects already in the model: fitted with it, and the others tested given them.

    Returns
    -------
    list of handeye.app.diagnosis_results.ScoreTest
        Every identifiable candidate, Bonferroni-adjusted over them, most significant first;
        the score's variance is robust to unequal noise between samples (:func:`_score_robust`).
    """
    prob = Samples(dataset)
    structure = Structure(centre=unknowns == "sensor+sphere", data_effects=tuple(skip))
    with np.errstate(all="ignore"):
        fit = prob.fit(structure, np.asarray(mask, bool), prob.point(structure, sensor2flange, centre))
    jac_cur = fit.jac[mask].reshape(-1, fit.p)
    if not (np.all(np.isfinite(jac_cur)) and np.all(np.isfinite(fit.e[mask]))):
        return []  # the model with ``skip`` has no derivative here (a centre on the laser plane): nothing to test
    found = []
    for effect in effects.catalogue():
        name = effect.NAME
        if effect.KIND not in ("data", "centre") or name in skip or (name == "sphere_center" and structure.centre):
            continue
        cols = _candidate_columns(prob, structure, fit, mask, name)
        if not np.all(np.isfinite(cols)):
            continue
        frac, _ = _gate(jac_cur, cols, fit.names)
        if frac < GATE:
            continue
        stat, p = _score_robust(fit, mask, cols)
        found.append((p, name, stat, frac))
    found.sort()
    return [ScoreTest(name, stat, min(p * len(found), 1.0), frac) for p, name, stat, frac in found]


def _summaries(prob, structure, fit, mask):
    e = fit.e[mask]
    return {
        "rms_mm": float(np.sqrt(np.mean(np.sum(e**2, axis=1)))),
        "chi2_dof": float(fit.sigma2 / prob.sigma**2),
        "sigma_mm": float(np.sqrt(fit.sigma2)),
        "heldout_rms_mm": prob.heldout_rms(structure, mask, fit),
    }


def diagnose(dataset, alpha=ALPHA, start=None, sigma=None):
    """Run the procedure (module docstring) on a dataset.

    Parameters
    ----------
    dataset : handeye.model.dataset.Dataset
    alpha : float
        Family-wise level of the effect and outlier tests.
    start : array_like, shape (6,), optional
        Start sensor pose (KUKA, mm, deg); default as :func:`handeye.app.calibrate.resolve_start`.
    sigma : float, optional
        Nominal noise per residual component (mm) for chi2/dof; default the dataset's
        ``[noise] centre_mm``.

    Returns
    -------
    handeye.app.diagnosis_results.DiagnosisResult
    """
    prob = Samples(dataset, sigma)
    start_pose, _ = resolve_start(dataset, "sensor", start)
    screening = robust.screen(dataset, "sensor", transform_from_pose(start_pose), alpha=alpha)
    mask, inconsistent = robust.exclude_inconsistent(dataset, "sensor", screening.inliers.copy(), [])
    allowed = ~np.isin(dataset.rows, [e.row for e in inconsistent])  # never reinstated
    structure = Structure()
    fit = prob.fit(structure, mask, prob.point(structure, screening.robust_sensor2flange))
    before = _summaries(prob, structure, fit, mask)
    before_norms = np.linalg.norm(fit.e, axis=1)
    steps = [{"step": "base model", **before}]
    absorbed, tested, implausible = {}, [], []
    flips, outliers = [], []
    for _ in range(3):  # effects, then discrete samples, until neither changes the other
        structure, fit = _search(prob, structure, fit, mask, alpha, absorbed, tested, steps, implausible)
        previous = (mask.copy(), structure.flips)
        structure, fit, mask, flips, outliers = _final_outliers(prob, structure, fit, mask, alpha, allowed)
        if not (np.array_equal(previous[0], mask) and previous[1] == structure.flips):
            steps.append({"step": _outlier_step_label(dataset, previous, mask, structure.flips),
                          **_summaries(prob, structure, fit, mask)})
        structure, fit = _backward(prob, structure, fit, mask, alpha)
        if np.array_equal(previous[0], mask) and previous[1] == structure.flips:
            break
    # structural effects: checked against the sensor pose and the sphere centre
    with_centre = _extend(structure, "sphere_center")
    full = prob.fit(with_centre, mask, fit.x if structure.centre else np.concatenate([fit.x, dataset.sphere_centre]),
                    fit.params)
    for effect in effects.catalogue("structural"):
        cols = _candidate_columns(prob, with_centre, full, mask, effect.NAME)
        frac, who = _gate(full.jac[mask].reshape(-1, full.p), cols, full.names)
        if frac < GATE:
            absorbed[effect.NAME] = who
    after = _summaries(prob, structure, fit, mask)
    result = _report(prob, structure, fit, mask, before, after, before_norms, steps, absorbed, tested, flips,
                     outliers, screening)
    if implausible:
        unexplained = "; ".join(dict.fromkeys(implausible)) + ". " + result.unexplained
        result = dataclasses.replace(result, unexplained=unexplained)
    return dataclasses.replace(result, inconsistent=inconsistent) if inconsistent else result


def _search(prob, structure, fit, mask, alpha, absorbed, tested, steps, implausible):
    """Steps 3-5: test every continuous candidate, confirm the best, repeat."""
    continuous = [e.NAME for e in effects.catalogue() if e.KIND in ("data", "centre")]
    for _ in range(len(continuous)):
        jac_cur = fit.jac[mask].reshape(-1, fit.p)
        candidates = []
        for name in continuous:
            if name in structure.data_effects or (name == "sphere_center" and structure.centre):
                continue
            cols = _candidate_columns(prob, structure, fit, mask, name)
            if not np.all(np.isfinite(cols)):
                continue  # not testable here (e.g. a centre reconstructed exactly on the equator)
            frac, who = _gate(jac_cur, cols, fit.names)
            if frac < GATE:
                absorbed[name] = who
                continue
            absorbed.pop(name, None)
            stat, p = _score(fit, mask, cols)
            candidates.append((p, name, stat, frac))
        if not candidates:
            break
        m_tests = len(candidates)
        candidates.sort()
        tested.append([{"name": nm, "score": st, "p_bonferroni": min(p * m_tests, 1.0), "gate": fr}
                       for p, nm, st, fr in candidates])
        accepted = None
        for p, name, _, _ in candidates:
            if p * m_tests >= alpha:
                break
            trial = _extend(structure, name)
            x0 = fit.x if name != "sphere_center" else np.concatenate([fit.x, prob.d.sphere_centre])
            new = prob.fit(trial, mask, x0, fit.params)
            why = effects.implausible(name, new.params.get(name, []), prob.radius)
            if why is not None:
                implausible.append(why)
                continue
            if _confirmed(prob, structure, fit, trial, new, mask, alpha):
                accepted = (name, trial, new)
                break
        if accepted is None:
            break
        name, structure, fit = accepted
        structure, fit = _backward(prob, structure, fit, mask, alpha)
        steps.append({"step": f"+ {name}", **_summaries(prob, structure, fit, mask)})
    return structure, fit


def _outlier_step_label(dataset, previous, mask, flips):
    """What the final outlier test changed, said: a step that raises the RMS says that it
    reinstates samples (more data, not a worse model)."""
    before_mask, before_flips = previous
    ids = dataset.ids
    parts = []
    new_flips = sorted(set(flips) - set(before_flips))
    if new_flips:
        parts.append("sign_flip " + ",".join(ids[i] for i in new_flips))
    back = [i for i in np.where(mask & ~before_mask)[0] if i not in new_flips]
    if back:
        parts.append("reinstated " + ",".join(ids[i] for i in back))
    out = np.where(~mask & before_mask)[0]
    if len(out):
        parts.append("excluded " + ",".join(ids[i] for i in out))
    return "outliers: " + "; ".join(parts)


def _extend(structure, name):
    if name == "sphere_center":
        return dataclasses.replace(structure, centre=True)
    return dataclasses.replace(structure, data_effects=structure.data_effects + (name,))


def _reduce(structure, name):
    if name == "sphere_center":
        return dataclasses.replace(structure, centre=False)
    return dataclasses.replace(structure, data_effects=tuple(e for e in structure.data_effects if e != name))


def _confirmed(prob, base_structure, base, structure, new, mask, alpha):
    """F test, Delta BIC and held-out error must agree that ``new`` improves on ``base``."""
    k = new.p - base.p
    if new.ssr >= base.ssr or new.m - new.p <= 0:
        return False
    f_stat = ((base.ssr - new.ssr) / k) / (new.ssr / (new.m - new.p))
    p_f = f_survival(f_stat, k, new.m - new.p)
    d_bic = new.m * np.log(new.ssr / base.ssr) + k * np.log(new.m)
    if not (p_f < alpha and d_bic < 0):
        return False
    return prob.heldout_rms(structure, mask, new) < prob.heldout_rms(base_structure, mask, base)


def _backward(prob, structure, fit, mask, alpha):
    """Re-test every accepted effect for removal (F test)."""
    names = (["sphere_center"] if structure.centre else []) + list(structure.data_effects)
    for name in names:
        reduced = _reduce(structure, name)
        x0 = fit.x[:12] if name == "sphere_center" else fit.x
        smaller = prob.fit(reduced, mask, x0, {k: v for k, v in fit.params.items() if k != name})
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


def _report(prob, structure, fit, mask, before, after, before_norms, steps, absorbed, tested, flips, outliers,
            screening):
    d = prob.d
    std, corr = fit.uncertainty(mask)
    index = {name: k for k, name in enumerate(fit.names)}
    named, all_cols = [], []
    if structure.centre:
        ks = [index["cx"], index["cy"], index["cz"]]
        delta = fit.x[12:15] - d.sphere_centre
        named.append(NamedEffect("sphere_center", dict(zip(("dx", "dy", "dz"), delta.tolist())),
                                 dict(zip(("dx", "dy", "dz"), std[ks].tolist()))))
        all_cols += ks
    for name in structure.data_effects:
        pnames = effects.get(name).PARAMS
        ks = [index[f"{name}.{p}"] for p in pnames]
        named.append(NamedEffect(name, dict(zip(pnames, fit.params[name].tolist())),
                                 dict(zip(pnames, std[ks].tolist()))))
        all_cols += ks
    if flips:
        named.append(NamedEffect("sign_flip", {"ids": [d.ids[i] for i in flips]}, None))
    sensor = prob.transform(fit.x)
    after_norms = np.linalg.norm(fit.e, axis=1)
    from handeye.app.results import Uncertainty
    from handeye.model import conventions

    return DiagnosisResult(
        centre_fitted=bool(structure.centre),
        convention=d.convention,
        columns=conventions.columns(d.convention),
        sensor_pose_as=conventions.pose_from(d.convention, sensor),
        std=Uncertainty(std[:3], np.degrees(std[3:6]), std[6:9] if structure.centre else None),
        dataset=d.name,
        effects=named,
        outliers=[d.ids[i] for i in outliers],
        absorbed_by=absorbed,
        rms_before_mm=before["rms_mm"],
        rms_after_mm=after["rms_mm"],
        heldout_rms_before_mm=before["heldout_rms_mm"],
        heldout_rms_after_mm=after["heldout_rms_mm"],
        chi2_dof_before=before["chi2_dof"],
        chi2_dof_after=after["chi2_dof"],
        nominal_sigma_mm=prob.sigma,
        sigma_after_mm=after["sigma_mm"],
        sensor_pose=pose_from_transform(sensor),
        sensor2flange=sensor,
        sphere_centre=np.asarray(prob.centre(structure, fit.x), float),
        effect_correlations={"names": [fit.names[k] for k in all_cols],
                             "matrix": np.round(corr[np.ix_(all_cols, all_cols)], 4).tolist()},
        steps=[Step(**s) for s in steps],
        tests=[[ScoreTest(**c) for c in round_] for round_ in tested],
        residuals=[DiagnosisResidual(i, float(b), float(a), bool(u))
                   for i, b, a, u in zip(d.ids, before_norms, after_norms, mask)],
        screened_out_first=[e.id for e in screening.excluded],
        unexplained=_unexplained(after, prob.sigma),
    )


def _unexplained(after, sigma):
    ratio = after["chi2_dof"]
    if ratio < 2.0:
        return f"nothing beyond the nominal noise: chi2/dof {ratio:.2f} at sigma = {sigma:g} mm"
    return (f"residual scatter sigma = {after['sigma_mm']:.3f} mm is {np.sqrt(ratio):.1f} x the nominal {sigma:g} mm: "
            "an effect outside the catalogue (or a larger noise than assumed) remains")


def text(res):
    """A readable report of a :class:`handeye.app.diagnosis_results.DiagnosisResult`."""
    lines = [f"handeye diagnose: dataset {res.dataset}", ""]
    if res.effects:
        lines.append("effects named:")
        for eff in res.effects:
            if eff.std is None:
                lines.append(f"  {eff.name}: {', '.join(eff.parameters['ids'])}")
            else:
                lines.append(f"  {eff.name}: " + ", ".join(
                    f"{k} = {v:.5g} +- {eff.std[k]:.2g}" for k, v in eff.parameters.items()))
    else:
        lines.append("effects named: none")
    lines.append("outliers excluded: " + (", ".join(res.outliers) or "none"))
    lines += [f"  {e.id} (row {e.row}): {e.reason}" for e in res.inconsistent]
    lines.append("not identifiable (absorbed): " + ("none" if not res.absorbed_by else ""))
    lines += [f"  {sentence}" for sentence in res.absorbed_explained]
    lines += ["", f"{'step':<34} {'RMS mm':>9} {'held-out':>9} {'chi2/dof':>9}"]
    for step in res.steps:
        lines.append(f"{step.step:<34} {step.rms_mm:9.4f} {step.heldout_rms_mm:9.4f} {step.chi2_dof:9.2f}")
    lines += ["", f"chi2/dof against a nominal sigma of {res.nominal_sigma_mm} mm per component",
              f"sensor pose ({res.convention}: {','.join(res.columns)}): "
              + " ".join(f"{v:.4f}" for v in (res.sensor_pose_as if res.sensor_pose_as is not None else res.sensor_pose)),
              "  1 sd: translation mm " + " ".join(f"{v:.4f}" for v in res.std.sensor_translation_mm)
              + "; rotation deg (about the sensor's axes) " + " ".join(f"{v:.4f}" for v in res.std.sensor_rotation_deg),
              "sphere centre (mm): " + " ".join(f"{v:.4f}" for v in res.sphere_centre),
              f"unexplained: {res.unexplained}"]
    return "\n".join(lines)


def figures(res, out):
    """Residuals before/after per sample, the gap shrinking step by step (PNG files in ``out``)."""
    import pathlib

    from handeye.app.files import save_figure_atomically
    from handeye.app.plotting import figure

    out = pathlib.Path(out)
    out.mkdir(parents=True, exist_ok=True)
    plt = figure()
    fig, ax = plt.subplots(figsize=(10, 4))
    ids = [r.id for r in res.residuals]
    k = np.arange(len(ids))
    ax.bar(k - 0.2, [r.before_mm for r in res.residuals], 0.4, label="base model")
    ax.bar(k + 0.2, [r.after_mm for r in res.residuals], 0.4, label="with named effects")
    for i, r in enumerate(res.residuals):
        if not r.used:
            ax.annotate("excluded", (i, r.after_mm), rotation=90, fontsize=6, ha="center", va="bottom")
    ax.set_xticks(k, ids, rotation=90, fontsize=6)
    ax.set(ylabel="|residual| (mm)", yscale="log", title=f"{res.dataset}: residuals per measurement")
    ax.legend()
    fig.tight_layout()
    save_figure_atomically(fig, out / "residuals.png", option="--figures")
    plt.close(fig)
    fig, ax = plt.subplots(figsize=(6, 4))
    labels = [s.step for s in res.steps]
    ax.plot(labels, [s.rms_mm for s in res.steps], "o-", label="fitted")
    ax.plot(labels, [s.heldout_rms_mm for s in res.steps], "s--", label="held out (5-fold)")
    ax.set(ylabel="RMS (mm)", yscale="log", title="the gap, step by step")
    ax.tick_params(axis="x", rotation=20)
    ax.legend()
    fig.tight_layout()
    save_figure_atomically(fig, out / "gap.png", option="--figures")
    plt.close(fig)
    return [out / "residuals.png", out / "gap.png"]
