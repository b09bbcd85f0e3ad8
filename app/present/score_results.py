"""Results of scoring a given sensor pose and of comparing two (:mod:`handeye.app.engine.score`).

:class:`ScoreResult` is ``handeye calibrate DATASET --sensor-pose POSE`` (or ``--calibration
FILE`` with the sensor among ``--unknowns``); :class:`CompareResult` is ``handeye compare DATASET
A.json B.json``. Both exit 0: the score is the answer, and it says whether the data contradict
the pose.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from handeye.app.present.protocol import ResultProtocol
from handeye.app.present.residual_table import ResidualTable
from handeye.app.present.result_parts import _list, frame_keys, of_user_frame, user_poses

#: Residual model -> what one of its rows is.
_PER = {"centre": "sphere centre", "measurement": "circle (xc, zc, r)", "points": "profile point"}


def _rms_dict(score):
    return {k: float(v) for k, v in score.rms_mm.items()}


def _rms(score, model):
    """The RMS of ``score`` (a PoseScore) in ``model``, or of the centre model when it has none of that."""
    return score.rms_mm.get(model, score.rms_mm["centre"])


@dataclasses.dataclass(frozen=True)
class ScoreResult(ResultProtocol):
    """A given sensor pose scored on a dataset (module docstring of :mod:`handeye.app.engine.score`).

    Attributes
    ----------
    dataset, dataset_path : str
    source : str
        Where the pose came from (``--sensor-pose ...`` or the calibration file).
    convention : str
        Of ``sensor_pose`` (the dataset's, or ``--convention``).
    columns : tuple of str
    sensor_pose : ndarray
        The given pose in ``convention``.
    sensor2flange : ndarray, shape (4, 4)
        The given pose, mm, in its mount's frame.
    given : handeye.app.engine.score.PoseScore
    estimate : handeye.app.present.results.CalibrationResult
        The data's own calibration with the same request (its screening is the score's).
    estimate_score : handeye.app.engine.score.PoseScore
    model : str
        The residual model tested.
    f_test : tuple
        ``(F, p, contradicted)`` of the given pose against the estimate.
    distance : dict
        ``translation_mm``, ``rotation_deg``, ``sd`` (Mahalanobis, estimate's covariance), ``p_value``.
    noise_test : handeye.app.present.result_parts.NoiseTest or None
        The given pose against the stated noise.
    centre_fitted : bool
        The sphere centre was fitted with the pose held.
    """

    caption = "handeye score"

    dataset: str
    dataset_path: str
    source: str
    convention: str
    columns: tuple
    sensor_pose: np.ndarray
    sensor2flange: np.ndarray
    given: object
    estimate: object
    estimate_score: object
    model: str
    f_test: tuple
    distance: dict
    noise_test: object | None
    centre_fitted: bool
    provenance: dict | None = None
    own_axes: np.ndarray | None = None
    pose_frame: str = "handeye"

    def in_user_frame(self):
        """The score with the given pose and the data's own calibration of the sensor's own frame
        when the profiles were turned (``own_axes``), as
        :meth:`handeye.app.present.results.CalibrationResult.in_user_frame`."""
        if self.own_axes is None or self.pose_frame == "own":
            return self
        matrix, pose, _ = user_poses(self.sensor2flange, self.own_axes, self.convention)
        estimate = dataclasses.replace(self.estimate, own_axes=self.own_axes).in_user_frame()
        return dataclasses.replace(self, sensor2flange=matrix, sensor_pose=pose, estimate=estimate, pose_frame="own")

    @property
    def contradicted(self):
        """True when the data contradict the given pose (module docstring of the engine); None when
        the data's own calibration did not converge (no minimum to test it against)."""
        return None if self.f_test[2] is None else bool(self.f_test[2])

    @property
    def converged(self):
        """Whether the score has a verdict: the data's own calibration converged (exit 0; else 1)."""
        return bool(self.estimate.converged)

    @property
    def error(self):
        """Why there is no verdict (exit 1), or None."""
        if self.converged:
            return None
        refused = self.estimate.message.startswith(("not a calibration", "unexplained"))
        return (f"no verdict: the data's own calibration {'is refused' if refused else 'did not converge'} "
                f"({self.estimate.message}), so there is no minimum of this model to test the given pose against")

    @property
    def residuals(self):
        """Every sample's residual at the given pose (used: the estimate's screening)."""
        est = self.estimate
        return ResidualTable([r.id for r in est.residuals], [r.row for r in est.residuals], self.given.residuals,
                             np.linalg.norm(self.given.residuals, axis=1), [r.used for r in est.residuals])

    def verdict(self):
        """One sentence: does the data contradict the pose?"""
        f, p, bad = self.f_test
        g, e = _rms(self.given, self.model), _rms(self.estimate_score, self.model)
        if not self.converged:
            return self.error
        if not np.isfinite(f):
            return "no comparison: the data's own calibration has no residual degrees of freedom"
        return (f"the data {'contradict' if bad else 'do not contradict'} the given pose: RMS {g:.4f} mm per "
                f"{_PER[self.model]} against {e:.4f} mm at the data's own calibration (F = {f:.3g}, p = {p:.2g}); it "
                f"lies {self._far()} from it")

    def _far(self):
        d = self.distance
        sd = "" if d["sd"] is None else f", {d['sd']:.1f} sd of that calibration"
        return f"{d['translation_mm']:.3f} mm and {d['rotation_deg']:.4f} deg{sd}"

    @of_user_frame
    def to_dict(self):
        f, p, bad = self.f_test
        est = self.estimate
        out = {
            "scored": True, "dataset": self.dataset, "dataset_path": self.dataset_path, "source": self.source,
            "error": self.error, "converged": self.converged and not bad,
            "sensor_mount": self.estimate.sensor_mount, "sensor_pose": _list(self.sensor_pose),
            "sensor_pose_as": {"convention": self.convention, "columns": list(self.columns),
                               "pose": _list(self.sensor_pose)},
            "sensor_matrix": _list(self.sensor2flange),
            **frame_keys(self.own_axes),
            "sphere_center": _list(self.given.centre),
            "centre_fitted": self.centre_fitted, "model": self.model, "rms_mm": _rms_dict(self.given),
            "ssr": self.given.ssr, "contradicted": self.contradicted, "verdict": self.verdict(),
            "f_test": {"statistic": f, "dof": [6, self.given.m - 6 - 3 * self.centre_fitted], "p_value": p},
            "distance_to_estimate": dict(self.distance),
            "noise_test": None if self.noise_test is None else self.noise_test.to_dict(),
            "estimate": {"sensor_pose": _list(est.sensor_pose), "sensor_matrix": _list(est.sensor2flange),
                         "sphere_center": _list(est.sphere_centre), "converged": bool(est.converged),
                         "message": est.message, "rms_mm": _rms_dict(self.estimate_score),
                         "ssr": self.estimate_score.ssr},
            "n_used": int(np.sum([r.used for r in est.residuals])), "outliers": list(est.outliers),
            "excluded": [e.to_dict() for e in est.excluded],
            "residuals": [r.to_dict() for r in self.residuals],
        }
        if self.provenance is not None:
            out["provenance"] = self.provenance
        return out

    @of_user_frame
    def summary(self):
        from handeye.app.present.report import residual_lines

        est = self.estimate
        n_used = int(np.sum([r.used for r in est.residuals]))
        lines = [f"handeye calibrate (score): dataset {self.dataset}, the sensor pose given by {self.source} held"
                 + (", the sphere centre fitted" if self.centre_fitted else ", nothing fitted"),
                 f"verdict: {self.verdict()}", "",
                 f"given pose ({self.convention}: {','.join(self.columns)}): " + " ".join(f"{v:.4f}" for v in self.sensor_pose)
                 + (" (the sensor's own frame, [profile] own_axes)" if self.own_axes is not None else ""),
                 f"data's own  ({self.convention}: {','.join(self.columns)}): " + " ".join(f"{v:.4f}" for v in est.sensor_pose)
                 + ("" if est.converged else "  (NOT converged)"),
                 "sphere centre (mm): " + " ".join(f"{v:.3f}" for v in self.given.centre)
                 + (" (fitted with the pose held)" if self.centre_fitted else " (given)"), "",
                 f"RMS per residual model over the {n_used} samples the data's own calibration keeps "
                 "(given pose | data's own calibration):"]
        lines += [f"  {name:<12} {value:9.4f} | {self.estimate_score.rms_mm[name]:9.4f} mm per {_PER[name]}"
                  for name, value in self.given.rms_mm.items()]
        if self.noise_test is not None:
            t = self.noise_test
            lines.append(f"noise test of the given pose ({self.model}): sd {t.ratio:.2f} x the stated {t.nominal} "
                         f"(chi2 = {t.statistic:.4g} on {t.dof} dof, p = {t.p_value:.2g}): "
                         + ("passed" if t.passed else "FAILED"))
        lines += ["", *residual_lines(self.residuals)]
        if est.excluded:
            lines += ["", "excluded samples (the data's own screening; not in the RMS):"]
            lines += [f"  {e.id} (row {e.row}): {e.reason}" for e in est.excluded[:50]]
        return "\n".join(lines)


@dataclasses.dataclass(frozen=True)
class CompareResult(ResultProtocol):
    """Two calibrations compared on one dataset (``handeye compare``).

    Attributes
    ----------
    dataset : str
    sources : tuple of str
        The two files (A, B).
    scores : tuple of ScoreResult
    vuong : tuple or None
        ``(z, p)``: z > 0 when B fits better; None when both fit every sample alike.
    alpha : float
        Level of "significant".
    between : dict
        How far B lies from A: ``translation_mm``, ``rotation_deg`` (and ``sd``: in the data's own
        calibration's sd).
    """

    caption = "handeye compare"

    dataset: str
    sources: tuple
    scores: tuple
    vuong: tuple | None
    alpha: float
    between: dict

    @property
    def better(self):
        """The file that fits these data better (smaller sum of squares), or None when they tie."""
        a, b = (s.given.ssr for s in self.scores)
        return None if a == b else self.sources[0] if a < b else self.sources[1]

    @property
    def significant(self):
        return self.vuong is not None and self.vuong[1] < self.alpha

    def verdict(self):
        model = self.scores[0].model
        rms = [_rms(s.given, model) for s in self.scores]
        if self.better is None or self.vuong is None:
            return f"{self.sources[0]} and {self.sources[1]} fit these data equally well"
        bad = [s.contradicted for s in self.scores]
        if bad.count(True) == 1:  # one is contradicted by the data outright: that first
            k = bad.index(False) if False in bad else 1 - bad.index(True)
            return (f"{self.sources[k]} fits these data better: they contradict {self.sources[1 - k]} "
                    f"({self.scores[1 - k].verdict()})")
        z, p = self.vuong
        k = 0 if self.better == self.sources[0] else 1
        how = ("significantly" if self.significant else "but not significantly")
        return (f"{self.better} fits these data better, {how} (Vuong z = {abs(z):.2f}, p = {p:.2g} at level "
                f"{self.alpha:g}): RMS {rms[k]:.4f} against {rms[1 - k]:.4f} mm per {_PER[model]}")

    def to_dict(self):
        return {"dataset": self.dataset, "files": list(self.sources), "better": self.better,
                "significant": self.significant, "error": None, "verdict": self.verdict(),
                "vuong": None if self.vuong is None else {"z": self.vuong[0], "p_value": self.vuong[1]},
                "alpha": self.alpha, "between": dict(self.between),
                "scores": {src: {k: v for k, v in s.to_dict().items() if k not in ("residuals", "excluded")}
                           for src, s in zip(self.sources, self.scores)}}

    def summary(self):
        lines = [f"handeye compare: dataset {self.dataset}", f"verdict: {self.verdict()}", ""]
        for src, s in zip(self.sources, self.scores):
            lines += [f"{src}: " + " ".join(f"{v:.4f}" for v in s.in_user_frame().sensor_pose) + f" ({s.convention})",
                      f"  {s.verdict()}"]
        b = self.between
        sd = "" if b.get("sd") is None else f" ({b['sd']:.1f} sd of the data's own calibration)"
        lines += ["", f"B lies {b['translation_mm']:.3f} mm and {b['rotation_deg']:.4f} deg from A{sd}"]
        return "\n".join(lines)
