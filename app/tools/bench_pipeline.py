"""What a user's calibration costs beyond its solve: the default pipeline, stage by stage,
against one IPOPT solve of its final problem built and solved from scratch (``handeye bench``).

The stages are :mod:`handeye.app.engine.calibrate`'s (request, prepare, screen, fit, verify,
describe), timed in process after a warm-up (generated code loaded, nothing cached between
runs but the code: each run on the dataset loaded anew, outside the timing, and the leave-one-out errors
kept for a problem asked again forgotten), median of ``reps`` runs; the reference is the final residual model of the
samples the pipeline kept, built (:func:`handeye.model.datasets.observations.build`), turned into a
CasADi NLP and solved by IPOPT from the same start, also median of ``reps``; and the lean solve a user
writes (``casadi.nlpsol`` over the pose's 6 numbers and the sphere-centre residuals of the same samples),
against which the whole calibration, its discrepancy search included, is timed too (issue 42).
"""
from __future__ import annotations

import time

import numpy as np

from handeye.app.tools.peak import once

STAGES = ("request", "prepare", "screen", "fit", "verify", "describe")


def _stage_times(dataset, loo):
    from handeye.app.engine import calibrate as engine
    from handeye.app.engine import describe
    from handeye.app.engine import loo as refits
    from handeye.app.engine.request import CalibrationRequest

    refits.forget_kept()  # what an earlier run of the same data kept is not this run's
    times = {}
    times["request"], request = once(lambda: CalibrationRequest(loo=loo).checked(dataset))
    times["prepare"], prep = once(lambda: engine.prepare(request, dataset))
    times["screen"], screened = once(lambda: engine.screen(prep))
    times["fit"], (final, verdict, start_used, warnings) = once(lambda: engine.fit(prep, screened))
    times["verify"], verified = once(lambda: engine.verify(prep, screened, final, verdict, start_used))
    times["describe"], _ = once(lambda: describe.result(prep, screened, verified, warnings))
    return times, prep, screened


def _ipopt_from_scratch(prep, screened):
    from handeye import solvers
    from handeye.app.engine.problems import calibration_problem
    from handeye.model.datasets import observations

    t = time.perf_counter()
    model = observations.build(screened.used, prep.kind, "matrix", prep.request.unknowns, prep.request.robot_sigma,
                               observations.Anchor(sensor2flange=prep.observed.sensor2flange(
                                   prep.observed.point_from_pose(prep.start_pose))))
    res = solvers.solve(calibration_problem(model), model.point_from_pose(prep.start_pose), method="ipopt")
    return time.perf_counter() - t, bool(res.converged)


def _lean_user_solve(used, start_pose, centre):
    """One IPOPT solve as a user writes it: ``casadi.nlpsol`` over the 6 numbers of the sensor in the flange
    (t mm, a rotation vector rad), the sum of squared sphere-centre residuals ``|F_i (R p_i + t) - c|^2`` of the
    samples ``used`` (written as ``|R p_i + t - F_i^-1 c|^2``: a rotation keeps lengths), built and solved from
    scratch from the start pose (KUKA); the seconds, whether IPOPT succeeded and the sensor pose it found (4x4).

    The graph is CasADi's MX over the whole (3, N) data, the faster of the two ways a user writes it: the same
    lines in SX expand every row (thesis-real 8 against 4.6 ms; 300 rows 53 against 8.4 ms; 3,000 rows 0.56 s
    against 25 ms; 30,000 rows 6.1 s against 0.18 s), and a slow reference would flatter the pipeline."""
    import casadi

    from handeye.model.chain.pose import transform_from_pose
    from handeye.model.common.rotation import matrix_from_rotvec, rotvec_from_matrix

    began = time.perf_counter()
    inverse = np.linalg.inv(used.motions())
    target = (inverse[:, :3, :3] @ np.asarray(centre, float) + inverse[:, :3, 3]).T  # (3, N)
    x = casadi.MX.sym("x", 6)
    angle = casadi.sqrt(casadi.sumsqr(x[3:]) + 1e-30)
    k = casadi.skew(x[3:] / angle)
    rotation = casadi.MX.eye(3) + casadi.sin(angle) * k + (1 - casadi.cos(angle)) * (k @ k)
    residual = rotation @ casadi.DM(used.centre_in_sensor.T) + casadi.repmat(x[:3], 1, len(used)) - casadi.DM(target)
    solver = casadi.nlpsol("user", "ipopt", {"x": x, "f": casadi.sumsqr(residual)},
                           {"print_time": False, "ipopt.print_level": 0, "ipopt.sb": "yes"})
    start = transform_from_pose(start_pose)
    found = np.asarray(solver(x0=np.concatenate([start[:3, 3], rotvec_from_matrix(start[:3, :3])]))["x"]).ravel()
    seconds = time.perf_counter() - began
    pose = np.eye(4)
    pose[:3, :3], pose[:3, 3] = matrix_from_rotvec(found[3:]), found[:3]
    return seconds, bool(solver.stats()["success"]), pose


def _whole(run, request, data):
    """Seconds of one whole calibration of ``data`` (``run`` of a default ``request``), nothing kept from an
    earlier one."""
    from handeye.app.engine import loo as refits

    refits.forget_kept()
    return once(lambda: run(request().checked(data), data))[0]


def pipeline_vs_solve(dataset="thesis-real", reps=5):
    """Median seconds of each stage (with and without leave-one-out), of the whole calibration (the stages and
    the discrepancy search, :func:`handeye.app.engine.calibrate.run`), of one IPOPT solve of the final problem
    and of one lean user's solve (:func:`_lean_user_solve`; None where the sphere centre is not given).

    Returns
    -------
    dict
        ``stages`` (name -> s, with leave-one-out), ``stages_no_loo``, ``total``, ``total_no_loo``,
        ``calibrate`` (s), ``ipopt`` (s), ``lean`` (s or None), ``ratio`` and ``ratio_no_loo`` (stages /
        the final problem's solve), ``ratio_lean`` and ``ratio_calibrate_lean`` (stages and whole calibration /
        the lean solve), ``dataset``, ``kind``, ``reps``.
    """
    from handeye.app.engine.calibrate import run
    from handeye.app.engine.request import CalibrationRequest
    from handeye.app.public.api import load_dataset

    data = load_dataset(dataset)
    _stage_times(data, True)  # warm-up: generated code loaded
    runs = {True: [], False: []}
    for _ in range(reps):
        for loo in (True, False):  # each run on the dataset loaded anew: what it keeps (Dataset.once) is not reused
            times, prep, screened = _stage_times(load_dataset(dataset), loo)
            runs[loo].append(times)
    whole = [_whole(run, CalibrationRequest, load_dataset(dataset)) for _ in range(reps)]
    solves = [_ipopt_from_scratch(prep, screened) for _ in range(reps)]
    lean = None if data.sphere_centre is None else [
        _lean_user_solve(screened.used, prep.start_pose, data.sphere_centre) for _ in range(reps)]
    ipopt = float(np.median([s for s, _ in solves]))
    median = {loo: {k: float(np.median([r[k] for r in runs[loo]])) for k in STAGES} for loo in runs}
    total = {loo: float(np.median([sum(r.values()) for r in runs[loo]])) for loo in runs}
    user = None if lean is None else float(np.median([s for s, _, _ in lean]))
    return {"dataset": str(dataset), "label": str(dataset), "samples": len(data), "kind": prep.kind, "reps": reps,
            "stages": median[True],
            "stages_no_loo": median[False], "total": total[True], "total_no_loo": total[False], "ipopt": ipopt,
            "ipopt_converged": all(ok for _, ok in solves), "ratio": total[True] / ipopt,
            "ratio_no_loo": total[False] / ipopt, "calibrate": float(np.median(whole)), "lean": user,
            "lean_converged": None if lean is None else all(ok for _, ok, _ in lean),
            "ratio_lean": None if user is None else total[True] / user,
            "ratio_calibrate_lean": None if user is None else float(np.median(whole)) / user}


def text(res):
    """Lines of the bench's report."""
    ms = 1e3
    lines = [f"default pipeline on {res['dataset']} (--model {res['kind']}), in process, median of {res['reps']}: "
             f"{res['total'] * ms:.1f} ms ({res['ratio']:.1f}x one IPOPT solve of its final problem built and solved "
             f"from scratch, {res['ipopt'] * ms:.1f} ms); without leave-one-out {res['total_no_loo'] * ms:.1f} ms "
             f"({res['ratio_no_loo']:.1f}x)"]
    if res["lean"] is not None:
        lines.append(f"against one lean user's solve (casadi.nlpsol, 6 variables, the centre model, from scratch: "
                     f"{res['lean'] * ms:.1f} ms): the stages {res['ratio_lean']:.1f}x; the whole calibration with its "
                     f"discrepancy search {res['calibrate'] * ms:.1f} ms, {res['ratio_calibrate_lean']:.1f}x")
    lines.append("  stage       with LOO   without   (ms)")
    return lines + [f"  {name:<10} {res['stages'][name] * ms:9.1f} {res['stages_no_loo'][name] * ms:9.1f}" for name in STAGES]


#: Issue 42's targets for the stages against the lean solve, by measurements (up to): 3x up to 3,000, 1.5x above;
#: the whole calibration with its discrepancy search 10x.
TARGETS = ((3_000, 3.0), (float("inf"), 1.5))
TARGET_WHOLE = 10.0


def target(n):
    """The stages' target ratio against the lean solve at ``n`` measurements (:data:`TARGETS`)."""
    return next(ratio for upto, ratio in TARGETS if n <= upto)


def ratios_text(rows, load=None):
    """The ratio table: each dataset's lean solve, stages and whole calibration, and their targets."""
    ms = 1e3
    lines = ["the pipeline against one lean user's solve (casadi.nlpsol in MX, 6 variables, the centre model, built and "
             f"solved from scratch), in process, median of {rows[0]['reps'] if rows else 0}"
             + (f", load {load}" if load is not None else "") + ":",
             f"  {'dataset':<14} {'samples':>8} {'lean ms':>8} {'stages ms':>10} {'x lean':>7} {'target':>7} "
             f"{'whole ms':>9} {'x lean':>7} {'target':>7}"]
    for r in rows:
        if r["lean"] is None:
            continue
        lines.append(f"  {r['label']:<14} {r['samples']:>8} {r['lean'] * ms:>8.1f} {r['total'] * ms:>10.1f} "
                     f"{r['ratio_lean']:>6.1f}x {target(r['samples']):>6.1f}x {r['calibrate'] * ms:>9.1f} "
                     f"{r['ratio_calibrate_lean']:>6.1f}x {TARGET_WHOLE:>6.1f}x")
    return lines
