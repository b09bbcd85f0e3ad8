"""The ``handeye`` command line.

Exit codes
----------
0  calibration converged
1  calibration did not converge (the result is still printed, and flagged)
2  bad input: unreadable or malformed dataset, bad option, too few or degenerate poses;
   one line on stderr naming file, row and column where there is one
3  internal error (a bug; set HANDEYE_DEBUG=1 for the traceback)
"""
from __future__ import annotations

import argparse
import json
import os
import sys

EXIT_OK, EXIT_NOT_CONVERGED, EXIT_BAD_INPUT, EXIT_INTERNAL = 0, 1, 2, 3


class _Parser(argparse.ArgumentParser):
    def error(self, message):
        self.print_usage(sys.stderr)
        print(f"handeye: error: {message}", file=sys.stderr)
        raise SystemExit(EXIT_BAD_INPUT)


def build_parser():
    from studies.calibrate import METHODS

    parser = _Parser(prog="handeye", description="Hand-eye calibration workbench (laser-line sensor, sphere).")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    cal = sub.add_parser("calibrate", help="calibrate the sensor pose on the flange from a dataset")
    cal.add_argument("dataset", nargs="?", default="thesis-real", help="embedded dataset name or folder (default thesis-real)")
    cal.add_argument("--unknowns", default="sensor", choices=["sensor", "sensor+sphere"])
    cal.add_argument("--method", default="ipopt", choices=list(METHODS))
    cal.add_argument("--rotation", default=None, choices=["matrix", "local", "euler"],
                     help="rotation parametrisation (default: matrix for ipopt, local otherwise)")
    cal.add_argument("--start", default=None, metavar="X,Y,Z,A,B,C",
                     help="start sensor pose, mm and degrees (write --start=-1,2,... for a leading minus)")
    cal.add_argument("--max-iter", type=int, default=None, help="iteration limit")
    cal.add_argument("--json", action="store_true", help="print the result as JSON")
    sub.add_parser("datasets", help="list the embedded datasets")
    return parser


def _calibrate(args):
    from model.dataset import load
    from studies.calibrate import calibrate, parse_pose
    from studies.report import calibration_text

    dataset = load(args.dataset)
    start = parse_pose(args.start) if args.start is not None else None
    options = {}
    if args.max_iter is not None:
        if args.max_iter < 1:
            raise ValueError("--max-iter must be at least 1")
        options["max_iter"] = args.max_iter
    res = calibrate(dataset, unknowns=args.unknowns, method=args.method, rotation=args.rotation, start=start,
                    options=options)
    if args.json:
        print(json.dumps(res, indent=1))
    else:
        print(calibration_text(res))
    return EXIT_OK if res["converged"] else EXIT_NOT_CONVERGED


def main(argv=None):
    """Entry point of the ``handeye`` console script; returns the exit code."""
    from model.dataset import DatasetError
    from solvers import UnsupportedProblem
    from studies.calibrate import CalibrationInputError

    args = build_parser().parse_args(argv)
    try:
        if args.command == "datasets":
            from model.dataset import embedded_names

            print("\n".join(embedded_names()))
            return EXIT_OK
        return _calibrate(args)
    except (DatasetError, CalibrationInputError, UnsupportedProblem, ValueError) as exc:
        print(f"handeye: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except Exception as exc:  # pragma: no cover - a bug, reported without a traceback
        if os.environ.get("HANDEYE_DEBUG"):
            raise
        print(f"handeye: internal error: {type(exc).__name__}: {exc} (set HANDEYE_DEBUG=1 for details)", file=sys.stderr)
        return EXIT_INTERNAL


if __name__ == "__main__":
    sys.exit(main())
