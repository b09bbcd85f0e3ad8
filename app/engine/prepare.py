"""Prepare a calibration: the dataset with a sphere centre, the residual model, the start and
the checks that every command fitting the data runs first (enough measurements, poses that
determine every unknown), each model built once (:class:`Prepared`)."""
from __future__ import annotations

import dataclasses

import numpy as np

from handeye.app.common.errors import CalibrationInputError
from handeye.app.engine import guarantee
from handeye.app.engine.fitting import closed_form_pose
from handeye.app.engine.request import enough
from handeye.model.chain.pose import transform_from_pose
from handeye.model.datasets import observations
from handeye.model.design import identifiability
from handeye.model.fit.calibration import CalibrationModel
from handeye.model.fit.closed_form import ClosedFormError, closed_form_estimate


@dataclasses.dataclass(frozen=True)
class Prepared:
    """What every later stage works from.

    Attributes
    ----------
    request : handeye.app.engine.request.CalibrationRequest
        Checked.
    dataset : handeye.model.datasets.dataset.Dataset
        Every sample, with a sphere centre (the known one, or the closed-form start value).
    kind : {'centre', 'measurement', 'points'}
        The final fit's residual.
    observed : handeye.model.fit.calibration.CalibrationModel
        The final fit's model of every sample (``kind``, the request's parametrisation and
        weights), built once; the final fit takes its rows of the samples kept.
    everything : handeye.model.fit.calibration.CalibrationModel
        The unweighted centre model of every sample on the local chart (plain fit, probes).
    basin : handeye.model.fit.global_fit.CentreMinima or None
        The centre model's minima on every sample.
    start_pose : ndarray, shape (6,)
        KUKA (mm, deg).
    start_used : str
        Where the start came from.
    warnings : tuple of str
    centre_given : bool
        The setup gave the sphere centre (else it is the closed-form estimate).
    """

    request: object
    dataset: object
    kind: str
    observed: object
    everything: object
    basin: object
    start_pose: np.ndarray
    start_used: str
    warnings: tuple
    centre_given: bool = True


def prepare(request, dataset):
    """The :class:`Prepared` record of a checked request; raises CalibrationInputError."""
    unknowns = request.unknowns
    dataset, centre_note = with_sphere_centre(dataset, unknowns)
    kind = request.model or observations.default_kind(dataset)
    start_pose, start_used = resolve_start(dataset, unknowns, request.start)
    basin = guarantee.centre_basin(dataset, unknowns)
    # the weights of profiled centres turn at the plain centre model's lowest minimum: the start's not
    anchor = transform_from_pose(start_pose) if basin is None else basin.best.sensor2flange
    observed = observations.build(dataset, kind, request.rotation, unknowns, request.robot_sigma,  # refuses early
                                  observations.Anchor(sensor2flange=anchor))
    # the same model of every sample when the final one is the plain centre model: not built (and held) twice
    same = observed.kind == "centre" and observed.whiten is None and observed.rotation == "local"
    everything = observed if same else CalibrationModel.from_dataset(dataset, "local", unknowns)
    check_identifiable(dataset, unknowns, transform_from_pose(start_pose), probe=everything)
    absorbed = getattr(getattr(dataset, "robot_model", None), "absorbed", "")  # the nominal gate's constants
    warnings = tuple(note for note in (*request.notes, centre_note, absorbed) if note)
    return Prepared(request, dataset, kind, observed, everything, basin,
                    np.asarray(start_pose, float), start_used, warnings, centre_note is None)


def gate(dataset, unknowns, start=None):
    """The checks every command that fits the data runs first (calibrate, diagnose): enough
    measurements for the unknowns, and poses that determine every unknown at the start.

    Returns the start pose (KUKA) and where it came from; raises CalibrationInputError.
    """
    enough(dataset, unknowns)
    start_pose, start_used = resolve_start(dataset, unknowns, start)
    check_identifiable(dataset, unknowns, transform_from_pose(start_pose))
    return start_pose, start_used


def with_sphere_centre(dataset, unknowns):
    """The dataset with a sphere centre to start from, and a note when it was estimated.

    A setup without ``[sphere] center`` can be calibrated only with the centre free
    (``unknowns='sensor+sphere'``): its start value is then the closed-form estimate.
    """
    if dataset.sphere_centre is not None:
        return dataset, None
    setup = dataset.path / "setup.toml"
    if unknowns != "sensor+sphere":
        raise CalibrationInputError(f"{setup}, column '[sphere] center': the setup gives no sphere centre (nor base_pose "
                                    "with center_in_plate): give it, or estimate it with --unknowns sensor+sphere")
    try:
        _, centre = closed_form_estimate(dataset.motions(), dataset.centre_in_sensor, None)
    except ClosedFormError as exc:
        raise CalibrationInputError(f"{setup}: no sphere centre given, and the poses do not determine the closed-form "
                                    f"estimate of it: {exc}") from None
    return dataclasses.replace(dataset, sphere_centre=centre), (
        "the setup gives no sphere centre: it is estimated with the sensor pose, starting from the closed-form "
        f"estimate ({', '.join(f'{v:.2f}' for v in centre)}) mm")


def check_identifiable(dataset, unknowns, start_transform, probe=None):
    """Raise CalibrationInputError when the robot poses leave an unknown undetermined
    (``probe``: the dataset's centre model on the local chart, when already built)."""
    probe = CalibrationModel.from_dataset(dataset, "local", unknowns) if probe is None else probe
    ident = identifiability.structural(probe, probe.point_from(start_transform))
    if not ident.full_rank:
        raise CalibrationInputError(
            f"{dataset.path / 'measurements.csv'}: the robot poses do not determine every unknown "
            f"(rank {ident.rank} of {ident.n}); undetermined direction(s): {ident.describe_null()}. "
            "Measure from poses with rotations about at least two different axes"
            + (", and not only translations (they cannot separate the sensor offset from the sphere centre)"
               if unknowns == "sensor+sphere" else "")
        )
    if ident.observability["O2"] < identifiability.NEARLY_SINGULAR:
        raise CalibrationInputError(
            f"{dataset.path / 'measurements.csv'}: the robot poses nearly leave a direction undetermined "
            f"(inverse condition number {ident.observability['O2']:.1e} < {identifiability.NEARLY_SINGULAR:g}): "
            f"{ident.describe_weakest()}. This happens when the sphere is always seen at one sensor point "
            "(pure rotations about it): "
            "add poses that see it elsewhere in the laser plane, or pure translations")
    return ident


def resolve_start(dataset, unknowns, start=None):
    """The start pose and where it came from: ``--start``, the setup, or the closed form."""
    if start is not None:
        return np.asarray(start, dtype=float), "given (--start)"
    if dataset.start_pose is not None:
        return np.asarray(dataset.start_pose, dtype=float), "setup.toml start_pose"
    return closed_form_pose(dataset, unknowns), "closed-form estimate (no start pose given)"
