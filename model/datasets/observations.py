"""From a dataset to a calibration model: which residual, which weights.

Three residual models (:mod:`handeye.model.fit.calibration`):

* ``centre`` -- the seed's: the sphere centre reconstructed in the sensor frame. Without
  profiles every component gets the same weight. With profiles each sample is whitened by
  its covariance: the circle fit's, propagated through ``y = side sqrt(R^2 - r^2)`` (y's error
  grows like ``(r/|y|) sigma_r`` near the equator), plus the robot's repeatability.
* ``measurement`` -- the circle (centre ``xc, zc`` and radius r in the laser plane) that the
  sensor actually measured, whitened by the circle fit's covariance plus the robot's
  repeatability propagated into it. The side of the laser plane no longer matters.
* ``points`` -- every profile point lies on the sphere. Equal weights.

The robot's repeatability (``robot_sigma``, mm per axis, default 0.025 mm: the KR 60 HA's
+-0.05 mm read as 2 sigma) is an assumption, stated in every result that uses it.

The gross-error test (:mod:`handeye.app.engine.robust`) judges every sample in this metric too
(:func:`screening_model`): a centre reconstructed from its profile carries its circle fit's
covariance (:func:`profile_covariance`) plus an isotropic part, the chain's, a reported centre the
isotropic part alone; that part is estimated from the data (:func:`chain_sd`), the covariances
turned from the sensor frame into the robot base, where the centre residual lies.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from handeye.model.common.errors import InputError
from handeye.model.datasets.dataset import NOISE_ROBOT_MM as ROBOT_SIGMA  # the default of [noise] robot_mm
from handeye.model.fit.calibration import KINDS, CalibrationModel
from handeye.model.geometry import circle

MODEL_KINDS = tuple(KINDS)  # the residual kinds, defined once in handeye.model.fit.calibration
CIRCLE_FIT = "geometric"


class ObservationError(InputError):
    """The dataset lacks what the residual model needs (profiles)."""


def default_kind(dataset):
    """``measurement`` when every sample has a profile, else ``centre``."""
    if dataset.profiles is not None and all(p is not None for p in dataset.profiles):
        return "measurement"
    return "centre"


def _require_profiles(dataset, kind):
    if dataset.profiles is None or any(p is None for p in dataset.profiles):
        missing = [i for i, p in zip(dataset.ids, dataset.profiles or [None] * len(dataset)) if p is None]
        raise ObservationError(
            f"{dataset.path / 'measurements.csv'}: --model {kind} needs a profile for every sample; "
            f"missing for {', '.join(missing[:8])}{' ...' if len(missing) > 8 else ''}"
        )


def circles(dataset, fit=CIRCLE_FIT):
    """Circles fitted to every profile and their covariances: (N, 3) and (N, 3, 3)."""
    _require_profiles(dataset, "measurement")
    out, covs = [], []
    for ident, row, pts in zip(dataset.ids, dataset.rows, dataset.profiles):
        try:
            c = circle.fit_circle(pts[:, 0], pts[:, 1], fit)
        except circle.CircleFitError as exc:
            raise ObservationError(f"{dataset.path / 'measurements.csv'}, row {row}, column 'profile': the profile of "
                                   f"sample {ident!r}: {exc}") from None
        out.append([c.x, c.z, c.r])
        covs.append(circle.circle_covariance(pts[:, 0], pts[:, 1], c))
    return np.array(out), np.array(covs)


def circle_noise(cov_circle, r, radius, robot_sigma):
    """Covariance of a measured circle ``(xc, zc, r)`` as the measurement residual sees it:
    the circle fit's plus the robot's repeatability, which moves the predicted centre
    isotropically and so the radius residual by ``-(p_y / r) dp_y``."""
    y_squared = max(radius**2 - r**2, 1e-12)
    return cov_circle + robot_sigma**2 * np.diag([1.0, 1.0, y_squared / r**2])


def profile_covariance(dataset):
    """The part of each sphere centre's covariance that its own measurement gives (N, 3, 3): its
    profile's or its point cloud's; None when no centre was reconstructed from a profile or fitted to
    a cloud.

    Parameters
    ----------
    dataset : handeye.model.datasets.dataset.Dataset

    Returns
    -------
    ndarray, shape (N, 3, 3), or None
        For a centre reconstructed from its profile the circle fit's covariance (the profile's
        own scatter, :func:`handeye.model.geometry.circle.circle_covariance`, evaluated at the
        Hyper circle the centre was reconstructed from) propagated to the
        centre (:func:`handeye.model.geometry.circle.centre_covariance`), sensor frame, mm^2; for a
        centre fitted to its cloud the sphere fit's (``dataset.centre_cov``,
        :mod:`handeye.model.geometry.sphere_cloud`); zero for a centre the sensor reported (its noise
        is the chain's, isotropic). Computed once per dataset.
    """
    rebuilt = np.asarray(getattr(dataset, "reconstructed", None) or (False,) * len(dataset), bool)
    clouds = getattr(dataset, "centre_cov", None)
    rebuilt &= getattr(dataset, "profiles", None) is not None
    if not rebuilt.any() and clouds is None:
        return None

    def compute():
        cov = np.zeros((len(dataset), 3, 3)) if clouds is None else np.array(clouds, float)
        if not rebuilt.any():
            return cov
        circ, covs = circles(dataset.subset(rebuilt), "hyper")  # the covariance at the Hyper circle: no iterations
        radius = dataset.sphere_diameter / 2
        cov[rebuilt] = [circle.centre_covariance(circle.Circle(*c), s, radius, dataset.side) for c, s in zip(circ, covs)]
        return cov

    return dataset.once("profile_covariance", compute) if hasattr(dataset, "once") else compute()


def whitening(cov):
    """Matrices W (N, m, m) with ``W^T W = cov^-1`` (inverse Cholesky factors)."""
    return np.linalg.inv(np.linalg.cholesky(cov))


@dataclasses.dataclass(frozen=True)
class Anchor:
    """Where a model is built (:func:`build`): the sphere centre it holds (3,), mm, None: the dataset's;
    the sensor pose (4, 4) at which the centre model of profiled samples turns their weights from the sensor
    frame into the residual's (:func:`turned_whitening`), None: the centre model of profiled samples is not
    built."""

    sphere_centre: object = None
    sensor2flange: object = None


def build(dataset, kind, rotation="local", unknowns="sensor", robot_sigma=ROBOT_SIGMA, at=Anchor()):
    """The calibration model of ``dataset`` with residual ``kind`` (module docstring), built ``at`` an
    :class:`Anchor`."""
    if kind not in MODEL_KINDS:
        raise ObservationError(f"unknown residual model {kind!r}; choose one of {', '.join(MODEL_KINDS)}")
    centre, sensor2flange = (dataset.sphere_centre if at.sphere_centre is None else at.sphere_centre), at.sensor2flange
    radius = None if dataset.sphere_diameter is None else dataset.sphere_diameter / 2  # None: no profiles
    f2b = dataset.motions()
    if kind == "points":
        _require_profiles(dataset, kind)
        return CalibrationModel.from_profiles(f2b, list(dataset.profiles), radius, centre, rotation, unknowns)
    has_profiles = dataset.profiles is not None and all(p is not None for p in dataset.profiles)
    if kind == "centre":
        whiten = None
        if has_profiles:
            if sensor2flange is None:
                raise ObservationError(f"{dataset.path / 'measurements.csv'}: the centre model of profiled samples needs "
                                       "a sensor pose to weigh them at (their weights lie in the sensor frame, the "
                                       "residual in the carrier's), and none is finite here")
            circ, covs = circles(dataset)
            cov = np.array([circle.centre_covariance(circle.Circle(*c), s, radius, dataset.side) for c, s in zip(circ, covs)])
            whiten = turned_whitening(dataset, sensor2flange, cov, robot_sigma)
        elif getattr(dataset, "centre_cov", None) is not None:  # centres fitted to clouds: each by its fit's covariance
            whiten = turned_whitening(dataset, _anchored(dataset, sensor2flange), profile_covariance(dataset), robot_sigma)
        return CalibrationModel(f2b, dataset.centre_in_sensor, centre, rotation, unknowns, whiten=whiten)
    circ, covs = circles(dataset)
    total = np.array([circle_noise(cov, r, radius, robot_sigma) for cov, r in zip(covs, circ[:, 2])])
    return CalibrationModel.from_circles(f2b, circ, radius, centre, rotation, unknowns, whiten=whitening(total))


def _anchored(dataset, sensor2flange):
    """``sensor2flange``, or the ObservationError saying a weighted centre model needs one."""
    if sensor2flange is None:
        raise ObservationError(f"{dataset.path / 'measurements.csv'}: the centre model of weighted samples needs a sensor "
                               "pose to weigh them at (their weights lie in the sensor frame, the residual in the "
                               "carrier's), and none is finite here")
    return sensor2flange


def screening_model(dataset, unknowns, sensor2flange, chain_mm, profile_cov=None):
    """The centre model of every sample of ``dataset`` on the local chart, whitened by each
    centre's covariance (:mod:`handeye.app.engine.robust`).

    Parameters
    ----------
    dataset : handeye.model.datasets.dataset.Dataset
    unknowns : {'sensor', 'sensor+sphere'}
    sensor2flange : ndarray, shape (4, 4)
        The sensor pose that turns a centre's covariance from the sensor frame into the robot
        base (where the residual is), mm.
    chain_mm : float
        The isotropic sd of a centre through the chain (robot, and a reported centre's own), mm.
    profile_cov : ndarray, shape (N, 3, 3), optional
        :func:`handeye.model.datasets.observations.profile_covariance` of ``dataset`` (sensor frame,
        mm^2); None: no centre was rebuilt, no whitening.
    """
    whiten = None if profile_cov is None else turned_whitening(dataset, sensor2flange, profile_cov, chain_mm)
    return CalibrationModel(dataset.motions(), dataset.centre_in_sensor, dataset.sphere_centre, "local", unknowns,
                            whiten=whiten)


def turned_whitening(dataset, sensor2flange, profile_cov, chain_mm):
    """Whitening matrices (N, 3, 3) of the centre residuals, which lie in the carrier's frame (the
    robot base for a sensor on the flange): ``W_i R_i^T`` with ``W_i^T W_i = (A_i + s^2 I)^-1``,
    ``A_i`` the profile's part (sensor frame, mm^2), ``s = chain_mm`` (at least
    :data:`CHAIN_SD_FLOOR_MM`) and ``R_i`` the rotation from the sensor frame into the residual's at
    the sensor pose ``sensor2flange`` (4, 4): ``(R C R^T)^-1 = (W R^T)^T (W R^T)``. The weights are
    held at that pose (a fit moves the pose by far less than the covariance's own uncertainty)."""
    w = whitening(profile_cov + max(chain_mm, CHAIN_SD_FLOOR_MM) ** 2 * np.eye(3))
    turn = dataset.motions()[:, :3, :3] @ np.asarray(sensor2flange, float)[:3, :3]  # sensor frame -> residual's
    return np.einsum("nij,nkj->nik", w, turn)


@dataclasses.dataclass(frozen=True)
class CentreMetric:
    """The samples' own metric of the centre residual (:func:`centre_metric`).

    Attributes
    ----------
    whiten : ndarray, shape (N, 3, 3)
        ``W_i R_i^T`` (:func:`turned_whitening`, :func:`in_mm`): a residual in the carrier's frame, whitened.
    turn : ndarray, shape (N, 3, 3)
        ``R_i``, the rotation from the sensor frame into the residual's at the pose the metric was taken at: a
        sample whose centre is read with y negated (a sign flip) has covariance ``D C D``, whitened by
        ``whiten_i R_i D R_i^T`` (D = diag(1, -1, 1)).
    """

    whiten: np.ndarray
    turn: np.ndarray


def in_mm(whiten):
    """``whiten`` (N, 3, 3) scaled so that a whitened residual reads in mm at the samples' typical sd:
    times the geometric mean over samples of ``det(C_i)^(1/6)`` (``C_i`` the covariance it whitens). Equal
    isotropic covariances give a rotation (into the sensor frame): the residual's length unchanged, in mm."""
    _, logdet = np.linalg.slogdet(whiten)  # log det W_i = -log det(C_i) / 2
    return whiten * float(np.exp(-np.mean(logdet) / 3.0))


def centre_metric(dataset, sensor2flange, centre=None, mask=None, n_params=6):
    """The samples' own metric of the centre residual at a calibration, in mm (a :class:`CentreMetric`:
    :func:`in_mm` of :func:`turned_whitening`), for the extended model's fits and tests
    (:class:`handeye.model.fit.extended.Samples`); None when no centre was rebuilt from its profile
    (every centre's noise is the chain's, isotropic: equal weights).

    Parameters
    ----------
    dataset : handeye.model.datasets.dataset.Dataset
    sensor2flange : ndarray, shape (4, 4)
        The sensor pose (in its carrier's frame, mm) the residuals and the weights' frame are taken at.
    centre : ndarray, shape (3,), optional
        The sphere centre (mm); default the dataset's.
    mask : ndarray of bool, shape (N,), optional
        The samples trusted (the chain's sd is estimated on them, :func:`chain_sd`); default all.
    n_params : int
        The fit's unknowns (6, or 9 with the sphere centre).
    """
    cov = profile_covariance(dataset)
    if cov is None:
        return None
    pose = np.asarray(sensor2flange, float)
    centre = np.asarray(dataset.sphere_centre if centre is None else centre, float)
    model = CalibrationModel(dataset.motions(), dataset.centre_in_sensor, centre, "local", "sensor")
    turn = dataset.motions()[:, :3, :3] @ pose[:3, :3]
    e_sensor = np.einsum("nji,nj->ni", turn, model.residuals(model.point_from(pose, centre)))  # R_i^T e_i
    keep = (np.ones(len(dataset), bool) if mask is None else np.asarray(mask, bool)) & np.isfinite(e_sensor).all(axis=1)
    chain = chain_sd(e_sensor[keep], cov[keep], n_params) if 3 * keep.sum() > n_params else CHAIN_SD_FLOOR_MM
    return CentreMetric(in_mm(turned_whitening(dataset, pose, cov, chain)), turn)


#: The chain's isotropic sd in the screening metric is estimated from the data (:func:`chain_sd`);
#: this floor (0.1 micron, below any robot's repeatability) only keeps the covariances invertible
#: where a centre has no profile part.
CHAIN_SD_FLOOR_MM = 1e-4


def chain_sd(e_sensor, profile_cov, n_params):
    """The isotropic sd (mm) of the chain's part of the centres' covariance that makes their
    residuals' whitened sum of squares its expectation: ``sum_i e_i^T (A_i + s^2 I)^-1 e_i =
    3 n - p`` (``A_i`` the profile's part; the left side falls as s grows), at least
    :data:`CHAIN_SD_FLOOR_MM`.

    Why estimated, not the stated ``[noise] robot_mm``: the stated repeatability is a bound (the
    KR 60 HA's +-0.05 mm read as 2 sigma), a calibration run's robot often does better, and the
    metric's shape (how much more a centre near the equator may err than one near the pole)
    rests on the ratio of the two parts: with 0.025 mm stated where the robot gave 0.008 mm, a
    rebuilt centre 1.7 of its own sd off tested as F ~ 60 against the others (indep_arcs seed 8).

    Parameters
    ----------
    e_sensor : ndarray, shape (n, 3)
        Residuals of the samples trusted (the robust pass's probable ones), turned into the
        sensor frame, mm.
    profile_cov : ndarray, shape (n, 3, 3)
        Their profile parts, mm^2.
    n_params : int
        The fit's unknowns.
    """
    lam, u = np.linalg.eigh(profile_cov)
    proj = np.einsum("nkj,nk->nj", u, e_sensor) ** 2  # the residual along each principal axis, squared
    target = max(e_sensor.size - n_params, 1)
    lo, hi = CHAIN_SD_FLOOR_MM**2, max(float(proj.sum()) / target, CHAIN_SD_FLOOR_MM**2)
    with np.errstate(divide="ignore"):
        if np.sum(proj / (lam + lo)) <= target:
            return CHAIN_SD_FLOOR_MM
    for _ in range(100):  # bisection on log s^2: the root lies in [lo, hi]
        mid = np.sqrt(lo * hi)
        lo, hi = (mid, hi) if np.sum(proj / (lam + mid)) > target else (lo, mid)
        if hi <= lo * (1 + 1e-6):
            break
    return float(np.sqrt(hi))
