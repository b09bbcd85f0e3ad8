"""The ``handeye`` command line's arguments: every subcommand's options, and the parser that
turns an argparse error into one line (exit 2; with ``--json`` its JSON object too).

Imports only the standard library and the names of the options (:mod:`handeye.app.choices`,
:mod:`handeye.model.names`), so that ``handeye --help`` never loads numpy
(:mod:`handeye.app.cli` runs the commands).
"""
from __future__ import annotations

import argparse
import sys

EXIT_BAD_INPUT = 2


def dumps(data):
    """JSON text of a result (:func:`handeye.app.present.results.dumps`, imported when needed)."""
    from handeye.app.present.results import dumps as to_json

    return to_json(data)


class Parser(argparse.ArgumentParser):
    def error(self, message):
        """The one line that matters and where to read more; no usage block (exit 2)."""
        if message.endswith("expected one argument"):  # `--sensor-pose -1750,...`: the value read as an option
            message += " (a value that starts with '-' is written --option=VALUE, e.g. --sensor-pose=-1750,...)"
        sys.stderr.write(f"{self.prog}: error: {message}\nsee `{self.prog} --help`\n")
        if json_wanted:  # the JSON of every exit: this one's too
            sys.stdout.write(dumps({"error": f"{self.prog}: {message}", "exit_code": EXIT_BAD_INPUT}) + "\n")
        raise SystemExit(EXIT_BAD_INPUT)


#: Set by :func:`handeye.app.cli.main`: ``--json`` among the arguments (an argparse error prints its
#: JSON object too).
json_wanted = False


def _plan_args(sub):
    plan = sub.add_parser("plan", help="choose the N most informative poses (D-optimal) from candidates")
    plan.add_argument("--n", type=int, default=None,
                      help="number of poses to choose (default 12; with a robot the number its --target takes)")
    plan.add_argument("--candidates", default=None, metavar="CSV",
                      help="candidate flange poses (a pose list in any convention, told by its header); default: the "
                           "thesis strategy's 36 orientations x 3 cuts scaled to the sphere (108 poses)")
    plan.add_argument("--dataset", default=None,
                      help="take the nominal sensor pose (start_pose), sphere centre and diameter, laser side and "
                           "robot convention from this dataset")
    plan.add_argument("--out", default=None, metavar="CSV",
                      help="write the chosen poses as a pose list in the dataset's convention (KUKA without --dataset)")
    plan.add_argument("--max-tilt", type=float, default=90.0, metavar="DEG",
                      help="largest sensor tilt from straight down of the candidates (default 90, the thesis's)")
    plan.add_argument("--margin", default=None, metavar="MM,DEG",
                      help="the nominal sensor pose may be off by this much: every planned pose still sees the sphere")
    plan.add_argument("--workspace", default=None, metavar="XMIN,XMAX,YMIN,YMAX,ZMIN,ZMAX",
                      help="flange positions allowed (robot base, mm); candidates outside are skipped")
    plan.add_argument("--score", default=None, metavar="CSV",
                      help="predict the accuracy of this pose list instead of choosing poses")
    plan.add_argument("--sensor-mount", default="flange", choices=["flange", "world"],
                      help="without --dataset: plan for `handeye simulate`'s nominal cell of these mounts")
    plan.add_argument("--sphere-mount", default="world", choices=["world", "flange", "positioner"],
                      help="without --dataset (with it: its setup.toml's mounts); on a positioner every pose list "
                           "carries one column per axis (degrees) after the pose's, and the plan chooses axis angles")
    plan.add_argument("--robot", default=None, metavar="MODEL",
                      help="plan for the robot's own errors too (default with a --dataset that has [robot] model): a "
                           "built-in nominal model (kr60ha, ur5e, ur10e, irb4600, m20ia) or a model file; poses reached "
                           "by its inverse kinematics, the other wrist a candidate of its own, j1..j6 in --out")
    plan.add_argument("--effects", default=None, metavar="NAME[,NAME]",
                      help="with a robot: joint_offsets (default), link_lengths, joint_compliance")
    plan.add_argument("--target", default=None, metavar="EFFECT=SD[,EFFECT=SD]",
                      help="with a robot: the 1-sd to reach, which sets how many poses (default joint_offsets=0.01 deg, "
                           "link_lengths=0.05 mm, joint_compliance=0.005 deg/m)")
    plan.add_argument("--sigma", type=float, default=None, metavar="MM",
                      help="with a robot: stated noise per component of a sphere centre (default [noise] centre_mm, "
                           "else 0.05)")
    plan.add_argument("--json", action="store_true")


def _compare_args(sub, alpha, kinds):
    co = sub.add_parser("compare", help="which of two calibrations fits a dataset better, and whether significantly")
    co.add_argument("dataset", help="embedded dataset name or folder")
    co.add_argument("a", metavar="A.json", help="a saved calibration (calibrate --out)")
    co.add_argument("b", metavar="B.json", help="another saved calibration")
    co.add_argument("--unknowns", default=None, choices=["sensor", "sensor+sphere"],
                    help="sensor+sphere fits the sphere centre with each pose held (default: sensor when setup.toml "
                         "gives [sphere] center, else sensor+sphere)")
    co.add_argument("--model", default=None, choices=list(kinds), help="residual model both are scored with (default: "
                                                                      "as calibrate)")
    co.add_argument("--alpha", type=float, default=None, help=f"level of 'significant' and of the screening (default "
                                                               f"{alpha:g})")
    co.add_argument("--keep-all", action="store_true", help="score every sample: no outlier screening")
    co.add_argument("--sigma", type=float, default=None, metavar="MM", help="stated noise, as calibrate's")
    co.add_argument("--robot-sigma", type=float, default=None, metavar="MM", help="robot repeatability, as calibrate's")
    co.add_argument("--json", action="store_true")


def _report_args(sub, conventions, kinds):
    rep = sub.add_parser("report", help="one self-contained HTML file of a calibration: the cell in 3-D, verdict, "
                                        "residual table, figures")
    rep.add_argument("dataset", nargs="?", default="thesis-real", help="embedded dataset name or folder")
    rep.add_argument("--html", required=True, metavar="OUT.html", help="the report to write (atomically)")
    rep.add_argument("--calibration", default=None, metavar="FILE",
                     help="a calibrate --out file of this dataset (its SHA-256 is checked), reported as it is; "
                          "default: calibrate now")
    rep.add_argument("--diagnose", action="store_true",
                     help="also run handeye diagnose and show its steps against the noise floor")
    rep.add_argument("--unknowns", default=None, metavar="PARTS",
                     help="as calibrate's, default sensor (without --calibration)")
    rep.add_argument("--model", default=None, choices=list(kinds), help="as calibrate's (without --calibration)")
    rep.add_argument("--convention", default=None, choices=list(conventions),
                     help="robot convention of the reported pose (default: the dataset's)")
    rep.add_argument("--keep-all", action="store_true", help="as calibrate's (without --calibration)")
    rep.add_argument("--no-clean", action="store_true", help="as calibrate's")
    rep.add_argument("--json", action="store_true", help="print what was written as JSON")


def _study_args(sub):
    from handeye.app.tools.registry import STUDIES  # names only: the studies are imported when one runs

    st = sub.add_parser("study", help="run a study (figures, tables, JSON) and check its claims")
    st.add_argument("name", choices=list(STUDIES) + ["all"])
    st.add_argument("--out", default="out", metavar="DIR", help="output folder (default ./out)")
    st.add_argument("--quick", action="store_true", help="small, honest version (CI)")
    st.add_argument("--jobs", type=int, default=None, help="worker processes for sweeps (default: all cores)")
    st.add_argument("--dask", default=None, metavar="ADDRESS|local",
                    help="run the sweeps on a Dask cluster: a scheduler address, or 'local' for a LocalCluster with "
                         "one worker process per core (--jobs of them when given); needs handeye[dask]")


def _export_args(sub, calibration):
    """``export``'s options; ``calibration(parser, option)`` adds the calibration's own."""
    from handeye.app.choices import FORMATS, ROBOT_FORMATS

    ex = sub.add_parser("export", help="write a saved calibration for UR, ROS 2, URDF, KUKA, ABB, FANUC, a matrix or "
                                       "JSON (handeye.app.outputs.formats)")
    calibration(ex, option=False)
    ex.add_argument("--format", choices=FORMATS + ROBOT_FORMATS, default="json",
                    help="what to write (default json: every format's numbers; robot-toml, robot-urdf: the robot's "
                         "model corrected by calibrated joint_offsets and link_lengths; its flange link is tool0)")
    ex.add_argument("--parent", default=None, help="parent frame name (ros2, urdf; default flange, or base_link for a "
                                                   "sensor fixed in the cell)")
    ex.add_argument("--child", default="sensor", help="sensor frame name (ros2, urdf, tool, base and variable names; "
                                                      "default sensor)")
    ex.add_argument("--tool", type=int, default=None, help="tool number of a sensor on the flange (KUKA TOOL_DATA, "
                                                           "FANUC UTOOL; default 1)")
    ex.add_argument("--base", type=int, default=None, help="base / user frame number of a sensor fixed in the cell "
                                                           "(KUKA BASE_DATA, FANUC UFRAME; default 1)")
    ex.add_argument("--register", type=int, default=99,
                    help="FANUC position register the TP program overwrites (default 99)")
    ex.add_argument("--sensor-mount", choices=("flange", "world"), default=None,
                    help="where the --sensor-pose is: on the flange (default) or fixed in the cell, the pose in the "
                         "robot base (a saved calibration says itself)")
    ex.add_argument("--out", default=None, metavar="FILE", help="write to FILE (atomically) instead of stdout")


def _use_args(sub, conventions):
    """``export``, ``cloud`` and ``validate``: what comes after a calibration."""
    from handeye.app.choices import CLOUD_FORMATS

    def calibration(p, option=True):
        """--calibration (or, for export, a positional RESULT.json), --sensor-pose, --convention, --force."""
        if option:
            p.add_argument("--calibration", default=None, metavar="RESULT.json",
                           help="a saved calibration (handeye calibrate DATASET --out RESULT.json)")
        else:
            p.add_argument("result", nargs="?", default=None, metavar="RESULT.json",
                           help="a saved calibration (handeye calibrate DATASET --out RESULT.json)")
        p.add_argument("--sensor-pose", default=None, metavar="X,Y,Z,...",
                       help="instead: a sensor pose on the flange typed in (e.g. the controller's TCP; export: or "
                            "in the robot base, with --sensor-mount world), in --convention's columns; no "
                            "uncertainty then")
        p.add_argument("--convention", choices=conventions, default=None,
                       help="convention of --sensor-pose (default: the dataset's; export has none: required)")
        p.add_argument("--force", action="store_true", help="use a calibration that did not converge")

    _export_args(sub, calibration)
    cl = sub.add_parser("cloud", help="every profile point of a scan in the robot base, through a calibration "
                                      "(PLY or CSV)")
    cl.add_argument("dataset", help="a scan or dataset folder with profiles (no sphere needed); every profile point, "
                                    "not cleaned (calibrate's profile cleaning does not apply)")
    calibration(cl)
    cl.add_argument("--out", required=True, metavar="FILE", help="the point cloud to write")
    cl.add_argument("--format", choices=CLOUD_FORMATS, default=None,
                    help="ply: binary little-endian, x y z double, pose int, sd float; csv (default: from --out's "
                         "extension, .csv is CSV, else PLY)")
    cl.add_argument("--json", action="store_true", help="print the summary as JSON")
    va = sub.add_parser("validate", help="measure the setup's sphere through a calibration: VDI/VDE 2634-2 PF, PS, "
                                         "SD and the centre, with their 1 sd")
    va.add_argument("dataset", help="a scan or dataset folder (profiles: sphere fit of every point, not cleaned -- a "
                                    "form test sees every point; --exclude leaves the worst out; without: sphere centres)")
    calibration(va)
    va.add_argument("--exclude", type=float, default=0.0, metavar="FRACTION",
                    help="leave out this fraction of points with the largest deviations (VDI/VDE 2634-2 allows "
                         "0.003; default 0)")
    va.add_argument("--mpe", default=None, metavar="PF,PS[,SD]",
                    help="maximum permissible errors (mm): exit 1 when PF, |PS| or |SD| exceeds its limit")
    va.add_argument("--json", action="store_true", help="print the result as JSON")
    va.add_argument("--plot", default=None, metavar="FILE",
                    help="radial deviations on the sphere (3-D) and their histogram")


def _dataset_args(sub):
    """``handeye dataset new OUT``: a dataset folder from loose files or a ROS 2 bag (handeye.app.ingest)."""
    ds = sub.add_parser("dataset", help="make a dataset folder: `handeye dataset new OUT` from loose files or a ROS 2 bag")
    actions = ds.add_subparsers(dest="action", required=True, parser_class=Parser)
    new = actions.add_parser("new", help="assemble a dataset folder (measurements.csv, setup.toml, profiles/, "
                                         "PROVENANCE.toml) from loose pose and profile files or a ROS 2 bag")
    new.add_argument("out", metavar="OUT", help="dataset folder to write (new or empty)")
    new.add_argument("--poses", metavar="FILE", help="flange poses in the robot base: CSV, whitespace text or JSON "
                                                     "(told by the content); header optional")
    new.add_argument("--profiles", action="append", default=[], metavar="FILES|GLOB|DIR",
                     help="laser profiles, one per pose (repeatable): OpenCV FileStorage YAML/XML/JSON, CSV/TXT with "
                          "2 (x,z) or 3 (x,y,z) columns, .npy/.npz, PLY, PCD")
    new.add_argument("--convention", choices=("kuka", "abb", "ur", "fanuc"), default=None,
                     help="the poses' convention (a headerless file's columns in order, optional leading id); the "
                          "dataset is written in it (named columns of another convention are converted; default: the "
                          "file's, abb for a bag)")
    new.add_argument("--columns", metavar="NAMES", help="the pose file's columns, e.g. id,x,y,z,qx,qy,qz,qw; - skips one")
    new.add_argument("--units", choices=("mm", "m"), default="mm", help="units of the pose positions (default mm)")
    new.add_argument("--angles", choices=("deg", "rad"), default=None,
                     help="units of the pose angles (default the convention's: degrees, radians for ur)")
    new.add_argument("--profile-units", choices=("mm", "m"), default=None, help="units of the profiles (default mm)")
    new.add_argument("--profile-axes", metavar="X,Z", help="the profile files' axes that are handeye's sensor x and z "
                                                           "(e.g. y,-x); default found from the data")
    new.add_argument("--diameter", type=float, metavar="MM", help="sphere diameter, mm (required unless --setup gives it)")
    new.add_argument("--setup", metavar="SETUP.toml", help="an existing setup.toml: its sphere diameter and centre, side, "
                                                          "start pose, convention and robot model fill the options not given")
    new.add_argument("--side", type=int, choices=(1, -1), default=None,
                     help="sign of the sphere centre's coordinate along the laser plane's normal in the profiles' own "
                          "frame (their y; default -1); written in handeye's frame")
    new.add_argument("--center", metavar="X,Y,Z", help="sphere centre in the robot base, mm (without it: calibrate "
                                                       "with --unknowns sensor+sphere)")
    new.add_argument("--start", metavar="X,Y,Z,...", help="start sensor pose on the flange, in the convention's columns")
    new.add_argument("--joints", metavar="FILE", help="joint angles j1..j6 per pose, degrees (needs --robot)")
    new.add_argument("--robot", metavar="MODEL", help="[robot] model: a built-in nominal model or a model file")
    new.add_argument("--pair", choices=("auto", "id", "order"), default="auto",
                     help="pair profiles with poses by a number in the file name (id), by order, or auto (default)")
    new.add_argument("--match", metavar="REGEX", help="regex with one group: the pose id in a profile's file name "
                                                      "(default: the last digits)")
    new.add_argument("--bag", metavar="PATH", help="a ROS 2 bag (sqlite3 or mcap) instead of --poses/--profiles "
                                                   "(pip install 'handeye[ros]')")
    new.add_argument("--pose-topic", metavar="TOPIC",
                     help="geometry_msgs/PoseStamped, or /tf with --base-frame and --flange-frame")
    new.add_argument("--profile-topic", metavar="TOPIC", help="sensor_msgs/PointCloud2 or sensor_msgs/LaserScan")
    new.add_argument("--base-frame", metavar="FRAME", help="with /tf: the robot base frame")
    new.add_argument("--flange-frame", metavar="FRAME", help="with /tf: the flange frame")
    new.add_argument("--max-dt", type=float, default=0.05, metavar="SECONDS",
                     help="largest time between a profile and its pose (default 0.05)")
    new.add_argument("--json", action="store_true", help="print the summary as JSON")


def _calibrate_args(sub):
    from handeye.app.choices import ALPHA as alpha
    from handeye.app.choices import CLASSIC_METHODS as classic
    from handeye.app.choices import METHODS as methods
    from handeye.model.names import CONVENTIONS as conventions
    from handeye.model.names import KINDS as kinds
    from handeye.model.names import ROTATIONS as rotations

    cal = sub.add_parser("calibrate", help="calibrate the sensor pose on the flange from a dataset")
    cal.add_argument("dataset", nargs="?", default="thesis-real", help="embedded dataset name or folder (default thesis-real)")
    cal.add_argument("--unknowns", default="sensor", metavar="PARTS",
                     help="what to estimate, +-joined: sensor, sphere, positioner (default sensor; e.g. sensor+sphere, "
                          "sphere+positioner, sensor+sphere+positioner); a part not estimated comes from setup.toml "
                          "or --calibration")
    cal.add_argument("--calibration", default=None, metavar="FILE",
                     help="a saved calibration (calibrate --out) whose sensor pose is held: calibrating the other parts "
                          "when --unknowns has no sensor, else scored as --sensor-pose is")
    cal.add_argument("--sensor-pose", default=None, metavar="X,Y,Z,...",
                     help="score this sensor pose (e.g. the vendor's, in --convention's columns) instead of calibrating "
                          "it: held, the sphere centre fitted with it under --unknowns sensor+sphere, judged against the "
                          "data's own calibration (exit 0; the verdict says whether the data contradict it); --calibration "
                          "FILE with the sensor among --unknowns does the same")
    cal.add_argument("--method", default=None, choices=list(methods) + list(classic),
                     help="solver of the least squares (default ipopt; lm above 5,000 measurements), or a closed-form "
                          "baseline: kim-cho (AX = XB, linear) or li-two-step (pure translations, then rotations; see "
                          "model/classics.py)")
    cal.add_argument("--rotation", default=None, choices=list(rotations),
                     help="rotation parametrisation (default: matrix for ipopt, local otherwise)")
    cal.add_argument("--start", default=None, metavar="X,Y,Z,A,B,C",
                     help="start sensor pose in --convention's columns (KUKA: mm and degrees; "
                          "write --start=-1,2,... for a leading minus)")
    cal.add_argument("--convention", default=None, choices=list(conventions),
                     help="robot convention of --start and of the reported pose (default: the dataset's)")
    cal.add_argument("--max-iter", type=int, default=None, help="iteration limit")
    cal.add_argument("--model", default=None, choices=list(kinds),
                     help="residual: reconstructed centres, measured circles, or profile points "
                          "(default: measurement when every sample has a profile, else centre)")
    cal.add_argument("--keep-all", action="store_true",
                     help="fit every sample: no outlier detection (rows that contradict themselves are still excluded)")
    cal.add_argument("--alpha", type=float, default=None,
                     help=f"family-wise level of the outlier tests (default {alpha:g})")
    cal.add_argument("--no-loo", action="store_true", help="skip the leave-one-out error (one refit per sample)")
    cal.add_argument("--no-clean", action="store_true",
                     help="fit every profile point: no profile cleaning (by default speckle and background points off "
                          "the sphere's arc are dropped and reported)")
    cal.add_argument("--sigma", type=float, default=None, metavar="MM",
                     help="stated noise of a sphere centre (mm per component) the centre residual is tested "
                          "against (default: setup.toml [noise] centre_mm, else 0.05); the profile models are "
                          "tested against each circle fit's covariance and --robot-sigma instead")
    cal.add_argument("--robot-sigma", type=float, default=None, metavar="MM",
                     help="robot repeatability, mm per axis (default: [noise] robot_mm, else 0.025)")
    cal.add_argument("--effects", default=None, metavar="NAME[,NAME]",
                     help="calibrate with catalogue effects: sensor_scale, sphere_radius, sphere_center "
                          "(as handeye diagnose names them)")
    cal.add_argument("--json", action="store_true", help="print the result as JSON")
    cal.add_argument("--plot", default=None, metavar="FILE", help="draw residuals and sphere-centre scatter (PNG)")
    cal.add_argument("--report", default=None, metavar="OUT.html",
                     help="also write the one-file HTML report (handeye report): the cell in 3-D, verdict, residuals")
    cal.add_argument("--out", default=None, metavar="FILE",
                     help="also write the JSON result, with the dataset's hash, tool version and options, atomically")


def _simulate_args(sub, conventions):
    sim = sub.add_parser("simulate", help="write a simulated dataset with known truth (handeye.model.simulate)")
    sim.add_argument("--out", required=True, metavar="DIR", help="dataset folder to write (must be empty or new)")
    sim.add_argument("--seed", type=int, default=0)
    sim.add_argument("--effect", action="append", default=[], metavar="NAME=VALUE",
                     help="hidden effect: sphere_center=dx,dy,dz | sensor_scale=s | sphere_radius=dr | "
                          "sign_flip=ID,ID | outlier=ID,ID | with --robot: joint_offsets=j2:0.05,j3:-0.03 (degrees), "
                          "link_lengths=a2:0.3,d4:-0.2 (mm, the model's length names), joint_compliance=j2:0.02,j3:0.01 "
                          "(degrees per metre of lever) (repeatable)")
    sim.add_argument("--robot", default=None, metavar="MODEL",
                     help="simulate a robot with joints: a nominal model (irb4600, kr60ha, m20ia, ur10e, ur5e or a "
                          "model file) reaches the poses by inverse kinematics; writes j1..j6 and [robot] model "
                          "(default sphere centre inside its workspace)")
    sim.add_argument("--profiles", action="store_true", help="also write the laser profiles")
    sim.add_argument("--poses", default=None, metavar="CSV",
                     help="flange poses (a pose list in any convention: id,x,y,z,a,b,c is KUKA, id,x,y,z,rx,ry,rz UR, "
                          "...) instead of the thesis strategy")
    sim.add_argument("--n-poses", type=int, default=36, help="poses of the thesis strategy (1-36)")
    sim.add_argument("--linearity", type=float, default=0.0,
                     help="sensor linearity error as a fraction of the 100 mm range (data sheet: 0.0016)")
    sim.add_argument("--motions", default="thesis", choices=["thesis", "about-sphere"],
                     help="thesis: the seed's 36 orientations, sphere seen at random points; about-sphere: the same "
                          "orientations rotating about the sphere (seen at one sensor point)")
    sim.add_argument("--translations", type=int, default=0, metavar="K",
                     help="add K pure flange translations (0..6) at each of two orientations (Li et al.'s first step)")
    sim.add_argument("--truth", default=None, metavar="POSE",
                     help="true sensor pose in its mount's frame, in --convention's columns (default KUKA "
                          "190,100,125,180,-88,0 on the flange; 1750,-50,1000,90,0,-110 in the cell)")
    sim.add_argument("--diameter", type=float, default=None, metavar="MM", help="sphere diameter (default 59.94507)")
    sim.add_argument("--center", default=None, metavar="X,Y,Z",
                     help="sphere centre in its mount's frame (robot base, flange or table), mm")
    sim.add_argument("--convention", default="kuka", choices=list(conventions),
                     help="robot convention of the written dataset and of --truth (default kuka)")
    sim.add_argument("--max-tilt", type=float, default=90.0, metavar="DEG",
                     help="largest sensor tilt from straight down (default 90, the thesis's)")
    sim.add_argument("--no-start", action="store_true", help="write no start pose (calibrate starts from the closed form)")
    sim.add_argument("--sensor-mount", default="flange", choices=["flange", "world"],
                     help="where the sensor is: on the flange (default) or fixed in the cell (robot base frame)")
    sim.add_argument("--sphere-mount", default="world", choices=["world", "flange", "positioner"],
                     help="where the sphere is: fixed in the cell (default), on the flange or on a positioner's table; "
                          "observable pairs: flange/world, world/flange, flange/positioner")
    sim.add_argument("--positioner-axes", default=None, metavar="NAME:PX,PY,PZ:DX,DY,DZ;...",
                     help="nominal positioner axes, base first: point and direction in the robot base at zero angles "
                          "(mm); default a KUKA KP1-V-like 2-axis positioner: e1:1500,0,600:0,1,0;e2:1500,0,800:0,0,1")
    sim.add_argument("--positioner-error", default=None, metavar="MM,DEG",
                     help="how far the true axes differ from the nominal ones written in setup.toml (default 1.0,0.2)")


def _diagnose_args(sub, alpha):
    diag = sub.add_parser("diagnose", help="find, name and add the effects the model is missing")
    diag.add_argument("dataset", nargs="?", default="thesis-real")
    diag.add_argument("--alpha", type=float, default=alpha, help=f"family-wise level of the tests (default {alpha:g})")
    diag.add_argument("--json", action="store_true")
    diag.add_argument("--no-clean", action="store_true", help="fit every profile point: no profile cleaning")
    diag.add_argument("--figures", default=None, metavar="DIR", help="write residuals.png and gap.png here")
    diag.add_argument("--plot", default=None, metavar="FILE", help="draw the gap shrinking step by step (PNG)")
    diag.add_argument("--sigma", type=float, default=None, metavar="MM",
                      help="nominal noise per residual component for chi2/dof (default: [noise] centre_mm, else 0.05)")
    diag.add_argument("--out", default=None, metavar="FILE", help="also write the JSON result with provenance")
    diag.add_argument("--unknowns", default="sensor", choices=["sensor", "sensor+sphere"],
                      help="sensor+sphere: the sphere centre estimated with the pose in every model (when setup.toml "
                           "gives none); default sensor: effects tested against the setup's centre")


def _bench_args(sub):
    bench = sub.add_parser("bench", help="time every method on the same calibrations, side by side")
    bench.add_argument("--quick", action="store_true", help="fewer cases and repetitions")
    bench.add_argument("--json", action="store_true")
    bench.add_argument("--plot", default=None, metavar="FILE", help="log-log time against measurements (PNG)")
    bench.add_argument("--no-startup", action="store_true", help="skip the cold/warm start-up measurement")
    bench.add_argument("--pipeline-sizes", default=None, metavar="N,N,...",
                       help="measurements of the end-to-end `handeye calibrate` section (time and own peak memory "
                            "each, log-log slopes); default 1000,10000,100000,1000000 (--quick: 10000,30000); 0: skip")
    bench.add_argument("--solvers", action="store_true",
                       help="instead: the solver-comparison bench (batched against single-start solvers, and the "
                            "wall time of the full `handeye study testfunction`)")
    bench.add_argument("--no-study", action="store_true", help="with --solvers: skip running the study")


def build_parser():
    from handeye.app.choices import ALPHA
    from handeye.model.names import CONVENTIONS, KINDS

    parser = Parser(prog="handeye", description="Hand-eye calibration workbench (laser-line sensor, sphere).")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=Parser)
    _calibrate_args(sub)
    sub.add_parser("datasets", help="list the embedded datasets")
    _simulate_args(sub, CONVENTIONS)
    _diagnose_args(sub, ALPHA)
    _plan_args(sub)
    _compare_args(sub, ALPHA, KINDS)
    _report_args(sub, CONVENTIONS, KINDS)
    _use_args(sub, list(CONVENTIONS))
    _study_args(sub)
    _dataset_args(sub)
    _bench_args(sub)
    return parser
