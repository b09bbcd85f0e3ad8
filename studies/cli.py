"""The ``handeye`` command line.

Exit codes
----------
0  calibration converged
1  calibration did not converge (the result is still printed, and flagged)
2  bad input: unreadable or malformed dataset, bad option, too few or degenerate poses;
   one line on stderr naming file, row and column where there is one
3  internal error (a bug; set HANDEYE_DEBUG=1 for the traceback)
4  a study's data did not support its claim (``handeye study``)
"""
from __future__ import annotations

import argparse
import json
import os
import sys

EXIT_OK, EXIT_NOT_CONVERGED, EXIT_BAD_INPUT, EXIT_INTERNAL, EXIT_CLAIM_FAILED = 0, 1, 2, 3, 4


class _Parser(argparse.ArgumentParser):
    def error(self, message):
        self.print_usage(sys.stderr)
        print(f"handeye: error: {message}", file=sys.stderr)
        raise SystemExit(EXIT_BAD_INPUT)


def _plan_args(sub):
    plan = sub.add_parser("plan", help="choose the N most informative poses (D-optimal) from candidates")
    plan.add_argument("--n", type=int, default=12, help="number of poses to choose (default 12)")
    plan.add_argument("--candidates", default=None, metavar="CSV",
                      help="candidate flange poses (header id,x,y,z,a,b,c); default: the thesis strategy's 36 "
                           "orientations with cuts at 5, 15 and 25 mm (108 poses)")
    plan.add_argument("--dataset", default=None,
                      help="take the nominal sensor pose (start_pose), sphere centre and diameter from this dataset")
    plan.add_argument("--out", default=None, metavar="CSV", help="write the chosen poses (id,x,y,z,a,b,c)")
    plan.add_argument("--json", action="store_true")


def _study_args(sub):
    from studies.study import STUDIES

    st = sub.add_parser("study", help="run a study (figures, tables, JSON) and check its claims")
    st.add_argument("name", choices=list(STUDIES) + ["all"])
    st.add_argument("--out", default="out", metavar="DIR", help="output folder (default ./out)")
    st.add_argument("--quick", action="store_true", help="small, honest version (CI)")
    st.add_argument("--jobs", type=int, default=None, help="worker processes for sweeps (default: all cores)")


def build_parser():
    from studies.calibrate import METHODS
    from studies.classic import METHODS as CLASSIC_METHODS

    parser = _Parser(prog="handeye", description="Hand-eye calibration workbench (laser-line sensor, sphere).")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    cal = sub.add_parser("calibrate", help="calibrate the sensor pose on the flange from a dataset")
    cal.add_argument("dataset", nargs="?", default="thesis-real", help="embedded dataset name or folder (default thesis-real)")
    cal.add_argument("--unknowns", default="sensor", choices=["sensor", "sensor+sphere"])
    cal.add_argument("--method", default="ipopt", choices=list(METHODS) + list(CLASSIC_METHODS),
                     help="solver of the least squares, or a closed-form baseline: kim-cho (AX = XB, linear) or "
                          "li-two-step (pure translations, then rotations; see model/classics.py)")
    cal.add_argument("--rotation", default=None, choices=["matrix", "local", "euler"],
                     help="rotation parametrisation (default: matrix for ipopt, local otherwise)")
    cal.add_argument("--start", default=None, metavar="X,Y,Z,A,B,C",
                     help="start sensor pose, mm and degrees (write --start=-1,2,... for a leading minus)")
    cal.add_argument("--convention", default=None, choices=["kuka", "abb", "ur", "fanuc"],
                     help="robot convention of --start and of the reported pose (default: the dataset's)")
    cal.add_argument("--max-iter", type=int, default=None, help="iteration limit")
    cal.add_argument("--model", default=None, choices=["centre", "measurement", "points"],
                     help="residual: reconstructed centres, measured circles, or profile points "
                          "(default: measurement when every sample has a profile, else centre)")
    cal.add_argument("--keep-all", action="store_true", help="fit every sample: no outlier detection")
    cal.add_argument("--alpha", type=float, default=None, help="family-wise level of the outlier tests (default 0.01)")
    cal.add_argument("--no-loo", action="store_true", help="skip the leave-one-out error (one refit per sample)")
    cal.add_argument("--json", action="store_true", help="print the result as JSON")
    cal.add_argument("--plot", default=None, metavar="FILE", help="draw residuals and sphere-centre scatter (PNG)")
    cal.add_argument("--out", default=None, metavar="FILE",
                     help="also write the JSON result, with the dataset's hash, tool version and options, atomically")
    sub.add_parser("datasets", help="list the embedded datasets")
    sim = sub.add_parser("simulate", help="write a simulated dataset with known truth (model.simulate)")
    sim.add_argument("--out", required=True, metavar="DIR", help="dataset folder to write (must be empty or new)")
    sim.add_argument("--seed", type=int, default=0)
    sim.add_argument("--effect", action="append", default=[], metavar="NAME=VALUE",
                     help="hidden effect: sphere_center=dx,dy,dz | sensor_scale=s | sphere_radius=dr | "
                          "sign_flip=ID,ID | outlier=ID,ID (repeatable)")
    sim.add_argument("--profiles", action="store_true", help="also write the laser profiles")
    sim.add_argument("--poses", default=None, metavar="CSV",
                     help="flange poses (header id,x,y,z,a,b,c) instead of the thesis strategy")
    sim.add_argument("--n-poses", type=int, default=36, help="poses of the thesis strategy (1-36)")
    sim.add_argument("--linearity", type=float, default=0.0,
                     help="sensor linearity error as a fraction of the 100 mm range (data sheet: 0.0016)")
    diag = sub.add_parser("diagnose", help="find, name and add the effects the model is missing")
    diag.add_argument("dataset", nargs="?", default="thesis-real")
    diag.add_argument("--alpha", type=float, default=0.01, help="family-wise level of the tests (default 0.01)")
    diag.add_argument("--json", action="store_true")
    diag.add_argument("--figures", default=None, metavar="DIR", help="write residuals.png and gap.png here")
    diag.add_argument("--plot", default=None, metavar="FILE", help="draw the gap shrinking step by step (PNG)")
    _plan_args(sub)
    _study_args(sub)
    bench = sub.add_parser("bench", help="time every method on the same calibrations, side by side")
    bench.add_argument("--quick", action="store_true", help="fewer cases and repetitions")
    bench.add_argument("--json", action="store_true")
    bench.add_argument("--plot", default=None, metavar="FILE", help="log-log time against measurements (PNG)")
    bench.add_argument("--no-startup", action="store_true", help="skip the cold/warm start-up measurement")
    sim.add_argument("--motions", default="thesis", choices=["thesis", "about-sphere"],
                     help="thesis: the seed's 36 orientations, sphere seen at random points; about-sphere: the same "
                          "orientations rotating about the sphere (seen at one sensor point)")
    sim.add_argument("--translations", type=int, default=0, metavar="K",
                     help="add K pure flange translations (0..6) at each of two orientations (Li et al.'s first step)")
    sim.add_argument("--truth", default=None, metavar="X,Y,Z,A,B,C", help="true sensor pose (default 190,100,125,180,-88,0)")
    return parser


def tool_version():
    """Installed version of handeye (or 'unknown' when run from a source tree)."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("handeye")
    except PackageNotFoundError:
        return "unknown (source tree)"


def provenance(args, dataset):
    """What makes a result traceable: tool version, dataset hash and every option."""
    import datetime

    return {
        "tool": "handeye",
        "version": tool_version(),
        "dataset_path": str(dataset.path),
        "dataset_sha256": dataset.content_hash(),
        "options": {k: v for k, v in vars(args).items() if k not in ("out",)},
        "created_utc": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
    }


def write_text_atomically(path, text):
    """Write ``text`` to ``path`` through a temporary file and a rename: never a half-written file."""
    import pathlib
    import tempfile

    target = pathlib.Path(path)
    folder = target.parent if str(target.parent) else pathlib.Path(".")
    if not folder.is_dir():
        raise ValueError(f"--out {path}: folder {folder} does not exist")
    with tempfile.NamedTemporaryFile("w", dir=folder, prefix=f".{target.name}.", suffix=".tmp", delete=False) as fh:
        fh.write(text)
        fh.flush()
        os.fsync(fh.fileno())
    os.replace(fh.name, target)


def write_json_atomically(path, data):
    """JSON through :func:`write_text_atomically`."""
    write_text_atomically(path, json.dumps(data, indent=1))


def _plan(args):
    import dataclasses

    import numpy as np

    from model import planning, simulate
    from model.dataset import load, read_pose_list

    setup = simulate.Setup(linearity=0.0)
    centre = np.asarray(setup.sphere_centre)
    if args.dataset is not None:
        d = load(args.dataset)
        if d.start_pose is None:
            raise ValueError(f"--dataset {args.dataset}: its setup.toml has no start_pose to plan around")
        setup = dataclasses.replace(setup, sensor_pose=tuple(d.start_pose), diameter=d.sphere_diameter, side=d.side)
        centre = d.sphere_centre
    if args.candidates is not None:
        ids, poses = read_pose_list(args.candidates)
    else:
        ids, poses = planning.thesis_candidates(setup, centre)
    if args.n < 1:
        raise ValueError("--n must be at least 1")
    result = planning.plan(ids, poses, args.n, setup, centre)
    if args.out:
        lines = ["id,x,y,z,a,b,c"] + [",".join([i] + [f"{v:.4f}" for v in p]) for i, p in zip(result.ids, result.poses)]
        write_text_atomically(args.out, "\n".join(lines) + "\n")
    report = {"n": args.n, "ids": result.ids, "poses": result.poses.tolist(), "logdet": result.logdet,
              "predicted_sd": {"sensor_translation_mm": result.predicted_sd[:3].tolist(),
                               "sensor_rotation_deg": result.predicted_sd[3:6].tolist()},
              "skipped": [{"id": i, "reason": r} for i, r in result.skipped],
              "noise_model": "simulator defaults: robot 0.025 mm, profile points 0.01 mm (model.simulate)"}
    if args.json:
        print(json.dumps(report, indent=1))
    else:
        print(f"chose {args.n} of {len(ids) - len(result.skipped)} usable candidate poses (D-optimal, log det {result.logdet:.2f})")
        print("predicted sd (Cramer-Rao bound): translation mm " + " ".join(f"{v:.4f}" for v in result.predicted_sd[:3])
              + "; rotation deg " + " ".join(f"{v:.4f}" for v in result.predicted_sd[3:6]))
        for i, p in zip(result.ids, result.poses):
            print(f"  {i:>14} " + " ".join(f"{v:10.3f}" for v in p))
        for i, r in result.skipped:
            print(f"  skipped {i}: {r}")
    return EXIT_OK


def _diagnose(args):
    from model.dataset import load
    from studies import diagnose

    if not 0 < args.alpha < 1:
        raise ValueError(f"--alpha must lie in (0, 1), got {args.alpha}")
    res = diagnose.diagnose(load(args.dataset), alpha=args.alpha)
    if args.figures:
        diagnose.figures(res, args.figures)
    if args.plot:
        import pathlib
        import shutil
        import tempfile

        with tempfile.TemporaryDirectory() as tmp:
            shutil.copyfile(diagnose.figures(res, tmp)[1], pathlib.Path(args.plot))
    print(json.dumps(res, indent=1) if args.json else diagnose.text(res))
    return EXIT_OK


def _bench(args):
    from studies import bench

    try:
        import scipy.optimize  # noqa: F401 - the baseline of every ratio
    except ImportError:
        raise ValueError("handeye bench compares against scipy, which is not installed: "
                         "pip install 'handeye[bench]'") from None

    res = bench.run(quick=args.quick, with_startup=not args.no_startup)
    if args.plot:
        bench.plot(res, args.plot)
    print(json.dumps(res, indent=1) if args.json else bench.text(res))
    return EXIT_OK


def _study(args):
    from studies import study, sweep

    if args.jobs is not None and args.jobs < 1:
        raise ValueError("--jobs must be at least 1")
    sweep.JOBS["n"] = args.jobs
    results = study.run(args.name, args.out, quick=args.quick)
    for name in results:
        print(f"study {name}: claims hold; figures, tables and summary.json in {args.out}/{name}")
    return EXIT_OK


def _simulate(args):
    import dataclasses
    import pathlib

    from model import simulate
    from model.dataset import read_pose_list
    from studies.calibrate import parse_pose

    out = pathlib.Path(args.out)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise ValueError(f"--out {out}: exists and is not an empty folder; choose a new one")
    if not 0 <= args.linearity < 0.1:
        raise ValueError(f"--linearity must lie in [0, 0.1), got {args.linearity}")
    setup = simulate.Setup(linearity=args.linearity)
    if args.truth is not None:
        setup = dataclasses.replace(setup, sensor_pose=tuple(parse_pose(args.truth, "--truth")))
    effects = simulate.parse_effects(args.effect)
    poses, ids = (None, None)
    if args.poses is not None:
        if args.motions != "thesis" or args.translations:
            raise ValueError("--poses gives the poses: --motions and --translations do not apply")
        ids, poses = read_pose_list(args.poses)
    elif args.motions != "thesis" or args.translations:
        import numpy as np

        from model import motions
        from model.pose import pose_from_transform

        ids, flanges = motions.strategy(setup, np.random.default_rng(args.seed), args.motions, args.n_poses,
                                        args.translations)
        poses = pose_from_transform(flanges)
    sim = simulate.simulate(setup, seed=args.seed, effects=effects, flange_poses=poses, n_poses=args.n_poses, ids=ids)
    simulate.write(sim, out, profiles=args.profiles)
    print(f"wrote {len(sim.ids)} simulated measurements to {out} (seed {args.seed}, effects {effects or 'none'})")
    for ident, reason in sim.dropped:
        print(f"dropped {ident}: {reason}")
    return EXIT_OK


def _alpha(args):
    """--alpha of calibrate, checked (default: the outlier tests' family-wise level)."""
    from studies.robust import ALPHA

    alpha = ALPHA if args.alpha is None else args.alpha
    if not 0 < alpha < 1:
        raise ValueError(f"--alpha must lie in (0, 1), got {alpha}")
    return alpha


def _calibrate_classic(args, dataset):
    """Result of a closed-form method; options that only the least squares has are refused."""
    from studies.classic import calibrate_classic

    ignored = [name for name, given in (("--start", args.start), ("--rotation", args.rotation),
                                        ("--max-iter", args.max_iter), ("--model", args.model), ("--plot", args.plot),
                                        ("--no-loo", args.no_loo or None))
               if given is not None]
    if ignored:
        raise ValueError(f"--method {args.method} is closed form; these options do not apply to it: {', '.join(ignored)}")
    return calibrate_classic(dataset, args.method, args.unknowns, outliers=not args.keep_all, alpha=_alpha(args))


def _calibrate(args):
    from model.dataset import load
    from studies.calibrate import calibrate, parse_pose
    from studies.classic import METHODS as CLASSIC_METHODS, classic_text
    from studies.report import calibration_text

    from model import conventions

    dataset = load(args.dataset)
    convention = args.convention or dataset.convention
    if args.method in CLASSIC_METHODS:
        res, text = _calibrate_classic(args, dataset), classic_text
    else:
        start = parse_pose(args.start, convention=convention) if args.start is not None else None
        options = {}
        if args.max_iter is not None:
            if args.max_iter < 1:
                raise ValueError("--max-iter must be at least 1")
            options["max_iter"] = args.max_iter
        res = calibrate(dataset, unknowns=args.unknowns, method=args.method, rotation=args.rotation, start=start,
                        options=options, outliers=not args.keep_all, alpha=_alpha(args), loo=not args.no_loo,
                        model=args.model)
        text = calibration_text
    res["sensor_pose_as"] = {"convention": convention, "columns": list(conventions.columns(convention)),
                             "pose": conventions.pose_from(convention, res["sensor_matrix"]).tolist()}
    if args.out:
        write_json_atomically(args.out, dict(res, provenance=provenance(args, dataset)))
    if args.plot:
        from studies.report import calibration_plot

        calibration_plot(res, dataset, args.plot)
    print(json.dumps(res, indent=1) if args.json else text(res))
    return EXIT_OK if res["converged"] else EXIT_NOT_CONVERGED


def main(argv=None):
    """Entry point of the ``handeye`` console script; returns the exit code."""
    from model.dataset import DatasetError
    from model.observations import ObservationError
    from model.simulate import SimulationError
    from solvers import UnsupportedProblem
    from studies.calibrate import CalibrationInputError
    from studies.study import StudyClaimFailed

    args = build_parser().parse_args(argv)
    try:
        if args.command == "datasets":
            from model.dataset import embedded_names

            print("\n".join(embedded_names()))
            return EXIT_OK
        if args.command == "simulate":
            return _simulate(args)
        if args.command == "diagnose":
            return _diagnose(args)
        if args.command == "bench":
            return _bench(args)
        if args.command == "plan":
            return _plan(args)
        if args.command == "study":
            return _study(args)
        return _calibrate(args)
    except (DatasetError, CalibrationInputError, ObservationError, SimulationError, UnsupportedProblem, ValueError) as exc:
        print(f"handeye: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except BrokenPipeError:  # the reader went away (e.g. `| head`): nothing left to say
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return EXIT_OK
    except StudyClaimFailed as exc:
        print(f"handeye: {exc}", file=sys.stderr)
        return EXIT_CLAIM_FAILED
    except Exception as exc:  # pragma: no cover - a bug, reported without a traceback
        if os.environ.get("HANDEYE_DEBUG"):
            raise
        print(f"handeye: internal error: {type(exc).__name__}: {exc} (set HANDEYE_DEBUG=1 for details)", file=sys.stderr)
        return EXIT_INTERNAL


if __name__ == "__main__":
    sys.exit(main())
