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

Start-up is light: this module and :mod:`handeye.app.command.parser` (the parser of every command's options)
import only the standard library and the names of the options (:mod:`handeye.app.common.choices`,
:mod:`handeye.model.chain.names`), so ``handeye --help`` never loads numpy, and the signal handlers
are in place before anything heavy is imported.
"""
from __future__ import annotations

import importlib
import os
import signal
import sys
import warnings

from handeye.app.command import parser as arguments
from handeye.app.command.parser import build_parser, dumps  # noqa: F401  (cli.build_parser: the parser, as before)
from handeye.model.common import scratch

EXIT_OK, EXIT_NOT_CONVERGED, EXIT_BAD_INPUT, EXIT_INTERNAL, EXIT_CLAIM_FAILED = 0, 1, 2, 3, 4
EXIT_INTERRUPTED, EXIT_TERMINATED = 130, 143


def _sizes(text, option):
    """``'1000,10000'`` -> (1000, 10000); None stays None (the default); ``'0'`` -> () (skip)."""
    from handeye.app.common.errors import RequestError

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
    from handeye.app.common.errors import RequestError

    if args.solvers:
        from handeye.app.tools import bench_solvers

        if args.plot:
            raise RequestError("--plot draws the calibration bench; the solver bench (--solvers) prints tables")
        res = bench_solvers.run(quick=args.quick, with_study=not args.no_study)
        print(dumps(res) if args.json else bench_solvers.text(res))
        return EXIT_OK
    from handeye.app.tools import bench

    try:
        import scipy.optimize  # noqa: F401 - the baseline of every ratio
    except ImportError:
        raise RequestError("handeye bench compares against scipy, which is not installed: "
                           "pip install 'handeye[bench]'") from None

    res = bench.run(quick=args.quick, with_startup=not args.no_startup,
                    pipeline_sizes=_sizes(args.pipeline_sizes, "--pipeline-sizes"))
    if args.plot:
        bench.plot(res, args.plot)
    print(dumps(res) if args.json else bench.text(res))
    return EXIT_OK


def _study(args):
    from handeye.app.tools import sweep
    from handeye.studies import study  # the one import of the studies, only when one is run

    # an interrupted sweep's worker pool is cleaned up by joblib's resource tracker (a child with
    # our stderr), which would report each semaphore and folder it removes: the one line is ours
    os.environ.setdefault("PYTHONWARNINGS", "ignore::UserWarning:joblib.externals.loky.backend.resource_tracker")
    with sweep.using(jobs=args.jobs, dask=args.dask):
        results = study.run(args.name, args.out, quick=args.quick)
    for name in results:
        print(f"study {name}: claims hold; figures, tables and summary.json in {args.out}/{name}")
    return EXIT_OK





def _result(args):
    """Call the command's public function with its keywords, read from the parsed arguments by
    the command's option table (:mod:`handeye.app.common.options`)."""
    from handeye.app.common import options

    name = args.command + (f" {args.action}" if args.command == "dataset" else "")
    module, _, function = options.COMMANDS[name].function.partition(":")
    return getattr(importlib.import_module(module), function)(**options.COMMANDS[name].keywords(vars(args)))


#: command -> its exit code from its result (the others: 0)
_EXITS = {
    "calibrate": lambda r: EXIT_OK if getattr(r, "converged", True) else EXIT_NOT_CONVERGED,  # a score: exit 0
    "report": lambda r: EXIT_OK if r.converged else EXIT_NOT_CONVERGED,
    "plan": lambda r: EXIT_NOT_CONVERGED if r.robot is not None and r.robot.n_needed is None else EXIT_OK,
    "validate": lambda r: EXIT_NOT_CONVERGED if r.passed is False else EXIT_OK,
}


def _public(args):
    """A command of the public API: its result printed (``--json``: as JSON), its exit code."""
    result = _result(args)
    if args.command == "export":
        print(f"written: {args.out} ({args.format})" if args.out else result.text, end="\n" if args.out else "")
    elif getattr(args, "json", False):
        print(result.to_json())
    else:
        print(result.summary())
    return _EXITS.get(args.command, lambda result: EXIT_OK)(result)


#: signal -> (what stderr says, exit code): the shell's 128 + signal number
_ENDINGS = {"SIGINT": ("interrupted", EXIT_INTERRUPTED), "SIGTERM": ("terminated", EXIT_TERMINATED)}


def _end(signum, frame):
    """SIGINT (Ctrl-C) or SIGTERM: remove the temporary files in flight, one line, and exit 130 or
    143 at once, even inside a solver or a worker pool that would otherwise swallow the
    KeyboardInterrupt (IPOPT turns it into a warning and goes on)."""
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


def install_signal_handlers(action=_end):
    """SIGINT and SIGTERM end the run with :func:`_end` (the console script's first act); ``action``
    ``signal.SIG_IGN``: ignored (its last)."""
    for name in _ENDINGS:
        signal.signal(getattr(signal, name), action)


def _run(args):
    """Run the parsed command; its exit code."""
    if args.command == "datasets":
        from handeye.model.datasets.dataset import embedded_names

        print("\n".join(embedded_names()))
        return EXIT_OK
    return {"bench": _bench, "study": _study}.get(args.command, _public)(args)


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
        warnings.simplefilter("ignore", RuntimeWarning)
        if argv is None:  # a warning the user must see (an unwritable code cache) is one line too
            warnings.formatwarning = _one_line_warning
    arguments.json_wanted = "--json" in (sys.argv[1:] if argv is None else list(argv))
    args = build_parser().parse_args(argv)
    code = _guarded(args)
    if argv is None:  # done: a signal during the interpreter's teardown no longer changes the outcome
        install_signal_handlers(signal.SIG_IGN)  # (the teardown restores the default action, which would end it with -2 or -15)
    return code


def _json_error(args, exc, code):
    """With ``--json``, the error as the JSON object on standard output too (a program reading the
    JSON of every exit finds ``error`` and what is known: the command, the dataset, and for a
    dataset's error its file, row and column)."""
    if not getattr(args, "json", False):
        return
    out = {"error": str(exc), "exit_code": code, "command": args.command, "dataset": getattr(args, "dataset", None)}
    out.update({key: getattr(exc, key) for key in ("file", "row", "column") if getattr(exc, key, None) is not None})
    print(dumps(out))


def _guarded(args):
    """Run the command; every failure becomes one line on stderr and its exit code."""
    from handeye.app.common.registry import StudyClaimFailed
    from handeye.model.common.errors import InputError

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
