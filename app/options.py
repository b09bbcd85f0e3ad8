"""Every command's options, declared once: one table per command (:data:`COMMANDS`).

Each option is a frozen :class:`Opt` (flag, keyword, type, unit, default, choices, metavar,
help, check). From the tables are made the argparse parser
(:func:`handeye.app.parser.build_parser`), the command line's call of the public function
(:func:`keywords`), the values a public function was given (:func:`given`; tests check that its
keywords and defaults are the table's), what the request validates (:attr:`Opt.check`, applied
by :mod:`handeye.app.engine.command_request`), the options saved with ``--out`` (:func:`record`)
and the README's option tables (:func:`markdown`).

Imports only the standard library and the names of the options (:mod:`handeye.app.choices`,
:mod:`handeye.model.names`): ``handeye --help`` never loads numpy.
"""
from __future__ import annotations

import dataclasses

from handeye.app.choices import ALPHA, CLASSIC_METHODS, CLOUD_FORMATS, FORMATS, METHODS, ROBOT_FORMATS
from handeye.model.names import CONVENTIONS, KINDS, ROTATIONS

#: Largest iteration limit accepted (a C int, IPOPT's, must hold it; no calibration needs more).
MAX_ITER = 1_000_000
#: The bounds of a stated noise (``--sigma``, ``--robot-sigma``), mm.
NOISE = ("number", 1e-6, 1e3)


@dataclasses.dataclass(frozen=True)
class Opt:
    """One option of one command, as the parser, the public function, the request, the
    provenance record and the README see it.

    Attributes
    ----------
    flag : str
        ``--max-iter``, or a positional's name (``dataset``).
    default : object
        The default of the command line and of the public function's keyword (immutable).
    type : {'int', 'float'} or None
        How the command line reads the text (None: kept as text).
    unit : str or None
        Unit of the value (``mm``, ``deg``), shown in the docs.
    choices : tuple, callable or None
        The values allowed (a callable gives them when the parser is built).
    metavar, help, nargs, required
        As argparse's.
    action : {'store_true', 'append'} or None
    doc : str or None
        The README's text of the option (default ``help``).
    keyword : str or None
        The public function's keyword; None: the flag's name (``max_iter``); ``''``: none
        (``--json`` is the command line's own).
    check : tuple
        What the request validates: ``('number', low, high)``, ``('integer', low, high)``.
    kind : {'value', 'path', 'pose'}
        How the provenance record saves it: as given, as text (a path, a dataset's folder), or
        as text or a flat list of numbers (a pose).
    """

    flag: str
    default: object = None
    type: str | None = None
    unit: str | None = None
    choices: object = None
    metavar: str | None = None
    help: str | None = None
    nargs: str | None = None
    action: str | None = None
    required: bool = False
    doc: str | None = None
    keyword: str | None = None
    check: tuple = ()
    kind: str = "value"

    def __post_init__(self):
        if self.action == "store_true":  # a flag is False until given
            object.__setattr__(self, "default", False)

    @property
    def dest(self):
        """The argparse attribute (``max_iter``)."""
        return self.flag.lstrip("-").replace("-", "_")

    @property
    def name(self):
        """The public function's keyword, or ``''`` for an option of the command line's own."""
        return self.dest if self.keyword is None else self.keyword

    def argument(self):
        """``(flags, keywords)`` of :meth:`argparse.ArgumentParser.add_argument`."""
        given = {"action": self.action, "help": self.help, "metavar": self.metavar, "nargs": self.nargs,
                 "type": {"int": int, "float": float}.get(self.type),
                 "choices": self.choices() if callable(self.choices) else self.choices,
                 "default": list(self.default) if self.action == "append" else self.default}
        if self.required:
            given["required"] = True
        if self.action == "store_true":
            given = {"action": "store_true", "help": self.help}
        return (self.flag,), {key: value for key, value in given.items() if value is not None}


@dataclasses.dataclass(frozen=True)
class Command:
    """A command's help line, its options and the public function they are the keywords of
    (``'module:name'``, imported when the command runs; None: the command line's own)."""

    help: str
    options: tuple
    function: str | None = None


def _studies():
    from handeye.app.tools.registry import STUDIES  # names only: the studies are imported when one runs

    return list(STUDIES) + ["all"]


def _json(text=None):
    return Opt("--json", action="store_true", help=text, keyword="")


def _held(flag):
    """A saved calibration (``--calibration``, or export's positional RESULT.json) or a sensor pose typed
    in, its convention, and ``--force``: what export, cloud and validate use."""
    return (Opt(flag, metavar="RESULT.json", nargs=None if flag.startswith("-") else "?", keyword="calibration",
                help="a saved calibration (handeye calibrate DATASET --out RESULT.json)"),
            Opt("--sensor-pose", metavar="X,Y,Z,...", kind="pose",
                help="instead: a sensor pose on the flange typed in (e.g. the controller's TCP; export: or in the robot "
                     "base, with --sensor-mount world), in --convention's columns; no uncertainty then"),
            Opt("--convention", choices=tuple(CONVENTIONS),
                help="convention of --sensor-pose (default: the dataset's; export has none: required)"),
            Opt("--force", action="store_true", help="use a calibration that did not converge"))


_CALIBRATE = (
    Opt('dataset', 'thesis-real', kind='path', nargs='?', help='embedded dataset name or folder (default thesis-real)',
        doc='an embedded dataset (`handeye datasets`: `thesis-real`, `thesis-sim`) or a folder'),
    Opt('--unknowns', 'sensor', metavar='PARTS',
        help='what to estimate, +-joined: sensor, sphere, positioner (default sensor; e.g. sensor+sphere, sphere+positioner,'
             ' sensor+sphere+positioner); a part not estimated comes from setup.toml or --calibration',
        doc="what to estimate, `+`-joined in any order: `sensor` (6: the sensor frame in its mount's frame), `sphere` (3: the"
            " centre in its mount's frame), `positioner` (4 per axis); e.g. `sensor+sphere`, `sphere+positioner`, "
            "`sensor+sphere+positioner` ([Any "
            "cell](#any-cell-a-sensor-fixed-in-the-cell-a-sphere-on-the-flange-or-on-a-positioner))"),
    Opt('--calibration', kind='path', metavar='FILE',
        help='a saved calibration (calibrate --out) whose sensor pose is held: calibrating the other parts when --unknowns '
             'has no sensor, else scored as --sensor-pose is',
        doc='a saved calibration (`calibrate --out`) whose sensor pose is held: the other parts calibrated when `--unknowns` '
            'has no `sensor` (else `[sensor] pose`); with `sensor` among `--unknowns`, the pose is scored as `--sensor-pose` '
            'is'),
    Opt('--sensor-pose', kind='pose', metavar='X,Y,Z,...',
        help="score this sensor pose (e.g. the vendor's, in --convention's columns) instead of calibrating it: held, the "
             "sphere centre fitted with it under --unknowns sensor+sphere, judged against the data's own calibration (exit "
             "0; the verdict says whether the data contradict it); --calibration FILE with the sensor among --unknowns does "
             "the same",
        doc="score a given sensor pose (the vendor's, last month's; `--convention`'s columns) instead of calibrating it: "
            "[Score a given pose](#score-a-given-pose-and-compare-two-calibrations)"),
    Opt('--method', choices=METHODS + CLASSIC_METHODS,
        help='solver of the least squares (default ipopt; lm above 5,000 measurements), or a closed-form baseline: kim-cho '
             '(AX = XB, linear) or li-two-step (pure translations, then rotations; see model/classics.py)',
        doc="IPOPT (default; `lm` above 5,000 measurements, said in the warnings, so that time and memory stay linear in the "
            "data), Gauss-Newton, Levenberg-Marquardt, trust region with exact Hessian, dogleg, local Newton (the solvers "
            "package also has damped Newton, steepest descent and BFGS for the studies); `kim-cho`, `li-two-step`: the "
            "thesis's state of the art as closed-form baselines (`model/classics.py`): Kim & Cho's linear AX = XB over every "
            "pair of samples, Li et al.'s pure translations → rotation, then every pose → translation; gross errors are "
            "screened first as for the least squares (`--keep-all` skips it); the report adds where the least squares goes "
            "from there. Exit 2, naming the missing motions, when the data lack them (thesis-real has no pure translations)"),
    Opt('--rotation', choices=ROTATIONS,
        help='rotation parametrisation (default: matrix for ipopt, local otherwise)',
        doc="default `matrix` (nine entries, RᵀR = I as constraints) for IPOPT, `local` (R·exp([δ]×)) otherwise; `euler` is "
            "the thesis's A, B, C"),
    Opt('--start', kind='pose', metavar='X,Y,Z,A,B,C',
        help="start sensor pose in --convention's columns (KUKA: mm and degrees; write --start=-1,2,... for a leading minus)",
        doc="start sensor pose in the dataset's convention (`--convention`'s; KUKA `X,Y,Z,A,B,C` in mm and degrees, UR "
            "`X,Y,Z,RX,RY,RZ` in mm and radians, ...; write `--start=` so that a leading minus is not read as an option), "
            "overrides the setup's; without either, the closed-form estimate"),
    Opt('--convention', choices=tuple(CONVENTIONS),
        help="robot convention of --start and of the reported pose (default: the dataset's)",
        doc="robot convention of `--start` and of the reported pose (`sensor_pose_as`); default the dataset's"),
    Opt('--max-iter', check=('integer', 1, MAX_ITER), type='int', help='iteration limit',
        doc='iteration limit (respected: no polish past it)'),
    Opt('--model', choices=tuple(KINDS),
        help='residual: reconstructed centres, measured circles, or profile points (default: measurement when every sample '
             'has a profile, else centre)',
        doc="residual: reconstructed centres (the thesis's), the measured circles in the laser plane, or every profile point;"
            " default `measurement` when every sample has a profile, else `centre`"),
    Opt('--keep-all', action='store_true',
        help='fit every sample: no outlier detection (rows that contradict themselves are still excluded)',
        doc='no outlier screening (a row whose `xs,ys,zs` contradict its own profile is excluded all the same, named with its'
            ' row: `model/consistency.py`)'),
    Opt('--alpha', check=('level',), type='float', help=f'family-wise level of the outlier tests (default {ALPHA:g})',
        doc='family-wise level of the outlier tests (default 0.01)'),
    Opt('--no-loo', action='store_true', help='skip the leave-one-out error (one refit per sample)',
        doc='skip the leave-one-out error (one exact refit per sample up to 2,000 used samples, the deletion formula above)'),
    Opt('--no-clean', action='store_true',
        help="fit every profile point: no profile cleaning (by default speckle and background points off the sphere's arc "
             "are dropped and reported)",
        doc="fit every profile point: no profile cleaning (by default the points off the sphere's arc -- speckle, background,"
            " clusters -- are dropped at load and reported; [Profile cleaning](#profile-cleaning))"),
    Opt('--sigma', unit='mm', check=NOISE, type='float', metavar='MM',
        help="stated noise of a sphere centre (mm per component) the centre residual is tested against (default: setup.toml "
             "[noise] centre_mm, else 0.05); the profile models are tested against each circle fit's covariance and "
             "--robot-sigma instead",
        doc='the stated noise the fit is tested against: per-component sd of a sphere centre through the chain, for the '
            '`centre` residual (default `[noise] centre_mm`, else 0.05)'),
    Opt('--robot-sigma', unit='mm', check=NOISE, type='float', metavar='MM',
        help='robot repeatability, mm per axis (default: [noise] robot_mm, else 0.025)',
        doc="robot repeatability per axis (default `[noise] robot_mm`, else 0.025), which with each circle fit's own "
            "covariance weights and tests the profile models"),
    Opt('--effects', metavar='NAME[,NAME]',
        help='calibrate with catalogue effects: sensor_scale, sphere_radius, sphere_center (as handeye diagnose names them)',
        doc='calibrate with catalogue effects, as `handeye diagnose` names them: `sensor_scale`, `sphere_radius`, '
            '`sphere_center` (= `--unknowns sensor+sphere`), `joint_offsets`, `link_lengths`, `joint_compliance` (with joint '
            'angles and `[robot] model`); their parameters and 1-sd in `effects`'),
    Opt('--json', action='store_true', help='print the result as JSON', keyword='',
        doc='machine-readable output'),
    Opt('--plot', kind='path', metavar='FILE', help='draw residuals and sphere-centre scatter (PNG)',
        doc='residuals per measurement and the sphere centres through the chain (PNG)'),
    Opt('--report', kind='path', metavar='OUT.html',
        help='also write the one-file HTML report (handeye report): the cell in 3-D, verdict, residuals',
        doc='also write the one-file HTML report ([`handeye report`](#a-report-to-look-at-handeye-report)): the cell in 3-D, '
            'verdict, residual table'),
    Opt('--out', metavar='FILE',
        help="also write the JSON result, with the dataset's hash, tool version and options, atomically",
        doc="the JSON also written atomically to FILE with the dataset's SHA-256, the tool's version and every option"),
)

_SIMULATE = (
    Opt('--out', metavar='DIR', required=True, help='dataset folder to write (must be empty or new)'),
    Opt('--seed', 0, type='int'),
    Opt('--effect', (), action='append', metavar='NAME=VALUE',
        help="hidden effect: sphere_center=dx,dy,dz | sensor_scale=s | sphere_radius=dr | sign_flip=ID,ID | outlier=ID,ID | "
             "with --robot: joint_offsets=j2:0.05,j3:-0.03 (degrees), link_lengths=a2:0.3,d4:-0.2 (mm, the model's length "
             "names), joint_compliance=j2:0.02,j3:0.01 (degrees per metre of lever) (repeatable)"),
    Opt('--robot', metavar='MODEL',
        help='simulate a robot with joints: a nominal model (irb4600, kr60ha, m20ia, ur10e, ur5e or a model file) reaches '
             'the poses by inverse kinematics; writes j1..j6 and [robot] model (default sphere centre inside its workspace)'),
    Opt('--profiles', action='store_true', help='also write the laser profiles'),
    Opt('--poses', metavar='CSV',
        help='flange poses (a pose list in any convention: id,x,y,z,a,b,c is KUKA, id,x,y,z,rx,ry,rz UR, ...) instead of the'
             ' thesis strategy'),
    Opt('--n-poses', 36, type='int', help='poses of the thesis strategy (1-36)'),
    Opt('--linearity', 0.0, type='float', help='sensor linearity error as a fraction of the 100 mm range (data sheet: 0.0016)'),
    Opt('--motions', 'thesis', choices=('thesis', 'about-sphere'),
        help="thesis: the seed's 36 orientations, sphere seen at random points; about-sphere: the same orientations rotating"
             " about the sphere (seen at one sensor point)"),
    Opt('--translations', 0, type='int', metavar='K',
        help="add K pure flange translations (0..6) at each of two orientations (Li et al.'s first step)"),
    Opt('--truth', metavar='POSE',
        help="true sensor pose in its mount's frame, in --convention's columns (default KUKA 190,100,125,180,-88,0 on the "
             "flange; 1750,-50,1000,90,0,-110 in the cell)"),
    Opt('--diameter', type='float', metavar='MM', help='sphere diameter (default 59.94507)'),
    Opt('--center', metavar='X,Y,Z', help="sphere centre in its mount's frame (robot base, flange or table), mm"),
    Opt('--convention', 'kuka', choices=tuple(CONVENTIONS),
        help='robot convention of the written dataset and of --truth (default kuka)'),
    Opt('--max-tilt', 90.0, type='float', metavar='DEG',
        help="largest sensor tilt from straight down (default 90, the thesis's)"),
    Opt('--no-start', action='store_true', help='write no start pose (calibrate starts from the closed form)'),
    Opt('--sensor-mount', 'flange', choices=('flange', 'world'),
        help='where the sensor is: on the flange (default) or fixed in the cell (robot base frame)'),
    Opt('--sphere-mount', 'world', choices=('world', 'flange', 'positioner'),
        help="where the sphere is: fixed in the cell (default), on the flange or on a positioner's table; observable pairs: "
             "flange/world, world/flange, flange/positioner"),
    Opt('--positioner-axes', metavar='NAME:PX,PY,PZ:DX,DY,DZ;...',
        help='nominal positioner axes, base first: point and direction in the robot base at zero angles (mm); default a KUKA'
             ' KP1-V-like 2-axis positioner: e1:1500,0,600:0,1,0;e2:1500,0,800:0,0,1'),
    Opt('--positioner-error', metavar='MM,DEG',
        help='how far the true axes differ from the nominal ones written in setup.toml (default 1.0,0.2)'),
)

_DIAGNOSE = (
    Opt('dataset', 'thesis-real', kind='path', nargs='?'),
    Opt('--alpha', ALPHA, check=('level',), type='float', help=f'family-wise level of the tests (default {ALPHA:g})'),
    _json(),
    Opt('--no-clean', action='store_true', help='fit every profile point: no profile cleaning'),
    Opt('--figures', kind='path', metavar='DIR', help='write residuals.png and gap.png here'),
    Opt('--plot', kind='path', metavar='FILE', help='draw the gap shrinking step by step (PNG)'),
    Opt('--sigma', unit='mm', check=NOISE, type='float', metavar='MM',
        help='nominal noise per residual component for chi2/dof (default: [noise] centre_mm, else 0.05)'),
    Opt('--out', metavar='FILE', help='also write the JSON result with provenance'),
    Opt('--unknowns', 'sensor', choices=('sensor', 'sensor+sphere'),
        help="sensor+sphere: the sphere centre estimated with the pose in every model (when setup.toml gives none); default "
             "sensor: effects tested against the setup's centre"),
)

_PLAN = (
    Opt('--n', type='int', help='number of poses to choose (default 12; with a robot the number its --target takes)'),
    Opt('--candidates', metavar='CSV',
        help="candidate flange poses (a pose list in any convention, told by its header); default: the thesis strategy's 36 "
             "orientations x 3 cuts scaled to the sphere (108 poses)"),
    Opt('--dataset',
        help='take the nominal sensor pose (start_pose), sphere centre and diameter, laser side and robot convention from '
             'this dataset'),
    Opt('--out', metavar='CSV',
        help="write the chosen poses as a pose list in the dataset's convention (KUKA without --dataset)"),
    Opt('--max-tilt', 90.0, type='float', metavar='DEG',
        help="largest sensor tilt from straight down of the candidates (default 90, the thesis's)"),
    Opt('--margin', metavar='MM,DEG',
        help='the nominal sensor pose may be off by this much: every planned pose still sees the sphere'),
    Opt('--workspace', metavar='XMIN,XMAX,YMIN,YMAX,ZMIN,ZMAX',
        help='flange positions allowed (robot base, mm); candidates outside are skipped'),
    Opt('--score', metavar='CSV', help='predict the accuracy of this pose list instead of choosing poses'),
    Opt('--sensor-mount', 'flange', choices=('flange', 'world'),
        help="without --dataset: plan for `handeye simulate`'s nominal cell of these mounts"),
    Opt('--sphere-mount', 'world', choices=('world', 'flange', 'positioner'),
        help="without --dataset (with it: its setup.toml's mounts); on a positioner every pose list carries one column per "
             "axis (degrees) after the pose's, and the plan chooses axis angles"),
    Opt('--robot', metavar='MODEL',
        help="plan for the robot's own errors too (default with a --dataset that has [robot] model): a built-in nominal "
             "model (kr60ha, ur5e, ur10e, irb4600, m20ia) or a model file; poses reached by its inverse kinematics, the "
             "other wrist a candidate of its own, j1..j6 in --out"),
    Opt('--effects', metavar='NAME[,NAME]', help='with a robot: joint_offsets (default), link_lengths, joint_compliance'),
    Opt('--target', metavar='EFFECT=SD[,EFFECT=SD]',
        help='with a robot: the 1-sd to reach, which sets how many poses (default joint_offsets=0.01 deg, link_lengths=0.05 '
             'mm, joint_compliance=0.005 deg/m)'),
    Opt('--sigma', type='float', metavar='MM',
        help='with a robot: stated noise per component of a sphere centre (default [noise] centre_mm, else 0.05)'),
    _json(),
)

_COMPARE = (
    Opt('dataset', help='embedded dataset name or folder'),
    Opt('a', metavar='A.json', help='a saved calibration (calibrate --out)'),
    Opt('b', metavar='B.json', help='another saved calibration'),
    Opt('--unknowns', choices=('sensor', 'sensor+sphere'),
        help='sensor+sphere fits the sphere centre with each pose held (default: sensor when setup.toml gives [sphere] '
             'center, else sensor+sphere)'),
    Opt('--model', choices=tuple(KINDS),
        help='residual model both are scored with (default: as calibrate)'),
    Opt('--alpha', check=('level',), type='float', help=f"level of 'significant' and of the screening (default {ALPHA:g})"),
    Opt('--keep-all', action='store_true', help='score every sample: no outlier screening'),
    Opt('--sigma', unit='mm', check=NOISE, type='float', metavar='MM', help="stated noise, as calibrate's"),
    Opt('--robot-sigma', unit='mm', check=NOISE, type='float', metavar='MM', help="robot repeatability, as calibrate's"),
    Opt('--convention', choices=tuple(CONVENTIONS), help="robot convention of the poses reported (default: the dataset's)"),
    _json(),
)

_REPORT = (
    Opt('dataset', 'thesis-real', nargs='?', help='embedded dataset name or folder'),
    Opt('--html', metavar='OUT.html', required=True, help='the report to write (atomically)'),
    Opt('--calibration', metavar='FILE',
        help='a calibrate --out file of this dataset (its SHA-256 is checked), reported as it is; default: calibrate now'),
    Opt('--diagnose', action='store_true', help='also run handeye diagnose and show its steps against the noise floor'),
    Opt('--unknowns', metavar='PARTS', help="as calibrate's, default sensor (without --calibration)"),
    Opt('--model', choices=tuple(KINDS), help="as calibrate's (without --calibration)"),
    Opt('--convention', choices=tuple(CONVENTIONS),
        help="robot convention of the reported pose (default: the dataset's)"),
    Opt('--keep-all', action='store_true', help="as calibrate's (without --calibration)"),
    Opt('--no-clean', action='store_true', help="as calibrate's"),
    _json('print what was written as JSON'),
)

_EXPORT = (
    *_held('result'),
    Opt('--format', 'json', choices=FORMATS + ROBOT_FORMATS,
        help="what to write (default json: every format's numbers; robot-toml, robot-urdf: the robot's model corrected by "
             "calibrated joint_offsets and link_lengths; its flange link is tool0)"),
    Opt('--parent', help='parent frame name (ros2, urdf; default flange, or base_link for a sensor fixed in the cell)'),
    Opt('--child', 'sensor', help='sensor frame name (ros2, urdf, tool, base and variable names; default sensor)'),
    Opt('--tool', type='int', help='tool number of a sensor on the flange (KUKA TOOL_DATA, FANUC UTOOL; default 1)'),
    Opt('--base', type='int',
        help='base / user frame number of a sensor fixed in the cell (KUKA BASE_DATA, FANUC UFRAME; default 1)'),
    Opt('--register', 99, type='int', help='FANUC position register the TP program overwrites (default 99)'),
    Opt('--sensor-mount', choices=('flange', 'world'),
        help='where the --sensor-pose is: on the flange (default) or fixed in the cell, the pose in the robot base (a saved '
             'calibration says itself)'),
    Opt('--out', metavar='FILE', help='write to FILE (atomically) instead of stdout'),
)

_CLOUD = (
    Opt('dataset',
        help="a scan or dataset folder with profiles (no sphere needed); every profile point, not cleaned (calibrate's "
             "profile cleaning does not apply)"),
    *_held('--calibration'),
    Opt('--out', metavar='FILE', required=True, help='the point cloud to write'),
    Opt('--format', choices=CLOUD_FORMATS,
        help="ply: binary little-endian, x y z double, pose int, sd float; csv (default: from --out's extension, .csv is "
             "CSV, else PLY)"),
    _json('print the summary as JSON'),
)

_VALIDATE = (
    Opt('dataset',
        help='a scan or dataset folder (profiles: sphere fit of every point, not cleaned -- a form test sees every point; '
             '--exclude leaves the worst out; without: sphere centres)'),
    *_held('--calibration'),
    Opt('--exclude', 0.0, type='float', metavar='FRACTION',
        help='leave out this fraction of points with the largest deviations (VDI/VDE 2634-2 allows 0.003; default 0)'),
    Opt('--mpe', metavar='PF,PS[,SD]', help='maximum permissible errors (mm): exit 1 when PF, |PS| or |SD| exceeds its limit'),
    _json('print the result as JSON'),
    Opt('--plot', metavar='FILE', help='radial deviations on the sphere (3-D) and their histogram'),
)

_STUDY = (
    Opt('name', choices=_studies),
    Opt('--out', 'out', metavar='DIR', help='output folder (default ./out)'),
    Opt('--quick', action='store_true', help='small, honest version (CI)'),
    Opt('--jobs', type='int', help='worker processes for sweeps (default: all cores)'),
    Opt('--dask', metavar='ADDRESS|local',
        help="run the sweeps on a Dask cluster: a scheduler address, or 'local' for a LocalCluster with one worker process "
             "per core (--jobs of them when given); needs handeye[dask]"),
)

_DATASET_NEW = (
    Opt('out', metavar='OUT', help='dataset folder to write (new or empty)'),
    Opt('--poses', metavar='FILE',
        help='flange poses in the robot base: CSV, whitespace text or JSON (told by the content); header optional'),
    Opt('--profiles', (), action='append', metavar='FILES|GLOB|DIR',
        help='laser profiles, one per pose (repeatable): OpenCV FileStorage YAML/XML/JSON, CSV/TXT with 2 (x,z) or 3 (x,y,z)'
             ' columns, .npy/.npz, PLY, PCD'),
    Opt('--convention', choices=('kuka', 'abb', 'ur', 'fanuc'),
        help="the poses' convention (a headerless file's columns in order, optional leading id); the dataset is written in "
             "it (named columns of another convention are converted; default: the file's, abb for a bag)"),
    Opt('--columns', metavar='NAMES', help="the pose file's columns, e.g. id,x,y,z,qx,qy,qz,qw; - skips one"),
    Opt('--units', 'mm', choices=('mm', 'm'), help='units of the pose positions (default mm)'),
    Opt('--angles', choices=('deg', 'rad'),
        help="units of the pose angles (default the convention's: degrees, radians for ur)"),
    Opt('--profile-units', choices=('mm', 'm'), help='units of the profiles (default mm)'),
    Opt('--profile-axes', metavar='X,Z',
        help="the profile files' axes that are handeye's sensor x and z (e.g. y,-x); default found from the data"),
    Opt('--diameter', type='float', metavar='MM', help='sphere diameter, mm (required unless --setup gives it)'),
    Opt('--setup', metavar='SETUP.toml',
        help='an existing setup.toml: its sphere diameter and centre, side, start pose, convention and robot model fill the '
             'options not given'),
    Opt('--side', type='int', choices=(1, -1),
        help="sign of the sphere centre's coordinate along the laser plane's normal in the profiles' own frame (their y; "
             "default -1); written in handeye's frame"),
    Opt('--center', metavar='X,Y,Z',
        help='sphere centre in the robot base, mm (without it: calibrate with --unknowns sensor+sphere)'),
    Opt('--start', metavar='X,Y,Z,...', help="start sensor pose on the flange, in the convention's columns"),
    Opt('--joints', metavar='FILE', help='joint angles j1..j6 per pose, degrees (needs --robot)'),
    Opt('--robot', metavar='MODEL', help='[robot] model: a built-in nominal model or a model file'),
    Opt('--pair', 'auto', choices=('auto', 'id', 'order'),
        help='pair profiles with poses by a number in the file name (id), by order, or auto (default)'),
    Opt('--match', metavar='REGEX',
        help="regex with one group: the pose id in a profile's file name (default: the last digits)"),
    Opt('--bag', metavar='PATH',
        help="a ROS 2 bag (sqlite3 or mcap) instead of --poses/--profiles (pip install 'handeye[ros]')"),
    Opt('--pose-topic', metavar='TOPIC', help='geometry_msgs/PoseStamped, or /tf with --base-frame and --flange-frame'),
    Opt('--profile-topic', metavar='TOPIC', help='sensor_msgs/PointCloud2 or sensor_msgs/LaserScan'),
    Opt('--base-frame', metavar='FRAME', help='with /tf: the robot base frame'),
    Opt('--flange-frame', metavar='FRAME', help='with /tf: the flange frame'),
    Opt('--max-dt', 0.05, type='float', metavar='SECONDS', help='largest time between a profile and its pose (default 0.05)'),
    _json('print the summary as JSON'),
)

_BENCH = (
    Opt('--quick', action='store_true', help='fewer cases and repetitions'),
    _json(),
    Opt('--plot', metavar='FILE', help='log-log time against measurements (PNG)'),
    Opt('--no-startup', action='store_true', help='skip the cold/warm start-up measurement'),
    Opt('--pipeline-sizes', metavar='N,N,...',
        help='measurements of the end-to-end `handeye calibrate` section (time and own peak memory each, log-log slopes); '
             'default 1000,10000,100000,1000000 (--quick: 10000,30000); 0: skip'),
    Opt('--solvers', action='store_true',
        help='instead: the solver-comparison bench (batched against single-start solvers, and the wall time of the full '
             '`handeye study testfunction`)'),
    Opt('--no-study', action='store_true', help='with --solvers: skip running the study'),
)


#: command -> its help line, options and public function (in the order of ``handeye --help``); ``dataset
#: new`` is the action ``new`` of the command ``dataset`` (:data:`GROUPS`)
COMMANDS = {
    "calibrate": Command("calibrate the sensor pose on the flange from a dataset", _CALIBRATE,
                         "handeye.app.api:calibrate"),
    "datasets": Command("list the embedded datasets", ()),
    "simulate": Command("write a simulated dataset with known truth (handeye.model.simulate)", _SIMULATE,
                        "handeye.app.making:simulate"),
    "diagnose": Command("find, name and add the effects the model is missing", _DIAGNOSE, "handeye.app.api:diagnose"),
    "plan": Command("choose the N most informative poses (D-optimal) from candidates", _PLAN, "handeye.app.making:plan"),
    "compare": Command("which of two calibrations fits a dataset better, and whether significantly", _COMPARE,
                       "handeye.app.api:compare"),
    "report": Command("one self-contained HTML file of a calibration: the cell in 3-D, verdict, residual table, figures",
                      _REPORT, "handeye.app.reporting:report"),
    "export": Command("write a saved calibration for UR, ROS 2, URDF, KUKA, ABB, FANUC, a matrix or JSON "
                      "(handeye.app.outputs.formats)", _EXPORT, "handeye.app.outputs.commands:export"),
    "cloud": Command("every profile point of a scan in the robot base, through a calibration (PLY or CSV)", _CLOUD,
                     "handeye.app.outputs.commands:cloud"),
    "validate": Command("measure the setup's sphere through a calibration: VDI/VDE 2634-2 PF, PS, SD and the centre, "
                        "with their 1 sd", _VALIDATE, "handeye.app.outputs.commands:validate"),
    "study": Command("run a study (figures, tables, JSON) and check its claims", _STUDY),
    "dataset new": Command("assemble a dataset folder (measurements.csv, setup.toml, profiles/, PROVENANCE.toml) from "
                           "loose pose and profile files or a ROS 2 bag", _DATASET_NEW,
                           "handeye.app.ingest.command:new_dataset"),
    "bench": Command("time every method on the same calibrations, side by side", _BENCH),
}
#: a command whose actions are commands of their own -> its help line
GROUPS = {"dataset": "make a dataset folder: `handeye dataset new OUT` from loose files or a ROS 2 bag"}


def keywords(command, values, table=None):
    """The public function's keywords of ``command`` from ``values`` (the parsed arguments by
    their argparse name, ``vars(args)``); ``table`` instead of the command's own options."""
    return {opt.name: values[opt.dest] for opt in table or COMMANDS[command].options if opt.name}


def defaults(command):
    """``{keyword: default}`` of ``command``'s public function, as the table declares them."""
    return {opt.name: opt.default for opt in COMMANDS[command].options if opt.name}


def given(command, scope, table=None):
    """The values a public function of ``command`` was called with: its keywords picked from
    ``scope`` (its ``locals()``), in the table's order."""
    return {opt.name: scope[opt.name] for opt in table or COMMANDS[command].options if opt.name}


def _saved(opt, value):
    """``value`` of ``opt`` as the provenance record keeps it (plain JSON types)."""
    if opt.action == "store_true":
        return bool(value)
    if value is None or isinstance(value, str) or opt.kind == "value":
        return value
    if opt.kind == "path":
        return str(getattr(value, "path", value))  # a Dataset given instead of its name: its folder
    value = value.tolist() if hasattr(value, "tolist") else value  # a pose as numbers: a flat list
    return [x for v in value for x in _saved(opt, v)] if isinstance(value, (list, tuple)) else [value]


def record(command, values, table=None):
    """The options saved with ``--out`` (``provenance['options']``): every keyword of the
    command but ``out`` itself, as JSON values."""
    return {opt.name: _saved(opt, values[opt.name]) for opt in table or COMMANDS[command].options
            if opt.name and opt.name != "out"}


def _cell(opt):
    """The option column of the docs: ``--method ipopt|gn|...``, ``--sigma MM``, ``DATASET``."""
    choices = opt.choices() if callable(opt.choices) else opt.choices
    if not opt.flag.startswith("-"):
        return f"`{opt.metavar or opt.flag.upper()}`"
    if opt.action == "store_true":
        return f"`{opt.flag}`"
    value = "|".join(map(str, choices)) if choices else opt.metavar or opt.dest.upper()
    return f"`{opt.flag} {value}`" + (" (repeatable)" if opt.action == "append" else "")


def markdown(command, table=None):
    """``command``'s options as the README's markdown table: option, default, meaning (the
    README's tables are this text; tests/test_options.py checks that they are)."""
    rows = ["| option | default | meaning |", "|---|---|---|"]
    for opt in table or COMMANDS[command].options:
        default = "" if opt.default in (None, ()) or opt.default is False else f"`{opt.default}`"
        cells = (_cell(opt), default, (opt.doc or opt.help or "") + (f" ({opt.unit})" if opt.unit else ""))
        rows.append("| " + " | ".join(cell.replace("|", "\\|") for cell in cells) + " |")
    return "\n".join(rows)
