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

from handeye.app.engine.robust import ALPHA
from handeye.app.errors import RequestError
from handeye.app.present.protocol import ResultProtocol


def load_dataset(name_or_folder):
    """Read and check a dataset.

    Parameters
    ----------
    name_or_folder : str, pathlib.Path or Dataset
        An embedded dataset (``'thesis-real'``, ``'thesis-sim'``; see
        :func:`handeye.model.dataset.embedded_names`) or a folder holding ``measurements.csv``
        and ``setup.toml``. A Dataset is returned as it is.

    Returns
    -------
    handeye.model.dataset.Dataset

    Raises
    ------
    handeye.InputError
        A :class:`handeye.model.dataset.DatasetError` naming file, row and column of the first
        problem found.
    """
    import os

    from handeye.model.dataset import Dataset, load

    if isinstance(name_or_folder, Dataset):
        return name_or_folder
    if not isinstance(name_or_folder, (str, os.PathLike)):
        raise RequestError(f"dataset: give an embedded dataset's name or a folder, got {name_or_folder!r}")
    return load(name_or_folder)


def _path_argument(value):
    import os

    if not isinstance(value, (str, os.PathLike)):
        raise RequestError(f"dataset: give an embedded dataset's name or a folder, got {value!r}")
    return value


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


def _pose_text(pose, option):
    """A pose given as text or numbers, as text (numbers that are not numbers are bad input)."""
    if isinstance(pose, str):
        return pose
    try:
        return ",".join(repr(float(v)) for v in np.ravel(np.asarray(pose, dtype=object)))
    except (TypeError, ValueError):
        raise RequestError(f"{option}: needs numbers, got {pose!r}") from None


def _number(value, option, low, high, low_open=False):
    ok = not isinstance(value, bool) and isinstance(value, (int, float, np.floating)) and np.isfinite(value)
    if not ok or value > high or value < low or (low_open and value == low):
        raise RequestError(f"{option} must lie in {'(' if low_open else '['}{low:g}, {high:g}], got {value!r}")
    return float(value)


#: Largest iteration limit accepted (a C int, IPOPT's, must hold it; no calibration needs more).
MAX_ITER = 1_000_000


def _integer(value, option, low, high=None):
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low or (
            high is not None and value > high):
        bound = f"at least {low}" if high is None else f"at least {low} and at most {high}"
        raise RequestError(f"{option} must be an integer {bound}, got {value!r}")
    return int(value)


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
    mount = getattr(cal, "sensor_mount", "flange")
    if mount != data.mounts.sensor:
        raise RequestError(f"--calibration: {calibration} is of a sensor mounted on the {mount}, the dataset's sensor "
                           f"is mounted on the {data.mounts.sensor} ([sensor] mount)")
    return pose_from_transform(cal.sensor2flange)


def calibrate(dataset="thesis-real", *, unknowns="sensor", method=None, rotation=None, start=None,
              convention=None, max_iter=None, model=None, keep_all=False, alpha=None, no_loo=False, plot=None,
              out=None, sigma=None, robot_sigma=None, effects=None, calibration=None):
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
               "calibration": None if calibration is None else str(calibration)}
    if method is not None and method not in METHODS + CLOSED_FORM:
        raise RequestError(f"--method: unknown {method!r}; choose one of {', '.join(METHODS + CLOSED_FORM)}")
    unknowns = unknown_parts(unknowns)
    if method in CLOSED_FORM and unknowns not in UNKNOWNS:
        raise RequestError(f"--method {method} is closed form: --unknowns {' or '.join(UNKNOWNS)}")
    data = load_dataset(dataset)
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
        raise RequestError("--effects: give one or more effect names (sensor_scale, sphere_radius, sphere_center)")
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


def diagnose(dataset="thesis-real", *, alpha=ALPHA, figures=None, plot=None, sigma=None, out=None):
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
    data = load_dataset(dataset)
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
                   "plot": None if plot is None else str(plot)}
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


@dataclasses.dataclass(frozen=True)
class SimulationResult(ResultProtocol):
    """A simulated dataset written by :func:`simulate`.

    Attributes
    ----------
    path : pathlib.Path
        The dataset folder.
    ids : list of str
        Measurements written.
    dropped : list of (str, str)
        Poses that could not see the sphere, with the reason.
    seed : int
    effects : dict
        Hidden effects (name -> value).
    """

    caption = 'handeye simulate'

    path: pathlib.Path
    ids: list
    dropped: list
    seed: int
    effects: dict

    @property
    def dataset(self):
        """The written dataset, loaded (:func:`load_dataset`)."""
        return load_dataset(self.path)

    def to_dict(self):
        return {"path": str(self.path), "ids": list(self.ids), "dropped": [list(d) for d in self.dropped],
                "seed": self.seed, "effects": {k: np.asarray(v).tolist() for k, v in self.effects.items()}}

    def summary(self):
        lines = [f"wrote {len(self.ids)} simulated measurements to {self.path} (seed {self.seed}, "
                 f"effects {self.effects or 'none'})"]
        lines += [f"dropped {ident}: {reason}" for ident, reason in self.dropped]
        return "\n".join(lines)


def simulate(out, *, seed=0, effect=(), profiles=False, poses=None, n_poses=36, linearity=0.0, motions="thesis",
             translations=0, truth=None, diameter=None, center=None, convention="kuka", max_tilt=90.0,
             no_start=False, sensor_mount="flange", sphere_mount="world", positioner_axes=None, positioner_error=None):
    """Write a simulated dataset with known truth (``handeye simulate``; :mod:`handeye.model.simulate`).

    Parameters
    ----------
    out : str or pathlib.Path
        Dataset folder to write (must be new or empty).
    seed : int
    effect : str or sequence of str
        Hidden effects ``'NAME=VALUE'``: ``sphere_center=dx,dy,dz``, ``sensor_scale=s``,
        ``sphere_radius=dr``, ``sign_flip=ID,ID``, ``outlier=ID,ID``.
    profiles : bool
        Also write the laser profiles.
    poses : str or pathlib.Path, optional
        A pose list (header ``id,x,y,z,a,b,c``, KUKA; on a positioner followed by its axis columns,
        degrees) instead of the thesis strategy.
    n_poses : int
        Poses of the thesis strategy (1-36).
    linearity : float
        Sensor linearity error as a fraction of the 100 mm range, in [0, 0.1).
    motions : {'thesis', 'about-sphere'}
    translations : int
        Pure flange translations (0-6) at each of two orientations.
    truth : str or array_like, optional
        True sensor pose in its mount's frame, in ``convention`` (KUKA: mm, degrees); default the
        thesis's (190, 100, 125, 180, -88, 0) in KUKA terms on the flange,
        :data:`handeye.model.simulate_mounts.WORLD_SENSOR` in the cell.
    diameter : float, optional
        Sphere diameter, mm; default the thesis's certified 59.94507.
    center : str or array_like, optional
        Sphere centre in its mount's frame, mm (``'X,Y,Z'`` or three numbers); default the
        thesis's in the base, :mod:`handeye.model.simulate_mounts`' on the flange or the table.
    convention : {'kuka', 'abb', 'ur', 'fanuc'}
        Robot convention of the written dataset (poses, start pose, truth) and of ``truth``.
    max_tilt : float
        Largest tilt of the sensor from looking straight down, degrees (the thesis: 90).
    no_start : bool
        Write no ``start_pose``: a calibration then starts from the closed-form estimate.
    sensor_mount, sphere_mount : str
        ``flange``/``world`` (the seed's cell), ``world``/``flange`` or ``flange``/``positioner``
        (:mod:`handeye.model.simulate_mounts`).
    positioner_axes : str, optional
        Nominal axes ``'NAME:px,py,pz:dx,dy,dz;...'`` (robot base at zero angles, mm), base first;
        default a KUKA KP1-V-like two-axis positioner.
    positioner_error : str or sequence of two floats, optional
        ``'MM,DEG'``: how far the true axes differ from the nominal ones (default 1.0, 0.2).

    Returns
    -------
    SimulationResult
    """
    from handeye.app.engine.request import parse_pose
    from handeye.model import conventions
    from handeye.model import motions as motion_strategies
    from handeye.model import simulate as sim
    from handeye.model.dataset import read_pose_list
    from handeye.model.pose import pose_from_transform

    conventions.check(convention)
    from handeye.app.files import check_output_folder

    folder = check_output_folder(out, "--out", empty=True)
    if isinstance(linearity, bool) or not isinstance(linearity, (int, float)) or not 0 <= linearity < 0.1:
        raise RequestError(f"--linearity must lie in [0, 0.1), got {linearity}")
    seed = _integer(seed, "--seed", 0)
    n_poses = _integer(n_poses, "--n-poses", 1)
    translations = _integer(translations, "--translations", 0)
    setup = sim.Setup(linearity=linearity, max_tilt_deg=_number(max_tilt, "--max-tilt", 0.0, 90.0, low_open=True))
    cell, setup = _simulated_cell(setup, seed, sensor_mount, sphere_mount, positioner_axes, positioner_error)
    if truth is not None:
        pose = parse_pose(_pose_text(truth, "--truth"), "--truth", convention=convention)
        setup = dataclasses.replace(setup, sensor_pose=tuple(pose))
    if diameter is not None:
        setup = dataclasses.replace(setup, diameter=_number(diameter, "--diameter", 0.0, 10_000.0, low_open=True))
    if center is not None:
        setup = dataclasses.replace(setup, sphere_centre=tuple(_floats(center, "--center", 3)))
    effects = sim.parse_effects([effect] if isinstance(effect, str) else list(effect))
    ids, flange_poses, angles = None, None, None
    if poses is not None:
        if motions != "thesis" or translations:
            raise RequestError("--poses gives the poses: --motions and --translations do not apply")
        ids, flange_poses, *angles = read_pose_list(poses, axes=cell.axis_names)
        angles = angles[0] if angles else None
    elif motions != "thesis" or translations:
        if not cell.default:
            raise RequestError("--motions and --translations apply to the sensor on the flange, sphere in the world")
        ids, flanges = motion_strategies.strategy(setup, np.random.default_rng(seed), motions, n_poses, translations)
        flange_poses = pose_from_transform(flanges)
    made = sim.simulate(setup, seed=seed, effects=effects, flange_poses=flange_poses, n_poses=n_poses, ids=ids,
                        cell=cell, axis_angles=angles)
    from handeye.app.files import write_folder_atomically

    write_folder_atomically(folder, lambda tmp: sim.write(made, tmp, profiles=profiles, convention=convention,
                                                         **({"start_offset": None} if no_start else {})))
    return SimulationResult(folder, list(made.ids), list(made.dropped), seed, effects)


def _simulated_cell(setup, seed, sensor_mount, sphere_mount, positioner_axes, positioner_error):
    """The simulated cell (:class:`handeye.model.simulate_mounts.Cell`) and the setup with this
    mount's default truth."""
    from handeye.model import simulate_mounts as sm

    sm.check_pair(sensor_mount, sphere_mount)
    if positioner_error is not None and sphere_mount != "positioner":
        raise RequestError("--positioner-error needs --sphere-mount positioner")
    axes = None if positioner_axes is None else sm.parse_axes(positioner_axes)
    error = sm.POSITIONER_ERROR if positioner_error is None else _floats(positioner_error, "--positioner-error", 2)
    cell = sm.make_cell(sensor_mount, sphere_mount, axes, error, seed)
    pose, centre = sm.default_truth(cell)
    if pose is not None:
        setup = dataclasses.replace(setup, sensor_pose=pose)
    if centre is not None:
        setup = dataclasses.replace(setup, sphere_centre=centre)
    return cell, setup


@dataclasses.dataclass(frozen=True)
class PlanResult(ResultProtocol):
    """Poses chosen (or scored) by :func:`plan`, with their predicted accuracy.

    Attributes
    ----------
    n : int
    ids : list of str
    poses : ndarray, shape (n, 6)
        Flange poses in the robot base, KUKA (mm, degrees).
    logdet : float
        log det of the information matrix (the D-optimality criterion).
    predicted_sd : ndarray, shape (6,)
        Cramer-Rao bound: translation (mm), rotation (degrees).
    skipped : list of (str, str)
        Candidates that cannot see the sphere (or lie outside the workspace), with the reason.
    usable : int
        Candidates that can.
    convention : str
        Robot convention of :meth:`pose_list` and of ``poses_as`` in :meth:`to_dict`.
    scored : bool
        True when the poses were given (``--score``), not chosen.
    margin : tuple of float
        (mm, deg) the nominal sensor pose may be off while every pose still sees the sphere.
    axis_names : tuple of str
        The positioner's axes (sphere on a positioner), else empty.
    axis_angles : ndarray, shape (n, k), or None
        Their angles at each pose, degrees (columns of :meth:`pose_list` after the pose's).
    mounts : tuple of str
        (sensor mount, sphere mount) of the planned cell.
    """

    caption = 'handeye plan'

    n: int
    ids: list
    poses: np.ndarray
    logdet: float
    predicted_sd: np.ndarray
    skipped: list
    usable: int
    convention: str = "kuka"
    scored: bool = False
    margin: tuple = (0.0, 0.0)
    warnings: tuple = ()
    axis_names: tuple = ()
    axis_angles: np.ndarray | None = None
    mounts: tuple = ("flange", "world")

    def poses_in_convention(self):
        from handeye.model import conventions

        return self.poses if self.convention == "kuka" else conventions.convert(self.poses, "kuka", self.convention)

    def to_dict(self):
        """The ``handeye plan --json`` object."""
        from handeye.model import conventions

        return {"n": self.n, "ids": list(self.ids), "poses": np.asarray(self.poses).tolist(), "logdet": self.logdet,
                "predicted_sd": {"sensor_translation_mm": np.asarray(self.predicted_sd[:3]).tolist(),
                                 "sensor_rotation_deg": np.asarray(self.predicted_sd[3:6]).tolist()},
                "skipped": [{"id": i, "reason": r} for i, r in self.skipped],
                "noise_model": "simulator defaults: robot 0.025 mm, profile points 0.01 mm (model.simulate)",
                "poses_as": {"convention": self.convention, "columns": list(conventions.columns(self.convention)),
                             "poses": np.asarray(self.poses_in_convention()).tolist()},
                "scored": self.scored, "margin": list(self.margin), "warnings": list(self.warnings)} | (
            {} if self.mounts == ("flange", "world") else
            {"sensor_mount": self.mounts[0], "sphere_mount": self.mounts[1], "axis_names": list(self.axis_names),
             "axis_angles": None if self.axis_angles is None else np.asarray(self.axis_angles).tolist()})

    def pose_list(self):
        """The poses as a pose-list CSV in :attr:`convention`, ready for the robot."""
        from handeye.model.dataset import pose_list_text

        return pose_list_text(self.ids, self.poses, self.convention, self.axis_names, self.axis_angles)

    def summary(self):
        from handeye.model import conventions

        if self.scored:
            head = f"scored {self.n} given poses (log det {self.logdet:.2f})"
        else:
            head = f"chose {self.n} of {self.usable} usable candidate poses (D-optimal, log det {self.logdet:.2f})"
        if any(self.margin):
            head += f"; each still sees the sphere with the sensor off by {self.margin[0]:g} mm / {self.margin[1]:g} deg"
        lines = [head,
                 "predicted sd (Cramer-Rao bound): translation mm " + " ".join(f"{v:.4f}" for v in self.predicted_sd[:3])
                 + "; rotation deg " + " ".join(f"{v:.4f}" for v in self.predicted_sd[3:6]),
                 f"poses ({self.convention}: {','.join(conventions.columns(self.convention) + self.axis_names)}):"]
        angles = self.axis_angles if self.axis_names else [()] * len(self.ids)
        lines += [f"  {i:>14} " + " ".join(f"{v:10.4f}" for v in (*p, *a))
                  for i, p, a in zip(self.ids, self.poses_in_convention(), angles)]
        lines += [f"  skipped {i}: {r}" for i, r in self.skipped]
        lines += [f"warning: {w}" for w in self.warnings]
        return "\n".join(lines)


def _floats(text, option, count):
    values = _pose_text(text, option).split(",")
    try:
        out = [float(v) for v in values]
    except ValueError:
        raise RequestError(f"{option}: not a number in {text!r}") from None
    if len(out) != count or not np.all(np.isfinite(out)):
        raise RequestError(f"{option} needs {count} finite numbers, got {text!r}")
    return out


def plan(*, n=12, candidates=None, dataset=None, out=None, max_tilt=90.0, margin=None, workspace=None, score=None,
         sensor_mount="flange", sphere_mount="world"):
    """Choose the ``n`` most informative poses, D-optimal (``handeye plan``), or score a given list.

    Parameters
    ----------
    n : int
        Number of poses to choose.
    candidates : str or pathlib.Path, optional
        Candidate flange poses (a pose list in any convention, told by its header); default
        the thesis strategy's 36 orientations x three cuts scaled to the sphere (108 poses).
    dataset : str, pathlib.Path or Dataset, optional
        Take the nominal sensor pose (``start_pose``), sphere centre, diameter, laser side and
        robot convention from it (only its ``setup.toml`` is read: a cell can be planned before
        it is measured); default the thesis's cell.
    out : str or pathlib.Path, optional
        Write the chosen poses as a pose list in the dataset's convention.
    max_tilt : float
        Largest tilt of the sensor from straight down of the default candidates, degrees.
    margin : str or sequence of two floats, optional
        ``'MM,DEG'``: the nominal sensor pose may be off by this much; every candidate keeps
        the sphere inside the laser line and the measuring range even then.
    workspace : str or sequence of six floats, optional
        ``'XMIN,XMAX,YMIN,YMAX,ZMIN,ZMAX'``: allowed flange positions (robot base, mm).
    score : str or pathlib.Path, optional
        A pose list to score (predicted accuracy) instead of choosing.
    sensor_mount, sphere_mount : str
        The cell without ``dataset`` (with it, its ``setup.toml``'s mounts): ``flange``/``world``
        (the thesis's cell), ``world``/``flange`` or ``flange``/``positioner``, with ``handeye
        simulate``'s nominal cell (:mod:`handeye.model.simulate_mounts`). On a positioner the pose
        lists (``candidates``, ``score``, ``out``) carry one column per axis after the pose's
        (degrees), and each default candidate has its own axis angles.

    Returns
    -------
    PlanResult
    """
    from handeye.app.files import check_output_path, write_text_atomically
    from handeye.model import planning
    from handeye.model import simulate as sim
    from handeye.model.dataset import read_pose_list

    n = _integer(n, "--n", 1)

    margin = (0.0, 0.0) if margin is None else tuple(_floats(margin, "--margin", 2))
    if min(margin) < 0:
        raise RequestError(f"--margin must not be negative, got {margin}")
    setup = sim.Setup(linearity=0.0, max_tilt_deg=_number(max_tilt, "--max-tilt", 0.0, 90.0, low_open=True))
    if dataset is not None and (sensor_mount, sphere_mount) != ("flange", "world"):
        raise RequestError("--dataset gives the mounts (its setup.toml): --sensor-mount and --sphere-mount do not apply")
    cell, setup = _simulated_cell(setup, 0, sensor_mount, sphere_mount, None,
                                  (0.0, 0.0) if sphere_mount == "positioner" else None)
    mounts = cell.mounts
    centre, convention = np.asarray(setup.sphere_centre), "kuka"
    if dataset is not None:
        from handeye.model.dataset import Dataset, load_setup

        d = dataset if isinstance(dataset, Dataset) else load_setup(_path_argument(dataset))
        if d.start_pose is None or d.sphere_centre is None:
            raise RequestError(f"--dataset {dataset}: its setup.toml needs a start_pose (the nominal sensor pose) and "
                               "a sphere center to plan around")
        setup = dataclasses.replace(setup, sensor_pose=tuple(d.start_pose), diameter=d.sphere_diameter, side=d.side)
        centre, convention, mounts = d.sphere_centre, d.convention, d.mounts
    if out is not None:  # before the work, and never over a file this command reads or of the dataset
        inputs = [p for p in (candidates, score) if p is not None]
        if dataset is not None:
            inputs += [f for f in pathlib.Path(d.path).rglob("*") if f.is_file()]
        check_output_path(out, "--out", inputs=inputs)
    cell_keys = {"axis_names": mounts.axis_names, "mounts": (mounts.sensor, mounts.sphere)}
    if score is not None:
        ids, poses, *angles = read_pose_list(score, axes=mounts.axis_names)
        angles = angles[0] if angles else None
        sd, value = planning.score(poses, setup, centre, mounts, angles)
        return PlanResult(len(ids), list(ids), np.asarray(poses), value, sd, [], len(ids), convention, True, margin,
                          tuple(planning.few_angles(angles, mounts.axis_names)), axis_angles=angles, **cell_keys)
    warnings, angles = [], None
    if candidates is not None:
        ids, poses, *angles = read_pose_list(candidates, axes=mounts.axis_names)
        angles = angles[0] if angles else None
    elif not mounts.default:
        ids, poses, angles = planning.cell_candidates(setup, mounts, centre, margin_mm=margin[0], margin_deg=margin[1])
    else:
        ids, poses = planning.thesis_candidates(setup, centre, margin_mm=margin[0], margin_deg=margin[1])
    if candidates is None:
        cuts, radius = planning.view_window(setup, *margin)["cuts"], setup.diameter / 2
        if np.ptp(cuts) < 0.2 * radius:
            warnings.append(
                f"the margin leaves the laser plane cutting the sphere only {cuts.min():.1f}-{cuts.max():.1f} mm from its "
                f"centre (R = {radius:g} mm): with one cut depth a wrong [profile] side and a sensor offset along y are "
                "hard to tell apart, and a scale error of the sensor hard to see; a smaller --margin spreads the cuts")
    skipped = []
    if workspace is not None:
        inside = planning.in_workspace(poses, _floats(workspace, "--workspace", 6))
        skipped = [(i, "flange position outside --workspace") for i, k in zip(ids, inside) if not k]
        ids, poses = [i for i, k in zip(ids, inside) if k], np.asarray(poses)[inside]
        angles = None if angles is None else angles[inside]
    if not ids:
        raise RequestError("no candidate pose is left to plan with (--workspace excludes them all)")
    chosen = planning.plan(ids, poses, n, setup, centre, mounts, angles)
    warnings += planning.few_angles(chosen.angles, mounts.axis_names)
    result = PlanResult(n, list(chosen.ids), np.asarray(chosen.poses), float(chosen.logdet),
                        np.asarray(chosen.predicted_sd), skipped + list(chosen.skipped),
                        len(ids) - len(chosen.skipped), convention, False, margin, tuple(warnings),
                        axis_angles=chosen.angles, **cell_keys)
    if out is not None:
        write_text_atomically(out, result.pose_list(), option="--out")
    return result
