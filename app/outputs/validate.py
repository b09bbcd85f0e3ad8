"""Validation by scanning: a sphere measured through the calibration (``handeye validate``).

The acceptance test of optical 3-D measuring systems, VDI/VDE 2634 part 2, measures a
calibrated sphere and reports, on the least-squares (geometric) sphere of the points:

- probing error form ``PF``: the range (max - min) of the radial deviations;
- probing error size ``PS``: fitted minus calibrated diameter;
- sphere-spacing error ``SD``: measured minus calibrated distance of two sphere centres.

Here the points are the scan's profiles put into the robot base through the flange poses and
the calibration (:mod:`handeye.model.geometry.cloud`), the fit is :func:`handeye.model.geometry.sphere.fit`, and
the centre is also compared with the setup's centre.

Uncertainty (1 sd) of the fitted centre and radius, from three independent sources, each
propagated through the fit's sensitivity ``-(J^T J)^-1 J^T`` (:mod:`handeye.model.geometry.sphere`):

1. the calibration's covariance (every point moves with the one sensor pose);
2. the robot's repeatability ``[noise] robot_mm`` (each pose's points move together);
3. the points' own scatter, ``s^2 (J^T J)^-1``.

PF is a range statistic and has no standard error; it grows with the number of points.

Without profiles (a dataset of sphere centres only, such as the thesis's) the validation is
of the centres: each pose's measured centre through the chain against the setup's centre
(``epsilon``, the thesis's Table 7-5), with the 1-sd the calibration's covariance predicts for it.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from handeye.app.common.errors import RequestError
from handeye.app.present.protocol import ResultProtocol
from handeye.app.present.result_parts import AsDict, _list, fields
from handeye.model.geometry import cloud, sphere

#: A pose's points whose mean lies farther than this many radii from every setup centre are of
#: no sphere of the setup (with two spheres: the pose cannot be assigned).
ASSIGN_RADII = 1.5


@dataclasses.dataclass(frozen=True)
class SphereCheck:
    """One sphere measured through the calibration (module docstring).

    Attributes
    ----------
    label : str
        ``sphere`` or ``sphere2`` (the setup's section).
    setup_diameter_mm : float
    setup_centre : ndarray, shape (3,), or None
        Robot base, mm.
    n_points, n_poses : int
    radius_mm, radius_sd_mm : float
    centre, centre_sd_mm : ndarray, shape (3,)
        Fitted centre (robot base, mm) and its 1-sd per axis.
    centre_offset_mm : ndarray, shape (3,), or None
        Fitted minus setup centre.
    form_error_mm : float
        PF.
    size_error_mm, size_error_sd_mm : float
        PS = 2 R - setup diameter, and its 1-sd.
    rms_mm, max_abs_deviation_mm : float
    sd_sources : dict
        1-sd of the radius and of the centre (norm of the per-axis sd) from each source:
        ``calibration``, ``robot``, ``points`` (mm).
    excluded_points : int
        Points left out as the largest deviations (``exclude``).
    deviations, points : ndarray
        Radial deviation (M,) and point (M, 3) of every point used (not in the JSON).
    """

    label: str
    setup_diameter_mm: float
    setup_centre: np.ndarray | None
    n_points: int
    n_poses: int
    radius_mm: float
    radius_sd_mm: float
    centre: np.ndarray
    centre_sd_mm: np.ndarray
    centre_offset_mm: np.ndarray | None
    form_error_mm: float
    size_error_mm: float
    size_error_sd_mm: float
    rms_mm: float
    max_abs_deviation_mm: float
    sd_sources: dict
    excluded_points: int
    deviations: np.ndarray = dataclasses.field(repr=False, default=None)
    points: np.ndarray = dataclasses.field(repr=False, default=None)

    def to_dict(self):
        lists = ("centre", "centre_sd_mm", "centre_offset_mm", "setup_centre")
        return fields(self, "label", "radius_mm", "radius_sd_mm", *lists, "setup_diameter_mm", "form_error_mm",
                      "size_error_mm", "size_error_sd_mm", "rms_mm", "max_abs_deviation_mm", "n_points", "n_poses",
                      "excluded_points", "sd_sources", lists=lists)


@dataclasses.dataclass(frozen=True)
class SpacingCheck(AsDict):
    """Sphere-spacing error SD: measured minus setup distance of the two centres, mm."""

    distance_mm: float
    setup_distance_mm: float
    error_mm: float
    error_sd_mm: float


@dataclasses.dataclass(frozen=True)
class CentreCheck:
    """Validation of centres (no profiles): per pose ``epsilon = F X x_s - c`` (mm)."""

    ids: tuple
    epsilon: np.ndarray
    predicted_sd_mm: np.ndarray | None
    setup_centre: np.ndarray

    def to_dict(self):
        norms = np.linalg.norm(self.epsilon, axis=1)
        sds = [None] * len(self.ids) if self.predicted_sd_mm is None else self.predicted_sd_mm
        return {"mean_offset_mm": _list(self.epsilon.mean(axis=0)), "rms_mm": float(np.sqrt(np.mean(norms ** 2))),
                "median_mm": float(np.median(norms)), "max_mm": float(norms.max()), "setup_centre": _list(self.setup_centre),
                "poses": [{"id": i, "epsilon_mm": _list(e), "norm_mm": float(n),
                           "predicted_sd_mm": None if s is None else float(s)}
                          for i, e, n, s in zip(self.ids, self.epsilon, norms, sds)]}


@dataclasses.dataclass(frozen=True)
class Acceptance:
    """Measured errors against maximum permissible errors (mm): PF <= MPE_PF, |PS| <= MPE_PS and,
    with two spheres, |SD| <= MPE_SD. ``failed`` names what exceeds its limit."""

    limits: dict
    measured: dict
    failed: list

    @property
    def passed(self):
        return not self.failed

    def to_dict(self):
        return {"limits": self.limits, "measured": self.measured, "failed": list(self.failed), "passed": self.passed}


def accept(result, mpe):
    """:class:`Acceptance` of a sphere validation against ``mpe`` = (PF, PS[, SD]; SD with two spheres) in mm
    (checked by :class:`handeye.app.outputs.request.ValidateRequest`)."""
    names = ("PF", "PS", "SD")[: len(mpe)]
    limits = dict(zip(names, map(float, mpe)))
    checks = [(f"{name} [{s.label}]", name, value) for s in result.spheres
              for name, value in (("PF", s.form_error_mm), ("PS", s.size_error_mm))]
    checks += [("SD", "SD", result.spacing.error_mm)] if "SD" in limits else []  # (key, limit's name, measured)
    return Acceptance(limits, {key: value for key, _, value in checks},
                      [key for key, name, value in checks if abs(value) > limits[name]])


@dataclasses.dataclass(frozen=True)
class ValidationResult(ResultProtocol):
    """The outcome of :func:`handeye.validate` (module docstring).

    Attributes
    ----------
    scan : str
        The scanned dataset's name.
    calibration : str
        Where the calibration came from.
    n_points, n_poses : int
        Points and poses used (sphere mode; poses only in centre mode).
    spheres : list of SphereCheck
        Empty in centre mode.
    spacing : SpacingCheck or None
        With two spheres whose setup centres are known.
    centres : CentreCheck or None
        Centre mode (a dataset without profiles).
    skipped : list of str
        Poses not used, with the reason.
    notes : list of str
        What this validation can and cannot show.
    own_data : bool or None
        True when the scan is the calibration's own dataset (same SHA-256), False when it is
        not, None when the calibration does not say (a pose typed in, an older file).
    acceptance : Acceptance or None
        The verdict against stated maximum permissible errors (``mpe``).
    frame : str
        The frame of the centres and points: the sphere mount's (``base``, ``flange``, ``table``).
    status : str or None
        The calibration's verdict, recomputed from its dataset or said to be the file's
        (:mod:`handeye.app.outputs.verdict`).
    """

    caption = 'handeye validate'

    scan: str
    calibration: str
    n_points: int
    n_poses: int
    spheres: list
    spacing: SpacingCheck | None
    centres: CentreCheck | None
    skipped: list
    notes: list
    own_data: bool | None = None
    acceptance: Acceptance | None = None
    frame: str = "base"
    status: str | None = None

    @property
    def passed(self):
        """The acceptance verdict, or None when no limits were stated."""
        return None if self.acceptance is None else self.acceptance.passed

    def to_dict(self):
        # "error" when a limit is exceeded: the exit 1 of handeye validate
        return {"scan": self.scan, "error": "a maximum permissible error (--mpe) is exceeded" if self.passed is False else None,
                **fields(self, "calibration", "n_points", "n_poses"),
                "sphere": self.spheres[0].to_dict() if self.spheres else None,
                "spheres": [s.to_dict() for s in self.spheres],
                "spacing": None if self.spacing is None else self.spacing.to_dict(),
                "centres": None if self.centres is None else self.centres.to_dict(),
                "skipped": list(self.skipped), "notes": list(self.notes), "own_data": self.own_data,
                "verdict": self.status,
                "acceptance": None if self.acceptance is None else self.acceptance.to_dict()}

    def summary(self):
        from handeye.app.present import report

        return report.validation_text(self)


def _sources(fit, a_cal, cov_cal, g_robot, robot_sigma):
    """Covariance (4x4) of (centre, radius) from each source (module docstring)."""
    inv = np.linalg.inv(fit.information)
    return {"points": fit.noise_covariance(),
            "robot": robot_sigma ** 2 * inv @ np.einsum("nij,nkj->ik", g_robot, g_robot) @ inv,
            "calibration": None if cov_cal is None else inv @ a_cal @ cov_cal @ a_cal.T @ inv}


@dataclasses.dataclass(frozen=True)
class SphereCloud:
    """The points one sphere's poses saw.

    ``points`` (M, 3): robot base, mm, grouped by pose (``index`` non-decreasing); ``xz`` (M, 2): the same
    points in the sensor frame, mm; ``f2b`` (N, 4, 4): the flange poses, mm; ``index`` (M,): pose of each point.
    """

    points: np.ndarray
    xz: np.ndarray
    f2b: np.ndarray
    index: np.ndarray


def check_sphere(label, seen, calib, setup, robot_sigma, exclude=0.0):
    """Fit and assess one sphere (module docstring).

    Parameters
    ----------
    label : str
    seen : SphereCloud
    calib : handeye.app.outputs.saved.Calibration
    setup : handeye.model.datasets.scan.Sphere
    robot_sigma : float
        Robot repeatability per axis, mm.
    exclude : float
        Fraction of points with the largest deviations left out.

    Returns
    -------
    check : SphereCheck
    a_cal : ndarray, shape (4, 6)
        ``J^T (dd/dcalibration)``, for the spacing's cross-covariance.
    info_inv : ndarray, shape (4, 4)
        ``(J^T J)^-1``.
    total : ndarray, shape (4, 4)
        Covariance of (centre, radius), all sources.
    """
    points, xz, f2b, index = seen.points, seen.xz, seen.f2b, seen.index
    if np.any(np.diff(index) < 0):
        raise ValueError("points must be grouped by pose (index non-decreasing)")
    fit = sphere.fit(points)
    dropped = int(np.floor(exclude * len(points))) if exclude > 0 else 0
    if dropped:
        keep = np.sort(np.argsort(np.abs(fit.deviations))[: len(points) - dropped])
        points, xz, index = points[keep], xz[keep], index[keep]
        fit = sphere.fit(points)
    jac = np.hstack([-fit.normals, -np.ones((len(points), 1))])  # (M, 4)
    a_cal = jac.T @ cloud.radial_jacobian(fit.normals, xz, f2b, index, calib.sensor2flange)  # (4, 6)
    starts = np.flatnonzero(np.r_[True, index[1:] != index[:-1]])  # points are grouped by pose
    g_robot = np.add.reduceat(jac[:, :, None] * fit.normals[:, None, :], starts, axis=0)  # (poses, 4, 3)
    covs = _sources(fit, a_cal, calib.covariance, g_robot, robot_sigma)
    total = sum(c for c in covs.values() if c is not None)
    sd = np.sqrt(np.clip(np.diag(total), 0.0, None))
    sd_sources = {k: None if c is None else {"radius_mm": float(np.sqrt(max(c[3, 3], 0.0))),
                                             "centre_mm": float(np.sqrt(max(np.trace(c[:3, :3]), 0.0)))}
                  for k, c in covs.items()}
    check = SphereCheck(
        label=label, setup_diameter_mm=setup.diameter, setup_centre=setup.centre, n_points=len(points),
        n_poses=len(starts), radius_mm=fit.radius, radius_sd_mm=float(sd[3]), centre=fit.centre,
        centre_sd_mm=sd[:3], centre_offset_mm=None if setup.centre is None else fit.centre - setup.centre,
        form_error_mm=fit.form_error, size_error_mm=2 * fit.radius - setup.diameter, size_error_sd_mm=float(2 * sd[3]),
        rms_mm=fit.rms, max_abs_deviation_mm=float(np.max(np.abs(fit.deviations))), sd_sources=sd_sources,
        excluded_points=dropped, deviations=fit.deviations, points=points)
    return check, a_cal, np.linalg.inv(fit.information), total


def assign(points, index, spheres, ids):
    """The setup sphere each pose saw.

    Parameters
    ----------
    points : ndarray, shape (M, 3)
        Robot base, mm.
    index : ndarray, shape (M,)
        Pose of each point.
    spheres : sequence of handeye.model.datasets.scan.Sphere
    ids : sequence of str

    Returns
    -------
    which : ndarray, shape (N,)
        Index into ``spheres`` per pose; -1 when its points' mean lies more than
        :data:`ASSIGN_RADII` radii from every setup centre.
    reasons : list of str
        Why each pose with -1 was left out.
    """
    n_poses = int(index.max()) + 1 if len(index) else 0
    counts = np.bincount(index, minlength=n_poses)
    means = np.stack([np.bincount(index, weights=points[:, k], minlength=n_poses) for k in range(3)], 1)
    means /= np.maximum(counts, 1)[:, None]
    if len(spheres) == 1 and spheres[0].centre is None:
        return np.zeros(n_poses, int), []
    if any(s.centre is None for s in spheres):
        raise RequestError("two spheres in setup.toml: each needs its center, so that every pose can be "
                           "assigned to the sphere it saw")
    dist = np.stack([np.linalg.norm(means - s.centre, axis=1) / (s.diameter / 2) for s in spheres], 1)
    which = np.argmin(dist, axis=1)
    far = dist[np.arange(n_poses), which] > ASSIGN_RADII
    reasons = [f"{ids[i]}: its points lie {dist[i, which[i]]:.1f} radii from the nearest setup sphere "
               "(not a sphere profile, or a wrong calibration or centre)" for i in np.flatnonzero(far)]
    which[far] = -1
    return which, reasons


def spacing(checks, a_cals, infos, totals, covariance):
    """SD of two spheres (module docstring): ``u^T (S11 + S22 - S12 - S21) u`` with the
    calibration's cross-covariance ``S12`` (both centres move with the one sensor pose).

    ``checks``, ``a_cals``, ``infos``, ``totals``: per sphere, as :func:`check_sphere` returns
    them; ``covariance`` (6, 6) of the calibration or None. Returns :class:`SpacingCheck`."""
    c1, c2 = checks
    d = c1.centre - c2.centre
    dist = float(np.linalg.norm(d))
    u = d / dist
    ref = float(np.linalg.norm(c1.setup_centre - c2.setup_centre))
    var = float(u @ (totals[0][:3, :3] + totals[1][:3, :3]) @ u)
    if covariance is not None:
        s1, s2 = ((info @ a_cal)[:3] for info, a_cal in zip(infos, a_cals))
        var -= 2.0 * float(u @ s1 @ covariance @ s2.T @ u)
    return SpacingCheck(dist, ref, dist - ref, float(np.sqrt(max(var, 0.0))))


NOTES_OWN = {
    True: "these are the calibration's own data: it has already fitted the sensor pose to them, so the centre offset "
          "and PS are near zero by construction (a wrong setup diameter is absorbed and shows only in PF); for an "
          "independent check scan held-out poses or a second sphere position",
    False: "these are not the calibration's data (another SHA-256): PS, the centre offset and SD are an independent "
           "check of the calibration",
    None: "if these are the data the calibration was fitted to, the centre offset and PS are near zero by "
          "construction (a wrong setup diameter shows only in PF); held-out poses or a second sphere position give "
          "an independent check",
}
NOTE_SPHERE = ("PF is a range (max - min) and grows with the number of points; PS, the centre and SD carry a 1-sd "
               "from the calibration, the robot's repeatability and the points' scatter")
NOTE_CENTRE = ("no profiles: the sphere's centre from each pose (xs, ys, zs) through the calibration against the "
               "setup's centre, with the 1 sd the calibration predicts (the sensor's and the robot's noise come on "
               "top); PF and PS need the profiles")


def validate_scan(scan, calib, exclude=0.0, own=None):
    """Sphere mode: the scan's profiles as a cloud, one fit per setup sphere (module docstring)."""
    if not scan.spheres:
        raise RequestError(f"{scan.path / 'setup.toml'}: validate needs the sphere: [sphere] diameter (and center to "
                           "compare the centre)")
    f2b = scan.motions()
    points, index = cloud.points_in_base(f2b, calib.sensor2flange, scan.profiles)
    xz = np.concatenate(scan.profiles, axis=0)
    which, reasons = assign(points, index, scan.spheres, scan.ids)
    fits = []  # check_sphere's (check, a_cal, info, total) per setup sphere
    for k, setup in enumerate(scan.spheres):
        mask = which[index] == k
        if not mask.any():
            raise RequestError(f"no pose of {scan.name} saw [{'sphere' if k == 0 else 'sphere2'}] (centre "
                               f"{_list(setup.centre)}): check the setup's centres and the calibration")
        try:
            fits.append(check_sphere("sphere" if k == 0 else "sphere2", SphereCloud(points[mask], xz[mask], f2b, index[mask]),
                                     calib, setup, scan.robot_sigma_mm, exclude))
        except sphere.SphereFitError as exc:
            raise RequestError(f"{scan.path}: {exc}") from None
    checks, a_cals, infos, totals = (list(column) for column in zip(*fits))
    gap = spacing(checks, a_cals, infos, totals, calib.covariance) if len(checks) == 2 else None
    return ValidationResult(scan.name, calib.source, int(sum(c.n_points for c in checks)), int(sum(c.n_poses for c in checks)),
                            checks, gap, None, [f"{i}: no profile" for i in scan.skipped] + reasons,
                            [NOTES_OWN[own], NOTE_SPHERE], own)


def validate_centres(data, calib, own=None):
    """Centre mode: each pose's measured centre through the chain (module docstring)."""
    if data.sphere_centre is None:
        raise RequestError(f"{data.path / 'setup.toml'}: validation without profiles compares sphere centres: "
                           "[sphere] needs its center (or base_pose and center_in_plate)")
    x = calib.sensor2flange
    centre_h = np.c_[data.centre_in_sensor, np.ones(len(data))]
    eps = np.einsum("nij,nj->ni", data.motions() @ x, centre_h)[:, :3] - data.sphere_centre
    predicted = None if calib.covariance is None else cloud.point_sd(data.centre_in_sensor, x, calib.covariance)
    return ValidationResult(data.name, calib.source, 0, len(data), [], None,
                            CentreCheck(tuple(data.ids), eps, predicted, data.sphere_centre), [], [NOTE_CENTRE, NOTES_OWN[own]],
                            own)

