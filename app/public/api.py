"""The public Python API: ``import handeye``, then the CLI's commands as functions.

Each function takes the CLI's options as keyword arguments, with the same names and the same
defaults (``--keep-all`` is ``keep_all=False``, ``--max-iter`` is ``max_iter=None``), and
returns a typed result whose ``to_dict()`` is the command's ``--json`` object and whose
``summary()`` is its text report. The CLI (:mod:`handeye.app.command.cli`) only parses arguments,
calls these functions and prints: there is one code path.

>>> import handeye
>>> r = handeye.calibrate("thesis-sim")            # doctest: +SKIP
>>> r.sensor2flange.shape, r.converged             # doctest: +SKIP
((4, 4), True)

Bad input raises :class:`handeye.InputError` (a ``ValueError``) with a message naming the
file, row and column or the option; the CLI turns exactly that class into exit code 2.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from handeye.app.common import options
from handeye.app.common.arguments import _path_argument, load_dataset
from handeye.app.engine.robust import ALPHA
from handeye.app.outputs import request as held_request
from handeye.app.public.making import PlanResult, SimulationResult, plan, simulate  # noqa: F401  (the API's)
from handeye.model.common import scratch
from handeye.model.common.errors import InputError


@options.COMMANDS["calibrate"].documented
def calibrate(dataset="thesis-real", *, unknowns="sensor", method=None, rotation=None, start=None,
              convention=None, max_iter=None, model=None, keep_all=False, alpha=None, no_loo=False, plot=None,
              out=None, sigma=None, robot_sigma=None, effects=None, calibration=None, sensor_pose=None,
              no_clean=False, report=None):
    """Calibrate the sensor pose (and the sphere, the positioner) of a cell (``handeye calibrate``).

    {parameters}

    Returns
    -------
    handeye.app.present.results.CalibrationResult or handeye.app.present.score_results.ScoreResult
        ``to_dict()`` is ``handeye calibrate --json``; ``summary()`` its text report. With a
        sensor pose given (``calibration`` or ``sensor_pose``) and ``sensor`` among ``unknowns``,
        the pose is scored, not calibrated (:mod:`handeye.app.engine.score`): held, the sphere
        centre fitted with it when ``unknowns`` is ``sensor+sphere``, and judged against the
        data's own calibration (the same request): a :class:`ScoreResult`.

    Raises
    ------
    handeye.InputError
        Bad dataset, bad option, too few or degenerate poses, missing motions.
    """
    return _calibrated(options.COMMANDS["calibrate"].given(locals()))


def _calibrated(values, story=False):
    """:func:`calibrate` on its keywords ``values``; with ``story`` the discrepancy search's whole story
    kept on the result (its ``search``: what :func:`diagnose` tells)."""
    from handeye.app.engine.calibrate import run
    from handeye.app.engine.classic import calibrate_classic, judged
    from handeye.app.engine.command_request import CalibrateRequest
    from handeye.app.engine.request import CalibrationRequest
    from handeye.app.engine.score import run_score

    data = load_dataset(values["dataset"], clean=not values["no_clean"])
    asked = CalibrateRequest.from_options(values, data)
    asked = dataclasses.replace(asked, request=dataclasses.replace(asked.request, story=story))
    request, free = asked.request, asked.free
    method = values["method"]
    given, source = held_request.given_sensor(values["calibration"], values["sensor_pose"], request.convention, data,
                                              free.scored)
    if asked.closed_form:
        result = calibrate_classic(data, method, free.parts, outliers=request.outliers, alpha=request.alpha,
                                   convention=request.convention)
        own = CalibrationRequest(unknowns=free.parts, outliers=request.outliers, alpha=request.alpha, loo=False,
                                 sigma=request.sigma, robot_sigma=request.robot_sigma)
        result = judged(result, run(own.checked(data), data))
    else:
        request = asked.holding(given, data)
        result = run_score(request, data, given, source) if free.scored else run(request, data)
    return _written(result, data, asked.options, out=values["out"], plot=values["plot"], report=values["report"])


def _written(result, data, record, out=None, plot=None, report=None):
    """``result`` written where asked, and returned with every pose of the user's frame (the sensor's
    own frame where the profiles were turned: its attributes too, as its JSON)."""
    from handeye.app.common.files import provenance

    if data.own_axes is not None:  # profiles turned by dataset new: every pose out is of the sensor's own frame
        result = dataclasses.replace(result, own_axes=np.asarray(data.own_axes, float))
    if data.poses_read is not None and hasattr(result, "warnings"):  # an older setup.toml: how its poses were read
        result = dataclasses.replace(result, warnings=[*result.warnings, data.poses_read])
    if out is not None:
        result = dataclasses.replace(result, provenance=provenance(data, record))
        result.save(out)
    if plot is not None:
        from handeye.app.engine.cell_stage import dataset_at
        from handeye.app.present.report import calibration_plot

        calibration_plot(result, dataset_at(result, data), plot)
    if report is not None:
        from handeye.app.present.web.write import Page, write_report

        write_report(Page(result.to_dict(), data, result_json=result.to_json()), report, option="--report")
    return result.in_user_frame()  # its attributes too: every pose in the frame of the user's files


@options.COMMANDS["diagnose"].documented
def diagnose(dataset="thesis-real", *, alpha=ALPHA, figures=None, plot=None, sigma=None, out=None, unknowns="sensor",
             no_clean=False):
    """Find, name and add the effects the model is missing (``handeye diagnose``).

    {parameters}

    Returns
    -------
    handeye.app.present.diagnosis_results.DiagnosisResult
        Where its search chose the model :func:`calibrate` fits on the same data, its pose, 1-sd and
        effect values are calibrate's (:mod:`handeye.app.engine.agreement`; its steps and residuals the
        search's own fit); ``against_calibrate`` says how far the search's own fit lies, or why the two
        differ (effects named, other samples excluded).
    """
    from handeye.app.engine.command_request import diagnose_request

    values = options.COMMANDS["diagnose"].given(locals())
    data = load_dataset(dataset, clean=not no_clean)
    checked, parts, record = diagnose_request(values, data)
    result, data = _diagnosed(data, parts, checked["alpha"], sigma)
    if out is not None:
        from handeye.app.common.files import provenance

        result = dataclasses.replace(result, provenance=provenance(data, record))
        result.save(out)
    if figures is not None or plot is not None:
        _diagnosis_figures(result, figures, plot)
    return result


def _diagnosed(data, parts, level, sigma):
    """The diagnosis of ``data`` with ``parts`` free: calibrate's search told (its own where calibrate ran
    none), beside calibrate's own pose; and the data (with the centre a free centre's calibration found)."""
    from handeye.app.engine import agreement, slips
    from handeye.app.engine import diagnose as procedure
    from handeye.app.engine.prepare import gate, with_sphere_centre
    from handeye.app.engine.search import searched_samples

    data = with_sphere_centre(data, parts)[0]  # a start for a centre not given
    gate(data, parts)  # the checks calibrate runs: too few or degenerate poses are bad input
    slips.check(data, parts, slips.plain_rms(data, parts) or 0.0)  # a wrong side is not an "effect"
    asked = {**options.COMMANDS["calibrate"].defaults(), "dataset": data, "unknowns": parts, "no_loo": True,
             "alpha": level, "sigma": sigma}
    try:  # calibrate, its search's story kept (what diagnose tells); with the centre unknown, the centre's start
        own = _calibrated(asked, story=True)
    except InputError as exc:  # calibrate refuses what diagnose is for (a taught centre off, say)
        own = exc
    if parts == "sensor+sphere" and not isinstance(own, Exception) and np.all(np.isfinite(own.sphere_centre)):
        data = dataclasses.replace(data, sphere_centre=np.asarray(own.sphere_centre, float))
    searched = searched_samples(data)  # beyond ROW_CHUNK samples, that many spread over the rows: as calibrate's
    result = getattr(own, "search", None)  # calibrate's search, told; run here where calibrate ran none
    if result is None:
        result = procedure.diagnose(searched, alpha=level, sigma=sigma, centre_unknown=parts == "sensor+sphere")
    result = dataclasses.replace(result, unknowns=parts,
                                 own_axes=None if data.own_axes is None else np.asarray(data.own_axes, float))
    result = result.in_user_frame()  # calibrate's pose (own) is of the user's frame too
    return agreement.at_calibration(result, own, len(searched), len(data)), data


def _diagnosis_figures(result, figures, plot):
    """``residuals.png`` and ``gap.png`` into the folder ``figures``, the gap figure to ``plot``."""
    from handeye.app.present.report import diagnosis_figures

    if figures is not None:
        diagnosis_figures(result, figures)
    if plot is not None:
        from handeye.app.common.files import write_bytes_atomically

        with scratch.temporary_folder() as tmp:
            write_bytes_atomically(plot, diagnosis_figures(result, tmp)[1].read_bytes(), option="--plot")


@options.COMMANDS["compare"].documented
def compare(dataset, a, b, *, unknowns=None, model=None, alpha=None, sigma=None, robot_sigma=None, convention=None,
            keep_all=False):
    """Which of two calibrations fits a dataset better, and is the difference significant
    (``handeye compare DATASET A.json B.json``; :mod:`handeye.app.engine.score`).

    {parameters}

    Returns
    -------
    handeye.app.present.score_results.CompareResult
    """
    from handeye.app.engine import score
    from handeye.app.engine.command_request import compare_request

    values = options.COMMANDS["compare"].given(locals())
    data = load_dataset(dataset)
    request, level = compare_request(values, data)
    cals = [held_request.same_mount(held_request.given_calibration(_path_argument(given) if isinstance(given, str) else given,
                                                                   own_axes=data.own_axes), data, "compare") for given in (a, b)]
    poses = [np.asarray(cal.sensor2flange, float) for cal in cals]
    sources = [cal.source + ("" if cal.converged else " (converged: false in the file)") for cal in cals]
    if sources[0] == sources[1]:
        sources = [f"A ({sources[0]})", f"B ({sources[1]})"]
    result = score.compare(request, data, poses, sources, level)
    return result if data.own_axes is None else dataclasses.replace(result, scores=tuple(
        dataclasses.replace(s, own_axes=np.asarray(data.own_axes, float)) for s in result.scores))
