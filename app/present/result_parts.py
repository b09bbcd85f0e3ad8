"""The parts a :class:`handeye.app.present.results.CalibrationResult` is made of, one typed record each.

A calibration hands its stages' outcomes to the result as these records: the fit (pose, solver,
residuals), its uncertainty, the screening, the effects of the catalogue; the global check and
the identifiability analysis are records of their own modules
(:class:`handeye.app.engine.guarantee.GlobalCheck`, :class:`handeye.model.design.identifiability.Identifiability`).
Every attribute of a part is also an attribute of the result (``result.rms_mm`` is
``result.fit.rms_mm``), and the JSON keys are the attributes' names, flat, as before the parts.
"""
from __future__ import annotations

import dataclasses
import functools

import numpy as np

from handeye.model.fit import power
from handeye.model.geometry.sphere_cloud import diameter_spread


def _list(value):
    return None if value is None else np.asarray(value, float).tolist()


def fields(record, *names, lists=()):
    """``{name: record.name}`` of ``names`` in their order, those in ``lists`` as :func:`_list` (JSON-ready)."""
    return {n: _list(getattr(record, n)) if n in lists else getattr(record, n) for n in names}


def of_user_frame(method):
    """``method`` run on the result in the user's frame (its ``in_user_frame()``: itself without a turn)."""
    @functools.wraps(method)
    def run(self, *args, **kwargs):
        return method(self.in_user_frame(), *args, **kwargs)
    return run


class AsDict:
    """Mixin of a flat record (a dataclass) whose JSON object is :func:`dataclasses.asdict` of it."""

    def to_dict(self):
        return dataclasses.asdict(self)


@dataclasses.dataclass(frozen=True)
class FitRecord:
    """The reported fit: the pose, how the solver got there, and its residuals.

    Attributes
    ----------
    sensor2flange : ndarray, shape (4, 4)
        Sensor frame in the flange frame (mm).
    sensor_pose : ndarray
        The same pose in the result's convention (``x, y, z`` mm, then its orientation columns).
    sensor_pose_kuka : ndarray, shape (6,)
        KUKA ``x, y, z, A, B, C`` (mm, degrees).
    sphere_centre : ndarray, shape (3,)
        Robot base, mm.
    converged : bool
    status : int or None
        Key of :data:`handeye.solvers.STATUS_MESSAGES`; None for a closed-form method.
    message : str
    residuals : list of handeye.app.present.residual_table.SampleResidual
        Every sample, used or excluded.
    iterations, evaluations, history, solver_point, solver_extra, hessian_eigenvalues
        The solver's record (None for a closed-form method).
    n_used, rms_mm, max_residual_mm, cost_mm2, rms_what, objective, noise_model, noise_test,
    loo_error_mm, loo
        The residuals' statistics (:class:`handeye.app.present.results.CalibrationResult`); None after
        a numerical failure.
    """

    sensor2flange: np.ndarray
    sensor_pose: np.ndarray
    sensor_pose_kuka: np.ndarray
    sphere_centre: np.ndarray
    converged: bool
    status: int | None
    message: str
    residuals: list = ()
    iterations: int | None = None
    evaluations: dict | None = None
    history: np.ndarray | None = None
    solver_point: np.ndarray | None = None
    solver_extra: dict | None = None
    hessian_eigenvalues: np.ndarray | None = None
    n_used: int | None = None
    rms_mm: float | None = None
    max_residual_mm: float | None = None
    cost_mm2: float | None = None
    rms_what: str | None = None
    objective: dict | None = None
    noise_model: str | None = None
    noise_test: object | None = None
    loo_error_mm: float | None = None
    loo: dict | None = None


@dataclasses.dataclass(frozen=True)
class UncertaintyRecord:
    """The fit's uncertainty: 1-sd, noise scale, covariance and correlation (local chart:
    ``tx, ty, tz`` mm, ``wx, wy, wz`` rad about the sensor's axes, then centre and effects).

    Attributes
    ----------
    std : Uncertainty or None
    sigma_mm : float or None
        Noise per component estimated from an unweighted fit, mm.
    sigma_scale : float or None
        Ratio of the residuals to their stated sd, for a weighted fit.
    parameter_names : tuple of str or None
    correlation, covariance : ndarray, shape (p, p), or None
        The covariance as reported: the fit's, scaled by ``t_factor`` squared and widened by the
        effects ``power`` says the data could have missed (:meth:`with_power`).
    dof : int or None
        Residual degrees of freedom of the noise estimate.
    t_factor : float or None
        The Student-t factor of ``dof`` the fit's sd are scaled by (:func:`handeye.model.fit.power.t_factor`).
    power : PowerStatement or None
        What the data could not see; None where the discrepancy search did not run.
    """

    std: object | None = None
    sigma_mm: float | None = None
    sigma_scale: float | None = None
    parameter_names: tuple | None = None
    correlation: np.ndarray | None = None
    covariance: np.ndarray | None = None
    dof: int | None = None
    t_factor: float | None = None
    power: object | None = None

    @classmethod
    def of_fit(cls, covariance, names, dof, sigma_mm=None, sigma_scale=None):
        """The record of a fit's covariance ``s^2 (J^T J)^-1`` (local chart, parameters ``names``; the
        noise ``s`` estimated on ``dof`` residual degrees of freedom), scaled by the Student-t factor
        of ``dof`` (:func:`handeye.model.fit.power.t_factor`: +-3 reported sd cover as the normal's
        3 sd do); NaN entries (a fit stopped against a bound) stay NaN."""
        factor = power.t_factor(dof)
        cov = np.asarray(covariance, float) * factor**2
        return cls(sigma_mm=sigma_mm, sigma_scale=sigma_scale, parameter_names=tuple(names), dof=dof,
                   t_factor=factor)._with_covariance(cov)

    def _with_covariance(self, cov):
        """This record with covariance ``cov`` (its own names) and the 1-sd and correlation of it."""
        names = self.parameter_names
        std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
        scale = np.where(std > 0, std, 1.0)
        centre = std[list(names).index("cx"):][:3] if "cx" in names else None
        return dataclasses.replace(self, std=Uncertainty(std[:3], np.degrees(std[3:6]), centre), covariance=cov,
                                   correlation=cov / np.outer(scale, scale))

    def with_power(self, statement):
        """This record with the power statement ``statement`` (:class:`PowerStatement`), its covariance
        widened by the covariances of the effects it says widen it (:attr:`PowerStatement.widening`:
        each on the parameters it shares with this record, by name)."""
        record = dataclasses.replace(self, power=statement)
        for missed in statement.widening:
            record = record.widened(missed.widening, statement.names)
        return record

    def widened(self, added, names):
        """This record with covariance ``added`` (parameters ``names``, the fit's step units) added on the
        parameters it shares with this one, by name (unchanged without a covariance)."""
        if self.covariance is None or self.parameter_names is None:
            return self
        cov = np.array(self.covariance, float)
        index = {n: k for k, n in enumerate(self.parameter_names)}
        ks = [(index[n], j) for j, n in enumerate(names) if n in index]
        ours, theirs = [k for k, _ in ks], [j for _, j in ks]
        cov[np.ix_(ours, ours)] += np.asarray(added, float)[np.ix_(theirs, theirs)]
        return self._with_covariance(cov)


@dataclasses.dataclass(frozen=True)
class PowerStatement:
    """What the data could not see (:mod:`handeye.model.fit.power`): per catalogue effect the search
    did not name, the size its score test would detect with 80 % power at the search's level, and
    the pose shift an effect of that size would cause if left out.

    Attributes
    ----------
    effects : tuple of handeye.model.fit.power.Missable
        Largest pose shift first.
    names : tuple of str
        Parameter names of their covariances (the search's fit: ``tx, ty, tz, wx, wy, wz``, ...).
    level : float
        The test's level (the search's alpha over its candidates, Bonferroni).
    """

    effects: tuple
    names: tuple
    level: float

    @property
    def widening(self):
        """The effects whose shift is beyond :data:`handeye.model.fit.power.SHIFT_FLOOR`: they widen the uncertainty."""
        return tuple(m for m in self.effects if m.beyond_floor)

    @property
    def text(self):
        """One line: the largest effects the data could have missed and whether the sd includes them."""
        if not self.effects:
            return "every catalogue effect is named or absorbed: nothing left unseen"
        head = "; ".join(m.text() for m in self.effects[:2])
        wide = ("the 1 sd includes the shift" if self.widening else
                f"below {power.SHIFT_FLOOR[0]:g} mm / {power.SHIFT_FLOOR[1]:g} deg: they widen no sd")
        return (f"the data could have missed (80 % power at level {self.level:.2g}): {head}; {wide}")

    def to_dict(self):
        return {"text": self.text, "level": self.level, "power": power.POWER,
                "widened": [m.name for m in self.widening],
                "effects": [{"name": m.name, "size": m.size, "unit": m.unit, "shift_mm": m.shift_mm,
                             "shift_deg": m.shift_deg, "shift_sd": m.shift_sd} for m in self.effects]}


@dataclasses.dataclass(frozen=True)
class ScreeningRecord:
    """What screening did: the plain fit of every sample and the samples excluded.

    Attributes
    ----------
    excluded : list of handeye.app.present.results.ExcludedSample
    before : handeye.app.present.results.Before or None
    """

    excluded: list = ()
    before: object | None = None


@dataclasses.dataclass(frozen=True)
class EffectsRecord:
    """The catalogue at the fit: score tests of effects not in the model, and the effects
    calibrated with the pose (``--effects``).

    Attributes
    ----------
    tests : list of handeye.model.fit.extended.ScoreTest or None
        The result's ``effect_tests``.
    calibrated : list of NamedEffect or None
        The result's ``effects``.
    """

    tests: list | None = None
    calibrated: list | None = None


@dataclasses.dataclass(frozen=True)
class PositionerRecord:
    """The positioner's axes as calibrated (or held), robot base frame, all angles zero.

    Attributes
    ----------
    axes : tuple of handeye.model.chain.mounts.Axis
    nominal : tuple of handeye.model.chain.mounts.Axis
        The axes of ``setup.toml``.
    point_sd : ndarray, shape (k, 3) or None
        1-sd of each axis's point, mm (it moves normal to the axis; along it is no parameter).
    direction_sd : ndarray, shape (k, 3) or None
        1-sd of each unit direction's components.
    tilt_sd_deg : ndarray, shape (k,) or None
        1-sd of the direction's tilt, degrees (root of the two normal variances' sum).
    calibrated : bool
    """

    axes: tuple
    nominal: tuple
    point_sd: np.ndarray | None = None
    direction_sd: np.ndarray | None = None
    tilt_sd_deg: np.ndarray | None = None
    calibrated: bool = False

    def to_dict(self):
        return [{**axis.to_dict(), "nominal": nom.to_dict(),
                 "point_sd": None if self.point_sd is None else [float(v) for v in self.point_sd[j]],
                 "direction_sd": None if self.direction_sd is None else [float(v) for v in self.direction_sd[j]],
                 "tilt_sd_deg": None if self.tilt_sd_deg is None else float(self.tilt_sd_deg[j]), "calibrated": self.calibrated}
                for j, (axis, nom) in enumerate(zip(self.axes, self.nominal))]


@dataclasses.dataclass(frozen=True)
class Uncertainty:
    """1-sd uncertainty of the calibration (local rotation chart).

    Attributes
    ----------
    sensor_translation_mm : ndarray, shape (3,)
        Of the sensor origin in the flange frame, mm.
    sensor_rotation_deg : ndarray, shape (3,)
        About the sensor's own x, y, z axes, degrees.
    sphere_center_mm : ndarray, shape (3,), or None
        Of the sphere centre (``unknowns='sensor+sphere'`` only), robot base, mm.
    """

    sensor_translation_mm: np.ndarray
    sensor_rotation_deg: np.ndarray
    sphere_center_mm: np.ndarray | None = None

    def to_dict(self):
        names = ("sensor_translation_mm", "sensor_rotation_deg", "sphere_center_mm")
        return fields(self, *names, lists=names)


@dataclasses.dataclass(frozen=True)
class NoiseTest(AsDict):
    """The fit tested against the stated noise model (``[noise]`` in setup.toml, ``--sigma``).

    Attributes
    ----------
    statistic : float
        ``SSR / sigma_nominal^2`` (whitened residuals: ``SSR``), chi-square with ``dof``
        degrees of freedom when the noise is as stated.
    dof : int
    p_value : float
        Probability of a statistic this large or larger under the stated noise.
    ratio : float
        Estimated over stated noise (sd ratio).
    nominal : str
        The stated noise, in words.
    passed : bool
        False when the residuals are larger than the noise at the 0.1 % level.
    whitened : bool
        Whether each row was whitened by its own stated covariance (else the stated centre noise).
    """

    statistic: float
    dof: int
    p_value: float
    ratio: float
    nominal: str
    passed: bool
    whitened: bool = False


@dataclasses.dataclass(frozen=True)
class NamedEffect:
    """An effect :func:`handeye.diagnose` named, with its parameters and their 1-sd errors.

    Attributes
    ----------
    name : str
        Catalogue name (:mod:`handeye.model.effects`) or ``sign_flip``.
    parameters : dict
        Parameter name -> value (units of the effect; ``sign_flip``: ``{'ids': [...]}``).
    std : dict or None
        Parameter name -> 1 sd (None for ``sign_flip``; a None value where the fit is not a
        minimum and the linearised sd means nothing).
    note : str or None
        What the sd is and why it is the size it is (``sphere_radius`` in calibrate).
    """

    name: str
    parameters: dict
    std: dict | None
    note: str | None = None

    def to_dict(self):
        return {"name": self.name, "parameters": dict(self.parameters),
                "std": None if self.std is None else dict(self.std), "note": self.note}


def cleaning_summary(dataset):
    """What profile cleaning (:mod:`handeye.model.geometry.profile_clean`) did to a dataset's profiles,
    JSON-ready (the calibration result's ``cleaning``).

    Parameters
    ----------
    dataset : handeye.model.datasets.dataset.Dataset

    Returns
    -------
    dict or None
        None without profiles; else ``applied`` (False when loaded with ``clean=False``: then
        nothing more), ``profiles``, ``points`` and ``dropped`` (totals), ``reasons`` (totals by
        reason), ``samples``: ``id``, ``row``, ``points``, ``dropped``, ``status``,
        ``reasons`` of each profile that lost points (only those), and ``bend``: the profiles' depth
        bend (:meth:`handeye.model.geometry.profile_bend.Bend.to_dict`; None with too few profiles).
    """
    if dataset.profiles is None:
        return _clouds_summary(dataset)
    bend = getattr(dataset, "bend", None)
    if dataset.cleaning is None:
        return {"applied": False, "profiles": sum(p is not None for p in dataset.profiles),
                "bend": None if bend is None else bend.to_dict()}
    records = [(i, r, c) for i, r, c in zip(dataset.ids, dataset.rows, dataset.cleaning) if c is not None]
    reasons = {}
    for _, _, c in records:
        for name, n in c.dropped:
            reasons[name] = reasons.get(name, 0) + int(n)
    return {"applied": True, "profiles": len(records), "points": int(sum(c.n_points for _, _, c in records)),
            "dropped": int(sum(c.n_dropped for _, _, c in records)), "reasons": reasons,
            "samples": [{"id": i, "row": int(r), **c.to_dict()} for i, r, c in records if c.n_dropped],
            "bend": None if bend is None else bend.to_dict()}


def _clouds_summary(dataset):
    """:func:`cleaning_summary` of a dataset's point clouds (:mod:`handeye.model.geometry.sphere_cloud`), with
    ``what`` ``'cloud'`` and, their radius free, ``diameters`` (``mean``, ``sd``, ``min``, ``max``, mm); None without."""
    fits = getattr(dataset, "clouds", None)
    if fits is None:
        return None
    records = [(i, r, c) for i, r, c in zip(dataset.ids, dataset.rows, fits) if c is not None]
    spread = diameter_spread(fits)
    return {"applied": True, "what": "cloud", "profiles": len(records), "points": int(sum(c.n_points for *_, c in records)),
            "dropped": int(sum(c.n_dropped for *_, c in records)),
            "reasons": {"off the sphere": int(sum(c.n_dropped for *_, c in records))},
            "samples": [{"id": i, "row": int(r), **c.to_dict()} for i, r, c in records if c.n_dropped], "bend": None,
            "diameters": None if spread is None else dict(zip(("mean", "sd", "min", "max"), spread))}


def user_poses(matrix, own_axes, convention):
    """``(4x4, pose in convention, KUKA pose)`` of the sensor's own frame of a sensor pose ``matrix``
    of handeye's frame (``[profile] own_axes``: :func:`handeye.model.chain.own_frame.to_own`)."""
    from handeye.model.chain import conventions, own_frame

    m = own_frame.to_own(matrix, own_axes)
    return m, conventions.pose_from(convention, m), conventions.pose_from("kuka", m)


def user_std(std, covariance, own_axes, names=("tx", "ty", "tz", "wx", "wy", "wz")):
    """The 1-sd :class:`Uncertainty` and the covariance (local chart, parameters ``names``) of a pose
    of handeye's frame as the sensor's own frame's: the rotation block about the own axes
    (``dw_own = R^T dw``); the sd from the turned covariance, or (without one) from the variances
    turned alone."""
    from handeye.model.chain import own_frame

    first = list(names).index("wx") if "wx" in names else None
    cov = own_frame.covariance_to_own(covariance, own_axes, first=first)
    if std is None or std.sensor_rotation_deg is None:
        return std, cov
    if cov is not None and first is not None:
        rot = np.degrees(np.sqrt(np.clip(np.diag(cov)[first:first + 3], 0.0, None)))
    else:
        rot = np.sqrt(np.asarray(own_axes, float).T ** 2 @ np.asarray(std.sensor_rotation_deg, float) ** 2)
    return dataclasses.replace(std, sensor_rotation_deg=rot), cov


def frame_keys(own_axes):
    """The JSON keys that say a result's poses are of the sensor's own frame (``own_axes``; none
    without a turn): what a saved file is read back with (:mod:`handeye.app.outputs.saved`)."""
    return {} if own_axes is None else {"own_axes": _list(own_axes), "sensor_frame": "own"}


#: Flat attribute of the result -> (part, attribute of the part).
FLAT = {
    **{f.name: ("fit", f.name) for f in dataclasses.fields(FitRecord)},
    **{f.name: ("uncertainty", f.name) for f in dataclasses.fields(UncertaintyRecord)},
    **{f.name: ("screening", f.name) for f in dataclasses.fields(ScreeningRecord)},
    "effect_tests": ("catalogue", "tests"),
    "effects": ("catalogue", "calibrated"),
}
