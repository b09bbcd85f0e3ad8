"""The extended model: the sensor pose with named effects of the catalogue, fitted and tested.

What :func:`handeye.diagnose` searches with and :func:`handeye.calibrate` tests and
calibrates with (``--effects``): a structure (which blocks of the one chain model are free: the sensor
pose, the centre, the positioner's axes, the data and robot effects of :mod:`handeye.model.effects`; sign
flips), its residuals and exact Jacobian (the cell model's, :class:`~handeye.model.fit.cell.CellModel`,
with each effect's block), its least-squares fit, and the score (Lagrange multiplier) test of a candidate
effect at a fit, with the identifiability gate that refuses what the poses cannot separate.
The application's workflow around it lives in :mod:`handeye.app.engine.diagnose`.
"""
from __future__ import annotations

import dataclasses
import functools

import numpy as np

from handeye import solvers
from handeye.model import effects
from handeye.model.common.statistics import chi2_survival
from handeye.model.fit.calibration import ROW_CHUNK
from handeye.model.fit.cell import CellModel, pack, unpack
from handeye.model.fit.score_tests import cholesky, gate, gate_from_sums, projection, score_test_robust


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


@dataclasses.dataclass(frozen=True)
class Structure:
    """Which blocks of the one chain model are free (a value: hashable, so fits of it are cached by it): the
    sensor pose (``sensor``), the sphere centre (``centre``), the positioner's axes named in ``axes`` (each 4
    parameters: :mod:`handeye.model.fit.cell`), the catalogue's data and robot effects in ``data_effects``; the
    samples in ``flips`` read with y negated. A held block stays at the dataset's value (the sensor: at the
    point's)."""

    centre: bool = False
    data_effects: tuple = ()
    flips: frozenset = frozenset()
    sensor: bool = True
    axes: tuple = ()

    def __post_init__(self):
        object.__setattr__(self, "centre", bool(self.centre))
        object.__setattr__(self, "data_effects", tuple(self.data_effects))
        object.__setattr__(self, "flips", frozenset(self.flips))
        object.__setattr__(self, "sensor", bool(self.sensor))
        object.__setattr__(self, "axes", tuple(self.axes))

    @property
    def parts(self):
        """The cell model's free parts (:data:`handeye.model.chain.names.PARTS`)."""
        return tuple(p for p, free in (("sensor", self.sensor), ("sphere", self.centre), ("positioner", self.axes))
                     if free)


@dataclasses.dataclass
class Fit:
    x: np.ndarray  # the cell model's point: R2 (9, row-major), t2, c (held: unused), per positioner axis p, d
    params: dict  # effect name -> array of parameters
    e: np.ndarray  # (N, 3) residuals of all samples
    jac: np.ndarray  # (N, 3, p) Jacobian of all samples: theta then effect parameters; None when chunked
    names: list
    ssr: float
    m: int
    p: int
    converged: bool = True
    message: str = ""
    #: ``(J^T J, J^T r, R)`` over the fit's samples where the Fit holds no Jacobian (``jac`` None: many
    #: samples, summed chunk by chunk; R the triangular factor of J's QR, accumulated chunk by chunk), else None
    normal: tuple | None = None

    @property
    def sigma2(self):
        return self.ssr / max(self.m - self.p, 1)

    def _jtj_jtr(self, mask):
        """``(J^T J, J^T r)`` over the samples in ``mask`` (the fit's own when it holds no Jacobian)."""
        if self.jac is None:
            return self.normal[:2]
        jac = self.jac[mask].reshape(-1, self.p)
        return jac.T @ jac, jac.T @ self.e[mask].ravel()

    def covariance(self, mask):
        """``sigma^2 (J^T J)^+`` over the samples in ``mask`` (step units: mm, rad, effect units)."""
        return self.sigma2 * np.linalg.pinv(self._jtj_jtr(mask)[0])

    def uncertainty(self, mask):
        """1-sd (step units: mm, rad, effect units) and correlation of every parameter, from
        ``sigma^2 (J^T J)^+`` over the samples in ``mask``."""
        cov = self.covariance(mask)
        std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
        scale = np.where(std > 0, std, 1.0)
        return std, cov / np.outer(scale, scale)

    def gradient_cosines(self, mask):
        """Per parameter ``|J_k^T r| / (|J_k| |r|)`` over the samples in ``mask``: 0 at a minimum."""
        jtj, jtr = self._jtj_jtr(mask)
        with np.errstate(all="ignore"):
            return np.abs(jtr) / (np.sqrt(np.diag(jtj)) * np.sqrt(np.sum(self.e[mask] ** 2)))

    def r_factor(self, mask):
        """The triangular factor R (p, p) of ``J = Q R`` over the samples in ``mask`` (the same singular values,
        right singular vectors and column norms as J, to J's own precision: what
        :func:`handeye.model.design.identifiability.analyse` takes with ``rows``)."""
        if self.jac is None:
            return self.normal[2]
        return np.linalg.qr(self.jac[mask].reshape(-1, self.p), mode="r")


def sample_chunks(mask, chunk=None):
    """The indices of the samples in ``mask`` (bool (N,)), at most ``chunk`` (default
    :data:`~handeye.model.fit.calibration.ROW_CHUNK`) at a time."""
    idx, step = np.flatnonzero(mask), chunk or ROW_CHUNK
    for a in range(0, len(idx), step):
        yield idx[a : a + step]


def spread(mask, limit=None):
    """``mask`` (N,) bool with at most ``limit`` (default :data:`~handeye.model.fit.calibration.ROW_CHUNK`)
    of its samples kept, spread evenly over them (a pose tour's order: every part of it)."""
    idx = np.flatnonzero(mask)
    limit = limit or ROW_CHUNK
    if len(idx) <= limit:
        return np.asarray(mask, bool)
    out = np.zeros(len(mask), bool)
    out[idx[np.unique(np.linspace(0, len(idx) - 1, limit).round().astype(int))]] = True
    return out


class Samples:
    """The dataset's samples with a structure: residuals, Jacobians, fits."""

    def __init__(self, dataset, sigma=None, metric=None):
        self.d = dataset
        #: the samples' own metric of the centre residual, in mm
        #: (:class:`handeye.model.datasets.observations.CentreMetric`: centres rebuilt from profiles are
        #: not equal, isotropic noise), or None: equal weights. Every residual, Jacobian and candidate
        #: column is in this metric; :meth:`raw` turns residuals back into mm.
        self.metric = metric
        self.sigma = float(sigma if sigma is not None else getattr(dataset, "noise_centre_mm", NOMINAL_SIGMA))
        self.f2b = dataset.motions()
        self.radius = dataset.sphere_radius_mm  # NaN without [sphere] diameter (effects that need it are no candidates)
        self.n = len(dataset)
        #: per robot effect (:mod:`handeye.model.robot.robot_errors`) the indices of the parameters it
        #: estimates, chosen by the identifiability gate (:func:`handeye.model.design.robot_gate.robot_free`); all until then
        self.robot_free = {}
        #: "effect.parameter" of the robot parameters no pose set separates (robot_gate.robot_free)
        self.robot_always = set()
        #: the held-out errors of the fits asked for (:meth:`heldout_rms`; a search asks for one fit's again)
        self._held_out = {}

    @property
    def whiten(self):
        """The metric's whitening (N, 3, 3), or None (equal weights)."""
        return None if self.metric is None else self.metric.whiten

    def _weights(self, rows=None, flips=frozenset()):
        """The whitening of the samples ``rows`` (default all), a flipped sample's turned by its reflection
        (:class:`~handeye.model.datasets.observations.CentreMetric`); None: equal weights."""
        if self.metric is None:
            return None
        take = (lambda a: a) if rows is None else (lambda a: a[rows])
        w = take(self.metric.whiten)
        flipped = np.isin(take(np.arange(self.n)), list(flips)) if flips else np.zeros(len(w), bool)
        if flipped.any():
            r = take(self.metric.turn)[flipped]
            w = w.copy()
            w[flipped] = w[flipped] @ r @ np.diag([1.0, -1.0, 1.0]) @ np.swapaxes(r, 1, 2)
        return w

    def whitened(self, arr, rows=None, flips=frozenset()):
        """Rows ``arr`` (k, 3) or (k, 3, q) of the samples ``rows`` (default all) in the samples' metric, the
        samples in ``flips`` read with y negated."""
        w = self._weights(rows, flips)
        return arr if w is None else np.einsum("nij,nj...->ni...", w, arr)

    def raw(self, e, rows=None):
        """Residuals ``e`` (k, 3) in the samples' metric back in mm (the carrier's frame; a flipped sample's
        reflected, its length the same)."""
        w = self._weights(rows)
        return e if w is None else np.linalg.solve(w, e[..., None])[..., 0]

    def params_of(self, name):
        """The parameter names an effect has on these samples (a robot effect: those it estimates)."""
        effect = effects.get(name)
        if effect.KIND != "robot":
            return effect.PARAMS
        names = effect.params(self.d.robot_model)
        return tuple(names[k] for k in self.robot_free.get(name, range(len(names))))

    def _free(self, name):
        return list(self.robot_free.get(name, range(len(effects.get(name).params(self.d.robot_model)))))

    def robot_motion(self, params, rows=None):
        """The carrier motions with the flange poses corrected by the robot effects ``params`` (name
        -> the estimated parameters) (N, 4, 4), and per effect their derivatives (N, k, 4, 4) with
        respect to its estimated parameters. The flange is ``F' = F_rep T(q)^-1 T*(q)``
        (:mod:`handeye.model.robot.robot_errors`); the motion is ``F'`` (sensor on the flange), its
        inverse (sensor fixed, sphere on the flange: ``d inv(F') = -inv(F') dF' inv(F')``), as
        :func:`handeye.model.chain.mounts.motions`; not with the sphere on a positioner (the robot effects'
        ``available`` says why)."""
        from handeye.model.chain.mounts import inverse_transforms
        from handeye.model.robot.robot_errors import perturbed

        model, mounts = self.d.robot_model, self.d.mounts
        values = {}
        for name, p in params.items():
            full = np.zeros(len(effects.get(name).params(model)))
            full[self._free(name)] = p
            values[name] = full
        take = (lambda a: a) if rows is None else (lambda a: a[rows])
        fk, derivatives = perturbed(model, take(self.d.joints), values)
        moved = take(self._reported_over_nominal)
        corrected = moved @ fk
        d = {name: moved[:, None] @ dfk[:, self._free(name)] for name, dfk in derivatives.items()}
        if mounts.default:
            return corrected, d
        if mounts.sensor != "world":
            raise ValueError("robot effects with the sphere on a positioner are not modelled")
        inv = inverse_transforms(corrected)
        return inv, {name: -inv[:, None] @ dm @ inv[:, None] for name, dm in d.items()}

    @functools.cached_property
    def _flange2base(self):
        """The flange poses (N, 4, 4), the motions of a chain whose positioner axes are free (once, not per step)."""
        return np.asarray(self.d.flange2base(), float)

    @functools.cached_property
    def _reported_over_nominal(self):
        """``F_rep T(q)^-1`` of every sample (N, 4, 4), the same at every evaluation."""
        return self.d.flange2base() @ np.linalg.inv(self.d.robot_model.flange2base(self.d.joints))

    def measured(self, structure, rows=None):
        """The measured centres (N, 3) with the structure's sign flips (of the samples ``rows``,
        an index array, only, when given)."""
        xs = self.d.centre_in_sensor.copy() if rows is None else self.d.centre_in_sensor[rows]
        if structure.flips:
            flipped = np.fromiter(structure.flips, int)
            flip = flipped if rows is None else np.isin(rows, flipped)
            xs[flip, 1] = -xs[flip, 1]
        return xs

    def evaluate(self, structure, x, params, rows=None):
        """Residuals (N, 3) and Jacobian (N, 3, p) at point x with effect parameters (of the
        samples ``rows``, an index array, only, when given), in the samples' metric, and the chain's
        :class:`~handeye.model.fit.cell.CellModel` of those samples (the robot's corrections in its motions)."""
        e, jac, model = self.chain(structure, x, params, rows)
        return self.whitened(e, rows, structure.flips), self.whitened(jac, rows, structure.flips), model

    def chain(self, structure, x, params, rows=None):
        """:meth:`evaluate` in mm, unweighted. The chain and the data effects are the one cell model's (its
        blocks free or held by the structure; with axes free the flange poses and the positioner's product of
        exponentials, else the carrier motions); a robot effect's columns are its flange derivatives moving
        the centre (:meth:`robot_motion`)."""
        xs = self.measured(structure, rows)
        take = (lambda a: a) if rows is None else (lambda a: a[rows])
        f2b = take(self._flange2base) if structure.axes else take(self.f2b)
        robot_names = [n for n in structure.data_effects if effects.get(n).KIND == "robot"]
        robot = {}
        if robot_names:
            f2b, robot = self.robot_motion({n: params[n] for n in robot_names}, rows)
        data_names = tuple(n for n in structure.data_effects if n not in robot)
        model = self._cell(structure, f2b, xs, data_names, take)
        chain = np.concatenate([x[:12], self.centre(structure, x), x[15:] if structure.axes else []])
        point = np.concatenate([chain, *(np.asarray(params[n], float) for n in data_names)])
        e, jac = model.evaluate(point)
        columns = {name: jac[:, :, a:b] for name, a, b in _blocks(model, data_names)}
        if robot:
            in_flange = np.einsum("ij,nj->ni", x[:9].reshape(3, 3), model.corrected(point)[0]) + x[9:12]
            columns |= {name: _moved_centre(robot[name], in_flange) for name in robot}
        free = model.columns[:len(model.columns) - model.n_effects]
        jac = np.concatenate([jac[:, :, free]] + [columns[n] for n in structure.data_effects], axis=2)
        return e, jac, model

    def _cell(self, structure, motions, xs, data_names, take):
        """The cell model of the samples ``take`` selects, its blocks free as ``structure`` says."""
        if not structure.axes:
            return CellModel(motions, xs, np.zeros((len(xs), 0)), free=structure.parts, effects=data_names,
                             radius=self.radius)
        return CellModel(motions, xs, take(np.asarray(self.d.axis_angles, float)), self.d.mounts.axis_names,
                         structure.parts, structure.axes, data_names, self.radius)

    def names(self, structure):
        base = list(self._chart(structure).names)
        for name in structure.data_effects:
            base += [f"{name}.{p}" for p in self.params_of(name)]
        return base

    def normal_equations(self, structure, x, params, mask, chunk=None):
        """``(J^T J, J^T r, r^T r)`` over the samples in ``mask``, summed over chunks of at most
        ``chunk`` (default :data:`~handeye.model.fit.calibration.ROW_CHUNK`) samples."""
        jtj, jtr, rtr = 0.0, 0.0, 0.0
        for rows in sample_chunks(mask, chunk):
            e, jac, _ = self.evaluate(structure, x, params, rows)
            flat, r = jac.reshape(-1, jac.shape[2]), e.ravel()
            jtj, jtr, rtr = jtj + flat.T @ flat, jtr + flat.T @ r, rtr + r @ r
        return jtj, jtr, rtr

    def _chunked_factors(self, structure, x, params, mask, chunk=None):
        """``(J^T J, J^T r, R)`` over the samples in ``mask``, chunk by chunk: R the triangular factor of J's
        QR, each chunk's rows stacked under the R so far (the Jacobian of every sample is never held)."""
        jtj, jtr, r_factor = 0.0, 0.0, np.zeros((0, 0))
        for rows in sample_chunks(mask, chunk):
            e, jac, _ = self.evaluate(structure, x, params, rows)
            flat = jac.reshape(-1, jac.shape[2])
            jtj, jtr = jtj + flat.T @ flat, jtr + flat.T @ e.ravel()
            r_factor = np.linalg.qr(np.vstack([r_factor.reshape(-1, flat.shape[1]), flat]), mode="r")
        return jtj, jtr, r_factor

    def residuals(self, structure, x, params, mask=None, chunk=None):
        """Residuals (N, 3) of the samples in ``mask`` (default all), chunk by chunk: the
        Jacobian of every sample is never held."""
        mask = np.ones(self.n, bool) if mask is None else mask
        out = np.full((self.n, 3), np.nan)
        for rows in sample_chunks(mask, chunk):
            out[rows] = self.evaluate(structure, x, params, rows)[0]
        return out

    def fit(self, structure, mask, x0, params0=None, chunk=None):
        """Least squares of the structure on the samples in ``mask``. Above
        :data:`~handeye.model.fit.calibration.ROW_CHUNK` samples (or with ``chunk``) on normal
        equations summed chunk by chunk: the Fit then holds no Jacobian (``jac`` None)."""
        z0, n, split, retract = self._layout(structure, x0, params0)
        big = chunk is not None or int(np.count_nonzero(mask)) > ROW_CHUNK
        problem = self._problem(structure, mask, (n, split, retract), chunk, big)
        solved = solvers.solve(problem, z0, "lm", {"max_iter": 200})
        x, params = split(solved.x)
        normal = None
        if big:
            e, jac = self.residuals(structure, x, params, None, chunk), None
            normal = self._chunked_factors(structure, x, params, mask, chunk)
        else:
            e, jac, _ = self.evaluate(structure, x, params)
        ssr = float(np.sum(e[mask] ** 2))
        return Fit(x, params, e, jac, self.names(structure), ssr, 3 * int(mask.sum()), n, bool(solved.converged),
                   solved.message, normal)

    def weighted_fit(self, structure, rows, weights, x0, params0=None, max_iter=100):
        """Weighted least squares ``sum w_i |e_i|^2`` of the structure on the samples ``rows``.

        Parameters
        ----------
        structure : Structure
        rows : ndarray of int
            The samples fitted (evaluated on these alone: a subsample of a large dataset).
        weights : ndarray, shape (len(rows),)
        x0 : ndarray
            Start point (local chart).
        params0 : dict, optional
            Start effect parameters (default zero).
        max_iter : int

        Returns
        -------
        x : ndarray
        params : dict
            Effect name -> parameters.
        e : ndarray, shape (len(rows), 3)
            Residuals of the samples ``rows`` at the fit.
        """
        z0, n, split, retract = self._layout(structure, x0, params0)
        sw = np.sqrt(np.repeat(np.asarray(weights, float), 3))
        problem = solvers.Problem(
            n=n, retract=retract,
            residual=lambda z: sw * self.evaluate(structure, *split(z), rows)[0].ravel(),
            jacobian=lambda z: sw[:, None] * self.evaluate(structure, *split(z), rows)[1].reshape(-1, n))
        x, params = split(solvers.solve(problem, z0, "lm", {"max_iter": max_iter}).x)
        return x, params, self.evaluate(structure, x, params, rows)[0]

    def _layout(self, structure, x0, params0):
        """The one vector of a point and the structure's effect parameters that :meth:`fit` and
        :meth:`weighted_fit` solve for: its start (``x0``, then ``params0``, default zero), its
        step's length, the split of a vector into the point and the parameters (name -> array),
        and the retraction of a step (the chart's, then the parameters' plain sum)."""
        keys = list(structure.data_effects)
        params0 = {n: np.zeros(len(self.params_of(n))) for n in keys} | (params0 or {})
        chart, n_pt = self._chart(structure), len(x0)
        ends = np.cumsum([n_pt] + [len(self.params_of(n)) for n in keys])

        def split(z):
            return z[:n_pt], {k: z[a:b] for k, a, b in zip(keys, ends[:-1], ends[1:])}

        def retract(z, delta):
            return np.concatenate([chart.retract(z[:n_pt], delta[:chart.n]), z[n_pt:] + delta[chart.n:]])

        return np.concatenate([x0] + [params0[k] for k in keys]), chart.n + int(ends[-1]) - n_pt, split, retract

    def _problem(self, structure, mask, layout, chunk, big):
        """The solvers' Problem of :meth:`fit` (``layout``: the step's length, split and retraction
        of :meth:`_layout`): on normal equations when ``big``."""
        n, split, retract = layout
        if big:
            return solvers.Problem(
                n=n, retract=retract,
                residual=lambda z: self.residuals(structure, *split(z), mask, chunk)[mask].ravel(),
                jacobian=lambda z: self.evaluate(structure, *split(z))[1][mask].reshape(-1, n),
                normal=lambda z: self.normal_equations(structure, *split(z), mask, chunk))
        at = solvers.last_point(lambda z: self.evaluate(structure, *split(z))[:2])  # a step's Jacobian at its residual's point
        return solvers.Problem(
            n=n, retract=retract,
            residual=lambda z: at(z)[0][mask].ravel(),
            jacobian=lambda z: at(z)[1][mask].reshape(-1, n))

    def _chart(self, structure):
        """The structure's cell model without samples: its point's layout, step names and retraction."""
        none = np.zeros((0, 3))
        if not structure.axes:
            return CellModel(np.zeros((0, 4, 4)), none, np.zeros((0, 0)), free=structure.parts)
        names = self.d.mounts.axis_names
        return CellModel(np.zeros((0, 4, 4)), none, np.zeros((0, len(names))), names, structure.parts, structure.axes)

    def point(self, structure, sensor2flange, centre=None, axes=None):
        """The point of a sensor pose (4, 4, in its carrier's frame), a sphere centre (3,, default the dataset's)
        and, where the structure frees axes, the positioner's axes (default the dataset's)."""
        centre = self.d.sphere_centre if centre is None else centre
        centre = np.zeros(3) if centre is None else centre
        return pack(sensor2flange, centre, (self.d.mounts.axes if axes is None else axes) if structure.axes else ())

    def heldout_rms(self, structure, mask, fit, raw=False):
        """RMS prediction error of held-out samples, 5-fold cross-validation over ``mask``: in the samples'
        metric (what a decision compares), or with ``raw`` in mm (what a report shows)."""
        key = (structure, mask.tobytes(), fit.x.tobytes(),
               tuple((k, np.asarray(v, float).tobytes()) for k, v in sorted(fit.params.items())), repr(self.robot_free))
        if key not in self._held_out:
            idx = np.where(mask)[0]
            folds = np.array_split(np.random.default_rng(0).permutation(idx), min(FOLDS, len(idx)))
            self._held_out[key] = [(fold, self.fit(structure, _without(mask, fold), fit.x, fit.params).e[fold])
                                   for fold in folds]
        errs = [np.sum((self.raw(e, fold) if raw else e) ** 2, axis=1) for fold, e in self._held_out[key]]
        return float(np.sqrt(np.mean(np.concatenate(errs))))

    def transform(self, x):
        """The sensor pose (4, 4) of a point."""
        return unpack(x[:15], ())[0]

    def centre(self, structure, x):
        """The sphere centre (3,) of a point: its own where the structure frees it, else the dataset's."""
        return np.asarray(x[12:15] if structure.centre else self.d.sphere_centre, float)

    def axes(self, structure, x):
        """The positioner's axes of a point (where the structure frees axes), else the dataset's."""
        return unpack(x, self.d.mounts.axis_names)[2] if structure.axes else self.d.mounts.axes


def _blocks(model, names):
    """``(name, first, end)`` of each data effect's columns in the full Jacobian of the cell ``model``."""
    at = model.n_chain
    for name in names:
        k = len(effects.get(name).PARAMS)
        yield name, at, at + k
        at += k


def _without(mask, rows):
    """``mask`` with ``rows`` left out (a new array)."""
    out = mask.copy()
    out[rows] = False
    return out


def _moved_centre(dfk, in_flange):
    """Derivatives (N, 3, k) of the centre ``F p`` seen from flanges whose derivatives are ``dfk``
    (N, k, 4, 4), ``in_flange`` (N, 3) the centre in the flange frame."""
    return np.einsum("nkij,nj->nik", dfk[..., :3, :3], in_flange) + np.swapaxes(dfk[..., :3, 3], 1, 2)


def candidate_columns(prob, structure, fit, mask, name):
    """Jacobian columns (rows of the samples in mask) of a candidate effect at the fit."""
    cols = candidate_rows(prob, structure, fit, None, name)
    return cols[mask].reshape(-1, cols.shape[2])


def candidate_rows(prob, structure, fit, rows, name):
    """Jacobian columns (k, 3, q) of a candidate effect at the fit, of the samples ``rows`` (an
    index array; None: every sample), in the samples' metric (:meth:`Samples.whitened`)."""
    return prob.whitened(_candidate_rows(prob, structure, fit, rows, name), rows, structure.flips)


def _candidate_rows(prob, structure, fit, rows, name):
    """:func:`candidate_rows` in mm (unweighted): a data or robot effect's are its block of the one model with
    it added (at zero), a centre's ``-I``, another effect's its own (:attr:`columns` of the chain's terms)."""
    effect = effects.get(name)
    if effect.KIND in ("data", "robot"):
        trial = dataclasses.replace(structure, data_effects=(*structure.data_effects, name))
        k = len(prob.params_of(name))
        return prob.chain(trial, fit.x, fit.params | {name: np.zeros(k)}, rows)[1][:, :, -k:]
    if effect.KIND == "centre":
        return -np.broadcast_to(np.eye(3), (prob.n if rows is None else len(rows), 3, 3))
    _, _, model = prob.chain(structure, fit.x, fit.params, rows)
    carrier = model.motions if not structure.axes else prob.f2b if rows is None else prob.f2b[rows]  # the chain's M_i
    xs, r2, f2b = model.corrected(_point_of(model, fit))[0], fit.x[:9].reshape(3, 3), carrier
    u = np.einsum("ij,nj->ni", r2, xs) + fit.x[9:12]
    q = np.einsum("nij,nj->ni", f2b[:, :3, :3], u) + f2b[:, :3, 3]
    return effect.columns({"q": q, "u": u, "R1": f2b[:, :3, :3], "R1R2": f2b[:, :3, :3] @ r2, "xs": xs})


def _point_of(model, fit):
    """The cell ``model``'s point of a fit (the chain's rotation, translation, an unused centre, its data effects)."""
    return np.concatenate([fit.x[:12], np.zeros(3), *(np.asarray(fit.params[n], float) for n in model.effects)])


def _candidates(structure, skip, dataset):
    """The catalogue's effects the score tests try on ``dataset``, in the catalogue's order."""
    return [effect.NAME for effect in effects.catalogue() if effect.KIND in ("data", "centre")
            and effect.NAME not in skip and not (effect.NAME == "sphere_center" and structure.centre)
            and effects.fittable(effect.NAME, dataset)]


def _chunk_columns(prob, structure, fit, rows, names):
    """The fit's Jacobian (3k, p), residual (3k,) and the candidates' columns (3k, q) of the
    samples ``rows``."""
    _, jac, _ = prob.evaluate(structure, fit.x, fit.params, rows)
    cols = {}
    for name in names:
        c = candidate_rows(prob, structure, fit, rows, name)
        cols[name] = c.reshape(-1, c.shape[2])
    return jac.reshape(-1, fit.p), fit.e[rows].ravel(), cols


def _first_pass(prob, structure, fit, mask, names, chunk):
    """Sums over the samples in ``mask``: ``J^T J``, ``J^T r``, whether J and r are finite, and
    per candidate ``(C^T J, C^T C, C^T r, finite)``."""
    p = fit.p
    jtj, jtr, finite = np.zeros((p, p)), np.zeros(p), True
    sums = {name: [0.0, 0.0, 0.0, True] for name in names}
    for rows in sample_chunks(mask, chunk):
        j, r, cols = _chunk_columns(prob, structure, fit, rows, names)
        finite = finite and bool(np.all(np.isfinite(j)) and np.all(np.isfinite(r)))
        jtj += j.T @ j
        jtr += j.T @ r
        for name, c in cols.items():
            s = sums[name]
            s[0], s[1], s[2] = s[0] + c.T @ j, s[1] + c.T @ c, s[2] + c.T @ r
            s[3] = s[3] and bool(np.all(np.isfinite(c)))
    return jtj, jtr, finite, sums


def score_by_sums(prob, structure, fit, mask, names, chunk=None):
    """The robust score tests (:func:`~handeye.model.fit.score_tests.score_test_robust`) of the
    candidates ``names`` in two passes over chunks of the samples in ``mask``, never holding the
    Jacobian of every sample: the first sums the normal equations and the candidates' cross
    products (gate, score), the second each sample's score for the variance. Returns
    ``[(p, name, statistic, gate)]``, ``[]`` when the fit has no finite derivative, or None when
    ``J^T J`` is too ill-conditioned for its Cholesky factor (then the full arrays' Householder
    QR is needed)."""
    jtj, jtr, finite, sums = _first_pass(prob, structure, fit, mask, names, chunk)
    if not finite:
        return []
    chol = cholesky(jtj)
    if chol is None:
        return None
    tested = {}
    for name, (cj, cc, cr, ok) in sums.items():
        frac = gate_from_sums(chol, cj, cc) if ok else 0.0
        if ok and frac >= GATE:
            b = np.linalg.solve(jtj, cj.T)  # projection coefficients G^-1 J^T C
            tested[name] = (b, cr - b.T @ jtr, frac, 0.0)
    for rows in sample_chunks(mask, chunk) if tested else ():
        j, r, cols = _chunk_columns(prob, structure, fit, rows, list(tested))
        for name, (b, g, frac, v) in tested.items():
            a = cols[name] - j @ b
            per_sample = np.einsum("nik,ni->nk", a.reshape(-1, 3, a.shape[1]), r.reshape(-1, 3))
            tested[name] = (b, g, frac, v + per_sample.T @ per_sample)
    m = fit.m
    found = []
    for name, (b, g, frac, v) in tested.items():
        stat = float(g @ np.linalg.lstsq(v * m / max(m - fit.p, 1), g, rcond=None)[0])
        found.append((chi2_survival(stat, len(g)), name, stat, frac))
    return found


@dataclasses.dataclass(frozen=True)
class Calibrated:
    """A calibration the effects are tested at.

    ``mask`` (N,) bool: the samples it used; ``sensor2flange`` (4, 4); ``centre`` (3,): the sphere centre in
    the base, mm; ``unknowns``: 'sensor' or 'sensor+sphere'.
    """

    mask: np.ndarray
    sensor2flange: np.ndarray
    centre: np.ndarray
    unknowns: str = "sensor"


def score_effects(dataset, at, skip=(), chunk=None, robot=None, prob=None):
    """Score tests of the catalogue's continuous effects at a calibration (step 3 alone).

    Parameters
    ----------
    dataset : handeye.model.datasets.dataset.Dataset
    at : Calibrated
    skip : sequence of str
        Data effects already in the model: fitted with it, and the others tested given them.
    chunk : int, optional
        Samples per chunk of the sums (:func:`score_by_sums`); default the full arrays up to
        :data:`~handeye.model.fit.calibration.ROW_CHUNK` samples used, chunks of that many above.
    robot : callable, optional
        ``robot(prob, structure, fit, mask) -> [(p, name, statistic, gate)]``: the robot effects'
        tests (:func:`handeye.model.design.robot_gate.robot_scores`, which gates their parameters), taken
        into the same Bonferroni family; not on the chunked path.
    prob : Samples, optional
        The dataset's samples with the robot effects of ``skip`` already gated
        (:func:`handeye.model.design.robot_gate.score_effects`); default new ones.

    Returns
    -------
    list of ScoreTest
        Every identifiable candidate, Bonferroni-adjusted over them, most significant first;
        the score's variance is robust to unequal noise between samples
        (:func:`~handeye.model.fit.score_tests.score_test_robust`).
    """
    prob, mask = prob or Samples(dataset), np.asarray(at.mask, bool)
    structure = Structure(centre=at.unknowns == "sensor+sphere", data_effects=tuple(skip))
    with np.errstate(all="ignore"):
        fit = prob.fit(structure, mask, prob.point(structure, at.sensor2flange, at.centre), chunk=chunk)
    if fit.jac is None:  # many samples: sums over chunks
        found = score_by_sums(prob, structure, fit, mask, _candidates(structure, skip, prob.d), chunk)
        if found is not None:
            return _ranked(found)
        fit = dataclasses.replace(fit, jac=prob.evaluate(structure, fit.x, fit.params)[1])
    jac_cur = fit.jac[mask].reshape(-1, fit.p)
    if not (np.all(np.isfinite(jac_cur)) and np.all(np.isfinite(fit.e[mask]))):
        return []  # the model with ``skip`` has no derivative here (a centre on the laser plane): nothing to test
    found, q = [], projection(jac_cur)  # one basis for every candidate
    for name in _candidates(structure, skip, prob.d):
        cols = candidate_columns(prob, structure, fit, mask, name)
        if not np.all(np.isfinite(cols)):
            continue
        frac, _ = gate(jac_cur, cols, fit.names, q=q, absorbers=False)
        if frac < GATE:
            continue
        stat, p = score_test_robust(fit, mask, cols, q=q)
        found.append((p, name, stat, frac))
    return _ranked(found + (robot(prob, structure, fit, mask) if robot is not None else []))


def _ranked(found):
    """ScoreTests of ``[(p, name, statistic, gate)]``, Bonferroni-adjusted, most significant first."""
    found = sorted(found)
    return [ScoreTest(name, stat, min(p * len(found), 1.0), frac) for p, name, stat, frac in found]


#: A robot parameter's column must keep this fraction outside the span of the sensor pose, the
#: sphere centre and the parameters already chosen to be estimated (stricter than :data:`GATE`:
#: one column).
JOINT_GATE = 1e-2

