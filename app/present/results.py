"""Typed results of a calibration: what :func:`handeye.calibrate` returns.

One type for every method -- least squares (IPOPT, Gauss-Newton, ...) and the closed-form
baselines -- as :class:`scipy.optimize.OptimizeResult` is one type for every solver. Every
exit of a calibration builds the complete type: fields that a path cannot fill (no
covariance after a numerical failure, no leave-one-out for a closed-form method) are None,
never missing. :meth:`CalibrationResult.to_dict` is exactly the ``handeye calibrate --json``
object (the CLI prints it; there is no second code path), :meth:`~CalibrationResult.summary`
the CLI's text report, and ``_repr_html_`` a compact table in Jupyter.

Frames and units: ``sensor2flange`` is the sensor frame in the flange frame (4x4, mm);
``sphere_centre`` is in the robot base (mm); poses are ``x, y, z`` in mm and the orientation
in the named robot convention (:mod:`handeye.model.chain.conventions`). A dataset whose profiles
``dataset new`` turned (``[profile] own_axes``) computes in handeye's frame and reports in the
sensor's own (:meth:`CalibrationResult.in_user_frame`: the JSON, the text, every saved and
exported form, and the attributes of what :func:`handeye.calibrate` returns; ``pose_frame`` says
which).
"""
from __future__ import annotations

import dataclasses
import json

import numpy as np

from handeye.app.common.jsonio import dumps
from handeye.app.present.protocol import ResultProtocol
from handeye.app.present.residual_table import residuals_json
from handeye.app.present.result_parts import (
    FLAT,
    AsDict,
    EffectsRecord,
    FitRecord,
    ScreeningRecord,
    UncertaintyRecord,
    _list,
    fields,
    frame_keys,
    of_user_frame,
    user_poses,
    user_std,
)


def _unit(name):
    """Unit of a covariance parameter: mm for translations and centres, rad for the local rotation."""
    return "rad" if name in ("wx", "wy", "wz") else "mm" if name in ("tx", "ty", "tz", "cx", "cy", "cz") else "effect"


@dataclasses.dataclass(frozen=True)
class ExcludedSample(AsDict):
    """A sample excluded as a gross error, or as a row that contradicts itself, with the
    evidence (:mod:`handeye.app.engine.robust`).

    Attributes
    ----------
    id : str
    row : int
    residual_mm : float
        Prediction error from the fit of the other samples, mm (NaN for a row excluded only
        because it contradicts itself, or set aside because its profile is no arc of the sphere:
        no fit decides that).
    robust_residual_mm : float
        Residual of the robust pass, mm (NaN likewise).
    statistic : float
        Externally studentised deletion statistic (F); for a row excluded only because it
        contradicts itself the chi-square (3 dof) of its profile's circle against its centre
        columns.
    p_bonferroni : float
        Bonferroni-adjusted p-value.
    reason : str
        The statistical reason, and the geometric one after it when there is one.
    geometry : str or None
        The profile's geometry when it explains a poorly determined centre (a short, one-sided
        arc near the equator ...: :mod:`handeye.model.geometry.arc_geometry`), else None.
    """

    id: str
    row: int
    residual_mm: float
    robust_residual_mm: float
    statistic: float
    p_bonferroni: float
    reason: str
    geometry: str | None = None


#: What :attr:`CalibrationResult.rms_mm` measures, for every residual model (the figure that
#: compares across ``--model``).
RMS_PER_CENTRE = ("RMS over the samples used of |e_i|, the distance (mm) of sample i's sphere centre carried through "
                  "the calibrated chain (T1_i T2 xs_i) from the sphere centre c: per sphere centre, unweighted, the same "
                  "figure for every --model (what --model centre minimises when no sample has a profile)")


@dataclasses.dataclass(frozen=True)
class Before(AsDict):
    """The plain least-squares fit of every sample, before any exclusion.

    Always the unweighted ``centre`` model (whatever ``--model`` the final fit uses): its
    ``rms_mm`` is the minimum of the per-centre RMS over all the samples (when the plain fit
    reaches its global minimum), so a final fit of the same samples with another objective
    (weights, circles, profile points) has a larger one (:attr:`CalibrationResult.rms_note`
    says why two figures differ).

    Attributes
    ----------
    n : int
    rms_mm : float
        Per sphere centre, unweighted (as :attr:`CalibrationResult.rms_mm`).
    loo_error_mm : float or None
        Leave-one-out error of this fit: the centre model refitted without each sample.
    model, weighted, what : str, bool, str
        The residual model and weighting of this fit, and what ``rms_mm`` measures (JSON only).
    """

    n: int
    rms_mm: float
    loo_error_mm: float | None
    model: str = "centre"
    weighted: bool = False
    what: str = ("plain least squares of the centre model on every sample (unweighted, nothing excluded); rms_mm per "
                 "sphere centre as the final fit's; loo_error_mm refits this centre model without each sample")


@dataclasses.dataclass(frozen=True)
class ClosedFormDetails:
    """What only a closed-form method (``kim-cho``, ``li-two-step``) reports.

    Attributes
    ----------
    linear_matrix : ndarray, shape (4, 4)
        The linear solution before its rotation block is projected onto SO(3).
    details : dict
        The method's own figures (pairs, condition number, translation pairs ...).
    time_ms : float
        Time of the closed-form solve alone.
    least_squares_from_here : dict
        Where the nonlinear least squares goes from this estimate: ``distance_mm``,
        ``distance_deg``, ``iterations``, ``converged``, ``rms_mm``.
    """

    linear_matrix: np.ndarray
    details: dict
    time_ms: float
    least_squares_from_here: dict

    def to_dict(self):
        return {"linear_matrix": _list(self.linear_matrix), "details": self.details, "time_ms": float(self.time_ms),
                "least_squares_from_here": dict(self.least_squares_from_here)}


@dataclasses.dataclass(frozen=True)
class CalibrationResult(ResultProtocol):
    """The outcome of :func:`handeye.calibrate` (module docstring).

    Made of typed parts (:mod:`handeye.app.present.result_parts`): ``fit`` (pose, solver, residuals),
    ``uncertainty``, ``screening`` (``before``, ``excluded``), ``global_check``,
    ``identifiability`` and ``catalogue`` (``effect_tests``, ``effects``). Every attribute of a
    part is an attribute of the result too, under the names below (``result.rms_mm`` is
    ``result.fit.rms_mm``), and :meth:`to_dict` keeps the flat JSON keys.

    Attributes
    ----------
    sensor2flange : ndarray, shape (4, 4)
        Sensor frame in its mount's frame (mm): the flange, or the robot base for a sensor fixed in
        the cell (``sensor_mount``). JSON key ``sensor_matrix``.
    sensor_mount, sphere_mount : str
        ``flange`` or ``world``; ``world``, ``flange`` or ``positioner`` (:mod:`handeye.model.chain.mounts`).
    robot_model : str or None
        The dataset's ``[robot] model`` (a built-in name or the model file's path), which
        ``export --format robot-toml|robot-urdf`` corrects by the calibrated ``joint_offsets``.
    positioner : handeye.app.present.result_parts.PositionerRecord or None
        The positioner's axes (calibrated with ``positioner`` in ``unknowns``, else as set up) and
        their 1-sd. JSON key ``positioner``: a list of axes.
    sensor_pose : ndarray
        The same pose in ``convention`` (``x, y, z`` mm, then its orientation columns).
    sensor_pose_kuka : ndarray, shape (6,)
        The same pose as KUKA ``x, y, z, A, B, C`` (mm, degrees).
    convention, columns : str, tuple of str
        Robot convention of ``sensor_pose`` (the dataset's unless asked otherwise) and its
        column names.
    sphere_centre : ndarray, shape (3,)
        Sphere centre in its mount's frame, mm: the robot base, the flange, or the positioner's
        table at zero axis angles (given, or estimated with ``sphere`` in ``unknowns``). JSON key
        ``sphere_center``, with ``sphere_center_sd``.
    converged : bool
        The method met its convergence test at a minimum (not a saddle, not only stationary
        in a singular Euler chart). The CLI exits 1 when False.
    status : int or None
        Key of :data:`handeye.solvers.STATUS_MESSAGES`; None for a closed-form method.
    message : str
    rms_mm, max_residual_mm, cost_mm2 : float or None
        Over the samples used, per sphere centre, unweighted (``rms_what``: sample i's centre
        through the calibrated chain against the sphere centre, for every ``--model``); None
        after a numerical failure. ``cost_mm2`` is ``1/2 sum |e_i|^2`` of these, not the
        objective the fit minimised (that is ``objective``).
    rms_what : str or None
        What ``rms_mm`` measures, in words.
    objective : dict or None
        What the final fit minimised and its RMS: ``model``, ``residual`` (rows), ``weighted``,
        ``rows`` (how many), ``cost`` (``1/2 sum |W_i e_i|^2``, mm^2 unweighted, else
        dimensionless), ``rms`` (``sqrt(sum |W_i e_i|^2 / rows)``: per profile point, per
        circle or per centre), ``unit`` (``mm``, or ``sd`` for whitened rows, where about
        sqrt(m) is expected when the noise is as stated), ``rms_unweighted_mm`` (the same rows
        unweighted) and ``what`` (in words).
    loo : dict or None
        How ``loo_error_mm`` was made: ``model``, ``weighted``, ``unknowns`` (the refitted
        model: the final one), ``method`` and ``what``.
    rms_note : str or None
        Why ``rms_mm`` and ``before.rms_mm`` differ (other samples, another objective); None
        when they are the same fit's. A property; a key of the JSON.
    residuals : list of SampleResidual or ResidualTable (:mod:`handeye.app.present.residual_table`)
        Every sample, used or excluded.
    excluded : list of ExcludedSample
        Gross errors excluded, with statistic and reason (``outliers`` in the JSON: their ids).
    std : handeye.app.present.result_parts.Uncertainty or None
    identifiability : handeye.model.design.identifiability.Identifiability or None
        Rank, singular values and observability of the final Jacobian.
    warnings : list of str
    before : Before or None
        The plain fit of every sample.
    closed_form : ClosedFormDetails or None
        Set for the closed-form methods only.
    noise_test : handeye.app.present.result_parts.NoiseTest or None
        The fit against the stated noise model (None for the ``points`` model and closed form).
    effect_tests : list of ScoreTest or None
        Score tests of the catalogue's effects at the fit (:func:`handeye.model.fit.extended.score_effects`):
        a significant one is named in a warning that points to ``handeye diagnose``.
    effects : list of handeye.app.present.result_parts.NamedEffect or None
        Catalogue effects calibrated with the sensor pose (``--effects``), with their 1-sd.
    provenance : dict or None
        Tool version, dataset hash, options and time, set when the result is saved.
    cleaning : dict or None
        What profile cleaning dropped (:func:`handeye.app.present.result_parts.cleaning_summary`: totals, and
        per profile that lost points its id, row, counts and reasons); ``{'applied': False}``
        with ``--no-clean``; None without profiles.
    own_axes : ndarray, shape (3, 3), or None
        The dataset's ``[profile] own_axes`` (its profiles turned from the sensor's own frame).
    pose_frame : {'handeye', 'own'}
        The frame of the pose attributes: handeye's (the profiles', what the fit works in), or
        the sensor's own (:meth:`in_user_frame`); the JSON and the text report are of the own
        frame whenever there is one (JSON keys ``own_axes`` and ``sensor_frame`` "own" say so).
    search : handeye.app.present.diagnosis_results.DiagnosisResult or None
        The discrepancy search that decided this result, its whole story, where it was asked for
        (:attr:`~handeye.app.engine.request.CalibrationRequest.story`: ``handeye diagnose`` tells it);
        of handeye's frame; never in the JSON.

    The remaining attributes (``dataset``, ``method``, ``rotation``, ``unknowns``, ``model``,
    ``start_pose`` (in ``convention``) and ``start_pose_kuka``, ``start_used``, ``iterations``,
    ``evaluations``, ``history`` (KUKA
    poses of the iterates), ``solver_point``, ``sigma_mm``, ``sigma_scale``, ``correlation``
    and ``covariance`` (full precision, local chart: ``tx, ty, tz`` mm, ``wx, wy, wz`` rad about
    the sensor's axes, then sphere centre and effects) with ``parameter_names``, ``loo_error_mm``,
    ``hessian_eigenvalues``, ``noise_model``)
    carry the JSON keys of the same name.
    """

    dataset: str
    dataset_path: str
    dataset_sha256: str
    method: str
    unknowns: str
    convention: str
    columns: tuple
    fit: FitRecord
    screening: ScreeningRecord
    warnings: list
    uncertainty: UncertaintyRecord = UncertaintyRecord()
    global_check: object | None = None
    identifiability: object | None = None
    catalogue: EffectsRecord = EffectsRecord()
    rotation: str | None = None
    model: str | None = None
    robot_sigma_mm: float | None = None
    start_pose: np.ndarray | None = None
    start_pose_kuka: np.ndarray | None = None
    start_used: str | None = None
    closed_form: ClosedFormDetails | None = None
    provenance: dict | None = None
    sensor_mount: str = "flange"
    sphere_mount: str = "world"
    positioner: object | None = None
    robot_model: str | None = None
    cleaning: dict | None = None
    own_axes: np.ndarray | None = None
    pose_frame: str = "handeye"
    search: object | None = dataclasses.field(default=None, repr=False, compare=False)

    caption = "handeye calibration"

    def __getattr__(self, name):
        """The parts' attributes as the result's own (``result.rms_mm`` is ``result.fit.rms_mm``)."""
        where = FLAT.get(name) if not name.startswith("__") else None
        if where is None:
            raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")
        return getattr(object.__getattribute__(self, where[0]), where[1])

    def __dir__(self):
        """The parts' flat attributes too (``dir``, tab completion), as before the parts."""
        return sorted(set(super().__dir__()) | set(FLAT))

    @property
    def outliers(self):
        """Ids of the excluded samples."""
        return [e.id for e in self.excluded]

    @property
    def rms_note(self):
        """Why ``rms_mm`` differs from ``before.rms_mm`` (text), or None when they are one fit's.

        Two causes, both named when both apply: other samples (the before fit keeps the excluded
        ones) and another objective (the before fit minimises the unweighted per-centre RMS
        itself; a weighted centre, circle or profile-point fit, or one with effects, minimises
        something else, so on the same samples its per-centre RMS is larger).
        """
        if self.before is None or self.rms_mm is None or self.objective is None:
            return None
        same_samples = self.n_used == self.before.n
        same_objective = (self.objective.get("model") == "centre" and not self.objective.get("weighted")
                          and not self.effects)
        if same_samples and same_objective:
            return None
        parts = []
        if not same_samples:
            n_out = self.before.n - (self.n_used or 0)
            parts.append(f"the before fit also fits the {n_out} excluded sample(s) ({', '.join(self.outliers[:6])}"
                         f"{' ...' if len(self.outliers) > 6 else ''}), which pull it")
        if self.effects:
            parts.append("the before fit has no effects; this fit corrects every centre by the effects "
                         f"({', '.join(e.name for e in self.effects)}: more parameters), so its per-centre RMS is of "
                         "other, corrected centres and is smaller when the effects explain something")
        elif not same_objective:
            parts.append(f"the before fit minimises this per-centre RMS itself (unweighted centre model), this fit "
                         f"minimises {self.objective.get('short', 'another objective')}, so on the same samples its "
                         "per-centre RMS cannot be smaller")
        return (f"RMS {self.rms_mm:.4f} mm here against {self.before.rms_mm:.4f} mm before exclusion "
                f"({self.rms_mm - self.before.rms_mm:+.2g} mm): " + "; and ".join(parts))

    def refused(self, why):
        """This result, not a calibration (exit 1): not converged, ``why`` its message and a warning."""
        return dataclasses.replace(self, fit=dataclasses.replace(self.fit, converged=False, message=why),
                                   warnings=[*self.warnings, why])

    def in_user_frame(self):
        """The result with every pose the user reads in the frame of the user's files: the
        sensor's own frame when the profiles were turned (``own_axes``; :mod:`handeye.model.chain.own_frame`):
        ``sensor2flange``, ``sensor_pose`` (and KUKA), the start pose, the iterates, the closed
        form's linear matrix, the covariance, correlation and 1-sd of the rotation and the
        identifiability analysis (about the own axes); ``pose_frame`` then ``"own"``. Itself without a turn
        or when turned already.
        :meth:`to_dict`, :meth:`summary` and every saved or exported form are of this one."""
        rot = self.own_axes
        if rot is None or self.pose_frame == "own" or self.sensor2flange is None:
            return self
        from handeye.model.chain import own_frame
        from handeye.model.chain.pose import transform_from_pose

        matrix, pose, kuka = user_poses(self.sensor2flange, rot, self.convention)
        history = None if self.history is None else np.array(
            [user_poses(transform_from_pose(h), rot, "kuka")[2] for h in self.history]).reshape(-1, 6)
        fit = dataclasses.replace(self.fit, sensor2flange=matrix, sensor_pose=pose, sensor_pose_kuka=kuka, history=history)
        std, cov = user_std(self.std, self.covariance, rot, self.parameter_names or ())
        corr = self.correlation
        if cov is not None:
            sd = np.sqrt(np.clip(np.diag(cov), 1e-300, None))
            corr = cov / np.outer(sd, sd)
        _, start, start_kuka = (None,) * 3 if self.start_pose_kuka is None else user_poses(
            transform_from_pose(self.start_pose_kuka), rot, self.convention)
        closed = self.closed_form if self.closed_form is None else dataclasses.replace(
            self.closed_form, linear_matrix=own_frame.to_own(self.closed_form.linear_matrix, rot))
        ident = self.identifiability
        if ident is not None and "wx" in ident.names:
            ident = ident.turned(own_frame.step_to_own(ident.n, rot, ident.names.index("wx")))
        return dataclasses.replace(
            self, fit=fit, uncertainty=dataclasses.replace(self.uncertainty, std=std, covariance=cov, correlation=corr),
            start_pose=start, start_pose_kuka=start_kuka, closed_form=closed, identifiability=ident, pose_frame="own")

    @of_user_frame
    def to_dict(self, residuals=True):
        """The ``handeye calibrate --json`` object (JSON-ready: lists, floats, str, None); without
        ``residuals`` their entry is None (:meth:`to_json` writes them column-wise). Its poses are
        of the user's frame (:meth:`in_user_frame`)."""
        out = {**self._request_keys(), **self._pose_keys(), **self._fit_keys(residuals), **self._uncertainty_keys()}
        if self.provenance is not None:
            out["provenance"] = self.provenance
        return out

    def _request_keys(self):
        """The JSON keys of what was asked: the dataset, method, model and start."""
        return fields(self, "dataset", "dataset_path", "dataset_sha256", "method", "rotation", "unknowns", "model",
                      "robot_sigma_mm", "start_pose", "start_pose_kuka", "start_used", lists=("start_pose", "start_pose_kuka"))

    def _pose_keys(self):
        """The JSON keys of the calibrated pose, its mounts and frames."""
        return {
            "sensor_pose": _list(self.sensor_pose),
            "sensor_pose_kuka": _list(self.sensor_pose_kuka),
            "sensor_pose_as": {"convention": self.convention, "columns": list(self.columns),
                               "pose": _list(self.sensor_pose)},
            **fields(self, "sensor_mount", "sphere_mount"),
            "sensor_matrix": _list(self.sensor2flange),
            **frame_keys(self.own_axes),
            "sphere_center": _list(self.sphere_centre),
            "sphere_center_sd": None if self.std is None else _list(self.std.sphere_center_mm),
            "positioner": None if self.positioner is None else self.positioner.to_dict(),
            "robot_model": self.robot_model,
        }

    def _fit_keys(self, residuals):
        """The JSON keys of the solver and the residuals."""
        return {
            "iterations": None if self.iterations is None else int(self.iterations),
            "evaluations": self.evaluations,
            "converged": bool(self.converged),
            "error": None if self.converged else self.message,
            "status": None if self.status is None else int(self.status),
            **fields(self, "message", "outliers"),
            "excluded": [e.to_dict() for e in self.excluded],
            "before": None if self.before is None else self.before.to_dict(),
            "warnings": list(self.warnings),
            **fields(self, "history", "solver_point", "solver_extra", "n_used", "rms_mm", "max_residual_mm", "cost_mm2",
                     lists=("history", "solver_point")),
            "residuals": [r.to_dict() for r in self.residuals] if residuals else None,
            **fields(self, "sigma_mm", "sigma_scale"),
        }

    def _uncertainty_keys(self):
        """The JSON keys of the uncertainty, the checks and the tests."""
        return {
            "std": None if self.std is None else self.std.to_dict(),
            "correlation": None if self.correlation is None else {
                "names": list(self.parameter_names), "matrix": np.round(self.correlation, 6).tolist()},
            "covariance": None if self.covariance is None else {
                "names": list(self.parameter_names), "units": [_unit(n) for n in self.parameter_names],
                "matrix": _list(self.covariance)},
            "sd_dof": self.dof,
            "sd_t_factor": self.t_factor,
            "power": None if self.power is None else self.power.to_dict(),
            "loo_error_mm": self.loo_error_mm,
            "identifiability": None if self.identifiability is None else self.identifiability.to_dict(),
            **fields(self, "hessian_eigenvalues", "noise_model", lists=("hessian_eigenvalues",)),
            "closed_form": None if self.closed_form is None else self.closed_form.to_dict(),
            "noise_test": None if self.noise_test is None else self.noise_test.to_dict(),
            "effect_tests": None if self.effect_tests is None else [t.to_dict() for t in self.effect_tests],
            "effects": None if self.effects is None else [e.to_dict() for e in self.effects],
            "global": None if self.global_check is None else self.global_check.to_dict(),
            **fields(self, "rms_what", "objective", "loo", "rms_note", "cleaning"),
        }

    def to_json(self, indent=1):
        """:meth:`to_dict` as strict JSON text (non-finite numbers as null); the residual rows
        compact, one a line."""
        out = self.to_dict(residuals=False)
        marker = "\x00residuals\x00"  # replaced by the rows' own text, in its place among the keys
        out["residuals"] = marker
        text = dumps(out, indent)
        return text.replace(json.dumps(marker), residuals_json(self.residuals), 1)

    def summary(self):
        """The CLI's text report."""
        from handeye.app.present import report

        return report.calibration_text(self.in_user_frame())

    @of_user_frame
    def _html_rows(self):
        """The Jupyter table's rows (:class:`~handeye.app.present.protocol.ResultProtocol`), of the user's frame."""
        rows = [
            ("dataset", f"{self.dataset} ({len(self.residuals)} samples, {self.n_used if self.n_used is not None else '?'}"
                        f" used, {len(self.excluded)} excluded)"),
            ("method", f"{self.method}" + (f", rotation {self.rotation}" if self.rotation else "")
             + f", unknowns {self.unknowns}" + (f", model {self.model}" if self.model else "")),
            ("status", f"{'converged' if self.converged else 'NOT CONVERGED'}: {self.message}"),
            (f"sensor pose ({self.convention}: {','.join(self.columns)})",
             " ".join(f"{v:.4f}" for v in self.sensor_pose)),
            ("sphere centre (base, mm)", " ".join(f"{v:.3f}" for v in self.sphere_centre)),
        ]
        if self.rms_mm is not None:
            rows.append(("RMS / max residual (mm)", f"{self.rms_mm:.4f} / {self.max_residual_mm:.4f}"))
        if self.loo_error_mm is not None:
            rows.append(("leave-one-out error (mm)", f"{self.loo_error_mm:.4f}"))
        if self.std is not None:
            rows.append(("1 sd translation (mm)", " ".join(f"{v:.4f}" for v in self.std.sensor_translation_mm)))
            rows.append(("1 sd rotation (deg)", " ".join(f"{v:.4f}" for v in self.std.sensor_rotation_deg)))
        return rows + [("warning", w) for w in self.warnings]

    @of_user_frame
    def __repr__(self):
        verdict = "converged" if self.converged else "NOT CONVERGED"
        rms = "n/a" if self.rms_mm is None else f"{self.rms_mm:.4f} mm"
        return (f"CalibrationResult(dataset={self.dataset!r}, method={self.method!r}, {verdict}, RMS {rms}, "
                f"sensor_pose[{self.convention}]={np.round(self.sensor_pose, 4).tolist()})")
