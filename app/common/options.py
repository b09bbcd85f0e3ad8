"""Every command's options, declared once: one table per command (:data:`COMMANDS`).

Each option is a frozen :class:`~handeye.app.common.option_record.Opt` (flag, keyword, type, unit,
default, choices, metavar, help, check). From the tables are made the argparse parser
(:func:`handeye.app.command.parser.build_parser`) and, by the methods of
:class:`~handeye.app.common.option_record.Command`, the command line's call of the public function
(``keywords``), the values a public function was given (``given``; tests check that its keywords
and defaults are the table's), its docstring's ``Parameters`` (``documented``), the options saved
with ``--out`` (``record``) and the README's option tables (``markdown``); what the request
validates is the options' ``check`` (applied by :mod:`handeye.app.engine.command_request`).

Imports only the standard library and the names of the options (:mod:`handeye.app.common.choices`,
:mod:`handeye.model.chain.names`): ``handeye --help`` never loads numpy.
"""
from __future__ import annotations

from handeye.app.common.choices import ALPHA, CLASSIC_METHODS, CLOUD_FORMATS, FORMATS, METHODS, ROBOT_FORMATS
from handeye.app.common.option_record import Command, Opt
from handeye.model.chain.names import CONVENTIONS, KINDS, ROTATIONS

#: Largest iteration limit accepted (a C int, IPOPT's, must hold it; no calibration needs more).
MAX_ITER = 1_000_000
#: The bounds of a stated noise (``--sigma``, ``--robot-sigma``), mm.
NOISE = ("number", 1e-6, 1e3)
#: The bounds of a largest sensor tilt from straight down (``--max-tilt``), degrees: (0, 90].
TILT = ("number", 0.0, 90.0, True)
#: A value among the option's choices (checked for the Python caller; the command line's parser checks it too).
ONE_OF = ("one_of",)
#: What compare takes as a calibration (the docstring's type).
_GIVEN_POSE = "str, pathlib.Path, CalibrationResult or array_like (4, 4)"


def _studies():
    from handeye.app.common.registry import STUDIES  # names only: the studies are imported when one runs

    return list(STUDIES) + ["all"]


def _json(text=None):
    return Opt("--json", action="store_true", help=text, keyword="")


def _dataset(help=None, kind="value"):
    """A command's dataset, by default thesis-real: an embedded dataset's name, a folder or a Dataset."""
    return Opt("dataset", "thesis-real", nargs="?", help=help, kind=kind, pytype="str, pathlib.Path or Dataset")


def _held(flag):
    """A saved calibration (``--calibration``, or export's positional RESULT.json) or a sensor pose typed
    in, its convention, and ``--force``: what export, cloud and validate use."""
    return (Opt(flag, metavar="RESULT.json", nargs=None if flag.startswith("-") else "?", keyword="calibration",
                help='a saved calibration (handeye calibrate DATASET --out RESULT.json)'),
            Opt("--sensor-pose", metavar="X,Y,Z,...", kind="pose",
                help="instead: a sensor pose on the flange typed in (e.g. the controller's TCP; export: or in the robot base, "
                     "with --sensor-mount world), in --convention's columns; no uncertainty then"),
            Opt("--convention", choices=tuple(CONVENTIONS),
                help="convention of --sensor-pose (default: the dataset's; export has none: required)"),
            Opt("--force", action="store_true", help="use a calibration that did not converge"))


_CALIBRATE = (
    _dataset('an embedded dataset (`handeye datasets`: `thesis-real`, `thesis-sim`) or a folder', kind='path'),
    Opt('--unknowns', 'sensor', metavar='PARTS',
        help="what to estimate, `+`-joined in any order: `sensor` (6: the sensor frame in its mount's frame), `sphere` (3: the"
             " centre in its mount's frame), `positioner` (4 per axis); e.g. `sensor+sphere`, `sphere+positioner`, "
             "`sensor+sphere+positioner` ([Any "
             "cell](#any-cell-a-sensor-fixed-in-the-cell-a-sphere-on-the-flange-or-on-a-positioner))"),
    Opt('--calibration', kind='path', metavar='FILE',
        help='a saved calibration (`calibrate --out`) whose sensor pose is held: the other parts calibrated when `--unknowns` '
             'has no `sensor` (else `[sensor] pose`); with `sensor` among `--unknowns`, the pose is scored as `--sensor-pose` '
             'is'),
    Opt('--sensor-pose', kind='pose', metavar='X,Y,Z,...',
        help="score a given sensor pose (the vendor's, last month's; `--convention`'s columns) instead of calibrating it: "
             "[Score a given pose](#score-a-given-pose-and-compare-two-calibrations)"),
    Opt('--method', choices=METHODS + CLASSIC_METHODS,
        help="IPOPT (default; `lm` above 5,000 measurements, said in the warnings, so that time and memory stay linear in the "
             "data), Gauss-Newton, Levenberg-Marquardt, trust region with exact Hessian, dogleg, local Newton (the solvers "
             "package also has damped Newton, steepest descent and BFGS for the studies); `kim-cho`, `li-two-step`: the "
             "thesis's state of the art as closed-form baselines (`model/fit/classics.py`): Kim & Cho's linear AX = "
             "XB over every "
             "pair of samples, Li et al.'s pure translations → rotation, then every pose → translation; gross errors are "
             "screened first as for the least squares (`--keep-all` skips it); the report adds where the least squares goes "
             "from there. Exit 2, naming the missing motions, when the data lack them (thesis-real has no pure translations). "
             "A baseline's verdict is the data's own (`app/engine/classic.py`): exit 1 where the default calibration of the "
             "same data refuses them, chooses another model (a sensor scale: before, exit 0 at 0.32-0.72 mm from the "
             "truth), or cannot vouch for the baseline: a baseline has no sd, so its distance from that calibration plus 3 "
             "of its sd must stay within 0.2 mm / 0.05° (Kim & Cho on thesis-real: 2.9 mm); its numbers are written all "
             "the same"),
    Opt('--rotation', choices=ROTATIONS,
        help="default `matrix` (nine entries, RᵀR = I as constraints) for IPOPT, `local` (R·exp([δ]×)) otherwise; `euler` is "
             "the thesis's A, B, C"),
    Opt('--start', kind='pose', metavar='X,Y,Z,A,B,C',
        help="start sensor pose in the dataset's convention and in the frame of your sensor's own files (its own "
             "frame when `dataset new` turned the profiles: `[profile] own_axes`) (`--convention`'s; KUKA `X,Y,Z,A,B,C` "
             "in mm and degrees, UR "
             "`X,Y,Z,RX,RY,RZ` in mm and radians, ...; write `--start=` so that a leading minus is not read as an option), "
             "overrides the setup's; without either, the closed-form estimate"),
    Opt('--convention', choices=tuple(CONVENTIONS),
        help="robot convention of `--start` and of the reported pose (`sensor_pose_as`); default the dataset's"),
    Opt('--max-iter', check=('integer', 1, MAX_ITER), type='int', help='iteration limit (respected: no polish past it)'),
    Opt('--model', choices=tuple(KINDS),
        help="residual: reconstructed centres (the thesis's), the measured circles in the laser plane, or every profile point;"
             " default `measurement` when every sample has a profile, else `centre` (and `centre` where effects are"
             " fitted: they correct the centres)"),
    Opt('--keep-all', action='store_true',
        help='no outlier screening (a row whose `xs,ys,zs` contradict its own profile is excluded all the same, named with its'
             ' row: `model/datasets/consistency.py`)'),
    Opt('--alpha', check=('level',), type='float', help='family-wise level of the outlier tests (default 0.01)'),
    Opt('--no-loo', action='store_true',
        help='skip the leave-one-out error (one exact refit per sample: in closed form for the centre model with the '
             'centre known, else up to 2,000 used samples, the deletion formula above)'),
    Opt('--no-clean', action='store_true',
        help="fit every profile point: no profile cleaning (by default the points off the sphere's arc -- speckle, background,"
             " clusters -- are dropped at load and reported; [Profile cleaning](#profile-cleaning)); the sensor's depth bend is"
             " still measured, on every point"),
    Opt('--sigma', unit='mm', check=NOISE, type='float', metavar='MM',
        help='the stated noise the fit is tested against: per-component sd of a sphere centre through the chain, for the '
             '`centre` residual (default `[noise] centre_mm`, else 0.05)'),
    Opt('--robot-sigma', unit='mm', check=NOISE, type='float', metavar='MM',
        help="robot repeatability per axis (default `[noise] robot_mm`, else 0.025), which with each circle fit's own "
             "covariance weights and tests the profile models"),
    Opt('--effects', metavar='NAME[,NAME]',
        help='calibrate with catalogue effects, as `handeye diagnose` names them: `sensor_scale` (a line scanner\'s), '
             '`centre_scale` (the three coordinates of a centre), `sphere_radius`, '
             '`sphere_center` (= `--unknowns sensor+sphere`), `joint_offsets`, `link_lengths`, `joint_compliance` (with joint '
             'angles and `[robot] model`); their parameters and 1-sd in `effects`. Without it calibrate adds the '
             'effects the data choose (the search `handeye diagnose` prints); with it (`none`: no effect) the model is '
             'yours and the search only checks it: a pose the search puts beyond 1 sd is refused (exit 1)',
        pytype='str or sequence of str, optional'),
    _json('machine-readable output'),
    Opt('--plot', kind='path', metavar='FILE', help='residuals per measurement and the sphere centres through the chain (PNG)'),
    Opt('--report', kind='path', metavar='OUT.html',
        help='also write the one-file HTML report ([`handeye report`](#a-report-to-look-at-handeye-report)): the cell in 3-D, '
             'verdict, residual table'),
    Opt('--out', metavar='FILE',
        help="the JSON also written atomically to FILE with the dataset's SHA-256, the tool's version and every option",
        kind='path'),
)

_SIMULATE = (
    Opt('--out', metavar='DIR', required=True, help='dataset folder to write (must be empty or new)',
        kind='path'),
    Opt('--seed', 0, check=('integer', 0), type='int'),
    Opt('--effect', (), action='append', metavar='NAME=VALUE',
        help="Hidden effects ``'NAME=VALUE'``: ``sphere_center=dx,dy,dz``, ``sensor_scale=s``, ``sphere_radius=dr``, "
             "``sign_flip=ID,ID``, ``outlier=ID,ID``, with ``robot`` ``joint_offsets=j2:0.05,j3:-0.03`` (degrees), "
             "``link_lengths=a2:0.3,d4:-0.2`` (mm, the model's length names) and ``joint_compliance=j2:0.02,j3:0.01`` (degrees"
             " per metre)."),
    Opt('--robot', metavar='MODEL',
        help='A nominal robot model (built-in name or model file, :mod:`handeye.model.robot.robots`): the poses are '
             'reached by its '
             'inverse kinematics and the dataset gets ``j1..j6`` and ``[robot] model`` '
             '(:mod:`handeye.model.simulation.simulate_robot`); '
             'without ``center`` the sphere is placed in its workspace '
             '(:data:`handeye.model.simulation.simulate_robot.CENTRES`). The '
             'sensor on the flange and the sphere in the world only.'),
    Opt('--profiles', action='store_true', help='also write the laser profiles'),
    Opt('--poses', metavar='CSV',
        help='A pose list (header ``id,x,y,z,a,b,c``, KUKA; on a positioner followed by its axis columns, degrees) instead of '
             'the thesis strategy.',
        kind='path'),
    Opt('--n-poses', 36, check=('integer', 1, 36), type='int', help='poses of the thesis strategy (1-36)'),
    Opt('--linearity', 0.0, check=('number', 0.0, 0.1), type='float',
        help='sensor linearity error as a fraction of the 100 mm range (data sheet: 0.0016)'),
    Opt('--motions', 'thesis', choices=('thesis', 'about-sphere'), check=ONE_OF,
        help="thesis: the seed's 36 orientations, sphere seen at random points; about-sphere: the same orientations rotating "
             "about the sphere (seen at one sensor point)"),
    Opt('--translations', 0, check=('integer', 0, 6), type='int', metavar='K',
        help='Pure flange translations (0-6) at each of two orientations.'),
    Opt('--truth', metavar='POSE',
        help="True sensor pose in its mount's frame, in ``convention`` (KUKA: mm, degrees); default the thesis's (190, 100, "
             "125, 180, -88, 0) in KUKA terms on the flange, "
             ":data:`handeye.model.simulation.simulate_mounts.WORLD_SENSOR` in the cell.",
        pytype='str or array_like, optional'),
    Opt('--diameter', check=('number', 0.0, 10_000.0, True), type='float', metavar='MM',
        help="Sphere diameter, mm; default the thesis's certified 59.94507."),
    Opt('--center', metavar='X,Y,Z',
        help="Sphere centre in its mount's frame, mm (``'X,Y,Z'`` or three numbers); default the thesis's in the base, "
             ":mod:`handeye.model.simulation.simulate_mounts`' on the flange or the table.",
        pytype='str or array_like, optional'),
    Opt('--convention', 'kuka', choices=tuple(CONVENTIONS), check=ONE_OF,
        help='Robot convention of the written dataset (poses, start pose, truth) and of ``truth``.'),
    Opt('--max-tilt', 90.0, check=TILT, type='float', metavar='DEG',
        help='Largest tilt of the sensor from looking straight down, degrees (the thesis: 90).'),
    Opt('--no-start', action='store_true', help='write no start pose (calibrate starts from the closed form)'),
    Opt('--sensor-mount', 'flange', choices=('flange', 'world'), check=ONE_OF,
        help='where the sensor is: on the flange (default) or fixed in the cell (robot base frame)'),
    Opt('--sphere-mount', 'world', choices=('world', 'flange', 'positioner'), check=ONE_OF,
        help="where the sphere is: fixed in the cell (default), on the flange or on a positioner's table; observable pairs: "
             "flange/world, world/flange, flange/positioner"),
    Opt('--positioner-axes', metavar='NAME:PX,PY,PZ:DX,DY,DZ;...',
        help="Nominal axes ``'NAME:px,py,pz:dx,dy,dz;...'`` (robot base at zero angles, mm), base first; default a KUKA "
             "KP1-V-like two-axis positioner."),
    Opt('--positioner-error', metavar='MM,DEG',
        help='how far the true axes differ from the nominal ones written in setup.toml (default 1.0,0.2)',
        pytype='str or sequence of two floats, optional'),
)

_DIAGNOSE = (
    _dataset(kind='path'),
    Opt('--alpha', ALPHA, check=('level',), type='float', help=f'family-wise level of the tests (default {ALPHA:g})'),
    _json(),
    Opt('--no-clean', action='store_true', help='fit every profile point: no profile cleaning'),
    Opt('--figures', kind='path', metavar='DIR', help='Folder to write ``residuals.png`` and ``gap.png`` into.'),
    Opt('--plot', kind='path', metavar='FILE', help='Write the gap-shrinking figure to this PNG.'),
    Opt('--sigma', unit='mm', check=NOISE, type='float', metavar='MM',
        help="Nominal noise per residual component (mm) that chi2/dof is stated against; default the setup's ``[noise] "
             "centre_mm`` (0.05)."),
    Opt('--out', metavar='FILE', help='also write the JSON result with provenance',
        kind='path'),
    Opt('--unknowns', 'sensor', choices=('sensor', 'sensor+sphere'),
        help="``sensor+sphere`` estimates the sphere centre with the pose in every model (needed when the setup gives none; "
             "its start is :func:`calibrate`'s estimate); ``sensor`` tests the effects against the setup's centre."),
)

_PLAN = (
    Opt('--n', check=('integer', 1), type='int',
        help='number of poses to choose (default 12; with a robot the number its --target takes)'),
    Opt('--candidates', metavar='CSV',
        help="candidate flange poses (a pose list in any convention, told by its header); default: the thesis strategy's 36 "
             "orientations x 3 cuts scaled to the sphere (108 poses)",
        kind='path'),
    Opt('--dataset',
        help="Take the nominal sensor pose (``start_pose``), sphere centre, diameter, laser side and robot convention from it "
             "(only its ``setup.toml`` is read: a cell can be planned before it is measured); default the thesis's cell.",
        pytype='str, pathlib.Path or Dataset, optional'),
    Opt('--out', metavar='CSV',
        help="write the chosen poses as a pose list in the dataset's convention (KUKA without --dataset)",
        kind='path'),
    Opt('--max-tilt', 90.0, check=TILT, type='float', metavar='DEG',
        help='Largest tilt of the sensor from straight down of the default candidates, degrees.'),
    Opt('--margin', metavar='MM,DEG',
        help="``'MM,DEG'``: the nominal sensor pose may be off by this much; every candidate keeps the sphere inside the laser "
             "line and the measuring range even then.",
        pytype='str or sequence of two floats, optional'),
    Opt('--workspace', metavar='XMIN,XMAX,YMIN,YMAX,ZMIN,ZMAX',
        help="``'XMIN,XMAX,YMIN,YMAX,ZMIN,ZMAX'``: allowed flange positions (robot base, mm).",
        pytype='str or sequence of six floats, optional'),
    Opt('--score', metavar='CSV', help='A pose list to score (predicted accuracy) instead of choosing.',
        kind='path'),
    Opt('--sensor-mount', 'flange', choices=('flange', 'world'), check=ONE_OF,
        help="without --dataset: plan for `handeye simulate`'s nominal cell of these mounts"),
    Opt('--sphere-mount', 'world', choices=('world', 'flange', 'positioner'), check=ONE_OF,
        help="without --dataset (with it: its setup.toml's mounts); on a positioner every pose list carries one column per "
             "axis (degrees) after the pose's, and the plan chooses axis angles"),
    Opt('--robot', metavar='MODEL',
        help="Plan for the robot's own errors too (:mod:`handeye.model.design.planning_robot`): a built-in nominal "
             "model or a model "
             "file (default the dataset's ``[robot] model``, which turns this on as well). Each candidate is reached by the "
             "nominal inverse kinematics (unreachable ones skipped), the other wrist offered as a candidate of its own; the "
             "parameters no candidate separates from the sensor pose and the sphere centre are named and left out; ``out`` "
             "gets j1..j6. Without a dataset the sphere is at :data:`handeye.model.simulation.simulate_robot.CENTRES`."),
    Opt('--effects', metavar='NAME[,NAME]', help='with a robot: joint_offsets (default), link_lengths, joint_compliance',
        pytype='str or sequence of str, optional'),
    Opt('--target', metavar='EFFECT=SD[,EFFECT=SD]',
        help="With a robot: ``'EFFECT=SD,...'``, the 1-sd each effect's parameters should reach (default 0.01 deg, 0.05 mm, "
             "0.005 deg/m): the number of poses it takes is the plan's ``n``.",
        pytype='str or dict, optional'),
    Opt('--sigma', check=('number', 0.0, 1e3, True), type='float', metavar='MM',
        help='with a robot: stated noise per component of a sphere centre (default [noise] centre_mm, else 0.05)'),
    _json(),
)

_COMPARE = (
    Opt('dataset', help='embedded dataset name or folder', pytype='str, pathlib.Path or Dataset'),
    Opt('a', metavar='A.json', help='a saved calibration (calibrate --out)', pytype=_GIVEN_POSE),
    Opt('b', metavar='B.json', help='another saved calibration', pytype=_GIVEN_POSE),
    Opt('--unknowns', choices=('sensor', 'sensor+sphere'),
        help='sensor+sphere fits the sphere centre with each pose held (default: sensor when setup.toml gives [sphere] center,'
             ' else sensor+sphere)'),
    Opt('--model', choices=tuple(KINDS), help='residual model both are scored with (default: as calibrate)'),
    Opt('--alpha', check=('level',), type='float', help=f"level of 'significant' and of the screening (default {ALPHA:g})"),
    Opt('--keep-all', action='store_true', help='score every sample: no outlier screening'),
    Opt('--sigma', unit='mm', check=NOISE, type='float', metavar='MM', help="stated noise, as calibrate's"),
    Opt('--robot-sigma', unit='mm', check=NOISE, type='float', metavar='MM', help="robot repeatability, as calibrate's"),
    Opt('--convention', choices=tuple(CONVENTIONS), help="robot convention of the poses reported (default: the dataset's)"),
    _json(),
)
_REPORT = (
    _dataset('embedded dataset name or folder'),
    Opt('--html', metavar='OUT.html', required=True, help='The HTML file to write (atomically; never over an input).',
        kind='path'),
    Opt('--calibration', metavar='FILE', kind='path',
        help='a calibrate --out file of this dataset (its SHA-256 is checked), reported as it is; default: calibrate now'),
    Opt('--diagnose', action='store_true',
        help='Also run the discrepancy workflow (:func:`handeye.diagnose`, ``unknowns`` sensor or sensor+sphere) and show its '
             'steps against the noise floor.'),
    Opt('--unknowns', metavar='PARTS', help="as calibrate's, default sensor (without --calibration)"),
    Opt('--model', choices=tuple(KINDS), help="as calibrate's (without --calibration)"),
    Opt('--convention', choices=tuple(CONVENTIONS), help="robot convention of the reported pose (default: the dataset's)"),
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
    Opt('--dataset', metavar='DIR', kind='path',
        help="the calibration's dataset: its verdict is recomputed from it at the pose and written with the failed checks "
             "(default: the file's dataset_path, when it still has the file's SHA-256)"),
)

_CLOUD = (
    Opt('dataset',
        help='A scan or dataset folder with profiles (:mod:`handeye.model.datasets.scan`); no sphere needed.',
        kind='path'),
    *_held('--calibration'),
    Opt('--out', metavar='FILE', required=True, help='Where to write the cloud.',
        kind='path'),
    Opt('--format', choices=CLOUD_FORMATS,
        help='``ply`` binary little-endian, or ``csv``; default: from the extension of ``out`` (``.csv`` is CSV, anything else'
             ' PLY).'),
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
        help="run the sweeps on a Dask cluster: a scheduler address, or 'local' for a LocalCluster with one worker process per"
             " core (--jobs of them when given); needs handeye[dask]"),
)

_DATASET_NEW = (
    Opt('out', metavar='OUT', help='The dataset folder to write (new or empty); written atomically (a temporary folder renamed).',
        kind='path'),
    Opt('--poses', metavar='FILE',
        help='Flange poses in the robot base: CSV, whitespace-separated text or JSON (:mod:`handeye.app.ingest.poses`), or '
             'the controller\'s own file: FANUC .ls, KUKA .src/.dat, ABB .mod, URScript, UR RTDE log '
             '(:mod:`handeye.app.ingest.controllers`).',
        kind='path'),
    Opt('--accept-frames', action='store_true',
        help="A controller file's poses taught in a tool other than the flange (FANUC UT, KUKA TOOL_NO, ABB tooldata, "
             "URScript set_tcp, RTDE tcp_offset) or in a user frame other than the robot base (UF, BASE_NO, wobjdata) "
             "read as flange poses in the base: only when that tool is zero and that frame the base (one of each)."),
    Opt('--still', metavar='MM,DEG,S',
        help="A UR RTDE log streamed while the robot moves is read as its stops: the TCP within MM of each stop's median "
             "position, its rotation and every joint within DEG, for at least S seconds, one pose per stop, its median "
             "(:mod:`handeye.app.ingest.controller_rtde`; default 0.1,0.05,0.2)."),
    Opt('--profiles', (), action='extend', nargs='+', metavar='PATH',
        help="Profile files (many: a shell glob as `--profiles scans/*.yml` gives them all), a quoted glob "
             "(`'scans/*.yml'`) or folders (:mod:`handeye.app.ingest.clouds`), one profile per pose; every word up to "
             "the next option is one, so give OUT first."),
    Opt('--clouds', (), action='extend', nargs='+', metavar='PATH',
        help="Instead of --profiles, a 3-D sensor's point cloud of the sphere per pose (x, y, z in the sensor frame; the "
             "same files, globs and folders, PLY, PCD, npy, CSV): the sphere is fitted to each "
             "(:mod:`handeye.model.datasets.cloud_rows`), its radius held at --diameter / 2 or, without it, free."),
    Opt('--centres', metavar='FILE',
        help="Instead of --profiles, the sphere centre a 3-D sensor reported per pose: a table of xs,ys,zs (or x,y,z; "
             "sensor frame, mm) with an optional id, paired by id or order; no --diameter needed.",
        kind='path'),
    Opt('--convention', check=ONE_OF, choices=tuple(CONVENTIONS),
        help="Of a headerless pose file, and of the dataset (named columns are converted to it); default the file's, abb for a"
             " bag."),
    Opt('--columns', metavar='NAMES', help="the pose file's columns, e.g. id,x,y,z,qx,qy,qz,qw; - skips one"),
    Opt('--units', 'mm', check=ONE_OF, choices=('mm', 'm'), help='Positions of the pose file.'),
    Opt('--angles', check=ONE_OF, choices=('deg', 'rad'),
        help="units of the pose angles (default the convention's: degrees, radians for ur)"),
    Opt('--profile-units', check=ONE_OF, choices=('mm', 'm'),
        help="Profile, cloud and centre coordinates (default mm; a bag's are metres)."),
    Opt('--profile-axes', metavar='X,Z',
        help="``X,Z``: the profile files' axes that are handeye's sensor x and z (``y,-x``); default found from the data "
             "(:mod:`handeye.app.ingest.plane`)."),
    Opt('--diameter', check=('number', 0.0, 10_000.0, True), type='float', metavar='MM',
        help='sphere diameter, mm (required with profiles unless --setup gives it; with --clouds it holds their radius)'),
    Opt('--setup', metavar='SETUP.toml',
        help='An existing ``setup.toml`` whose ``[sphere] diameter``, ``center`` and ``mount``, ``[profile] side``, '
             '``[sensor] start_pose`` and ``mount``, ``[positioner] axes`` and ``[robot] convention`` and ``model`` fill '
             'the options not given.',
        kind='path'),
    Opt('--side', check=ONE_OF, type='int', choices=(1, -1),
        help="Sign of the sphere centre's coordinate along the laser plane's normal in the profiles' own frame (their y for "
             "2-column profiles; default -1); written as ``[profile] side`` in handeye's frame "
             "(:meth:`~handeye.app.ingest.plane.PlaneMapping.side`)."),
    Opt('--center', metavar='X,Y,Z',
        help="sphere centre in its mount's frame, mm: the robot base (default), the flange (--sphere-mount flange) or the "
             "table at zero angles (positioner); without it: calibrate with --unknowns sensor+sphere",
        pytype='str or sequence of 3 floats, optional'),
    Opt('--start', metavar='X,Y,Z,...',
        help="Start sensor pose in its mount's frame (the flange; the robot base with --sensor-mount world) in the "
             "dataset's convention and the sensor's own frame (the frame of the profile files; ``[sensor] start_pose``).",
        pytype='str or sequence, optional'),
    Opt('--sensor-mount', check=ONE_OF, choices=('flange', 'world'),
        help="where the sensor is: on the flange (default) or fixed in the cell (``[sensor] mount``)"),
    Opt('--sphere-mount', check=ONE_OF, choices=('world', 'flange', 'positioner'),
        help="Where the sphere is: fixed in the cell (default), on the flange or on a positioner's table (``[sphere] "
             "mount``); the cells: flange/world, world/flange, flange/positioner (:mod:`handeye.app.ingest.mounts`)."),
    Opt('--positioner-axes', metavar='NAME:PX,PY,PZ:DX,DY,DZ;...',
        help="With --sphere-mount positioner: its nominal axes ``'e1:px,py,pz:dx,dy,dz;e2:...'`` (robot base at zero "
             "angles, mm), base first (``[positioner] axes``); the pose file's columns named as the axes hold each "
             "pose's angles, degrees."),
    Opt('--joints', metavar='FILE', help='joint angles j1..j6 per pose, degrees (needs --robot)',
        kind='path'),
    Opt('--robot', metavar='MODEL',
        help='``[robot] model``: a built-in model name (``handeye.model.robot.robots``) or a model file.'),
    Opt('--pair', 'auto', check=ONE_OF, choices=('auto', 'id', 'order'),
        help='How profiles are paired with poses (:mod:`handeye.app.ingest.pairing`).'),
    Opt('--match', metavar='REGEX',
        help="regex with one group: the pose id in a profile's file name (default: the last digits)"),
    Opt('--bag', metavar='PATH',
        help="A ROS 2 bag instead of ``poses`` and ``profiles`` (needs ``pip install 'handeye[ros]'``).",
        kind='path'),
    Opt('--pose-topic', metavar='TOPIC',
        help='geometry_msgs/PoseStamped, or /tf with --base-frame and --flange-frame'),
    Opt('--profile-topic', metavar='TOPIC',
        help='sensor_msgs/PointCloud2 or sensor_msgs/LaserScan'),
    Opt('--base-frame', metavar='FRAME',
        help='with /tf: the robot base frame'),
    Opt('--flange-frame', metavar='FRAME',
        help='with /tf: the flange frame'),
    Opt('--max-dt', 0.05, check=('number', 0.0, float('inf'), True), type='float', metavar='SECONDS',
        help='largest time between a profile and its pose (default 0.05)'),
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
                         "handeye.app.public.api:calibrate"),
    "datasets": Command("list the embedded datasets", ()),
    "simulate": Command("write a simulated dataset with known truth (handeye.model.simulation.simulate)", _SIMULATE,
                        "handeye.app.public.making:simulate"),
    "diagnose": Command("find, name and add the effects the model is missing", _DIAGNOSE, "handeye.app.public.api:diagnose"),
    "plan": Command("choose the N most informative poses (D-optimal) from candidates", _PLAN, "handeye.app.public.making:plan"),
    "compare": Command("which of two calibrations fits a dataset better, and whether significantly", _COMPARE,
                       "handeye.app.public.api:compare"),
    "report": Command("one self-contained HTML file of a calibration: the cell in 3-D, verdict, residual table, figures",
                      _REPORT, "handeye.app.public.reporting:report"),
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
