"""The verdict of a saved calibration recomputed from the data at its pose (``report``, ``export``,
``cloud``, ``validate`` with ``--calibration FILE``): the tool never knows more than it computed.

A ``calibrate --out`` file's fields (``converged``, ``rms_mm``, ``noise_test``, ``covariance``,
``sensor_mount``, ``dataset_sha256``) are claims. What an output shows of a verdict is computed here
from the data and the file's pose by the held-pose score path
(:class:`handeye.app.engine.score.Scorer`, what ``calibrate --calibration FILE`` scores with): the
residuals, RMS, covariance (as a calibration reports it: Student-t scaled and widened by what the
data could not see at the pose, :mod:`handeye.model.fit.power`) and noise test at the pose held (the
sphere centre refitted with it when the file's unknowns free it), and one Gauss-Newton step from the
pose, whose sum of squares tests whether the pose is the data's minimum
(:func:`handeye.app.engine.score.f_test`, the rule for any part held: the data *contradict* the
pose). That is one evaluation of residuals and Jacobian, never a calibration (milliseconds;
thesis-real 6 ms).

Where a field disagrees with what the data give, the file is named as hand-edited or foreign,
with the field and both values (:class:`Disagreement`, one line). Fatal (the caller exits 2,
naming the file and the field): a ``sensor_mount`` that is not the dataset's, a ``sensor_matrix``
that is not the file's own ``sensor_pose_as``, and a pose the data contradict in a file that says
it converged. The others (RMS, covariance, noise test, the dataset's hash in ``provenance``) are
said beside the recomputed values, which the output shows instead.

A file with effects (``--effects``, or those the search chose; data and robot effects) is recomputed in
the extended model at its pose, centre and effects (:mod:`handeye.app.engine.held_effects`): residuals,
RMS, noise test and whether the data contradict it; a file whose effects cannot be held (an unknown name,
a parameter missing or not a number, a chain not finite with them) is refused, naming ``effects``. What is
not compared, and said: the covariance of a file with effects (widened by what the search could not see
at its fit); the covariance of a file that calibrated the positioner's axes (its sensor block includes the axes'
uncertainty, which a pose held at the axes has not).
"""
from __future__ import annotations

import dataclasses

import numpy as np

from handeye.app.engine import bend, held_effects
from handeye.app.engine.describe import _fit_statistics, noise_test
from handeye.app.engine.diagnose import held_power
from handeye.app.engine.held_chain import held_at
from handeye.app.engine.levels import POSE_AGREES, RMS_AGREES, SD_BAND  # the verdict's levels, one place
from handeye.app.engine.score import Scorer, f_test
from handeye.app.present.result_parts import UncertaintyRecord
from handeye.model.chain import conventions
from handeye.model.common.rotation import pose_distance, pose_sd
from handeye.model.datasets import observations


@dataclasses.dataclass(frozen=True)
class Disagreement:
    """A field of the file that is not what the data (or the file's own numbers) give.

    Attributes
    ----------
    key : str
        The file's field (``sensor_matrix``, ``rms_mm``, ...).
    in_file, from_data : str
        Its value in the file, and what the data give (with where from), in words.
    fatal : bool
        The result is unusable: the caller refuses the file (exit 2).
    """

    key: str
    in_file: str
    from_data: str
    fatal: bool = False

    def text(self):
        """The field and both values, in words."""
        return f"hand-edited or foreign: {self.key} {self.in_file} in the file, {self.from_data}"

    def line(self, source):
        """One line naming the file, the field and both values."""
        return f"{source}: {self.text()}"


@dataclasses.dataclass(frozen=True)
class HeldVerdict:
    """The verdict of a saved pose recomputed on its dataset (module docstring).

    Attributes
    ----------
    dataset : str
        The dataset's name.
    used : ndarray of bool, shape (N,)
        Samples the file's calibration used (every sample when it does not say).
    residuals : ndarray, shape (N, 3)
        Every sample's sphere centre through the chain at the pose minus the sphere centre, mm.
    rms_mm, max_mm : float
        RMS and largest ``|e_i|`` over the used samples, mm per sphere centre.
    centre : ndarray, shape (3,)
        The sphere centre (the file's unknowns free it: refitted with the pose held), mm.
    covariance : ndarray, shape (6, 6), or None
        Of the sensor pose's local chart at the held pose (mm, rad), ``s^2 (J^T J)^-1``.
    noise : handeye.app.present.result_parts.NoiseTest or None
        The residuals at the pose against the stated noise.
    contradicted : bool or None
        The data contradict the pose (F test against one Gauss-Newton step); None: not tested.
    distance : dict or None
        How far the data's minimum (one step) lies from the pose: mm, deg, sd.
    disagreements : tuple of Disagreement
    not_recomputed : str or None
        Why the file's model could not be recomputed (effects it names that cannot be held), in words.
    effects : tuple of str
        The file's data effects, held with its pose (:mod:`handeye.app.engine.held_effects`); the residuals
        are of the centres they correct, and the file's covariance (widened by what the search could not see
        at its fit) is not compared.
    """

    dataset: str
    used: np.ndarray
    residuals: np.ndarray
    rms_mm: float
    max_mm: float
    centre: np.ndarray
    covariance: np.ndarray | None
    noise: object
    contradicted: bool | None
    distance: dict | None
    disagreements: tuple = ()
    not_recomputed: str | None = None
    effects: tuple = ()

    @property
    def converged(self):
        """The pose is the data's minimum (the data do not contradict it)."""
        return not self.contradicted

    def sd(self):
        """1-sd ``(translation (3,) mm, rotation (3,) deg)`` of the recomputed covariance, or None."""
        return pose_sd(self.covariance)

    def fatal(self):
        """The disagreements that make the file unusable."""
        return [d for d in self.disagreements if d.fatal]

    def failed(self):
        """The recomputed checks that fail, one short line each (none where the plain chain cannot
        recompute the file's model: :attr:`not_recomputed`)."""
        if self.not_recomputed:
            return []
        out = []
        if self.contradicted:
            out.append(f"the data contradict the pose: their minimum lies {_far(self.distance)} from it")
        if self.noise is not None and not self.noise.passed:
            out.append(f"residuals above the stated noise: sd {self.noise.ratio:.1f} x the stated {self.noise.nominal} "
                       f"(chi2 = {self.noise.statistic:.4g} on {self.noise.dof} dof)")
        return out

    def line(self):
        """The recomputed verdict in one line."""
        if self.not_recomputed:
            return f"{self.not_recomputed}; its mount, dataset and pose's own numbers checked"
        noise = "" if self.noise is None else (f", noise test {'passed' if self.noise.passed else 'FAILED'} (sd "
                                               f"{self.noise.ratio:.2f} x stated)")
        status = {None: "not tested", False: "the data's minimum"}.get(
            self.contradicted, f"CONTRADICTED by the data (their minimum {_far(self.distance)} away)")
        held = f" and effects ({', '.join(self.effects)})" if self.effects else ""
        return (f"recomputed from {self.dataset} at the file's pose{held}: RMS {self.rms_mm:.4g} mm per sphere centre over "
                f"{int(self.used.sum())} samples{noise}; pose: {status}"
                + (f"; {self.not_recomputed}" if self.not_recomputed else ""))


def _far(distance):
    if not distance:
        return "an unknown distance"
    sd = "" if distance.get("sd") is None else f", {distance['sd']:.3g} sd"
    return f"{distance['translation_mm']:.3g} mm / {distance['rotation_deg']:.3g} deg{sd}"


def used_mask(doc, data):
    """The samples the file's calibration used (its ``residuals``' ``used``, by id; every sample
    whose id the file does not list)."""
    rows = doc.get("residuals") if isinstance(doc.get("residuals"), list) else []
    used = {r.get("id"): bool(r.get("used", True)) for r in rows if isinstance(r, dict)}
    return np.array([used.get(i, True) for i in data.ids], bool)


def _stated(doc, data):
    """The stated noise and robot repeatability the file's calibration ran with (mm)."""
    options = ((doc.get("provenance") or {}).get("options") or {}) if isinstance(doc.get("provenance"), dict) else {}
    sigma, robot = options.get("sigma"), doc.get("robot_sigma_mm") or options.get("robot_sigma")
    sigma = float(sigma) if isinstance(sigma, (int, float)) else data.noise_centre_mm
    return sigma, float(robot) if isinstance(robot, (int, float)) else data.noise_robot_mm


def _effects(doc):
    """The names of the file's catalogue effects (``--effects``, or the search's), as written."""
    effects = doc.get("effects")
    return [str(e.get("name")) for e in effects if isinstance(e, dict)] if isinstance(effects, list) else []


def recompute(doc, sensor2flange, data):
    """The :class:`HeldVerdict` of the file ``doc`` (its JSON object) at its pose ``sensor2flange``
    (4x4, handeye's frame, the mount's frame) on ``data`` (at the positioner axes the file holds).

    Parameters
    ----------
    doc : dict
        The saved calibration (``calibrate --out``).
    sensor2flange : array_like, shape (4, 4)
        The file's pose, mm.
    data : handeye.model.datasets.dataset.Dataset
        Its dataset (the caller checked the SHA-256).
    """
    s = np.asarray(sensor2flange, float)
    unknowns = str(doc.get("unknowns") or "sensor")
    kind = doc.get("model") if doc.get("model") in ("centre", "measurement", "points") else "centre"
    sigma, robot_sigma = _stated(doc, data)
    mask = used_mask(doc, data)
    centre = np.asarray(doc["sphere_center"], float) if _vector(doc.get("sphere_center")) else None
    unread = None
    if doc.get("effects") not in (None, []) and (not isinstance(doc.get("effects"), list) or any(
            n not in held_effects.NOT_HELD for n in _effects(doc))):
        try:
            if centre is None:
                raise held_effects.UnreadEffects("the file gives no sphere_center to hold its effects with")
            read = held_effects.file_effects(doc, data)
            verdict = _with_effects(data, mask, s, centre, (read, held_effects.centre_freed(doc)), sigma)
            return dataclasses.replace(verdict, disagreements=tuple(disagreements(doc, verdict, data)))
        except (held_effects.UnreadEffects, np.linalg.LinAlgError, FloatingPointError, ValueError) as exc:
            unread = Disagreement("effects", str(doc.get("effects"))[:80], f"but {exc}: not a calibration of "
                                  f"{data.name} this tool can hold", True)
    scorer = Scorer(data, mask, kind, robot_sigma, "sphere" in unknowns.split("+"), s)
    given = scorer.score(s, centre)
    x = scorer.model.point_from(s, given.centre)
    _, cov, ssr = _fit_statistics(scorer.model, x)
    if kind == "points":  # the tests are of its circles (Scorer); the covariance is of the points, as the fit's
        points = observations.build(data.subset(mask), kind, "local", scorer.model.unknowns, robot_sigma,
                                    observations.Anchor(given.centre))
        cov = _fit_statistics(points, points.point_from(s, given.centre))[1]
    cov = _as_reported(cov, scorer, s, given.centre)
    whitened = scorer.model.whiten is not None
    noise = (noise_test(ssr, given.m - scorer.model.n, sigma, whitened, [], "")
             if whitened or scorer.kind == "centre" else None)
    contradicted, distance = None, None
    if "sensor" in unknowns.split("+"):
        step = np.linalg.lstsq(scorer.model.jacobian(x), -scorer.model.residual(x), rcond=None)[0]
        moved = scorer.model.retract(x, step)
        minimum = scorer.score(scorer.model.sensor2flange(moved), scorer.model.sphere_centre(moved))
        contradicted = f_test(given, minimum, scorer.n_params)[2]
        distance = pose_distance(s, minimum.sensor2flange, cov.matrix, scorer.model.names)
    norms = np.linalg.norm(given.residuals, axis=1)
    verdict = HeldVerdict(data.name, mask, given.residuals, float(given.rms_mm["centre"]), float(norms[mask].max()),
                          given.centre, np.asarray(cov.matrix)[:6, :6], noise, contradicted, distance,
                          not_recomputed=None if unread is None else f"not recomputed: {unread.text()}")
    return dataclasses.replace(verdict, disagreements=tuple(disagreements(doc, verdict, data))
                               + (() if unread is None else (unread,)))


def _with_effects(data, mask, sensor2flange, centre, held, stated):
    """The :class:`HeldVerdict` of a file with data effects (:mod:`handeye.app.engine.held_effects`; ``held``
    its effects and whether its centre is free), its covariance Student-t scaled as a calibration's."""
    r = held_effects.recompute(data, mask, sensor2flange, centre, held, stated)
    dof = max(r.noise.dof if r.noise is not None else 1, 1)
    cov = UncertaintyRecord.of_fit(r.covariance, ["tx", "ty", "tz", "wx", "wy", "wz"], dof).covariance
    return HeldVerdict(data.name, mask, r.residuals, r.rms_mm, r.max_mm, centre, np.asarray(cov), r.noise,
                       r.contradicted, r.distance, effects=tuple(held[0][0]))


def _as_reported(cov, scorer, sensor2flange, centre):
    """The recomputed covariance as a calibration reports it (one place:
    :class:`~handeye.app.present.result_parts.UncertaintyRecord`): Student-t scaled to its dof and
    widened by what the data could not see at the pose (:func:`handeye.app.engine.diagnose.held_power`);
    a :class:`~handeye.model.common.statistics.Covariance` with that matrix (``scorer``: the samples
    and model the verdict is of, :class:`~handeye.app.engine.score.Scorer`)."""
    record = UncertaintyRecord.of_fit(cov.matrix, scorer.model.names, cov.dof)
    try:
        record = record.with_power(held_power(scorer.dataset, scorer.mask, sensor2flange, centre, scorer.centre_free))
        chain = held_at(scorer.dataset, scorer.mask, (sensor2flange, centre), scorer.centre_free)
        record = bend.widened(record, chain, scorer.mask, getattr(scorer.dataset, "bend", None))
    except (np.linalg.LinAlgError, FloatingPointError, ValueError):
        pass  # no statement where the plain chain cannot be evaluated at the pose: the fit's sd, t-scaled
    return dataclasses.replace(cov, matrix=record.covariance)


def _vector(value):
    return isinstance(value, list) and len(value) == 3 and all(isinstance(v, (int, float)) for v in value)


def disagreements(doc, verdict, data):
    """The file's fields against the recomputed ``verdict`` on ``data`` (module docstring)."""
    out = own_disagreements(doc)
    mount = doc.get("sensor_mount", "flange")
    if mount != data.mounts.sensor:
        out.append(Disagreement("sensor_mount", repr(mount), f"{data.path / 'setup.toml'} mounts the sensor on the "
                                f"{data.mounts.sensor} ([sensor] mount)", True))
    if verdict.not_recomputed:
        return out
    if verdict.contradicted and doc.get("converged", True) is True:
        held = f" and effects ({', '.join(verdict.effects)})" if verdict.effects else ""
        out.append(Disagreement("sensor_matrix" + (" / effects" if verdict.effects else ""), "(converged: true)",
                                f"the data contradict the pose{held}: RMS {verdict.rms_mm:.4g} mm at it, their minimum "
                                f"{_far(verdict.distance)} away", True))
    rms = doc.get("rms_mm")
    if isinstance(rms, (int, float)) and abs(rms - verdict.rms_mm) > RMS_AGREES * max(verdict.rms_mm, 1e-9):
        out.append(Disagreement("rms_mm", f"{rms:.4g} mm", f"{verdict.rms_mm:.4g} mm from {data.name} at its pose"))
    noise = doc.get("noise_test")
    if isinstance(noise, dict) and verdict.noise is not None and noise.get("passed") is not verdict.noise.passed:
        out.append(Disagreement("noise_test", f"passed {noise.get('passed')}", f"passed {verdict.noise.passed} from "
                                f"{data.name} (sd {verdict.noise.ratio:.3g} x the stated noise)"))
    out += _covariance_disagreement(doc, verdict)
    return out


def _file_sd(doc):
    """The file's sensor 1-sd (tx, ty, tz mm, wx, wy, wz deg) by the field it is read from:
    ``covariance`` (what the outputs use) and ``std`` (what the file shows)."""
    out = {}
    cov = doc.get("covariance") if isinstance(doc.get("covariance"), dict) else {}
    try:
        if list(cov.get("names") or [])[:6] == ["tx", "ty", "tz", "wx", "wy", "wz"]:
            sd = np.sqrt(np.clip(np.diag(np.asarray(cov["matrix"], float))[:6], 0.0, None))
            out["covariance"] = np.r_[sd[:3], np.degrees(sd[3:6])]
    except (TypeError, ValueError, KeyError, IndexError):
        pass  # a covariance the file's reader refuses or leaves out; nothing to compare
    std = doc.get("std") if isinstance(doc.get("std"), dict) else {}
    trans, rot = std.get("sensor_translation_mm"), std.get("sensor_rotation_deg")
    if _vector(trans) and _vector(rot):
        out["std"] = np.r_[trans, rot]
    return out


def _covariance_disagreement(doc, verdict):
    """The file's sensor sd against the recomputed one (:data:`SD_BAND`); not for calibrated axes."""
    calibrated_axes = any(isinstance(a, dict) and a.get("calibrated") for a in doc.get("positioner") or [])
    if calibrated_axes or verdict.covariance is None or verdict.effects:
        return []
    from_data = np.r_[verdict.sd()]
    for key, in_file in _file_sd(doc).items():
        ratio = in_file / np.maximum(from_data, 1e-300)
        if np.all((ratio >= SD_BAND[0]) & (ratio <= SD_BAND[1])):
            continue
        k = int(np.argmax(np.abs(np.log(np.maximum(ratio, 1e-300)))))
        what, unit = ("tx", "ty", "tz", "wx", "wy", "wz")[k], "mm" if k < 3 else "deg"
        return [Disagreement(key, f"1 sd {what} {in_file[k]:.3g} {unit}",
                             f"{from_data[k]:.3g} {unit} from the data at its pose ({ratio[k]:.3g} x)")]
    return []


def own_disagreements(doc):
    """What the file's own fields say against each other, no data needed: its ``sensor_matrix``
    against its ``sensor_pose_as`` (fatal beyond :data:`POSE_AGREES`; not in an older file of turned
    profiles, whose frames the file does not say), its ``dataset_sha256`` against its ``provenance``'s."""
    out = []
    pose_as = doc.get("sensor_pose_as") if isinstance(doc.get("sensor_pose_as"), dict) else {}
    if doc.get("own_axes") is not None and doc.get("sensor_frame") != "own":
        pose_as = {}  # an older file of turned profiles: its matrix of handeye's frame, its poses maybe not
    values, convention = pose_as.get("pose"), pose_as.get("convention")
    try:
        written = conventions.transform_from(convention, np.asarray(values, float))
        matrix = np.asarray(doc.get("sensor_matrix"), float)
        far = pose_distance(matrix, written)
    except (TypeError, ValueError, KeyError, IndexError):
        far = None  # no pose of its own to compare (a hand-made file, an older one)
    if far is not None and (far["translation_mm"] > POSE_AGREES[0] or far["rotation_deg"] > POSE_AGREES[1]):
        out.append(Disagreement("sensor_matrix", f"{far['translation_mm']:.4g} mm / {far['rotation_deg']:.4g} deg "
                                f"from its own sensor_pose_as ({convention} {', '.join(f'{v:.6g}' for v in values)})",
                                "but both are written from one 4x4: one of them was edited", True))
    prov = doc.get("provenance") if isinstance(doc.get("provenance"), dict) else {}
    sha, prov_sha = doc.get("dataset_sha256"), prov.get("dataset_sha256")
    if isinstance(sha, str) and isinstance(prov_sha, str) and sha != prov_sha:
        out.append(Disagreement("dataset_sha256", f"{sha[:12]}...", f"its provenance says {prov_sha[:12]}..."))
    return out
