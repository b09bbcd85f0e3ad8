"""Scoring a given sensor pose on a dataset, and comparing two (``handeye calibrate DATASET
--sensor-pose POSE``, ``--calibration FILE`` with the sensor among ``--unknowns``; ``handeye
compare DATASET A.json B.json``).

A score holds the pose given (the vendor's, last month's) and fits only what else is unknown:
nothing, or the sphere centre (``--unknowns sensor+sphere``). It is judged against the same
data's own calibration, run with the same request (screening, residual model, stated noise),
on the samples that calibration keeps:

- the residual of every sample at the given pose (its sphere centre through the chain minus the
  sphere centre, robot base, mm) and the RMS under each residual model the data allow: ``centre``
  (mm per sphere centre), ``measurement`` (mm per circle ``(xc, zc, r)``), ``points`` (mm per
  profile point);
- the noise test of the given pose: the request's (whitened) model's sum of squares against
  chi-square on its ``m - p`` degrees of freedom (:func:`handeye.app.engine.describe.noise_test`);
- the F test of the given pose against the estimate, which frees its six parameters (nested
  models): ``F = ((S_g - S_e) / 6) / (S_e / (m - p))``; the data *contradict* the pose when
  ``p < P_HELD`` and the RMS is larger by ``HELD_FACTOR``, the rule for any part held
  (:mod:`handeye.app.engine.cell_stage`);
- the distance of the given pose from the estimate: mm, degrees, and in the estimate's own sd
  (Mahalanobis distance on the six pose parameters of the local chart, ``chi^2_6``).

Two poses A and B are compared on the same samples and model: the one with the smaller sum of
squares fits better; whether significantly is Vuong's (1989) test for non-nested models, on the
per-sample differences ``d_i`` of the whitened squared residuals: ``z = sqrt(n) mean(d) / sd(d)``,
two-sided against the normal distribution. (A and B have the same number of parameters, so no
penalty term.)

Vuong, Q. H. (1989). Likelihood ratio tests for model selection and non-nested hypotheses.
Econometrica 57(2), 307-333.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from handeye.app.engine.cell_stage import HELD_FACTOR, P_HELD, mask_of
from handeye.model.chain import conventions
from handeye.model.common.rotation import pose_distance
from handeye.model.common.statistics import f_survival
from handeye.model.datasets import observations
from handeye.model.fit.calibration import CalibrationModel

#: Gauss-Newton steps of the sphere centre with the pose held (linear for the centre model: one).
CENTRE_STEPS = 30


@dataclasses.dataclass(frozen=True)
class PoseScore:
    """One pose on one dataset's samples (module docstring).

    Attributes
    ----------
    sensor2flange : ndarray, shape (4, 4)
        The pose scored (mm), in its mount's frame.
    centre : ndarray, shape (3,)
        Sphere centre used (given, or fitted with the pose held), robot base or its mount's frame, mm.
    residuals : ndarray, shape (N, 3)
        Every sample's sphere centre through the chain minus ``centre``, mm.
    rms_mm : dict
        Residual model -> unweighted RMS over the samples used (mm per centre, circle or point).
    ssr : float
        Sum of squares of the request's (whitened) model over the samples used.
    per_sample : ndarray, shape (n_used,)
        Each used sample's share of ``ssr``.
    m : int
        Residual components in ``ssr``.
    """

    sensor2flange: np.ndarray
    centre: np.ndarray
    residuals: np.ndarray
    rms_mm: dict
    ssr: float
    per_sample: np.ndarray
    m: int


class Scorer:
    """The models of one dataset's used samples, built once, to score any number of poses.

    Parameters
    ----------
    dataset : handeye.model.datasets.dataset.Dataset
    mask : ndarray of bool, shape (N,)
        Samples used (the data's own calibration's).
    kind : {'centre', 'measurement', 'points'}
        The request's residual model; its sum of squares is tested, but for ``points`` (a
        profile's points share its pose's robot error: not independent rows for an F test) the
        ``measurement`` model's, the circles of the same points.
    robot_sigma : float
        Robot repeatability, mm per axis (weights of the profile models).
    centre_free : bool
        Fit the sphere centre with each pose held.
    sensor2flange : ndarray, shape (4, 4), optional
        The pose the weights of the centre model of centres rebuilt from profiles are turned at
        (:func:`handeye.model.datasets.observations.build`); needed for that model alone.
    """

    def __init__(self, dataset, mask, kind, robot_sigma, centre_free, sensor2flange=None):
        kind = "measurement" if kind == "points" else kind
        self.dataset, self.mask, self.kind, self.centre_free = dataset, np.asarray(mask, bool), kind, centre_free
        used = dataset.subset(self.mask)
        start = dataset.sphere_centre if dataset.sphere_centre is not None else np.zeros(3)
        unknowns = "sensor+sphere" if centre_free else "sensor"
        self.model = observations.build(used, kind, "local", unknowns, robot_sigma,
                                        observations.Anchor(start, sensor2flange))
        self.plain = {"centre": CalibrationModel.from_dataset(used, "local", unknowns, start)}
        if used.profiles is not None and all(p is not None for p in used.profiles):
            circ, _ = observations.circles(used)
            radius = used.sphere_diameter / 2
            self.plain["measurement"] = CalibrationModel.from_circles(used.motions(), circ, radius, start, "local", unknowns)
            self.plain["points"] = CalibrationModel.from_profiles(used.motions(), list(used.profiles), radius, start,
                                                                  "local", unknowns)

    def centre_for(self, sensor2flange, centre=None):
        """The sphere centre: the dataset's, or (free) the least squares of the model with the pose held."""
        if not self.centre_free:
            return np.asarray(self.dataset.sphere_centre, float)
        c = None if centre is None else np.asarray(centre, float)
        if c is None or not np.all(np.isfinite(c)):  # the unweighted centre model's own least squares: the mean
            used = self.dataset.subset(self.mask)
            xs = np.column_stack([used.centre_in_sensor, np.ones(len(used))])
            c = np.mean((np.asarray(used.motions()) @ sensor2flange @ xs[..., None])[:, :3, 0], axis=0)
        for _ in range(CENTRE_STEPS):
            x = self.model.point_from(sensor2flange, c)
            r, jac = self.model.residual(x), self.model.jacobian(x)[:, 6:9]
            step = np.linalg.lstsq(jac, -r, rcond=None)[0]
            c = c + step
            if np.linalg.norm(step) < 1e-10 * (1.0 + np.linalg.norm(c)):
                break
        return c

    def score(self, sensor2flange, centre=None):
        """The :class:`PoseScore` of a pose (4x4); ``centre``: start of a free centre."""
        s = np.asarray(sensor2flange, float)
        c = self.centre_for(s, centre)
        x = self.model.point_from(s, c)
        r = self.model.residual(x)
        per_row = (r.reshape(-1, self.model.m) ** 2).sum(axis=1)
        per_sample = per_row if self.model.groups is None else np.bincount(self.model.groups, weights=per_row)
        rms = {name: float(np.sqrt(np.mean(np.sum(plain.residuals(plain.point_from(s, c)) ** 2, axis=1))))
               for name, plain in self.plain.items()}
        xs = np.column_stack([self.dataset.centre_in_sensor, np.ones(len(self.dataset))])
        e_all = (np.asarray(self.dataset.motions()) @ s @ xs[..., None])[:, :3, 0] - c
        return PoseScore(s, c, e_all, rms, float(r @ r), per_sample, len(r))

    @property
    def n_params(self):
        """Parameters of the estimate: the pose (6) and a free centre (3)."""
        return 6 + 3 * self.centre_free


def f_test(given, estimate, n_params):
    """The given pose's score against the estimate's (nested: the estimate frees 6 parameters):
    ``(F, p, contradicted)`` (module docstring)."""
    return held_test(given.ssr, estimate.ssr, given.m, 6, n_params)


def held_test(held_ssr, free_ssr, m, freed, n_params):
    """The rule for any part held: the sum of squares with it held (``held_ssr``) against the fit that frees
    ``freed`` parameters (``free_ssr``; ``n_params`` in all, ``m`` residual components): ``(F, p,
    contradicted)``, contradicted when ``p < P_HELD`` and the RMS is larger by ``HELD_FACTOR``."""
    dof = m - n_params
    if dof <= 0 or not free_ssr > 0:
        return float("nan"), float("nan"), False
    f = max(held_ssr - free_ssr, 0.0) / freed / (free_ssr / dof)
    p = float(f_survival(f, freed, dof))
    return float(f), p, bool(p < P_HELD and math.sqrt(held_ssr / free_ssr) > HELD_FACTOR)


def vuong(a, b):
    """Vuong's test of two non-nested poses on the same samples: ``(z, two-sided p)``; z > 0 when
    B fits better. None when the two fit every sample identically."""
    d = a.per_sample - b.per_sample
    sd = float(np.std(d, ddof=1)) if len(d) > 1 else 0.0
    if sd <= 0:
        return None
    z = math.sqrt(len(d)) * float(np.mean(d)) / sd
    return z, float(math.erfc(abs(z) / math.sqrt(2.0)))


def scorer_for(estimate, dataset, request):
    """The :class:`Scorer` of the samples the data's own calibration ``estimate`` used."""
    pose = np.asarray(estimate.sensor2flange, float)
    return Scorer(dataset, mask_of(estimate), estimate.model, request.robot_sigma, "sphere" in request.unknowns,
                  pose if np.all(np.isfinite(pose)) else None)


def run_score(request, dataset, sensor2flange, source):
    """Score ``sensor2flange`` (4x4) on ``dataset`` with a checked ``request`` whose unknowns hold
    the sensor (the data's own calibration): a
    :class:`~handeye.app.present.score_results.ScoreResult`."""
    return score_against(own_calibration(request, dataset), dataset, request, sensor2flange, source)


def own_calibration(request, dataset):
    """The data's own calibration under the requested model: the search checks it but never
    changes it (a score is of one model; data that contradict the model give no verdict)."""
    from handeye.app.engine.calibrate import run

    return run(dataclasses.replace(request, chosen=True).checked(dataset), dataset)


def score_against(estimate, dataset, request, sensor2flange, source, scorer=None):
    """The :class:`~handeye.app.present.score_results.ScoreResult` of a pose against the data's own
    calibration ``estimate`` (``scorer``: built once for several poses)."""
    from handeye.app.engine.describe import noise_test
    from handeye.app.present.score_results import ScoreResult

    scorer = scorer or scorer_for(estimate, dataset, request)
    s = np.asarray(sensor2flange, float)
    given = scorer.score(s, estimate.sphere_centre)
    own = scorer.score(estimate.sensor2flange, estimate.sphere_centre)
    cov = estimate.covariance if estimate.converged else None
    distance = pose_distance(s, np.asarray(estimate.sensor2flange, float), cov, estimate.parameter_names)
    tested = f_test(given, own, scorer.n_params) if estimate.converged else (float("nan"), float("nan"), None)
    whitened = scorer.model.whiten is not None
    test = (noise_test(given.ssr, given.m - 3 * scorer.centre_free, request.sigma, whitened, [], "")
            if whitened or scorer.kind == "centre" else None)
    return ScoreResult(dataset.name, str(dataset.path), source, request.convention,
                       conventions.columns(request.convention), conventions.pose_from(request.convention, s), s,
                       given, estimate, own, scorer.kind, tested, distance, test,
                       scorer.centre_free)


def compare(request, dataset, poses, sources, alpha):
    """Two poses (4x4 each) scored against one calibration of the data and against each other:
    a :class:`~handeye.app.present.score_results.CompareResult`."""
    from handeye.app.present.score_results import CompareResult

    estimate = own_calibration(request, dataset)
    scorer = scorer_for(estimate, dataset, request)
    scores = tuple(score_against(estimate, dataset, request, p, src, scorer) for p, src in zip(poses, sources))
    cov = estimate.covariance if estimate.converged else None
    between = pose_distance(np.asarray(poses[1], float), np.asarray(poses[0], float), cov, estimate.parameter_names)
    return CompareResult(dataset.name, tuple(sources), scores, vuong(scores[0].given, scores[1].given), alpha, between)
