"""Typed results of a diagnosis: what :func:`handeye.diagnose` returns (the discrepancy
workflow's steps, score tests, per-sample residuals before and after the named effects).

:meth:`DiagnosisResult.to_dict` is exactly the ``handeye diagnose --json`` object.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from handeye.app.present.protocol import ResultProtocol
from handeye.app.present.result_parts import AsDict, Uncertainty, _list, fields, frame_keys, of_user_frame, user_poses, user_std
from handeye.model import effects


@dataclasses.dataclass(frozen=True)
class Step(AsDict):
    """One step of the diagnosis: the fit after it (mm; chi2/dof against the nominal sigma)."""

    step: str
    rms_mm: float
    chi2_dof: float
    sigma_mm: float
    heldout_rms_mm: float


@dataclasses.dataclass(frozen=True)
class DiagnosisResidual(AsDict):
    """|residual| of one sample before (base model) and after (with the named effects), mm."""

    id: str
    before_mm: float
    after_mm: float
    used: bool


def absorbed_sentence(name, by, centre_fitted=True, always=False):
    """Why an effect is "absorbed": the poses cannot tell it from the sensor pose or the centre
    (``always``: no pose set could, as for the catalogue's structural effects)."""
    if len(by) == 1 and by[0].startswith("1 sd "):  # a robot parameter the poses barely move
        return (f"{name}: too weakly seen here to estimate -- {by[0]} at the stated noise on these poses "
                "(beside the sensor pose and the centre); poses that move it more could separate it")
    groups = {"t": "the sensor position", "w": "the sensor orientation", "c": "the sphere centre"}
    what = list(dict.fromkeys(groups.get(p[0], p) if len(p) == 2 else p for p in by))
    structural = always or effects.get(name.split(".")[0]).KIND == "structural"
    held = ("the given sphere centre is not fitted here, so where the data hold it, it shows as a sphere_center "
            "offset (which diagnose would name)" if any(p.startswith("c") for p in by) and not centre_fitted
            else "which the calibration fits anyway, so those fitted values already contain it")
    return (f"{name}: not measurable here -- any amount of it is reproduced exactly by a change of "
            f"{' and '.join(what)} ({', '.join(by)}); {held}; "
            + ("no choice of poses can separate it (it is part of what they describe)"
               if structural else "poses with other rotations could separate it"))


@dataclasses.dataclass(frozen=True)
class DiagnosisResult(ResultProtocol):
    """The outcome of :func:`handeye.diagnose`; :meth:`to_dict` is ``handeye diagnose --json``.

    Attributes
    ----------
    effects : list of NamedEffect
    outliers : list of str
        Ids excluded as outliers at the end (the rows in ``inconsistent`` among them).
    inconsistent : list of ExcludedSample
        Rows whose centre columns contradict their own profile, excluded for good, with the
        reason (the same records as calibrate's ``excluded``; :mod:`handeye.model.datasets.consistency`).
    absorbed_by : dict
        Effect name -> the parameters that reproduce it (not identifiable from these poses).
    rms_before_mm, rms_after_mm, heldout_rms_before_mm, heldout_rms_after_mm : float
        Fitted and 5-fold held-out RMS, base model and with the named effects, mm.
    chi2_dof_before, chi2_dof_after : float
        Against ``nominal_sigma_mm`` per residual component.
    sensor2flange : ndarray, shape (4, 4)
        Sensor in flange (mm) of the final model. JSON key ``sensor_matrix``.
    sensor_pose : ndarray, shape (6,)
        KUKA x, y, z, A, B, C (mm, deg) of the model with the named effects.
    sensor_pose_as, convention, columns
        The same pose in the dataset's robot convention (JSON ``sensor_pose_as``).
    std : Uncertainty
        Its 1-sd (translation mm; rotation deg about the sensor's axes), and the sphere
        centre's when ``sphere_center`` is named.
    sphere_centre : ndarray, shape (3,)
        Robot base, mm. JSON key ``sphere_center``.
    steps : list of Step
    tests : list of list of handeye.model.fit.extended.ScoreTest
        The score tests of each round.
    residuals : list of DiagnosisResidual
    unexplained : str
        What remains after the named effects.
    always_absorbed : tuple of str
        The robot parameters (``effect.parameter``) no pose set could separate.
    robot_alternatives : str or None
        Other robot effects that explain the data about as well as those named (their BIC and
        how far the sensor pose moves with them; :mod:`handeye.app.engine.robot_choice`), or None.
    robot_rivals : tuple of (str, ndarray (4, 4))
        Those alternatives' labels and sensor poses (handeye's frame, the mount's), which calibrate's sd holds.
    cleaning : dict or None
        What profile cleaning dropped, as :attr:`CalibrationResult.cleaning
        <handeye.app.present.results.CalibrationResult>` (``{'applied': False}`` with
        ``--no-clean``; None without profiles).
    beyond_catalogue : tuple of str
        Why the nearest effects to the discrepancy were not named (their fitted values beyond
        the catalogue's physical range): structure no catalogue effect explains (also at the
        head of ``unexplained``).
    power : handeye.app.present.result_parts.PowerStatement or None
        What the data could not see at the final fit: the effects not named, the size each would
        be detected at with 80 % power, and the pose shift it would cause if missed.
    configuration : str or None
        Excluded samples that coincide with a robot configuration group (the wrist flipped, ...),
        said, with whether the search keeps them with an effect
        (:mod:`handeye.app.engine.configuration_group`); None when they do not.
    """

    caption = "handeye diagnosis"

    dataset: str
    effects: list
    outliers: list
    absorbed_by: dict
    rms_before_mm: float
    rms_after_mm: float
    heldout_rms_before_mm: float
    heldout_rms_after_mm: float
    chi2_dof_before: float
    chi2_dof_after: float
    nominal_sigma_mm: float
    sigma_after_mm: float
    sensor_pose: np.ndarray
    sensor2flange: np.ndarray
    sphere_centre: np.ndarray
    effect_correlations: dict
    steps: list
    tests: list
    residuals: list
    screened_out_first: list
    unexplained: str
    convention: str = "kuka"
    columns: tuple = ("x", "y", "z", "a", "b", "c")
    sensor_pose_as: np.ndarray | None = None
    std: Uncertainty | None = None
    provenance: dict | None = None
    centre_fitted: bool = True
    inconsistent: list = dataclasses.field(default_factory=list)
    robot_alternatives: str | None = None
    robot_rivals: tuple = dataclasses.field(default=(), repr=False)
    always_absorbed: tuple = ()
    unknowns: str = "sensor"
    against_calibrate: str | None = None
    own_axes: np.ndarray | None = None
    cleaning: dict | None = None
    pose_frame: str = "handeye"
    beyond_catalogue: tuple = ()
    power: object | None = None
    configuration: str | None = None

    @property
    def absorbed_explained(self):
        """Each absorbed effect in a sentence a user understands."""
        return [absorbed_sentence(name, by, self.centre_fitted, name in self.always_absorbed)
                for name, by in self.absorbed_by.items()]

    @property
    def not_identifiable(self):
        """Names of the catalogue effects these poses cannot separate from the model."""
        return sorted(self.absorbed_by)

    def in_user_frame(self):
        """The diagnosis with its sensor pose (and the 1-sd of its rotation) of the sensor's own frame
        when the profiles were turned (``own_axes``), as
        :meth:`handeye.app.present.results.CalibrationResult.in_user_frame`."""
        if self.own_axes is None or self.pose_frame == "own":
            return self
        matrix, pose, kuka = user_poses(self.sensor2flange, self.own_axes, self.convention)
        return dataclasses.replace(self, sensor2flange=matrix, sensor_pose=kuka, sensor_pose_as=pose,
                                   std=user_std(self.std, None, self.own_axes)[0], pose_frame="own")

    @of_user_frame
    def to_dict(self):
        """The ``handeye diagnose --json`` object (its pose of the user's frame: :meth:`in_user_frame`)."""
        return {
            **fields(self, "dataset", "unknowns", "against_calibrate"),
            "effects": [e.to_dict() for e in self.effects],
            "outliers": list(self.outliers),
            "inconsistent": [e.to_dict() for e in self.inconsistent],
            "not_identifiable": self.not_identifiable,
            "absorbed_by": {k: list(v) for k, v in self.absorbed_by.items()},
            **fields(self, "rms_before_mm", "rms_after_mm", "heldout_rms_before_mm", "heldout_rms_after_mm",
                     "chi2_dof_before", "chi2_dof_after", "nominal_sigma_mm", "sigma_after_mm", "sensor_pose",
                     lists=("sensor_pose",)),
            "sensor_matrix": _list(self.sensor2flange),
            **frame_keys(self.own_axes),
            "sphere_center": _list(self.sphere_centre),
            "effect_correlations": self.effect_correlations,
            "steps": [s.to_dict() for s in self.steps],
            "tests": [[t.to_dict() for t in round_] for round_ in self.tests],
            "residuals": [r.to_dict() for r in self.residuals],
            "screened_out_first": list(self.screened_out_first),
            **fields(self, "unexplained", "robot_alternatives", "configuration"),
            "sensor_pose_as": {"convention": self.convention, "columns": list(self.columns),
                               "pose": _list(self.sensor_pose_as if self.sensor_pose_as is not None
                                             else self.sensor_pose)},
            "std": None if self.std is None else self.std.to_dict(),
            **fields(self, "absorbed_explained", "cleaning"),
            "power": None if self.power is None else self.power.to_dict(),
            **({"provenance": self.provenance} if self.provenance is not None else {}),
        }

    def summary(self):
        """The CLI's text report."""
        from handeye.app.present import report

        return report.diagnosis_text(self.in_user_frame())

    def figures(self, folder):
        """Write ``residuals.png`` and ``gap.png`` into ``folder``; returns their paths."""
        from handeye.app.present import report

        return report.diagnosis_figures(self, folder)

    def _html_rows(self):
        """The Jupyter table's rows (:class:`~handeye.app.present.protocol.ResultProtocol`)."""
        named = "; ".join(
            e.name + (": " + ", ".join(e.parameters["ids"]) if e.std is None else
                      ": " + ", ".join(f"{k} = {v:.4g} ± {e.std[k]:.2g}" for k, v in e.parameters.items()))
            for e in self.effects) or "none"
        return [("dataset", self.dataset), ("effects named", named),
                ("outliers", ", ".join(self.outliers) or "none"),
                ("absorbed (not identifiable)", ", ".join(self.not_identifiable) or "none"),
                ("RMS before → after (mm)", f"{self.rms_before_mm:.4f} → {self.rms_after_mm:.4f}"),
                ("held-out RMS before → after (mm)",
                 f"{self.heldout_rms_before_mm:.4f} → {self.heldout_rms_after_mm:.4f}"),
                ("unexplained", self.unexplained)]
