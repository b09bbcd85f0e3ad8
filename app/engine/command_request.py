"""The options of ``calibrate``, ``diagnose`` and ``compare``, validated in one place.

Each command reads its dataset, then turns its options into a request here, then runs, then
writes: ``load -> *_request(options, data) -> run -> write`` (as scipy's ``least_squares``
checks its arguments in one block and its back-ends never check them again). The options come
as the public function was given them (``COMMANDS[name].given``); the checks of the
option tables (:attr:`handeye.app.common.option_record.Opt.check`) run first, then what only a command knows
(a closed-form method takes no start, a score no effects), then what only the dataset can tell
(a sensor held needs a pose, a file to write must not be one read). What is free and what is
held is one record, :class:`~handeye.app.engine.request.Free`.
"""
from __future__ import annotations

import dataclasses
import pathlib

from handeye.app.common.arguments import _integer, _number, _pose_text
from handeye.app.common.choices import ALPHA, CLASSIC_METHODS
from handeye.app.common.errors import RequestError
from handeye.app.common.options import COMMANDS
from handeye.app.engine.request import UNKNOWNS, CalibrationRequest, Free, parse_pose, unknown_parts
from handeye.model.chain import conventions
from handeye.model.chain.own_frame import kuka_to_internal
from handeye.model.chain.pose import pose_from_transform


def _level(value, option):
    value = ALPHA if value is None else value
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 < value < 1:
        raise RequestError(f"{option} must lie in (0, 1), got {value}")
    return float(value)


def _one_of(value, option, allowed):
    if value not in allowed:
        raise RequestError(f"{option} must be one of {', '.join(map(str, allowed))}, got {value!r}")
    return value


#: the validators an option's ``check`` names: (value, option, *bounds) -> the value checked
CHECKS = {"number": _number, "integer": _integer, "level": _level, "one_of": _one_of}


def checked_values(command, values):
    """``values`` with every option of ``command``'s table (a name, or a
    :class:`~handeye.app.common.option_record.Command`) that declares a ``check`` validated (a new
    dict; None stays None except for a ``level``, whose None is :data:`ALPHA`)."""
    out = dict(values)
    for opt in (COMMANDS[command] if isinstance(command, str) else command).options:
        if opt.check and (values.get(opt.name) is not None or opt.check[0] == "level"):
            bounds = (opt.choices,) if opt.check[0] == "one_of" else opt.check[1:]
            out[opt.name] = CHECKS[opt.check[0]](values.get(opt.name), opt.flag, *bounds)
    return out


def outputs_checked(data, paths):
    """Every output (``{option: path}``, None: not written) checked before the work: never half
    a result, never over an input of ``data``."""
    from handeye.app.common.files import check_output_folder, check_output_path, input_files

    inputs = input_files(data) if any(path is not None for path in paths.values()) else ()
    for option, path in ((option, path) for option, path in paths.items() if path is not None):
        if option == "--figures":  # a folder, with the two files it will write
            check_output_folder(path, option)
            if pathlib.Path(path).is_dir():
                for name in ("residuals.png", "gap.png"):
                    check_output_path(pathlib.Path(path) / name, option, inputs=inputs)
        else:
            check_output_path(path, option, inputs=inputs, plot=option == "--plot")


def score_checked(free, method, plot, data):
    """The options (and cells) a score of a given sensor pose refuses."""
    unknowns = free.parts
    if data.mounts.sphere == "positioner":
        raise RequestError(f"{data.path / 'setup.toml'}: the sphere is on a positioner; a given sensor pose is not scored "
                           "there (the set-up axes' errors would be blamed on it): hold it while the axes are calibrated, "
                           "--unknowns sphere+positioner with --sensor-pose or --calibration")
    if unknowns not in UNKNOWNS:
        raise RequestError(f"a sensor pose given with --unknowns {unknowns}: leave out sensor (--unknowns "
                           f"{unknowns.replace('sensor+', '')}) to hold it while the others are calibrated")
    for given, option in ((free.effects, "--effects"), (plot, "--plot")):
        if given:
            raise RequestError(f"{option} does not apply to a score of a given sensor pose")
    if method in CLASSIC_METHODS:
        raise RequestError(f"--method {method} is closed form: a given sensor pose is scored with a least-squares "
                           "method")


def _closed_form_checked(v, free):
    method = v["method"]
    if free.parts not in UNKNOWNS:
        raise RequestError(f"--method {method} is closed form: --unknowns {' or '.join(UNKNOWNS)}")
    ignored = [option for option, given in (("--start", v["start"]), ("--rotation", v["rotation"]),
                                            ("--max-iter", v["max_iter"]), ("--model", v["model"]),
                                            ("--plot", v["plot"]), ("--no-loo", v["no_loo"] or None))
               if given is not None]
    if ignored:
        raise RequestError(f"--method {method} is closed form; these options do not apply to it: {', '.join(ignored)}")
    if free.effects:
        raise RequestError(f"--method {method} is closed form; --effects does not apply to it")


@dataclasses.dataclass(frozen=True)
class CalibrateRequest:
    """``handeye calibrate``'s options, checked against a dataset.

    Attributes
    ----------
    request : CalibrationRequest
        What the engine runs (least squares: checked by :meth:`holding` once the held pose is
        read; a closed form: as asked).
    free : Free
        What is estimated and what is held.
    closed_form : bool
        ``--method`` is a closed-form baseline.
    options : dict
        The provenance record of the options (saved with ``--out``).
    """

    request: CalibrationRequest
    free: Free
    closed_form: bool
    options: dict

    @classmethod
    def from_options(cls, values, data):
        """The request of the options ``values`` (the public function's keywords) on ``data``;
        raises :class:`handeye.InputError` naming the option at fault."""
        v = checked_values("calibrate", values)
        free = Free.from_options(v["unknowns"], v["effects"], v["calibration"], v["sensor_pose"])
        closed_form = v["method"] in CLASSIC_METHODS
        if closed_form:
            _closed_form_checked(v, free)
        if free.scored:
            score_checked(free, v["method"], v["plot"], data)
            if v["report"] is not None:
                raise RequestError("--report: a scored pose has no report; report the data's own calibration (without "
                                   "--sensor-pose / --calibration), or compare the two with `handeye compare`")
        convention = conventions.check(v["convention"] or data.convention)
        outputs_checked(data, {"--out": v["out"], "--plot": v["plot"], "--report": v["report"]})
        start = None if v["start"] is None else kuka_to_internal(  # typed in the user's frame: turned once, here
            parse_pose(_pose_text(v["start"], "--start"), "--start", convention), data.own_axes)
        request = CalibrationRequest(
            unknowns=free.parts, method=v["method"], rotation=v["rotation"], start=start,
            options={} if v["max_iter"] is None else {"max_iter": v["max_iter"]}, outliers=not v["keep_all"],
            alpha=v["alpha"], loo=not v["no_loo"], model=v["model"], convention=convention, sigma=v["sigma"],
            robot_sigma=v["robot_sigma"], effects=free.effects, chosen=free.chosen or None)
        return cls(request, free, closed_form, COMMANDS["calibrate"].record(values))

    def holding(self, sensor2flange, data):
        """The least-squares request with the given sensor pose (4x4, None: none given), checked
        against ``data``: every default resolved."""
        held = None if sensor2flange is None or self.free.scored else pose_from_transform(sensor2flange)
        return dataclasses.replace(self.request, sensor_pose=held).checked(data)


def diagnose_request(values, data):
    """``handeye diagnose``'s options on ``data`` checked: ``(values, parts, record)``, the
    values with the level and noise validated, the unknowns' canonical parts, and the
    provenance record of the options."""
    v = checked_values("diagnose", values)
    parts = unknown_parts(v["unknowns"])
    if parts not in UNKNOWNS:
        raise RequestError(f"--unknowns {parts}: diagnose estimates sensor or sensor+sphere (a positioner's axes are "
                           "tested as its first effect)")
    outputs_checked(data, {"--out": v["out"]})
    if data.sphere_centre is None and parts == "sensor":
        raise RequestError(f"{data.path / 'setup.toml'}, column '[sphere] center': no sphere centre given; estimate it "
                           f"with the pose: `handeye diagnose {values['dataset']} --unknowns sensor+sphere`")
    outputs_checked(data, {"--figures": v["figures"], "--plot": v["plot"]})
    return v, parts, COMMANDS["diagnose"].record({**values, "unknowns": parts})


def compare_request(values, data):
    """``handeye compare``'s options on ``data``: the request both poses are scored with
    (checked), and its level of "significant"."""
    v = checked_values("compare", values)
    parts = unknown_parts(v["unknowns"] or ("sensor" if data.sphere_centre is not None else "sensor+sphere"))
    score_checked(Free(parts), None, None, data)
    request = CalibrationRequest(unknowns=parts, model=v["model"], outliers=not v["keep_all"], alpha=v["alpha"],
                                 loo=False, convention=conventions.check(v["convention"] or data.convention),
                                 sigma=v["sigma"], robot_sigma=v["robot_sigma"])
    return request.checked(data), v["alpha"]
