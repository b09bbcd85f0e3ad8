"""A calibration request: every option checked once, before any work, into a frozen record.

:func:`handeye.calibrate` (the CLI's keywords) and the engine
:func:`handeye.app.engine.calibrate.calibrate` (checked values) both build a
:class:`CalibrationRequest`; :meth:`CalibrationRequest.checked` validates it against the
dataset once and resolves every default (method, rotation, residual model, noise levels,
convention), so that no later stage validates or defaults an option again.
"""
from __future__ import annotations

import copy
import dataclasses

import numpy as np

from handeye import solvers
from handeye.app.common.choices import CLASSIC_METHODS, METHODS
from handeye.app.common.errors import CalibrationInputError
from handeye.model.chain import conventions
from handeye.model.chain.names import PARTS, ROTATIONS, UNKNOWNS
from handeye.model.readers.tables import GUESS_LIMITS, LIMIT_POSITION_MM

# METHODS (and UNKNOWNS) are defined without numpy, for the command line's choices

#: Which rotation parametrisations each method can use.
SUPPORTED = {"ipopt": ("matrix", "euler"), **dict.fromkeys(("gn", "lm", "tr", "dogleg", "newton"), ("local", "euler"))}
#: Parametrisation used when none is asked for.
DEFAULT_ROTATION = {"ipopt": "matrix"}

#: Above this many measurements the default method is Levenberg-Marquardt on the local chart
#: (numpy, time and memory linear in the data) instead of IPOPT (whose problem graph costs far
#: more per measurement); leave-one-out uses the deletion formula above robust.LOO_EXACT_UP_TO samples but for
#: the centre model with the centre known (in closed form at any size).
LARGE = 5000

#: Catalogue effects that ``--effects`` can calibrate (continuous, identifiable from the poses).
EFFECTS = ("sensor_scale", "centre_scale", "sphere_radius", "sphere_center", "joint_offsets", "link_lengths", "joint_compliance")
#: The effects the cell stage fits with the parts (:func:`handeye.app.engine.cell_stage.fit`): the data effects.
DATA_EFFECTS = ("sensor_scale", "sphere_radius", "centre_scale")


def fingerprint(dataset):
    """Which dataset a request was checked against: its folder and number of measurements."""
    return f"{dataset.path} ({len(dataset)} measurements)"


def min_measurements(unknowns, n_axes=2):
    """Fewest measurements with more equations (3 each) than unknowns (sensor 6, sphere 3,
    positioner 4 per axis)."""
    parts = unknowns.split("+")
    n = 6 * ("sensor" in parts) + 3 * ("sphere" in parts) + 4 * n_axes * ("positioner" in parts)
    return n // 3 + 1


def unknown_parts(text):
    """``--unknowns`` as its canonical ``+``-joined parts (``'sphere+sensor'`` -> ``'sensor+sphere'``)."""
    names = [p.strip() for p in str(text).split("+")]
    bad = [p for p in names if p not in PARTS]
    if bad or not names or len(set(names)) != len(names):
        raise CalibrationInputError(f"--unknowns: {text!r} is not a +-joined set of {', '.join(PARTS)} "
                                    "(for example sensor+sphere, sphere+positioner, sensor+sphere+positioner)")
    return "+".join(p for p in PARTS if p in names)


def effect_names(effects):
    """``--effects`` (``'a,b'`` or a sequence) as its names, each checked against :data:`EFFECTS`;
    ``'none'``: no effect, chosen; given but naming none is bad input (None and ``()``: no effects)."""
    names = [effects] if isinstance(effects, str) else list(effects or ())
    names = [n.strip() for name in names for n in str(name).split(",") if n.strip()]
    if names == ["none"]:
        return ()  # the model as asked, with no effect (the search checks it, :mod:`handeye.app.engine.search`)
    if not names and effects is not None and effects != ():
        raise CalibrationInputError("--effects: give one or more effect names (sensor_scale, sphere_radius, "
                                    "sphere_center, joint_offsets)")
    for name in names:
        if name not in EFFECTS:
            raise CalibrationInputError(f"--effects: unknown {name!r}; calibrate can add {', '.join(EFFECTS)} "
                                        "(handeye diagnose names the effect a dataset needs)")
    return tuple(names)


@dataclasses.dataclass(frozen=True)
class Free:
    """What a calibration estimates and what it holds: ``--unknowns``, ``--effects`` and a given
    sensor pose (``--calibration``, ``--sensor-pose``) as one record.

    Attributes
    ----------
    parts : str
        The parts estimated, canonical and ``+``-joined (:func:`unknown_parts`).
    effects : tuple of str
        The catalogue effects estimated with them (:func:`effect_names`).
    given : str or None
        The option that gives a sensor pose (``'--calibration'`` or ``'--sensor-pose'``), else None.
    chosen : bool
        ``--effects`` was given (``none`` for no effect): the user chose the model, which the
        search checks instead of choosing (:mod:`handeye.app.engine.search`).
    """

    parts: str = "sensor"
    effects: tuple = ()
    given: str | None = None
    chosen: bool = False

    @classmethod
    def from_options(cls, unknowns="sensor", effects=None, calibration=None, sensor_pose=None):
        """The record of the options as given; raises CalibrationInputError naming the option."""
        if calibration is not None and sensor_pose is not None:
            raise CalibrationInputError("give --calibration or --sensor-pose, not both")
        given = "--calibration" if calibration is not None else "--sensor-pose" if sensor_pose is not None else None
        return cls(unknown_parts(unknowns), effect_names(effects), given, effects not in (None, ()))

    @property
    def scored(self):
        """A given sensor pose scored, not calibrated (the sensor among the parts)."""
        return self.given is not None and "sensor" in self.parts.split("+")


def _conditional(parts, dataset, sensor_pose, effects):
    """The unknowns of the conditional stages for ``parts`` (checked against the dataset's cell)."""
    if parts in UNKNOWNS:
        return parts
    setup = dataset.path / "setup.toml"
    if "positioner" in parts and dataset.mounts.sphere != "positioner":
        raise CalibrationInputError(f"--unknowns {parts}: {setup} has no positioner ([sphere] mount = "
                                    "\"positioner\" with [positioner] axes)")
    if "sensor" not in parts and sensor_pose is None and dataset.sensor_pose is None:
        raise CalibrationInputError(f"--unknowns {parts} holds the sensor: give its pose as [sensor] pose in {setup} "
                                    "or --calibration FILE (an earlier calibrate --out)")
    if "sphere" not in parts and dataset.sphere_centre is None:
        raise CalibrationInputError(f"--unknowns {parts} holds the sphere: give [sphere] center in {setup}")
    other = [n for n in effects if n not in DATA_EFFECTS]
    if other:
        raise CalibrationInputError(
            f"--effects {','.join(other)} with --unknowns {parts}: the cell stage fits the data effects "
            f"({', '.join(DATA_EFFECTS)}) with the parts" + (" (sphere_center: add sphere to --unknowns)"
                                                              if "sphere_center" in other else ""))
    return "sensor+sphere" if "sphere" in parts or "sensor" not in parts else "sensor"


@dataclasses.dataclass(frozen=True)
class CalibrationRequest:
    """What to calibrate and how: the engine's options (checked values, not CLI text).

    Attributes
    ----------
    unknowns : {'sensor', 'sensor+sphere'}
    method : {'ipopt', 'gn', 'lm', 'tr', 'dogleg', 'newton'} or None
        None: ``ipopt``, or ``lm`` above :data:`LARGE` measurements (said in ``notes``).
    rotation : {'matrix', 'local', 'euler'} or None
        None: ``matrix`` for IPOPT, ``local`` otherwise.
    start : array_like, shape (6,), optional
        Start sensor pose (KUKA: mm, degrees); None: the setup's, else the closed form.
    options : mapping, optional
        Solver options (:class:`handeye.solvers.Options`), held read-only.
    outliers : bool
        Screen and exclude gross errors (:mod:`handeye.app.engine.robust`).
    alpha : float
        Family-wise level of the outlier tests.
    loo : bool
        Leave-one-out prediction errors (one exact refit per sample).
    model : {'centre', 'measurement', 'points'} or None
        Residual of the final fit; None: ``measurement`` when every sample has a profile.
    robot_sigma, sigma : float, optional
        Robot repeatability and stated centre noise (mm, 1 sd per axis); None: the setup's.
    convention : str, optional
        Convention of the reported pose; None: the dataset's.
    effects : sequence of str
        Catalogue effects (:data:`EFFECTS`) calibrated with the pose (``'a,b'`` or a list).
    chosen : bool or None
        Whether the model (``effects``, none included) is the user's choice, which the
        discrepancy search then checks instead of choosing (:mod:`handeye.app.engine.search`);
        None: chosen when ``effects`` is given (``'none'`` included) or ``model`` is a profile model.
    story : bool
        Keep the discrepancy search's whole story (``handeye diagnose``'s figures: each step's held-out
        RMS, the effects absorbed) on the result (its ``search``): diagnose is calibrate's search told.
    notes : tuple of str
        What :meth:`checked` decided that the user should read (a default method changed).
    sigma_stated : bool or None
        Whether the user stated the centre noise (``sigma`` given); set by :meth:`checked` from the
        request as first asked (None until then) and kept through the search's refits, whose ``sigma``
        is the resolved one.
    resolved : str or None
        Set by :meth:`checked` (not a constructor argument): which dataset (folder and number
        of measurements) it was checked against, every option valid and every default resolved;
        :func:`run <handeye.app.engine.calibrate.run>` refuses a request checked against other
        data (its defaults, the stated noise and the convention, are that dataset's).
    """

    unknowns: str = "sensor"
    method: str | None = None
    rotation: str | None = None
    start: object = None
    options: object = None
    outliers: bool = True
    alpha: float = 0.01
    loo: bool = True
    model: str | None = None
    robot_sigma: float | None = None
    convention: str | None = None
    sigma: float | None = None
    effects: tuple = ()
    chosen: bool | None = None
    story: bool = False
    notes: tuple = ()
    sensor_pose: object = None
    sigma_stated: bool | None = None
    resolved: str | None = dataclasses.field(default=None, init=False)
    parts: str | None = dataclasses.field(default=None, init=False)

    @property
    def solver_options(self):
        """A fresh dict of the solver options (the request itself stays unchanged)."""
        return copy.deepcopy(dict(self.options or {}))

    @property
    def polish(self):
        """Whether a solver that stops early may be polished: not when the user set an
        iteration limit (a limit is respected, not polished past)."""
        return not _limits_iterations(self.options or {})

    def checked(self, dataset):
        """This request validated against ``dataset``, every default resolved.

        Raises
        ------
        CalibrationInputError
            The option at fault named (``--method``, ``--rotation``, ``--effects``, ...).
        """
        if self.resolved is not None:
            if self.resolved != fingerprint(dataset):
                raise ValueError(f"this request was checked against {self.resolved}, not {fingerprint(dataset)}")
            return self  # checked once; the stages never check again
        method, note = _method(self.method, self.rotation, len(dataset))
        rotation = _rotation(method, self.rotation)
        parts = unknown_parts(self.unknowns)
        unknowns = _conditional(parts, dataset, self.sensor_pose, self.effects)
        effects, unknowns, model = _effects(self.effects, unknowns, self.model)
        if parts in UNKNOWNS:
            parts = unknowns  # --effects sphere_center frees the centre
        _robot_effects_possible(effects, dataset)
        enough(dataset, parts)
        start = None if self.start is None else np.asarray(self.start, float).copy()
        checked = dataclasses.replace(
            self, method=method, rotation=rotation, effects=effects, unknowns=unknowns, model=model, start=start,
            chosen=_chosen(self.chosen, self.effects, model),
            options=copy.deepcopy(_solver_options(self.options)), alpha=float(self.alpha),
            convention=conventions.check(self.convention or dataset.convention),
            sigma=dataset.noise_centre_mm if self.sigma is None else float(self.sigma),
            sigma_stated=(self.sigma is not None) if self.sigma_stated is None else self.sigma_stated,
            robot_sigma=dataset.noise_robot_mm if self.robot_sigma is None else float(self.robot_sigma),
            notes=(note,) if note else ())
        object.__setattr__(checked, "resolved", fingerprint(dataset))
        object.__setattr__(checked, "parts", parts)
        return checked

    @property
    def cell(self):
        """Whether the parts need the cell stage (:mod:`handeye.app.engine.cell_stage`)."""
        return self.parts is not None and self.parts != self.unknowns


def _method(method, rotation, n):
    if method is None:
        if n <= LARGE or rotation in ("matrix", "euler"):
            return "ipopt", None
        return "lm", (f"{n} measurements: the default method is lm (Levenberg-Marquardt on the local chart, linear "
                      f"in the data) above {LARGE}; ask for --method ipopt to use IPOPT")
    if method not in METHODS:
        raise CalibrationInputError(f"--method: unknown {method!r}; choose one of {', '.join(METHODS + CLASSIC_METHODS)}")
    return method, None


def _rotation(method, rotation):
    rotation = rotation or DEFAULT_ROTATION.get(method, "local")
    if rotation not in ROTATIONS:
        raise CalibrationInputError(f"--rotation: unknown {rotation!r}; choose one of {', '.join(ROTATIONS)}")
    if rotation not in SUPPORTED[method]:
        raise CalibrationInputError(
            f"--rotation {rotation} does not work with --method {method} (it supports {', '.join(SUPPORTED[method])}):"
            + (" the matrix entries need the orthogonality constraints only IPOPT handles" if rotation == "matrix" else "")
            + (" IPOPT has no retraction for the local parametrisation" if rotation == "local" else "")
        )
    return rotation


def _chosen(chosen, effects, model):
    """Whether the model is the user's (the search checks it, never changes it): said so
    (``chosen``), ``--effects`` given (``none`` included), or a profile residual model asked
    for (``--model measurement|points``: the search's effects need the centre residual)."""
    if chosen is not None:
        return bool(chosen)
    return (effects is not None and effects != ()) or model in ("measurement", "points")


def _effects(effects, unknowns, model):
    """Validated effect names; ``sphere_center`` is the free centre (``unknowns='sensor+sphere'``)."""
    names = effect_names(effects or ())
    if not names:
        return (), unknowns, model
    if model not in (None, "centre"):
        raise CalibrationInputError(f"--effects works on the centre residual, not --model {model}")
    if "sphere_center" in names:
        unknowns = "sensor+sphere"
    return tuple(dict.fromkeys(n for n in names if n != "sphere_center")), unknowns, "centre"


def _robot_effects_possible(effects, dataset):
    """Raise CalibrationInputError when a robot effect is asked of a dataset that cannot show it."""
    from handeye.model import effects as catalogue

    for name in (n for n in effects if not catalogue.fittable(n, dataset)):
        raise CalibrationInputError(f"--effects {name} needs [sphere] diameter in {dataset.path / 'setup.toml'}: it "
                                    "corrects centres rebuilt from a laser line by the sphere's radius")
    for name in (n for n in effects if catalogue.get(n).KIND == "robot" and not catalogue.get(n).available(dataset)):
        if dataset.joints is not None and dataset.robot_model is not None:
            raise CalibrationInputError(
                f"--effects {name}: not with the sphere on a positioner ({dataset.path / 'setup.toml'}): the turning "
                "axes absorb the robot's errors in part, and what remains cannot be told from them")
        raise CalibrationInputError(
            f"--effects {name} needs the joint angles j1..j6 in {dataset.path / 'measurements.csv'} with "
            f"[robot] model in {dataset.path / 'setup.toml'}")


def enough(dataset, unknowns):
    """Raise CalibrationInputError when ``dataset`` has too few measurements for ``unknowns``."""
    need = min_measurements(unknowns, len(dataset.mounts.axes))
    if len(dataset) < need:
        raise CalibrationInputError(
            f"{dataset.path / 'measurements.csv'}: {len(dataset)} measurement(s); unknowns {unknowns!r} "
            f"need at least {need} (3 equations each for {3 * need - 3} unknowns, plus redundancy)")


def _limits_iterations(options):
    """True when the options set an iteration limit anywhere (``max_iter``, nested dicts too)."""
    return any(k == "max_iter" or (isinstance(v, dict) and _limits_iterations(v))
               for k, v in options.items())


def _solver_options(options):
    """Solver options checked up front: an unknown key is bad input, not a crash."""
    options = dict(options or {})
    try:
        solvers.Options.from_mapping(options)
    except solvers.UnsupportedProblem as exc:
        raise CalibrationInputError(f"options: {exc}") from None
    return options


def parse_pose(text, what="--start", convention="kuka"):
    """Parse a pose written in a robot convention (``'X,Y,Z,A,B,C'`` for KUKA: mm, degrees)
    into a KUKA pose; raises CalibrationInputError."""
    pose = _parse_pose(text, what, convention)
    if np.any(np.abs(pose[:3]) > LIMIT_POSITION_MM):
        raise CalibrationInputError(f"{what}: a position beyond +-{LIMIT_POSITION_MM:g} mm in {text!r}: a unit or a "
                                    "misprint?")
    return pose


def _parse_pose(text, what, convention):
    cols = conventions.columns(convention)
    parts = [p.strip() for p in str(text).split(",")]
    if len(parts) != len(cols):
        if convention == "kuka":
            raise CalibrationInputError(f"{what}: needs six comma-separated numbers X,Y,Z,A,B,C, got {text!r}")
        raise CalibrationInputError(f"{what}: needs {len(cols)} numbers {','.join(cols)} ({convention}), got {text!r}")
    try:
        values = np.array([float(p) for p in parts])
    except ValueError:
        raise CalibrationInputError(f"{what}: not a number in {text!r}") from None
    if not np.all(np.isfinite(values)):
        raise CalibrationInputError(f"{what}: values must be finite, got {text!r}")
    if convention != "kuka":
        try:
            return conventions.convert(values, convention, "kuka")
        except conventions.ConventionError as exc:
            raise CalibrationInputError(f"{what}: {exc}") from None
    for name, v, lim in zip("ABC", values[3:], GUESS_LIMITS):
        if abs(v) > lim:
            raise CalibrationInputError(f"{what}: angle {name} = {v} out of range [-{lim:g}, {lim:g}] degrees")
    return values
