"""The extended model: the sensor pose with named effects of the catalogue, fitted and tested.

What :func:`handeye.diagnose` searches with and :func:`handeye.calibrate` tests and
calibrates with (``--effects``): a structure (the centre free or not, the data effects of
:mod:`handeye.model.effects` in the model, sign flips), its residuals and exact Jacobian
(the chain's, :class:`~handeye.model.calibration.CalibrationModel`, times each effect's
derivative), its least-squares fit, and the score (Lagrange multiplier) test of a candidate
effect at a fit, with the identifiability gate that refuses what the poses cannot separate.
The application's workflow around it lives in :mod:`handeye.app.engine.diagnose`.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from handeye import solvers
from handeye.model import effects
from handeye.model.calibration import CalibrationModel
from handeye.model.statistics import chi2_survival


@dataclasses.dataclass(frozen=True)
class ScoreTest:
    """A candidate effect's score test in one round (Bonferroni over the round's candidates)."""

    name: str
    score: float
    p_bonferroni: float
    gate: float

    def to_dict(self):
        return dataclasses.asdict(self)



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


def _times(tall, small):
    """``tall @ small`` for a tall (m, p) and a small (p, k) matrix, as ``(small^T tall^T)^T``:
    the same products, several times faster (numpy's matmul of a tall matrix by a small one
    does not reach BLAS's speed; the transposed product does)."""
    return (small.T @ tall.T).T


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
        q = _times(q, np.linalg.inv(r))
    return q


def gate(jac_cur, cand, names, q=None, absorbers=True):
    """Fraction of the candidate's columns outside the current span, and who absorbs it
    (``q``: :func:`_projection` of ``jac_cur`` when already computed; without ``absorbers``
    the list is empty and its least-squares solve skipped)."""
    norms = np.linalg.norm(cand, axis=0)
    scaled = cand / np.where(norms > 0, norms, 1.0)
    q = _projection(jac_cur) if q is None else q
    perp = scaled - _times(q, q.T @ scaled)
    s_perp = np.linalg.svd(perp, compute_uv=False)
    s_full = np.linalg.svd(scaled, compute_uv=False)
    frac = float(s_perp[-1] / max(s_full[-1], 1e-300))
    if not absorbers:
        return frac, []
    coef, *_ = np.linalg.lstsq(jac_cur, scaled, rcond=None)
    weight = np.abs(coef) * np.linalg.norm(jac_cur, axis=0)[:, None]
    # strongest first; weights equal to 6 digits (a frame shift absorbed by cx, cy, cz alike)
    # keep the parameters' order, so the list does not follow the last bits of the solve
    strength = np.round(weight.max(axis=1) / max(weight.max(), 1e-300), 6)
    top = np.argsort(-strength, kind="stable")
    absorbers = [names[k] for k in top if strength[k] > 0.1][:6]
    return frac, absorbers


def candidate_columns(prob, structure, fit, mask, name):
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


def score_test(fit, mask, cand):
    jac_cur = fit.jac[mask].reshape(-1, fit.p)
    r = fit.e[mask].ravel()
    q = _projection(jac_cur)
    a = cand - _times(q, q.T @ cand)
    g = a.T @ r
    stat = float(g @ np.linalg.lstsq(a.T @ a, g, rcond=None)[0]) / fit.sigma2
    return stat, chi2_survival(stat, cand.shape[1])


def score_test_robust(fit, mask, cand, q=None):
    """The score test with a variance robust to unequal noise between samples (a reconstructed
    centre's y is noisier where the laser plane passes near the sphere's centre): the score's
    variance is summed over the samples (cluster-robust), with the small-sample factor m / (m - p).
    ``q``: :func:`_projection` of the fit's Jacobian on ``mask`` when already computed."""
    r = fit.e[mask].ravel()
    q = _projection(fit.jac[mask].reshape(-1, fit.p)) if q is None else q
    a = cand - _times(q, q.T @ cand)
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
    list of ScoreTest
        Every identifiable candidate, Bonferroni-adjusted over them, most significant first;
        the score's variance is robust to unequal noise between samples (:func:`score_test_robust`).
    """
    prob = Samples(dataset)
    structure = Structure(centre=unknowns == "sensor+sphere", data_effects=tuple(skip))
    with np.errstate(all="ignore"):
        fit = prob.fit(structure, np.asarray(mask, bool), prob.point(structure, sensor2flange, centre))
    jac_cur = fit.jac[mask].reshape(-1, fit.p)
    if not (np.all(np.isfinite(jac_cur)) and np.all(np.isfinite(fit.e[mask]))):
        return []  # the model with ``skip`` has no derivative here (a centre on the laser plane): nothing to test
    found, q = [], _projection(jac_cur)  # one basis for every candidate
    for effect in effects.catalogue():
        name = effect.NAME
        if effect.KIND not in ("data", "centre") or name in skip or (name == "sphere_center" and structure.centre):
            continue
        cols = candidate_columns(prob, structure, fit, mask, name)
        if not np.all(np.isfinite(cols)):
            continue
        frac, _ = gate(jac_cur, cols, fit.names, q=q, absorbers=False)
        if frac < GATE:
            continue
        stat, p = score_test_robust(fit, mask, cols, q=q)
        found.append((p, name, stat, frac))
    found.sort()
    return [ScoreTest(name, stat, min(p * len(found), 1.0), frac) for p, name, stat, frac in found]
