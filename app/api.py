"""The public Python API: ``import handeye``, then the CLI's commands as functions.

Each function takes the CLI's options as keyword arguments, with the same names and the same
defaults (``--keep-all`` is ``keep_all=False``, ``--max-iter`` is ``max_iter=None``), and
returns a typed result whose ``to_dict()`` is the command's ``--json`` object and whose
``summary()`` is its text report. The CLI (:mod:`handeye.app.cli`) only parses arguments,
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
import pathlib

import numpy as np

from handeye.app.arguments import (  # noqa: F401  (load_dataset and MAX_ITER: public names of the API too)
    MAX_ITER,
    _integer,
    _number,
    _path_argument,
    _pose_text,
    load_dataset,
)
from handeye.app.engine.robust import ALPHA
from handeye.app.errors import RequestError
from handeye.app.making import PlanResult, SimulationResult, plan, simulate  # noqa: F401  (the API's)


def _alpha(alpha):
    alpha = ALPHA if alpha is None else alpha
    if isinstance(alpha, bool) or not isinstance(alpha, (int, float)) or not 0 < alpha < 1:
        raise RequestError(f"--alpha must lie in (0, 1), got {alpha}")
    return float(alpha)


def start_pose_from(start, convention):
    """A start pose given as ``'X,Y,Z,...'`` text or numbers, in ``convention``, as KUKA (6,).

    Parameters
    ----------
    start : str or array_like
        The columns of ``convention`` (:func:`handeye.model.conventions.columns`): mm, then
        degrees (KUKA, FANUC), a quaternion w, x, y, z (ABB) or a rotation vector in radians
        (UR).
    convention : str
    """
    from handeye.app.engine.request import parse_pose

    return parse_pose(_pose_text(start, "--start"), "--start", convention=convention)


def _closed_form_options(method, start, rotation, max_iter, model, plot, no_loo):
    ignored = [name for name, given in (("--start", start), ("--rotation", rotation), ("--max-iter", max_iter),
                                        ("--model", model), ("--plot", plot), ("--no-loo", no_loo or None))
               if given is not None]
    if ignored:
        raise RequestError(f"--method {method} is closed form; these options do not apply to it: {', '.join(ignored)}")


def _held_sensor(calibration, data):
    """The sensor pose (KUKA) of a saved calibration, checked against the dataset's sensor mount."""
    if calibration is None:
        return None
    from handeye.app.outputs import saved
    from handeye.model.pose import pose_from_transform

    cal = saved.load(_path_argument(calibration))
    if not cal.converged:
        raise RequestError(f"--calibration: {calibration} did not converge; handeye will not hold its sensor pose "
                           "(calibrate again)")
    mount = getattr(cal, "sensor_mount", "flange")
    if mount != data.mounts.sensor:
        raise RequestError(f"--calibration: {calibration} is of a sensor mounted on the {mount}, the dataset's sensor "
                           f"is mounted on the {data.mounts.sensor} ([sensor] mount)")
    return pose_from_transform(cal.sensor2flange)


def calibrate(dataset="thesis-real", *, unknowns="sensor", method=None, rotation=None, start=None,
              convention=None, max_iter=None, model=None, keep_all=False, alpha=None, no_loo=False, plot=None,
              out=None, sigma=None, robot_sigma=None, effects=None, calibration=None, no_clean=False):
    """Calibrate the sensor pose (and the sphere, the positioner) of a cell (``handeye calibrate``).

    Parameters
    ----------
    dataset : str, pathlib.Path or Dataset
        Embedded name or folder (:func:`load_dataset`); default ``'thesis-real'``.
    unknowns : str
        The parts estimated, ``+``-joined: ``sensor`` (6 unknowns: the sensor frame in its mount's
        frame), ``sphere`` (3: the centre in its mount's frame), ``positioner`` (4 per axis); for
        example ``sensor``, ``sensor+sphere``, ``sphere+positioner``, ``sensor+sphere+positioner``
        (:mod:`handeye.app.engine.cell_stage`). A part not estimated comes from ``setup.toml``
        (``[sensor] pose``, ``[sphere] center``, ``[positioner] axes``) or ``calibration``.
    method : {'ipopt', 'gn', 'lm', 'tr', 'dogleg', 'newton', 'kim-cho', 'li-two-step'}, optional
        A least-squares solver, or a closed-form baseline (the last two). Default ``ipopt``,
        and ``lm`` above :data:`handeye.app.engine.request.LARGE` measurements (time and memory
        linear in the data; the result says so).
    rotation : {'matrix', 'local', 'euler'}, optional
        Rotation parametrisation; default ``matrix`` for IPOPT, ``local`` otherwise.
    start : str or array_like, optional
        Start sensor pose in ``convention`` (``'X,Y,Z,A,B,C'`` for KUKA: mm, degrees);
        default the setup's ``start_pose``, else the closed-form estimate.
    convention : {'kuka', 'abb', 'ur', 'fanuc'}, optional
        Robot convention of ``start`` and of the result's ``sensor_pose``; default the
        dataset's.
    max_iter : int, optional
        Iteration limit of the solver.
    model : {'centre', 'measurement', 'points'}, optional
        Residual; default ``measurement`` when every sample has a profile, else ``centre``.
    keep_all : bool
        Fit every sample: no outlier screening (a row whose centre columns contradict its own
        profile is still excluded, :mod:`handeye.model.consistency`).
    alpha : float, optional
        Family-wise level of the outlier tests (default 0.01).
    no_loo : bool
        Skip the leave-one-out error (one refit per sample).
    plot : str or pathlib.Path, optional
        Draw residuals and the sphere centres through the chain to this PNG.
    out : str or pathlib.Path, optional
        Also write the JSON result, with the dataset's hash, the tool's version and the
        options (``provenance``), atomically.
    sigma : float, optional
        Stated noise of a sphere centre through the chain, mm per component, that the
        ``centre`` residual is tested against; default the setup's ``[noise] centre_mm``
        (0.05). The ``measurement`` residual is tested against each circle fit's covariance
        (from its own points) plus ``robot_sigma`` instead.
    robot_sigma : float, optional
        Robot repeatability, mm per axis (weights of the profile models); default the setup's
        ``[noise] robot_mm`` (0.025).
    effects : str or sequence of str, optional
        Catalogue effects to calibrate with the sensor pose: ``sensor_scale``,
        ``sphere_radius``, ``sphere_center`` (``'a,b'`` or a list); as ``handeye diagnose``
        names them.
    calibration : str or pathlib.Path, optional
        A saved calibration (``calibrate --out``) whose sensor pose is held when ``unknowns``
        has no ``sensor`` (instead of ``[sensor] pose``).
    no_clean : bool
        Fit every profile point: no profile cleaning (:mod:`handeye.model.profile_clean`; by
        default speckle and background points off the sphere's arc are dropped, and the result's
        ``cleaning`` says how many of which profile). Applies when ``dataset`` is a name or folder.

    Returns
    -------
    handeye.app.present.results.CalibrationResult
        ``to_dict()`` is ``handeye calibrate --json``; ``summary()`` its text report.

    Raises
    ------
    handeye.InputError
        Bad dataset, bad option, too few or degenerate poses, missing motions.
    """
    from handeye.app.engine.calibrate import run
    from handeye.app.engine.classic import METHODS as CLOSED_FORM
    from handeye.app.engine.classic import calibrate_classic
    from handeye.app.engine.request import METHODS, UNKNOWNS, CalibrationRequest, unknown_parts
    from handeye.app.files import check_output_path, input_files, provenance
    from handeye.model import conventions

    options = {"dataset": str(dataset) if not hasattr(dataset, "path") else str(dataset.path),
               "unknowns": unknowns, "method": method, "rotation": rotation,
               "start": start if start is None or isinstance(start, str) else np.ravel(start).tolist(),
               "convention": convention, "max_iter": max_iter, "model": model, "keep_all": bool(keep_all),
               "alpha": alpha, "no_loo": bool(no_loo), "plot": None if plot is None else str(plot),
               "sigma": sigma, "robot_sigma": robot_sigma, "effects": effects,
               "calibration": None if calibration is None else str(calibration), "no_clean": bool(no_clean)}
    if method is not None and method not in METHODS + CLOSED_FORM:
        raise RequestError(f"--method: unknown {method!r}; choose one of {', '.join(METHODS + CLOSED_FORM)}")
    unknowns = unknown_parts(unknowns)
    if method in CLOSED_FORM and unknowns not in UNKNOWNS:
        raise RequestError(f"--method {method} is closed form: --unknowns {' or '.join(UNKNOWNS)}")
    data = load_dataset(dataset, clean=not no_clean)
    if calibration is not None and "sensor" in unknowns.split("+"):
        raise RequestError(f"--calibration holds the sensor pose: it does not apply with --unknowns {unknowns} (which "
                           "estimates it); leave out sensor, e.g. --unknowns sphere+positioner")
    held = _held_sensor(calibration, data)
    inputs = input_files(data) if out is not None or plot is not None else ()
    for path, option in ((out, "--out"), (plot, "--plot")):
        if path is not None:  # before the work (never half a result), and never over an input
            check_output_path(path, option, inputs=inputs, plot=option == "--plot")
    convention = conventions.check(convention or data.convention)
    level = _alpha(alpha)
    for value, option in ((sigma, "--sigma"), (robot_sigma, "--robot-sigma")):
        if value is not None:
            _number(value, option, 1e-6, 1e3)
    if effects is not None and not [n for n in str(effects if isinstance(effects, str) else ",".join(effects)).split(",")
                                    if n.strip()]:
        raise RequestError("--effects: give one or more effect names (sensor_scale, sphere_radius, sphere_center, "
                           "joint_offsets)")
    if method in CLOSED_FORM:
        _closed_form_options(method, start, rotation, max_iter, model, plot, no_loo)
        if effects:
            raise RequestError(f"--method {method} is closed form; --effects does not apply to it")
        result = calibrate_classic(data, method, unknowns, outliers=not keep_all, alpha=level, convention=convention)
    else:
        solver_options = {} if max_iter is None else {"max_iter": _integer(max_iter, "--max-iter", 1, MAX_ITER)}
        start_kuka = start_pose_from(start, convention) if start is not None else None
        request = CalibrationRequest(
            unknowns=unknowns, method=method, rotation=rotation, start=start_kuka, options=solver_options,
            outliers=not keep_all, alpha=level, loo=not no_loo, model=model, convention=convention, sigma=sigma,
            robot_sigma=robot_sigma, effects=effects or (), sensor_pose=held).checked(data)
        result = run(request, data)
    if out is not None:
        result = dataclasses.replace(result, provenance=provenance(data, options))
        result.save(out)
    if plot is not None:
        from handeye.app.engine.cell_stage import dataset_at
        from handeye.app.present.report import calibration_plot

        calibration_plot(result, dataset_at(result, data), plot)
    return result


def diagnose(dataset="thesis-real", *, alpha=ALPHA, figures=None, plot=None, sigma=None, out=None, no_clean=False):
    """Find, name and add the effects the model is missing (``handeye diagnose``).

    Parameters
    ----------
    dataset : str, pathlib.Path or Dataset
    alpha : float
        Family-wise level of the tests (default 0.01).
    figures : str or pathlib.Path, optional
        Folder to write ``residuals.png`` and ``gap.png`` into.
    plot : str or pathlib.Path, optional
        Write the gap-shrinking figure to this PNG.
    sigma : float, optional
        Nominal noise per residual component (mm) that chi2/dof is stated against; default the
        setup's ``[noise] centre_mm`` (0.05).
    out : str or pathlib.Path, optional
        Also write the JSON result with provenance, atomically.
    no_clean : bool
        Fit every profile point: no profile cleaning (as :func:`calibrate`).

    Returns
    -------
    handeye.app.present.diagnosis_results.DiagnosisResult
    """
    from handeye.app.engine import diagnose as procedure
    from handeye.app.files import check_output_folder, check_output_path, input_files, provenance
    from handeye.app.present.report import diagnosis_figures

    level = _alpha(alpha)
    if sigma is not None:
        _number(sigma, "--sigma", 1e-6, 1e3)
    data = load_dataset(dataset, clean=not no_clean)
    inputs = input_files(data) if (out, figures, plot) != (None, None, None) else ()
    if out is not None:
        check_output_path(out, "--out", inputs=inputs)
    if data.sphere_centre is None:
        raise RequestError(f"{data.path / 'setup.toml'}, column '[sphere] center': diagnose tests effects against a "
                           "known sphere centre; give it (`handeye calibrate DATASET --unknowns sensor+sphere` estimates one "
                           "to write there)")
    if figures is not None:
        check_output_folder(figures, "--figures")
        if pathlib.Path(figures).is_dir():  # the two files it will write: never over an input
            for name in ("residuals.png", "gap.png"):
                check_output_path(pathlib.Path(figures) / name, "--figures", inputs=inputs)
    if plot is not None:
        check_output_path(plot, "--plot", inputs=inputs, plot=True)
    from handeye.app.engine import slips
    from handeye.app.engine.prepare import gate

    gate(data, "sensor")  # the checks calibrate runs: too few or degenerate poses are bad input
    slips.check(data, "sensor", slips.plain_rms(data, "sensor") or 0.0)  # a wrong side is not an "effect"
    result = procedure.diagnose(data, alpha=level, sigma=sigma)
    if out is not None:
        options = {"dataset": str(dataset) if not hasattr(dataset, "path") else str(dataset.path), "alpha": alpha,
                   "sigma": sigma, "figures": None if figures is None else str(figures),
                   "plot": None if plot is None else str(plot), "no_clean": bool(no_clean)}
        result = dataclasses.replace(result, provenance=provenance(data, options))
        result.save(out)
    if figures is not None:
        diagnosis_figures(result, figures)
    if plot is not None:
        from handeye.app.files import write_bytes_atomically
        from handeye.model import scratch

        with scratch.temporary_folder() as tmp:
            write_bytes_atomically(plot, diagnosis_figures(result, tmp)[1].read_bytes(), option="--plot")
    return result
