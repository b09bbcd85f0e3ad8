"""First-setup slips: the laser side, length units, angle units -- caught and named, never "solved".

A new cell's first dataset often carries one of a few slips that no single value betrays:
``[profile] side`` with the wrong sign (every reconstructed centre on the wrong side of the
laser plane), robot positions in metres (as UR's RTDE and URScript give them) where the
dataset wants millimetres, or angles in radians where KUKA and FANUC want degrees. Each makes
an official-looking calibration with a large residual.

The test is the alternative hypothesis itself: when the plain least-squares fit of every
sample is poor -- RMS above :data:`SUSPECT_RMS_MM`, or residuals larger than the stated noise
(``[noise] centre_mm``, chi-square at the 1 % level) -- the same fit is made with each slip
undone (side flipped, positions times 1000, the sphere centre too, angles from radians to
degrees), each from its own closed-form start. Both fits have the same number of unknowns,
so the ratio of their sums of squares is F-distributed with equal degrees of freedom when
neither is better. A slip is named when undoing it explains the data significantly and
clearly better: F-test p below :data:`P_SLIP`, RMS lower by at least :data:`FACTOR`, and at
most :data:`EXPLAINED_RMS_MM` after. A wrong side is nearly a shift of the sensor when every
pose cuts the sphere at the same depth; the F test still tells them apart where the fits
differ (12 poses at one depth: RMS 0.139 mm as given against 0.044 mm flipped). The
calibration then stops with exit 2 and a message that names the setting, both RMS values
and the fix; nothing is changed silently.

A *pairing shift* is the same kind of slip: every pose paired with its neighbour's measurement
(a logger that writes each measurement one row late or early; profile files paired by order with
one file too many or too few at the start), named with its direction and fix. Undoing it
(:meth:`~handeye.model.datasets.dataset.Dataset.paired`, :data:`SHIFTS`) moves the sensor's fields
(centres, profiles, their cleaning and reconstruction) against the robot's (poses, raw poses,
positioner and joint angles, and the ids and rows, which name the poses), and leaves one sample
fewer; the comparison stays fair by comparing it with the given pairing on as many samples (the
rows without the last, or without the first, whichever fits better: equal degrees of freedom,
and a gross error at an end cannot favour the shift). On a smoothly ordered tour a shift leaves
millimetres of residual that look like a converged fit (RMS 8 mm at exit 0, 5-27 deg off, on
simulated tours of a sensor fixed in the cell); shuffled rows shifted are as clearly named (the
shift undone restores the pairing whatever the order). What no test can see: a tour whose every
pose is the previous one times one fixed motion D (a constant-step screw motion,
``M_{i+1} = M_i D``) shifted by one row fits *exactly* at the sensor pose ``D X`` (or ``D^-1 X``):
``(M_i D X)^-1 c = (M_{i+1} X)^-1 c``, the next row's centre. There the pose is off by one step and
the data cannot say so; only a model of the time offset could (a later issue), and it is not
claimed here.

The same test names a convention slip (the poses read in another robot's convention, inverted,
in other units: :mod:`handeye.app.engine.detective`), rows whose side of the laser plane the data do
not settle (:func:`check_equator`), and, for calibrate, a taught sphere centre the sensor pose
would absorb (:func:`handeye.app.engine.taught_sphere.check_centre`; a diameter: its ``check_radius``).
"""
from __future__ import annotations

import dataclasses

import numpy as np

from handeye.app.common.errors import CalibrationInputError
from handeye.app.engine.levels import (  # the verdict's levels, one place
    DIAMETER_AGREE,
    DIAMETER_AGREE_MM,
    EQUATOR_BAND,
    EXPLAINED_RMS_MM,
    FACTOR,
    P_SIDE,
    P_SLIP,
    P_SUSPECT,
    SIDE_MOVE_DEG,
    SIDE_MOVE_MM,
    SIDE_MOVE_SD,
    SUSPECT_RMS_MM,
)
from handeye.model.chain import conventions
from handeye.model.chain.pose import pose_from_transform
from handeye.model.common.rotation import transform_distance
from handeye.model.common.statistics import chi2_survival, covariance, f_survival
from handeye.model.fit import global_fit
from handeye.model.fit.calibration import CalibrationModel


@dataclasses.dataclass(frozen=True)
class Slip:
    """A slip undone: the dataset it gives and what to tell the user."""

    name: str
    dataset: object
    fix: str
    #: Where the slip undone has fewer samples (a pairing shift): the given pairing on as many
    #: samples, each compared in its place of the given dataset (the lowest RMS of them counts).
    baseline: tuple = ()


def _side_in_files(dataset, side):
    """For a dataset whose profiles ``handeye dataset new`` turned (``[profile] own_axes``): the
    same side as ``dataset new --side`` takes it, in the files' own frame."""
    if getattr(dataset, "own_axes", None) is None:
        return ""
    row = np.asarray(dataset.own_axes, float)[1]  # handeye's y along the files' normal
    k = int(np.argmax(np.abs(row)))
    return (f"; with handeye dataset new, --side {int(side * np.sign(row[k])):+d} (the side in the profile files' "
            f"{'xyz'[k]}, as that command takes it)")


def _candidates(dataset):
    d, setup = dataset, dataset.path / "setup.toml"
    out = []
    if d.reconstructed is not None and any(d.reconstructed):  # side decided the sign of these rows' y
        rows = np.array(d.reconstructed)
        xs = d.centre_in_sensor.copy()
        xs[rows, 1] = -xs[rows, 1]
        out.append(Slip("[profile] side", dataclasses.replace(d, centre_in_sensor=xs, side=-d.side),
                        f"set side = {-d.side} in {setup} (the side of the laser plane the sphere's centre lies on, "
                        "in the sensor's y)" + _side_in_files(d, -d.side)))
    given = np.ones(len(d), bool) if d.reconstructed is None else ~np.array(d.reconstructed)
    if given.any():  # centres the file gives: their y sign is the sensor's (a y axis the other way?)
        xs = d.centre_in_sensor.copy()
        xs[given, 1] = -xs[given, 1]
        out.append(Slip("the sign of ys", dataclasses.replace(d, centre_in_sensor=xs),
                        f"negate the ys column of {d.path / 'measurements.csv'} (handeye's sensor y is z x x, with x "
                        "along the laser line and z the measuring direction; the sensor's may point the other way); "
                        "or, if the sensor's y is handeye's, the sensor's true pose was off its nominal one by more "
                        "than the plan allowed for, and the laser plane cut the sphere on the other side: plan again "
                        "with a --margin as large as that error"))
    poses = d.flange_poses.copy()
    poses[:, :3] *= 1000.0
    out.append(Slip("robot positions in metres", dataclasses.replace(d, flange_poses=poses),
                    f"write the flange positions x, y, z of {d.path / 'measurements.csv'} in millimetres (x 1000)"))
    if d.sphere_centre is not None:
        out.append(Slip("robot positions and sphere centre in metres",
                        dataclasses.replace(d, flange_poses=poses, sphere_centre=d.sphere_centre * 1000.0),
                        f"write the flange positions and the [sphere] center of {setup} in millimetres (x 1000)"))
    if d.convention in ("kuka", "fanuc") and np.all(np.abs(d.flange_poses[:, 3:]) <= 2 * np.pi + 1e-9):
        degrees = d.flange_poses.copy()
        if d.convention == "fanuc":  # the file's W, P, R read as radians, then as KUKA again
            fanuc = conventions.convert(d.flange_poses, "kuka", "fanuc")
            fanuc[:, 3:] = np.degrees(fanuc[:, 3:])
            degrees = conventions.convert(fanuc, "fanuc", "kuka")
        else:
            degrees[:, 3:] = np.degrees(degrees[:, 3:])
        out.append(Slip("robot angles in radians", dataclasses.replace(d, flange_poses=degrees),
                        f"write the flange angles of {d.path / 'measurements.csv'} in degrees"))
    if len(d.mounts.axes) == 2:  # base first: the axis that carries the other one listed second?
        swapped = dataclasses.replace(d.mounts, axes=d.mounts.axes[::-1])
        out.append(Slip("positioner axes in the other order", dataclasses.replace(
            d, mounts=swapped, axis_angles=np.asarray(d.axis_angles)[:, ::-1]),
            f"list [positioner] axes of {setup} base first ({swapped.axes[0].name}, then "
            f"{swapped.axes[1].name}: the axis that carries the other one comes first)"))
    if d.axis_angles is not None and np.all(np.abs(d.axis_angles) <= 2 * np.pi + 1e-9):
        out.append(Slip("positioner angles in radians", dataclasses.replace(d, axis_angles=np.degrees(d.axis_angles)),
                        f"write the positioner axis columns {', '.join(d.mounts.axis_names)} of "
                        f"{d.path / 'measurements.csv'} in degrees"))
    return out + _pairing_shifts(d)


#: The pairing shifts tried (rows): each pose with the next row's measurement, and with the previous one's.
SHIFTS = (1, -1)


def _pairing_shifts(d):
    """A pairing shift of one row undone (:data:`SHIFTS`), each against the given pairing on as many
    samples: the rows without the last and without the first (module docstring)."""
    out, n = [], len(d)
    if n < 3:
        return out
    csv = d.path / "measurements.csv"
    columns = " and ".join(c for c, used in (("xs, ys, zs", d.reconstructed is None or not all(d.reconstructed)),
                                             ("profile", d.profiles is not None)) if used)
    rows, ends = d.rows, (np.arange(n) < n - 1, np.arange(n) > 0)
    baseline = tuple(d.subset(e) for e in ends)  # the given pairing without the last row, without the first
    for step in SHIFTS:
        pose, meas = (rows[0], rows[1]) if step > 0 else (rows[1], rows[0])
        way, drop = ("up", "first row's measurement and the last row's pose") if step > 0 else (
            "down", "last row's measurement and the first row's pose")
        out.append(Slip(
            f"a pairing shift, each row's measurement belongs to the pose {'above' if step > 0 else 'below'} it "
            f"(row {meas}'s measurement to row {pose}'s pose, and so on: the measurements "
            f"{'lag one row behind' if step > 0 else 'run one row ahead of'} the poses)", d.paired(step),
            f"move the {columns} column{'s' if ',' in columns else ''} of {csv} {way} one row (dropping the {drop}); "
            "where `handeye dataset new` made the folder, pair the files again (--pair id with --match, or --pair order "
            f"with one {'missing' if step > 0 else 'extra'} entry at the start of the pose list or one "
            f"{'extra' if step > 0 else 'missing'} at the start of the measurements)",
            baseline=baseline))
    return out


def _plain_fit(dataset, unknowns):
    """The plain least-squares fit of every sample, the unweighted centre model's global minimum
    (:mod:`handeye.model.fit.global_fit`: one SVD with the centre known), and its RMS (mm); both
    None when the data do not determine it."""
    centre = None if unknowns == "sensor+sphere" else dataset.sphere_centre
    try:
        with np.errstate(all="ignore"):
            best = global_fit.centre_minima(dataset.motions(), dataset.centre_in_sensor, centre).best
    except global_fit.GlobalFitError:
        return None, None
    rms = float(np.sqrt(2.0 * best.cost / len(dataset)))
    return best, rms if np.isfinite(rms) else None


def plain_rms(dataset, unknowns):
    """RMS (mm) of the plain least-squares fit of every sample (:func:`_plain_fit`), or None when
    the data do not determine it."""
    return _plain_fit(dataset, unknowns)[1]


def free_axes_rms(dataset, unknowns):
    """For a sphere on a positioner: RMS (mm) of the plain fit with the positioner's turning axes
    estimated too (:mod:`handeye.app.engine.cell_stage`), from the centre model's global minimum at
    the set-up axes; else (or when they are not determined) :func:`plain_rms`. Set-up axes a few
    millimetres off leave millimetres of residual that no slip explains: slips are compared
    without them."""
    return _free_axes_fit(dataset, unknowns)[0]


def _free_axes_fit(dataset, unknowns):
    """:func:`free_axes_rms` and how many parameters its fit had beside the plain fit's (the axes')."""
    best, rms = _plain_fit(dataset, unknowns)
    if dataset.mounts.sphere != "positioner" or rms is None:
        return rms, 0
    from handeye.app.engine import cell_stage

    try:
        known = unknowns != "sensor+sphere" and dataset.sphere_centre is not None  # as _plain_fit held it
        free = ("sensor", "positioner") if known else ("sensor", "sphere", "positioner")
        fitted = cell_stage.fit(dataset, free, cell_stage.Start(best.sensor2flange, best.centre), np.ones(len(dataset), bool),
                                axes=cell_stage.turning_axes(dataset))
    except (global_fit.GlobalFitError, CalibrationInputError, np.linalg.LinAlgError):
        return rms, 0
    r = fitted.residual()
    return float(np.sqrt(r @ r / len(dataset))), fitted.n - (6 if unknowns == "sensor" else 9)  # as _suspect counts


def _suspect(dataset, unknowns, rms_given):
    """Whether the plain fit of RMS ``rms_given`` (mm) is poor: above :data:`SUSPECT_RMS_MM` or the stated
    noise; and its degrees of freedom."""
    n, p = len(dataset), 6 if unknowns == "sensor" else 9
    dof = 3 * n - p
    if not np.isfinite(rms_given) or dof <= 0:
        return False, dof
    chi2 = n * rms_given**2 / dataset.noise_centre_mm**2
    return bool(rms_given > SUSPECT_RMS_MM or chi2_survival(chi2, dof) < P_SUSPECT), dof


def check_diameter(dataset):
    """Raise :class:`CalibrationInputError` when the sensor's own centres (``xs, ys, zs`` given
    beside a profile) and the profiles disagree on the sphere: each pair implies a radius
    ``sqrt(r^2 + ys^2)`` (r the profile circle's); their median against ``[sphere] diameter``.

    Without this the centre residual (screening, leave-one-out) would use the sensor's centres
    and the profile models the setup's diameter: two calibrations reported as one.
    """
    from handeye.model.geometry import circle

    if dataset.profiles is None or dataset.reconstructed is None:
        return
    radii = []
    for pts, rebuilt, xs in zip(dataset.profiles, dataset.reconstructed, dataset.centre_in_sensor):
        if pts is None or rebuilt:
            continue
        try:
            r = circle.fit_circle(pts[:, 0], pts[:, 1], "hyper").r
        except circle.CircleFitError:
            continue  # named by the model that needs the circle
        radii.append(float(np.hypot(r, xs[1])))
    if len(radii) < 3:
        return
    radii = np.array(radii)
    med = float(np.median(radii))
    se = 1.4826 * float(np.median(np.abs(radii - med))) / np.sqrt(len(radii))
    setup = dataset.sphere_diameter / 2
    if abs(med - setup) > max(DIAMETER_AGREE * setup, DIAMETER_AGREE_MM, 6 * se):
        raise CalibrationInputError(
            f"{dataset.path}: the sensor's centres (xs, ys, zs) and the profiles disagree on the sphere: together "
            f"they imply a diameter of {2 * med:.4g} mm (median of {len(radii)}), setup.toml says "
            f"{dataset.sphere_diameter:g} mm. Check [sphere] diameter, or leave xs, ys, zs empty to reconstruct the "
            "centres from the profiles")


def check(dataset, unknowns, rms_given):
    """Raise :class:`CalibrationInputError` naming a slip that explains a poor fit (module docstring).

    Parameters
    ----------
    dataset : handeye.model.datasets.dataset.Dataset
    unknowns : {'sensor', 'sensor+sphere'}
    rms_given : float
        RMS (mm, of |e_i|) of the plain fit of every sample as the dataset is (with a positioner
        the slips are compared with its turning axes estimated: :func:`free_axes_rms`).
    """
    check_diameter(dataset)
    suspect, dof = _suspect(dataset, unknowns, rms_given)
    if suspect and dataset.mounts.sphere == "positioner":  # compared with the axes free (set-up axes may be off)
        rms_given, extra = _free_axes_fit(dataset, unknowns)
        dof -= extra  # each fit compared has the axes' parameters too
    if suspect and rms_given is not None:
        _check_slips(dataset, unknowns, rms_given, dof)
        _check_conventions(dataset, unknowns, rms_given, dof)
    check_equator(dataset, unknowns)  # on data no slip explains better


def _check_slips(dataset, unknowns, rms_given, dof):
    """Raise :class:`CalibrationInputError` naming the first-setup slip (:func:`_candidates`)
    whose undoing explains the data clearly and significantly better (module docstring)."""
    best = None
    for slip in _candidates(dataset):
        if slip.dataset.sphere_centre is None and unknowns == "sensor":
            continue
        rms = free_axes_rms(slip.dataset, unknowns)
        if rms is None or rms <= 0 or rms > EXPLAINED_RMS_MM:
            continue
        given, k = _baseline(slip, unknowns, rms_given, dof - 3 * (len(dataset) - len(slip.dataset)))
        if given is None or k <= 0 or rms * FACTOR > given:
            continue
        if f_survival((given / rms) ** 2, k, k) < P_SLIP and (best is None or rms < best[1]):
            best = (slip, rms, given)
    if best is not None:
        slip, rms, given = best
        raise CalibrationInputError(
            f"{dataset.path}: the data look like a setup slip, {slip.name}: as given, the plain fit of "
            f"{'every sample' if given == rms_given else f'{len(slip.dataset)} samples'} has RMS {given:.3g} mm; with "
            f"that slip undone, {rms:.3g} mm. {slip.fix[0].upper() + slip.fix[1:]}, and calibrate again")


def _baseline(slip, unknowns, rms_given, dof):
    """The given data's RMS (mm) to compare ``slip`` with, and the degrees of freedom ``dof`` of
    both fits (the slip undone's): every sample's RMS, or where the slip undone has fewer
    samples, the lowest of its baselines' on as many (a fair comparison: the same number of
    samples and unknowns, and the given pairing's best); (None, dof) when not determined."""
    if not slip.baseline:
        return rms_given, dof
    fits = [b.once(("free_axes_rms", unknowns), lambda b=b: free_axes_rms(b, unknowns)) for b in slip.baseline]
    fits = [r for r in fits if r is not None]  # each baseline's fit once (both shifts share them)
    return (min(fits) if fits else None), dof


def _check_conventions(dataset, unknowns, rms_given, dof):
    """Raise :class:`CalibrationInputError` when the poses read another way (:mod:`handeye.app.engine.detective`)
    fit clearly and significantly better, and fit: at most :data:`EXPLAINED_RMS_MM`, or within
    the stated noise (a reading that still leaves centimetres is not named: following it would
    not help)."""
    from handeye.app.engine import detective

    found = detective.best(dataset, unknowns)
    if found is None:
        return
    candidate, rms = found
    if dataset.mounts.sphere == "positioner":  # compared as the dataset is: the turning axes estimated too
        reread = dataclasses.replace(dataset, flange_poses=pose_from_transform(candidate.robot_poses),
                                     sphere_centre=None if dataset.sphere_centre is None else
                                     dataset.sphere_centre * (candidate.scale if candidate.centre_scaled else 1.0))
        rms = free_axes_rms(reread, unknowns) or rms
    n = len(dataset)
    at_noise = chi2_survival(n * rms**2 / dataset.noise_centre_mm**2, dof) >= P_SUSPECT  # fits the stated noise
    if not (rms > 0 and rms * FACTOR <= rms_given and (rms <= EXPLAINED_RMS_MM or at_noise)):
        return
    if f_survival((rms_given / rms) ** 2, dof, dof) >= P_SLIP:
        return
    todo = detective.fix(candidate, dataset)
    raise CalibrationInputError(
        f"{dataset.path}: the robot poses fit with {candidate.describe()}, not as declared "
        f"({dataset.convention} {','.join(conventions.columns(dataset.convention)[3:])}): the plain fit has RMS "
        f"{rms:.3g} mm read so, {rms_given:.3g} mm as declared. {todo[0].upper() + todo[1:]}, and calibrate again")


def pose_covariance(dataset, unknowns, minimum):
    """Covariance (6 x 6: t mm in the flange, w rad about the sensor's axes) of the centre
    model's pose at a minimum, sigma estimated from its residuals."""
    model = CalibrationModel.from_dataset(dataset, "local", unknowns, sphere_centre=minimum.centre)
    x = model.point_from(minimum.sensor2flange, minimum.centre)
    return np.asarray(covariance(model.residual(x), model.jacobian(x)).matrix)[:6, :6]


def _pose_sd(dataset, unknowns, minimum):
    """1 sd (mm, deg; norms over the axes) of the centre model's pose at ``minimum``."""
    std = np.sqrt(np.clip(np.diag(pose_covariance(dataset, unknowns, minimum)), 0.0, None))
    return float(np.linalg.norm(std[:3])), float(np.degrees(np.linalg.norm(std[3:6])))


def check_equator(dataset, unknowns="sensor"):
    """Raise :class:`CalibrationInputError` when the rows cut near the sphere's equator leave the
    side of the laser plane, and with it the pose, undetermined.

    A laser line cuts the sphere in a circle of radius r that gives the centre's distance from
    the laser plane, ``|y| = sqrt(R^2 - r^2)``, but not its side: every row's sign is the
    assumption ``[profile] side`` (or the sensor's). Near the equator (``|y|`` below
    :data:`EQUATOR_BAND` R) a sensor pose a few millimetres off its nominal value moves the
    centre across the plane unseen, and the data then fit a wrong pose centimetres off at an
    RMS that looks like noise (planned 2-inch cells whose CAD pose was more off than the plan's
    margin: 8-17 mm, exit 0). The test is the alternative itself: the centre model's global
    minimum with those rows as given and with them on the other side. Unless the rows as given
    fit significantly better (F test p below :data:`P_SIDE`), while the two put the sensor in
    different places (more than :data:`SIDE_MOVE_MM` or :data:`SIDE_MOVE_DEG`, and more than
    :data:`SIDE_MOVE_SD` standard deviations of the pose), the data do not
    settle the side (they fit alike, or better the other way), and that is said instead of a
    calibration. Rows on both sides (a sensor that measures y itself) and
    rows whose side the rest of the data settle pass.
    """
    if dataset.sphere_diameter is None:  # no profiles: every centre measured in 3-D, its y too
        return
    p = dataset.centre_in_sensor
    y = p[:, 1]
    radius = dataset.sphere_diameter / 2
    near = np.abs(y) < EQUATOR_BAND * radius
    near &= np.array([c is None for c in (getattr(dataset, "clouds", None) or (None,) * len(y))])  # a cloud's y is measured
    if not near.any() or not (np.all(y <= 0) or np.all(y >= 0)):
        return
    centre = None if unknowns == "sensor+sphere" else dataset.sphere_centre
    flipped = p.copy()
    flipped[near, 1] = -flipped[near, 1]
    try:
        given = global_fit.centre_minima(dataset.motions(), p, centre).best
        other = global_fit.centre_minima(dataset.motions(), flipped, centre).best
    except global_fit.GlobalFitError:
        return
    dof = 3 * len(p) - (6 if centre is not None else 9)
    settled = given.cost < other.cost and f_survival(other.cost / max(given.cost, 1e-300), dof, dof) < P_SIDE
    dt, dr = transform_distance(given.sensor2flange, other.sensor2flange)
    if dof <= 0 or settled or (dt <= SIDE_MOVE_MM and dr <= SIDE_MOVE_DEG):
        return
    sd_mm, sd_deg = _pose_sd(dataset, unknowns, given)
    if dt <= SIDE_MOVE_SD * sd_mm and dr <= SIDE_MOVE_SD * sd_deg:
        return  # the side moves the pose less than its own uncertainty does
    rms = [float(np.sqrt(2 * m.cost / len(p))) for m in (given, other)]
    verdict = ("and they fit better on the other side" if other.cost < given.cost
               and f_survival(given.cost / max(other.cost, 1e-300), dof, dof) < P_SIDE
               else "and the data cannot tell which side")
    raise CalibrationInputError(
        f"{dataset.path / 'measurements.csv'}: {int(near.sum())} of {len(y)} rows cut the sphere within "
        f"{EQUATOR_BAND * radius:.3g} mm of its equator (|ys| up to {np.abs(y[near]).max():.3g} mm, R = {radius:g} mm), "
        f"all on one assumed side, {verdict}: with those rows as given the centre model fits with RMS {rms[0]:.3g} mm, "
        f"on the other side {rms[1]:.3g} mm, at sensor poses {dt:.3g} mm / {dr:.3g} deg apart. There a circle tells "
        "neither the side of the laser plane nor the distance from it, and a few mm of pose error moves rows across the "
        "plane unseen. Measure poses that cut the sphere between 0.1 R and 0.9 R from "
        "its centre (handeye plan, with a --margin at least as large as the nominal pose's error)")
