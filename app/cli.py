"""The ``handeye`` command line.

Exit codes
----------
0  calibration converged (report: the reported one); a given sensor pose scored (calibrate --sensor-pose: the verdict says
   whether the data contradict it); compare; dataset new
1  calibration did not converge (the result is still printed, and flagged; a report still written,
   saying so); a score without a
   verdict (the data's own calibration did not converge); validate: a maximum permissible error
   (--mpe) exceeded; plan: even every candidate misses --target. With --json the printed object
   says why in ``error`` (null on exit 0), on exit 2 too (``error``, ``exit_code``, ``command``,
   and a dataset error's ``file``, ``row``, ``column``)
2  bad input: unreadable or malformed dataset, bad option, too few or degenerate poses;
   one line on stderr naming file, row and column where there is one (an argparse error: that
   line and ``see `handeye SUBCOMMAND --help```); an output that cannot be written, standard
   output closed or a pipe nobody reads included
3  internal error (a bug; set HANDEYE_DEBUG=1 for the traceback)
4  a study's data did not support its claim (``handeye study``)
130 interrupted (SIGINT, Ctrl-C); 143 terminated (SIGTERM): one line, no temporary file left

Start-up is light: this module and :mod:`handeye.app.parser` (every subcommand's options)
import only the standard library and the names of the options (:mod:`handeye.app.choices`,
:mod:`handeye.model.names`), so ``handeye --help`` never loads numpy, and the signal handlers
are in place before anything heavy is imported.
"""
from __future__ import annotations

import os
import sys

from handeye.app import parser as arguments
from handeye.app.parser import build_parser  # noqa: F401  (cli.build_parser: the parser, as before)
from handeye.model import scratch

EXIT_OK, EXIT_NOT_CONVERGED, EXIT_BAD_INPUT, EXIT_INTERNAL, EXIT_CLAIM_FAILED = 0, 1, 2, 3, 4
EXIT_INTERRUPTED, EXIT_TERMINATED = 130, 143


def dumps(data):
    """JSON text of a result (:func:`handeye.app.present.results.dumps`, imported when needed)."""
    from handeye.app.present.results import dumps as to_json

    return to_json(data)


def _compare(args):
    from handeye.app import api

    result = api.compare(args.dataset, args.a, args.b, unknowns=args.unknowns, model=args.model, alpha=args.alpha,
                         sigma=args.sigma, robot_sigma=args.robot_sigma, keep_all=args.keep_all)
    print(dumps(result.to_dict()) if args.json else result.summary())
    return EXIT_OK


def _report(args):
    from handeye.app.reporting import report

    result = report(args.dataset, html=args.html, calibration=args.calibration, diagnose=args.diagnose,
                    unknowns=args.unknowns, model=args.model, convention=args.convention, keep_all=args.keep_all,
                    no_clean=args.no_clean)
    print(dumps(result.to_dict()) if args.json else result.summary())
    return EXIT_OK if result.converged else EXIT_NOT_CONVERGED


def _dataset(args):
    from handeye.app.ingest.command import new_dataset

    result = new_dataset(args.out, poses=args.poses, profiles=args.profiles, convention=args.convention,
                         columns=args.columns, units=args.units, angles=args.angles, profile_units=args.profile_units,
                         profile_axes=args.profile_axes, diameter=args.diameter, side=args.side, center=args.center,
                         start=args.start, joints=args.joints, robot=args.robot, pair=args.pair, match=args.match,
                         bag=args.bag, pose_topic=args.pose_topic, profile_topic=args.profile_topic,
                         base_frame=args.base_frame, flange_frame=args.flange_frame, max_dt=args.max_dt, setup=args.setup)
    print(dumps(result.to_dict()) if args.json else result.summary())
    return EXIT_OK


def _plan(args):
    from handeye.app import api

    result = api.plan(n=args.n, candidates=args.candidates, dataset=args.dataset, out=args.out, max_tilt=args.max_tilt,
                      margin=args.margin, workspace=args.workspace, score=args.score, sensor_mount=args.sensor_mount,
                      sphere_mount=args.sphere_mount, robot=args.robot, effects=args.effects, target=args.target,
                      sigma=args.sigma)
    print(dumps(result.to_dict()) if args.json else result.summary())
    return EXIT_NOT_CONVERGED if result.robot is not None and result.robot.n_needed is None else EXIT_OK


def _diagnose(args):
    from handeye.app import api

    result = api.diagnose(args.dataset, alpha=args.alpha, figures=args.figures, plot=args.plot, sigma=args.sigma,
                          out=args.out, unknowns=args.unknowns, no_clean=args.no_clean)
    print(result.to_json() if args.json else result.summary())
    return EXIT_OK


def _sizes(text, option):
    """``'1000,10000'`` -> (1000, 10000); None stays None (the default); ``'0'`` -> () (skip)."""
    from handeye.app.errors import RequestError

    if text is None:
        return None
    try:
        sizes = tuple(int(float(v)) for v in str(text).split(",") if v.strip())
    except ValueError:
        raise RequestError(f"{option}: comma-separated numbers of measurements, got {text!r}") from None
    if any(n < 0 for n in sizes):
        raise RequestError(f"{option}: sizes must be positive, got {text!r}")
    return tuple(n for n in sizes if n > 0)


def _bench(args):
    if args.solvers:
        from handeye.app.tools import bench_solvers

        if args.plot:
            from handeye.app.errors import RequestError

            raise RequestError("--plot draws the calibration bench; the solver bench (--solvers) prints tables")
        res = bench_solvers.run(quick=args.quick, with_study=not args.no_study)
        print(dumps(res) if args.json else bench_solvers.text(res))
        return EXIT_OK
    from handeye.app.tools import bench

    try:
        import scipy.optimize  # noqa: F401 - the baseline of every ratio
    except ImportError:
        from handeye.app.errors import RequestError

        raise RequestError("handeye bench compares against scipy, which is not installed: "
                           "pip install 'handeye[bench]'") from None

    res = bench.run(quick=args.quick, with_startup=not args.no_startup,
                    pipeline_sizes=_sizes(args.pipeline_sizes, "--pipeline-sizes"))
    if args.plot:
        bench.plot(res, args.plot)
    print(dumps(res) if args.json else bench.text(res))
    return EXIT_OK


def _study(args):
    from handeye.app.errors import RequestError
    from handeye.app.tools import sweep
    from handeye.studies import study  # the one import of the studies, only when one is run

    if args.jobs is not None and args.jobs < 1:
        raise RequestError("--jobs must be at least 1")
    # an interrupted sweep's worker pool is cleaned up by joblib's resource tracker (a child with
    # our stderr), which would report each semaphore and folder it removes: the one line is ours
    os.environ.setdefault("PYTHONWARNINGS", "ignore::UserWarning:joblib.externals.loky.backend.resource_tracker")
    with sweep.using(jobs=args.jobs, dask=args.dask):
        results = study.run(args.name, args.out, quick=args.quick)
    for name in results:
        print(f"study {name}: claims hold; figures, tables and summary.json in {args.out}/{name}")
    return EXIT_OK


def _simulate(args):
    from handeye.app import api

    result = api.simulate(args.out, seed=args.seed, effect=args.effect, profiles=args.profiles, poses=args.poses,
                          n_poses=args.n_poses, linearity=args.linearity, motions=args.motions,
                          translations=args.translations, truth=args.truth, diameter=args.diameter,
                          center=args.center, convention=args.convention, max_tilt=args.max_tilt,
                          no_start=args.no_start, sensor_mount=args.sensor_mount, sphere_mount=args.sphere_mount,
                          positioner_axes=args.positioner_axes, positioner_error=args.positioner_error,
                          robot=args.robot)
    print(result.summary())
    return EXIT_OK


def _export(args):
    from handeye.app.errors import RequestError
    from handeye.app.outputs import commands as use

    if args.result is None and args.sensor_pose is None:
        raise RequestError("give the saved calibration (handeye export RESULT.json --format ...) or --sensor-pose")
    result = use.export(args.result, format=args.format, parent=args.parent, child=args.child, tool=args.tool,
                        register=args.register, out=args.out, sensor_pose=args.sensor_pose,
                        convention=args.convention, force=args.force, base=args.base,
                        sensor_mount=args.sensor_mount)
    print(f"written: {args.out} ({args.format})" if args.out else result.text, end="\n" if args.out else "")
    return EXIT_OK


def _cloud(args):
    from handeye.app.outputs import commands as use

    result = use.cloud(args.dataset, args.calibration, out=args.out, format=args.format, sensor_pose=args.sensor_pose,
                       convention=args.convention, force=args.force)
    print(dumps(result.to_dict()) if args.json else result.summary())
    return EXIT_OK


def _validate(args):
    from handeye.app.outputs import commands as use

    result = use.validate(args.dataset, args.calibration, plot=args.plot, exclude=args.exclude,
                          sensor_pose=args.sensor_pose, convention=args.convention, force=args.force, mpe=args.mpe)
    print(dumps(result.to_dict()) if args.json else result.summary())
    return EXIT_NOT_CONVERGED if result.passed is False else EXIT_OK


def _calibrate(args):
    from handeye.app import api

    result = api.calibrate(args.dataset, unknowns=args.unknowns, method=args.method, rotation=args.rotation,
                           start=args.start, convention=args.convention, max_iter=args.max_iter, model=args.model,
                           keep_all=args.keep_all, alpha=args.alpha, no_loo=args.no_loo, plot=args.plot,
                           out=args.out, sigma=args.sigma, robot_sigma=args.robot_sigma, effects=args.effects,
                           calibration=args.calibration, sensor_pose=args.sensor_pose, no_clean=args.no_clean,
                           report=args.report)
    print(result.to_json() if args.json else result.summary())
    return EXIT_OK if getattr(result, "converged", True) else EXIT_NOT_CONVERGED  # a score (no converged) is exit 0


#: signal -> (what stderr says, exit code): the shell's 128 + signal number
_ENDINGS = {"SIGINT": ("interrupted", EXIT_INTERRUPTED), "SIGTERM": ("terminated", EXIT_TERMINATED)}


def _end(signum, frame):
    """SIGINT (Ctrl-C) or SIGTERM: remove the temporary files in flight, one line, and exit 130 or
    143 at once, even inside a solver or a worker pool that would otherwise swallow the
    KeyboardInterrupt (IPOPT turns it into a warning and goes on)."""
    import signal

    word, code = _ENDINGS.get(signal.Signals(signum).name, ("interrupted", 128 + signum))
    try:
        scratch.remove_all()
        _stop_workers()
        sys.stderr.write(f"handeye: {word}\n")
        sys.stderr.flush()
    finally:
        os._exit(code)


def _stop_workers():
    """SIGTERM to the worker processes of a sweep (joblib's and Dask's are multiprocessing
    children): an orphan would compute its task to the end after the run has stopped."""
    if "multiprocessing" not in sys.modules:
        return
    import multiprocessing

    for child in multiprocessing.active_children():
        try:
            child.terminate()
        except Exception:  # noqa: BLE001 - on the way out, a worker already gone is no matter
            pass


def install_signal_handlers():
    """SIGINT and SIGTERM end the run with :func:`_end` (the console script's first act)."""
    import signal

    for name in _ENDINGS:
        signal.signal(getattr(signal, name), _end)


def _run(args):
    """Run the parsed command; its exit code."""
    if args.command == "datasets":
        from handeye.model.dataset import embedded_names

        print("\n".join(embedded_names()))
        return EXIT_OK
    commands = {"simulate": _simulate, "diagnose": _diagnose, "bench": _bench, "export": _export, "cloud": _cloud,
                "validate": _validate, "plan": _plan, "study": _study, "compare": _compare, "dataset": _dataset,
                "report": _report}
    return commands.get(args.command, _calibrate)(args)


def _cannot_write(exc):
    """Exit code and stderr line of an OSError: the output cannot be written (2), or a bug (3)."""
    if isinstance(exc, BrokenPipeError) or exc.errno == 32:  # EPIPE: the reader is gone (`| head -c0`)
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # nothing more to flush at exit
        return EXIT_BAD_INPUT, "handeye: error: cannot write the output: standard output is closed (broken pipe)"
    if exc.filename is not None or exc.errno not in (28, 5, 9):  # ENOSPC, EIO, EBADF only
        if os.environ.get("HANDEYE_DEBUG"):
            raise exc
        return EXIT_INTERNAL, f"handeye: internal error: {type(exc).__name__}: {exc} (set HANDEYE_DEBUG=1 for details)"
    return EXIT_BAD_INPUT, f"handeye: error: cannot write the output: {exc.strerror}"


def _one_line_warning(message, category, filename, lineno, line=None):
    return f"handeye: warning: {message}\n"


def main(argv=None):
    """Entry point of the ``handeye`` console script; returns the exit code."""
    if argv is None:  # the console script, not a caller's Python process: a signal ends it at once
        install_signal_handlers()
    if sys.stdout is None:  # started with stdout closed (`handeye ... >&-`): every result would be lost
        print("handeye: error: standard output is closed; redirect it (> FILE, or > /dev/null to discard)",
              file=sys.stderr)
        return EXIT_BAD_INPUT
    if not os.environ.get("HANDEYE_DEBUG"):  # one line on stderr: numpy's overflow chatter is not it
        import warnings

        warnings.simplefilter("ignore", RuntimeWarning)
        if argv is None:  # a warning the user must see (an unwritable code cache) is one line too
            warnings.formatwarning = _one_line_warning
    arguments.json_wanted = "--json" in (sys.argv[1:] if argv is None else list(argv))
    args = build_parser().parse_args(argv)
    code = _guarded(args)
    if argv is None:  # done: a signal during the interpreter's teardown no longer changes the outcome
        _ignore_signals()  # (the teardown restores the default action, which would end it with -2 or -15)
    return code


def _ignore_signals():
    import signal

    for name in _ENDINGS:
        signal.signal(getattr(signal, name), signal.SIG_IGN)


def _json_error(args, exc, code):
    """With ``--json``, the error as the JSON object on standard output too (a program reading the
    JSON of every exit finds ``error`` and what is known: the command, the dataset, and for a
    dataset's error its file, row and column)."""
    if not getattr(args, "json", False):
        return
    out = {"error": str(exc), "exit_code": code, "command": args.command, "dataset": getattr(args, "dataset", None)}
    for key in ("file", "row", "column"):
        if getattr(exc, key, None) is not None:
            out[key] = getattr(exc, key)
    print(dumps(out))


def _guarded(args):
    """Run the command; every failure becomes one line on stderr and its exit code."""
    from handeye.app.tools.registry import StudyClaimFailed
    from handeye.model.errors import InputError

    try:
        code = _run(args)
        sys.stdout.flush()  # a closed pipe or a full disk shows here, not as a warning at exit
        return code
    except InputError as exc:  # exactly the bad-input hierarchy: anything else is a bug (exit 3)
        print(f"handeye: error: {exc}", file=sys.stderr)
        _json_error(args, exc, EXIT_BAD_INPUT)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:  # Ctrl-C in a caller's process (no handler): one line, the shell's code
        print("handeye: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except OSError as exc:  # the output itself cannot be written (a closed pipe, a full disk, /dev/full)
        code, line = _cannot_write(exc)
        print(line, file=sys.stderr)
        return code
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
