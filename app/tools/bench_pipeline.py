"""What a user's calibration costs beyond its solve: the default pipeline, stage by stage,
against one IPOPT solve of its final problem built and solved from scratch (``handeye bench``).

The stages are :mod:`handeye.app.engine.calibrate`'s (request, prepare, screen, fit, verify,
describe), timed in process after a warm-up (generated code loaded, nothing cached between
runs but the code), median of ``reps`` runs; the reference is the final residual model of the
samples the pipeline kept, built (:func:`handeye.model.datasets.observations.build`), turned into a
CasADi NLP and solved by IPOPT from the same start, also median of ``reps``.
"""
from __future__ import annotations

import time

import numpy as np

from handeye.app.tools.peak import once

STAGES = ("request", "prepare", "screen", "fit", "verify", "describe")


def _stage_times(dataset, loo):
    from handeye.app.engine import calibrate as engine
    from handeye.app.engine import describe
    from handeye.app.engine.request import CalibrationRequest

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


def pipeline_vs_solve(dataset="thesis-real", reps=5):
    """Median seconds of each stage (with and without leave-one-out) and of one IPOPT solve.

    Returns
    -------
    dict
        ``stages`` (name -> s, with leave-one-out), ``stages_no_loo``, ``total``,
        ``total_no_loo``, ``ipopt`` (s), ``ratio`` and ``ratio_no_loo`` (pipeline / solve),
        ``dataset``, ``kind``, ``reps``.
    """
    from handeye.app.public.api import load_dataset

    data = load_dataset(dataset)
    _stage_times(data, True)  # warm-up: generated code loaded
    runs = {True: [], False: []}
    for _ in range(reps):
        for loo in (True, False):
            times, prep, screened = _stage_times(data, loo)
            runs[loo].append(times)
    solves = [_ipopt_from_scratch(prep, screened) for _ in range(reps)]
    ipopt = float(np.median([s for s, _ in solves]))
    median = {loo: {k: float(np.median([r[k] for r in runs[loo]])) for k in STAGES} for loo in runs}
    total = {loo: float(np.median([sum(r.values()) for r in runs[loo]])) for loo in runs}
    return {"dataset": str(dataset), "kind": prep.kind, "reps": reps, "stages": median[True],
            "stages_no_loo": median[False], "total": total[True], "total_no_loo": total[False], "ipopt": ipopt,
            "ipopt_converged": all(ok for _, ok in solves), "ratio": total[True] / ipopt,
            "ratio_no_loo": total[False] / ipopt}


def text(res):
    """Lines of the bench's report."""
    ms = 1e3
    lines = [f"default pipeline on {res['dataset']} (--model {res['kind']}), in process, median of {res['reps']}: "
             f"{res['total'] * ms:.1f} ms ({res['ratio']:.1f}x one IPOPT solve of its final problem built and solved "
             f"from scratch, {res['ipopt'] * ms:.1f} ms); without leave-one-out {res['total_no_loo'] * ms:.1f} ms "
             f"({res['ratio_no_loo']:.1f}x)",
             "  stage       with LOO   without   (ms)"]
    return lines + [f"  {name:<10} {res['stages'][name] * ms:9.1f} {res['stages_no_loo'][name] * ms:9.1f}" for name in STAGES]
