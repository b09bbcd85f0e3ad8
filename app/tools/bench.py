"""``handeye bench``: the calibration's speed, method by method, in one process and one run.

Cases: thesis-real with its flagged samples removed, and simulated datasets of 30, 300,
3,000 and 30,000 measurements (thesis orientations, new sphere placements, noise 0.02 mm).
Methods, each from the same start (the dataset's; for simulations 40 mm and a few degrees off):

* ``thesis`` -- the seed's pipeline: Gauss-Newton on Euler angles, forward-difference
  Jacobian with step 5e-7 (C4), stop when the cost no longer changes (C5's tol = 1e-20);
* ``scipy-2point`` -- ``scipy.optimize.least_squares`` (trf, 2-point differences) on the
  vectorised numpy residual: what a Python user would write (the baseline of every ratio),
  with tolerances 1e-15 so that it gets as close to the minimum as it can;
* ``scipy-exact`` -- the same with our exact Jacobian;
* ``ipopt-matrix`` -- CasADi IPOPT on the rotation-matrix parametrisation (up to 3,000);
* ``fast-vm`` -- :mod:`handeye.model.compiled.fast`'s Levenberg-Marquardt in Python, normal equations from the
  CasADi virtual machine (up to 3,000);
* ``fast`` -- the same iteration compiled: generated C for the model, C driver, one call.

Per method: median and minimum time per calibration over the repetitions, iterations,
evaluations, final cost, and whether it lands on the fast path's transform within 1e-6 mm
and 1e-6 deg. Then: the fast path's time against the number of measurements (log-log slope),
a profile of where its time goes on thesis-real, Monte Carlo throughput, and the start-up
time of ``handeye calibrate`` with a cold and a warm generated-code cache. Timing is measured
here, never in tests.
"""
from __future__ import annotations

import json
import os
import pathlib
import subprocess
import sys

import numpy as np

from handeye import solvers
from handeye.app.engine import robust
from handeye.app.tools import bench_guarantee, bench_peers, bench_pipeline, bench_points
from handeye.app.tools.peak import machine, machine_line, once, timed
from handeye.model.chain.pose import pose_from_transform, transform_from_pose
from handeye.model.common import scratch
from handeye.model.common.rotation import nearest_transform, transform_distance
from handeye.model.compiled import fast
from handeye.model.datasets.dataset import load
from handeye.model.fit.calibration import CalibrationModel
from handeye.model.simulation import simulate

SIZES = (30, 300, 3000, 30000)
SCALING = (30, 100, 300, 1000, 3000, 10000, 30000)
ORDER = ("fast", "fast-vm", "thesis", "scipy-2point", "scipy-exact", "ipopt-matrix")


def simulated_batch(m, n, seed=0):
    """m simulated datasets of n measurements each, vectorised.

    Returns
    -------
    flange2base : ndarray (m, n, 4, 4)
    centre_in_sensor : ndarray (m, n, 3)
        Noisy (0.02 mm) sphere centres in the sensor frame, 210-270 mm range.
    sphere_centre : ndarray (3,)
    start : ndarray (4, 4)
        The setup's sensor pose moved by (40, -30, 20) mm and (3, 2, -3) deg.
    truth : ndarray (4, 4)
    """
    rng = np.random.default_rng(seed)
    setup = simulate.Setup()
    truth = transform_from_pose(setup.sensor_pose)
    rots = np.array([r for _, r in simulate.thesis_orientations(36)])[np.arange(n) % 36]
    centre = np.asarray(setup.sphere_centre, float)
    seen_at = simulate.random_view(setup, rng, (m, n))
    flanges = simulate.flanges_for_views(setup, rots, seen_at)
    xs = seen_at + rng.normal(0, 0.02, seen_at.shape)
    start = transform_from_pose(np.asarray(setup.sensor_pose) + [40, -30, 20, 3, 2, -3])
    return flanges, xs, centre, start, truth


def simulated_case(n, seed=0):
    """Flange poses, centres, sphere centre and start of one simulated dataset of n measurements."""
    flanges, xs, centre, start, _ = simulated_batch(1, n, seed)
    return flanges[0], xs[0], centre, start


def real_case():
    """thesis-real without the samples the robust screening flags, and its CAD start."""
    d = load("thesis-real")
    start = transform_from_pose(d.start_pose)
    s = robust.screen(d, "sensor", start)
    return d.motions()[s.inliers], d.centre_in_sensor[s.inliers], d.sphere_centre, start


def _methods(f2b, xs, centre, start, n):
    """name -> callable returning (sensor2flange, iterations or None where the method does not
    report them, evaluations, cost)."""
    euler = CalibrationModel(f2b, xs, centre, "euler")
    x0 = euler.point_from_pose(pose_from_transform(start))

    def thesis():
        res = solvers.solve(solvers.Problem(n=6, residual=euler.residual, jacobian=euler.jacobian), x0, "gn",
                            {"jacobian": "forward", "fd_step": 5e-7, "ftol": 1e-20, "gtol": 0.0, "xtol": 0.0,
                             "max_iter": 250})
        return euler.sensor2flange(res.x), res.iterations, res.nfev, res.cost

    def scipy_fit(jac):
        from scipy.optimize import least_squares

        res = least_squares(euler.residual, x0, jac=jac, method="trf", xtol=1e-15, ftol=1e-15, gtol=1e-15)
        # scipy reports evaluations (nfev, without those of the 2-point Jacobian), not iterations
        return euler.sensor2flange(res.x), None, res.nfev, 0.5 * float(res.fun @ res.fun)

    def fast_path(compiled):
        res = fast.calibrate_fast(f2b, xs, centre, start, compiled=compiled)
        return res.sensor2flange, res.iterations, res.evaluations, res.cost

    out = {"fast": lambda: fast_path(True), "thesis": thesis, "scipy-2point": lambda: scipy_fit("2-point"),
           "scipy-exact": lambda: scipy_fit(lambda x: euler.jacobian(x))}
    if n <= 3000:
        out["fast-vm"] = lambda: fast_path(False)
        matrix = CalibrationModel(f2b, xs, centre, "matrix")
        problem = solvers.Problem(n=12, nlp=matrix.nlp())
        xm = matrix.point_from(start)

        def ipopt():
            res = solvers.solve(problem, xm, "ipopt")
            return nearest_transform(matrix.sensor2flange(res.x)), res.iterations, res.nfev, res.cost

        out["ipopt-matrix"] = ipopt
    return out


def compare(cases, reps):
    """Every method on every case: the side-by-side table."""
    result = {}
    for name, (f2b, xs, centre, start) in cases.items():
        methods = _methods(f2b, xs, centre, start, len(xs))
        methods["fast"]()  # compile (or load) outside the timing
        table, ref = {}, None
        for method in (m for m in ORDER if m in methods):
            times, (t, its, evals, cost) = timed(methods[method], reps)
            ref = t if ref is None else ref
            dt, dr = transform_distance(t, ref)
            table[method] = {"median_ms": float(np.median(times) * 1e3), "min_ms": float(np.min(times) * 1e3),
                             "iterations": None if its is None else int(its), "evaluations": int(evals), "cost": float(cost),
                             "agrees": bool(dt < 1e-6 and dr < 1e-6), "distance_mm": float(dt),
                             "distance_deg": float(dr)}
        result[name] = table
    return result


def _driver(case):
    """Callable running the compiled driver alone (data prepared once) with an iteration limit;
    ``n=0`` measures the bare ctypes call."""
    f2b, xs, centre, start = case
    lib = fast.library()
    f2b, xs, c = (np.ascontiguousarray(a, float) for a in (f2b, xs, centre))
    pose0, pose, info = np.array(start, float, order="C"), np.array(start, float, order="C"), np.zeros(5)
    pf, px, pc, pp, pi = (a.ctypes.data for a in (f2b, xs, c, pose, info))

    def run(max_iter=100, n=len(xs), _keep=(f2b, xs, c)):  # noqa: B008 - _keep: the arrays behind the addresses stay alive
        pose[:] = pose0
        lib.he_lm(n, pf, px, pc, pp, max_iter, pi)
        return int(info[1])

    return run


def scaling(sizes=SCALING, reps=5):
    """Fast-path time against the number of measurements, and the log-log slope of the compiled
    iteration's time per evaluation of the normal equations (1 = linear in n)."""
    rows = []
    for n in sizes:
        f2b, xs, centre, start = case = simulated_case(n, seed=1)
        fast.calibrate_fast(f2b, xs, centre, start)
        times, res = timed(lambda: fast.calibrate_fast(f2b, xs, centre, start), reps)
        row = {"n": int(n), "median_ms": float(np.median(times) * 1e3), "evaluations": res.evaluations}
        if fast.library() is not None:
            driver = _driver(case)
            loop, evals = timed(driver, reps)
            call, _ = timed(lambda: driver(n=0), reps)
            row["per_evaluation_us"] = float((np.median(loop) - np.median(call)) * 1e6 / evals)
        else:
            row["per_evaluation_us"] = float(np.median(times) * 1e6 / res.evaluations)
        rows.append(row)
    ns = np.log([r["n"] for r in rows])
    slope = np.polyfit(ns, np.log([r["per_evaluation_us"] for r in rows]), 1)[0] if len(rows) > 1 else float("nan")
    return {"rows": rows, "slope": float(slope)}


def profile(case, reps=200):
    """Where the fast path's time goes on one dataset: Python preparation and the ctypes call
    versus the compiled iteration; evaluations, instructions of the generated model and the
    compute limit they imply."""
    f2b, xs, centre, start = case
    total, res = timed(lambda: fast.calibrate_fast(f2b, xs, centre, start), reps)
    out = {"total_us": float(np.median(total) * 1e6), "evaluations": res.evaluations, "n": len(xs),
           "instructions_per_measurement": int(fast._per_measurement().n_instructions()),
           "compiled": fast.library() is not None}
    if not out["compiled"]:
        return out
    driver = _driver(case)
    call, _ = timed(lambda: driver(n=0), reps)  # the bare ctypes call
    one, _ = timed(lambda: driver(0), reps)  # one evaluation, no step
    iterate, _ = timed(driver, reps)
    out["call_us"] = float(np.median(call) * 1e6)
    out["compiled_loop_us"] = float(np.median(iterate) * 1e6) - out["call_us"]
    out["one_evaluation_us"] = float(np.median(one) * 1e6) - out["call_us"]
    out["steps_us"] = out["compiled_loop_us"] - res.evaluations * out["one_evaluation_us"]
    out["python_us"] = out["total_us"] - out["compiled_loop_us"] - out["call_us"]
    executed = out["instructions_per_measurement"] * len(xs) * res.evaluations
    out["instructions_executed"] = int(executed)
    out["ns_per_instruction"] = res.evaluations * out["one_evaluation_us"] * 1e3 / executed
    return out


def _monte_carlo(seed, m, n=31):
    """Simulate m datasets and calibrate them; (converged, seconds spent calibrating, RMS
    translation error to the truth in mm)."""
    flanges, xs, centre, start, truth = simulated_batch(m, n, seed)
    spent, (poses, info) = once(lambda: fast.calibrate_many(flanges, xs, centre, np.broadcast_to(start, (m, 4, 4))))
    err = np.linalg.norm(poses[:, :3, 3] - truth[:3, 3], axis=1)
    return int(np.sum(info[:, 3] > 0)), spent, float(np.sqrt(np.mean(err**2)))


def throughput(quick=False, n=None, chunk=1000):
    """Monte Carlo: independent calibrations of 31 measurements per second on all cores (joblib),
    wall clock including the simulation of their data; and the calibration-only rate of one core.
    Every calibration must converge."""
    from handeye.app.tools import sweep

    n = n or (4000 if quick else 40000)
    jobs = sweep.n_jobs()
    sizes = [min(chunk, n - k) for k in range(0, n, chunk)]
    sweep.run(_monte_carlo, [(0, 2)] * jobs, label="warm workers")  # start the pool outside the timing
    wall, parts = once(lambda: sweep.run(_monte_carlo, [(1000 + k, m) for k, m in enumerate(sizes)], label="monte carlo"))
    ok, spent = sum(p[0] for p in parts), sum(p[1] for p in parts)
    return {"calibrations": n, "converged": int(ok), "all_cores_per_s": n / wall, "jobs": jobs,
            "calibration_only_per_s_one_core": n / spent, "rms_translation_error_mm": float(
                np.sqrt(np.mean([p[2] ** 2 for p in parts])))}


def startup():
    """Wall time of ``handeye calibrate`` (default options, thesis-real) with an empty
    generated-code cache (cold: sympy derives and CasADi builds) and then with it filled (warm)."""
    cmd = [sys.executable, "-m", "handeye.app.command.cli", "calibrate", "--json"]
    out = {}
    with scratch.temporary_folder() as cache:
        env = dict(os.environ, HANDEYE_CACHE=cache)
        for label in ("cold", "warm", "warm again"):
            out[label + "_s"], proc = once(lambda: subprocess.run(cmd, env=env, capture_output=True, text=True))
            out[label + "_exit"] = proc.returncode
    return out


#: Sizes (measurements) of the default pipeline's scaling: ``handeye calibrate DATASET`` as a user runs it.
PIPELINE = (1_000, 10_000, 100_000, 1_000_000)


def write_dataset(folder, n, seed=0):
    """A simulated dataset of ``n`` measurements (thesis orientations, 0.02 mm noise) in ``folder``."""
    flanges, xs, centre, start, _ = simulated_batch(1, n, seed)
    folder = pathlib.Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    table = np.column_stack([pose_from_transform(flanges[0]), xs[0]])
    body = "\n".join(f"m{k}," + ",".join(f"{v:.8f}" for v in row) for k, row in enumerate(table))
    (folder / "measurements.csv").write_text("id,x,y,z,a,b,c,xs,ys,zs\n" + body + "\n")
    s = ", ".join(repr(float(v)) for v in pose_from_transform(start))
    c = ", ".join(repr(float(v)) for v in centre)
    (folder / "setup.toml").write_text(f"[sensor]\nstart_pose = [{s}]\n[sphere]\ndiameter = 59.94507\ncenter = [{c}]\n")
    return folder


#: Runs ``{call}`` after ``{setup}`` in a fresh Python and reports its time (after the
#: interpreter's start and the setup), its own peak memory (:func:`handeye.app.tools.peak.own_peak_kb`)
#: and the call's value (the exit code) on stderr.
_PROBE = ("import sys, time; from handeye.app.tools.peak import own_peak_kb; {setup}; t0 = time.perf_counter(); "
          "code = {call}; "
          "print('PEAK', own_peak_kb(), time.perf_counter() - t0, code, file=sys.stderr)")


def measure_python(setup="pass", call="0", args=()):
    """``{'seconds', 'peak_mb', 'exit'}`` of a fresh Python that runs ``setup``, then times
    ``call`` (an expression: the exit code reported), with ``args`` in ``sys.argv[1:]``.

    The peak is the child's own high-water mark (MB), not ``ru_maxrss`` of ``RUSAGE_CHILDREN``
    or of the child itself, which on Linux carry this process's size over fork and exec
    (:mod:`handeye.app.tools.peak`). Seconds and peak are None when the child died before reporting.
    """
    out = subprocess.run([sys.executable, "-c", _PROBE.format(setup=setup, call=call), *args], capture_output=True, text=True)
    line = [x for x in out.stderr.splitlines() if x.startswith("PEAK")]
    if not line:
        return {"seconds": None, "peak_mb": None, "exit": out.returncode}
    _, kb, seconds, code = line[-1].split()
    return {"seconds": float(seconds), "peak_mb": int(kb) / 1024, "exit": int(code)}


def measure_cli(args):
    """``{'seconds', 'peak_mb', 'exit'}`` of ``handeye ARGS`` in a fresh process (seconds and
    peak None when it died before reporting; :func:`measure_python`)."""
    return measure_python("from handeye.app.command.cli import main", "main(sys.argv[1:])", args)


#: Simulated sizes of the pipeline-to-lean-solve ratios beside thesis-real and thesis-sim (issue 42's).
RATIO_SIZES = (300, 3_000, 30_000)


def ratios(sizes=RATIO_SIZES, reps=5):
    """:func:`handeye.app.tools.bench_pipeline.pipeline_vs_solve` on thesis-real, thesis-sim and a simulated
    dataset of each of ``sizes`` measurements (:func:`write_dataset`), in one run: the rows of
    :func:`~handeye.app.tools.bench_pipeline.ratios_text`."""
    rows = [bench_pipeline.pipeline_vs_solve(name, reps) for name in ("thesis-real", "thesis-sim")]
    with scratch.temporary_folder() as tmp:
        for n in sizes:
            row = bench_pipeline.pipeline_vs_solve(str(write_dataset(f"{tmp}/n{n}", n)), reps)
            rows.append({**row, "label": f"simulated {n:,}"})
    return rows


def pipeline(sizes=PIPELINE):
    """Wall time and peak memory of ``handeye calibrate`` with default options (screening, fit,
    covariance, leave-one-out) against the number of measurements, each in a fresh process."""
    rows = []
    with scratch.temporary_folder() as tmp:
        for n in sizes:
            folder = write_dataset(f"{tmp}/n{n}", n)
            rows.append(dict(n=n, **measure_cli(["calibrate", str(folder), "--json"])))
    # slopes over the sizes where the pipeline is the same one: above 5,000 measurements the default is
    # lm (below, IPOPT: a different algorithm); the bench's centre model with the centre known has its
    # leave-one-out in closed form at every size
    from handeye.app.engine.request import LARGE

    ok = [r for r in rows if r["seconds"] and r["n"] > LARGE]
    logn = np.log([r["n"] for r in ok])
    slope = float(np.polyfit(logn, np.log([r["seconds"] for r in ok]), 1)[0]) if len(ok) >= 2 else None
    mem_slope = float(np.polyfit(logn, np.log([r["peak_mb"] for r in ok]), 1)[0]) if len(ok) >= 2 else None
    return {"rows": rows, "time_slope": slope, "memory_slope": mem_slope, "slope_above": LARGE}


#: Points of the ``handeye cloud`` / ``validate`` scaling (1,280-point profiles, as the sensor's).
CLOUD = (10_240, 102_400, 1_024_000, 3_072_000)


def write_scan(folder, n_points, per_profile=1280, seed=0):
    """A scan of a 30 mm-radius sphere at (1500, -600, 1100) with ``n_points`` points in
    1,280-point profiles (0.01 mm noise), and a calibration file with a covariance beside it."""
    rng = np.random.default_rng(seed)
    folder = pathlib.Path(folder)
    (folder / "p").mkdir(parents=True, exist_ok=True)
    x = transform_from_pose(np.array([190.0, 100.0, 125.0, 180.0, -88.0, 0.0]))
    centre, radius = np.array([1500.0, -600.0, 1100.0]), 30.0
    rows = ["id,x,y,z,a,b,c,profile"]
    for k in range(int(np.ceil(n_points / per_profile))):
        angles = np.array([rng.uniform(-180, 180), rng.uniform(-30, 30), 180 + rng.uniform(-30, 30)])
        s2b = transform_from_pose(np.r_[0.0, 0.0, 0.0, angles])
        ys = rng.uniform(-0.7, 0.7) * radius
        in_sensor = np.array([rng.uniform(-10, 10), ys, rng.uniform(220, 260)])
        s2b[:3, 3] = centre - s2b[:3, :3] @ in_sensor
        r = np.sqrt(radius ** 2 - ys ** 2)
        phi = np.linspace(np.pi + 0.2, 2 * np.pi - 0.2, per_profile)
        xz = np.c_[in_sensor[0] + r * np.cos(phi), in_sensor[2] + r * np.sin(phi) + rng.normal(0, 0.01, per_profile)]
        (folder / "p" / f"{k}.csv").write_text("x,z\n" + "\n".join(f"{a:.5f},{b:.5f}" for a, b in xz) + "\n")
        rows.append(f"s{k}," + ",".join(f"{v:.9f}" for v in pose_from_transform(s2b @ np.linalg.inv(x))) + f",p/{k}.csv")
    (folder / "measurements.csv").write_text("\n".join(rows) + "\n")
    (folder / "setup.toml").write_text(f"[sphere]\ndiameter = {2 * radius}\ncenter = {centre.tolist()}\n")
    cov = np.diag(np.square([0.05, 0.05, 0.05, 5e-4, 5e-4, 5e-4]))
    names = ["tx", "ty", "tz", "wx", "wy", "wz"]
    (folder.parent / f"{folder.name}.json").write_text(json.dumps(
        {"sensor_matrix": x.tolist(), "converged": True, "covariance": {"names": names, "matrix": cov.tolist()}}))
    return folder


#: The slopes of the cloud and validate scaling are fitted from this many points on.
SLOPE_FROM = 100_000


def use_scaling(sizes=CLOUD):
    """Wall time and peak memory of ``handeye cloud`` (binary PLY with per-point sd) and
    ``handeye validate`` against the number of points, each in a fresh process."""
    rows = []
    with scratch.temporary_folder() as tmp:
        for n in sizes:
            folder = write_scan(f"{tmp}/n{n}", n)
            cal = str(pathlib.Path(tmp) / f"n{n}.json")
            row = {"points": n}
            for what, args in (("cloud", ["cloud", str(folder), "--calibration", cal, "--out", f"{tmp}/c.ply"]),
                               ("validate", ["validate", str(folder), "--calibration", cal, "--json"])):
                row[what] = measure_cli(args)
                if row[what]["seconds"] is not None:
                    row[what]["points_per_s"] = n / row[what]["seconds"]
            rows.append(row)
    out = {"rows": rows, "slope_from": SLOPE_FROM}
    for what in ("cloud", "validate"):  # above the fixed cost of a process's imports and set-up
        ok = [r for r in rows if r[what]["seconds"] and r[what]["exit"] == 0 and r["points"] >= SLOPE_FROM]
        if len(ok) >= 2:
            logn = np.log([r["points"] for r in ok])
            out[f"{what}_time_slope"] = float(np.polyfit(logn, np.log([r[what]["seconds"] for r in ok]), 1)[0])
            out[f"{what}_memory_slope"] = float(np.polyfit(logn, np.log([r[what]["peak_mb"] for r in ok]), 1)[0])
    return out


def peers(reps=20):
    """Ceres and GTSAM beside the fast path and scipy on thesis-real (:mod:`handeye.app.tools.bench_peers`)."""
    case = real_case()
    return bench_peers.measure(case, _methods(*case, len(case[1])), reps)


def run(quick=False, reps=None, sizes=None, throughput_n=None, with_startup=True, scaling_sizes=None,
        pipeline_sizes=None, cloud_sizes=None):
    """Run the benchmark; returns the JSON-ready result."""
    reps = reps or (5 if quick else 20)
    started = machine()
    cases = {"thesis-real": real_case(),
             **{f"sim-{n}": simulated_case(n) for n in (sizes if sizes is not None else (SIZES[:2] if quick else SIZES))}}
    result = {"reps": reps, "cases": compare(cases, reps)}
    real = result["cases"]["thesis-real"]
    result["speedup_vs_scipy"] = real["scipy-2point"]["median_ms"] / real["fast"]["median_ms"]
    scaling_sizes = (SCALING[:4] if quick else SCALING) if scaling_sizes is None else scaling_sizes
    result["scaling"] = scaling(scaling_sizes, reps=3 if quick else 5)
    result["profile"] = profile(cases["thesis-real"], reps=50 if quick else 500)
    result["throughput"] = tp = throughput(quick, throughput_n)
    result["throughput_per_s"] = tp["all_cores_per_s"]
    result["guarantee"] = [bench_guarantee.measure("thesis-real", reps=min(reps, 3 if quick else 9), unknowns=u)
                           for u in ("sensor", "sensor+sphere")]
    result["ratios"] = ratios(RATIO_SIZES[:1] if quick else RATIO_SIZES, reps=min(reps, 3 if quick else 9))
    result["stages"] = result["ratios"][0]  # thesis-real's, stage by stage
    result["peers"] = peers(reps)
    result["points"] = bench_points.measure(reps=min(reps, 5))
    if with_startup:
        result["startup"] = startup()
    pipeline_sizes = ((10_000, 30_000) if quick else PIPELINE) if pipeline_sizes is None else pipeline_sizes
    if pipeline_sizes:
        result["pipeline"] = pipeline(pipeline_sizes)
    cloud_sizes = (CLOUD[:2] if quick else CLOUD) if cloud_sizes is None else cloud_sizes
    if cloud_sizes:
        result["use"] = use_scaling(cloud_sizes)
    result["machine"] = {**started, "load_at_end": machine()["load"]}
    return result


def text(res):
    """The report: one table with ratios to scipy-2point, then scaling, profile, throughput, start-up."""
    lines = [machine_line(res["machine"]), ""] if "machine" in res else []
    lines += [*_cases_text(res), "", *_scaling_text(res["scaling"]), "", *_profile_text(res["profile"]), "",
              _throughput_text(res["throughput"])]
    load = res.get("machine", {}).get("load")
    sections = (("guarantee", lambda g: ["", bench_guarantee.text(g)]),
                ("ratios", lambda r: ["", *bench_pipeline.ratios_text(r, load)]),
                ("stages", lambda s: ["", *bench_pipeline.text(s)]),
                ("peers", lambda r: ["", bench_peers.text(r)]), ("points", lambda r: ["", bench_points.text(r)]),
                ("startup", _startup_text), ("pipeline", _pipeline_text), ("use", _use_text))
    for key, show in sections:
        if key in res:
            lines += show(res[key])
    return "\n".join(lines)


def _cases_text(res):
    """The table of every case and method, with its ratio to scipy-2point."""
    lines = [f"{'case':<12} {'method':<13} {'median ms':>10} {'min ms':>9} {'x scipy':>8} {'iters':>6} {'evals':>6} "
             f"{'cost':>12} agrees"]
    for case, table in res["cases"].items():
        base = table["scipy-2point"]["median_ms"]
        for method, row in table.items():
            agrees = "yes" if row["agrees"] else "NO (%.1e mm, %.1e deg)" % (row["distance_mm"], row["distance_deg"])
            its = "-" if row["iterations"] is None else row["iterations"]  # scipy reports none
            lines.append(f"{case:<12} {method:<13} {row['median_ms']:10.3f} {row['min_ms']:9.3f} "
                         f"{base / row['median_ms']:8.1f} {its:>6} {row['evaluations']:6d} "
                         f"{row['cost']:12.6g} {agrees}")
    return lines + ["", f"fast path vs scipy-2point (thesis-real): {res['speedup_vs_scipy']:.0f}x"]


def _scaling_text(sc):
    return ["fast path against the number of measurements:",
            "".join(f"  n={r['n']}: {r['median_ms']:.3f} ms ({r['per_evaluation_us']:.1f} us/evaluation)\n"
                    for r in sc["rows"]).rstrip(),
            f"  log-log slope of the compiled time per evaluation: {sc['slope']:.2f} (1 = linear)"]


def _profile_text(p):
    lines = [f"profile, thesis-real (n = {p['n']}, {p['evaluations']} evaluations): {p['total_us']:.1f} us median"]
    if not p["compiled"]:
        return lines + ["  no C compiler: the CasADi virtual machine ran the model"]
    return lines + [f"  compiled iteration {p['compiled_loop_us']:.1f} us = {p['evaluations']} evaluations x "
                    f"{p['one_evaluation_us']:.2f} us + {max(p['steps_us'], 0.0):.1f} us of 6 x 6 solves and updates "
                    "(a difference of medians: 0 means below the timing's resolution)",
                    f"  ctypes call {p['call_us']:.1f} us; Python around it (data layout, result) {p['python_us']:.1f} us",
                    f"  generated model: {p['instructions_per_measurement']} instructions per measurement, "
                    f"{p['instructions_executed']} executed, {p['ns_per_instruction']:.2f} ns each"]


def _throughput_text(tp):
    return (f"Monte Carlo (31 measurements, {tp['calibrations']} calibrations, {tp['converged']} converged, "
            f"RMS translation error {tp['rms_translation_error_mm']:.3f} mm): {tp['all_cores_per_s']:.0f}/s on "
            f"{tp['jobs']} cores including simulation; calibration alone {tp['calibration_only_per_s_one_core']:.0f}/s "
            "per core")


def _startup_text(s):
    return [f"handeye calibrate start-to-finish: cold cache {s['cold_s']:.2f} s, warm {s['warm_s']:.2f} s, "
            f"{s['warm again_s']:.2f} s (exit {s['cold_exit']}/{s['warm_exit']})"]


def _pipeline_text(pl):
    lines = ["", "handeye calibrate, default options (screening, fit, covariance, leave-one-out), by size:"]
    lines += [f"  {r['n']:>9} measurements: failed (exit {r['exit']})" if r["seconds"] is None else
              f"  {r['n']:>9} measurements: {r['seconds']:8.2f} s, peak {r['peak_mb']:8.0f} MB, exit {r['exit']}"
              for r in pl["rows"]]
    if pl["time_slope"] is not None:
        lines.append(f"  log-log slope above {pl['slope_above']} measurements (lm; leave-one-out in closed form): "
                     f"time {pl['time_slope']:.2f}, peak memory {pl['memory_slope']:.2f} (1 = linear; below, "
                     "the default is IPOPT)")
    return lines


def _use_text(u):
    lines = ["", "handeye cloud (binary PLY, per-point sd) and validate (sphere fit, PF/PS, 1-sd), by points:"]
    for r in u["rows"]:
        cells = [f"{what} failed (exit {c['exit']})" if c["seconds"] is None else
                 f"{what} {c['seconds']:6.2f} s, {c['points_per_s'] / 1e6:5.2f} M points/s, peak {c['peak_mb']:6.0f} MB"
                 for what, c in (("cloud", r["cloud"]), ("validate", r["validate"]))]
        lines.append(f"  {r['points']:>9} points: " + "; ".join(cells))
    if "cloud_time_slope" in u:
        lines.append(f"  log-log slopes from {u['slope_from']:,} points: cloud time {u['cloud_time_slope']:.2f}, "
                     f"memory {u['cloud_memory_slope']:.2f}; "
                     f"validate time {u['validate_time_slope']:.2f}, memory {u['validate_memory_slope']:.2f} "
                     "(1 = linear)")
    return lines


def plot(res, path):
    """Log-log time against measurements for the fast path and every method of the table."""
    from handeye.app.present import figure_style as style
    from handeye.app.present.plotting import figure

    plt = figure()
    fig, ax = plt.subplots(figsize=(8.4, 5.4))
    rows = res["scaling"]["rows"]
    ns = np.array([r["n"] for r in rows])
    ax.loglog(ns, [r["median_ms"] for r in rows], "o-", label="fast (compiled), scaling run")
    sizes = {int(c.split("-")[1]): t for c, t in res["cases"].items() if c.startswith("sim-")}
    for k, method in enumerate(ORDER[1:]):
        pts = sorted((n, t[method]["median_ms"]) for n, t in sizes.items() if method in t)
        if len(pts) > 1:
            ax.loglog(*zip(*pts), style.MARKERS[(k + 1) % len(style.MARKERS)] + "--", label=method, alpha=0.8)
    ref = rows[-1]["median_ms"] * ns / ns[-1]
    ax.loglog(ns, ref, "k:", label="linear reference")
    ax.set_xlabel("measurements")
    ax.set_ylabel("time per calibration (ms)")
    ax.set_title(f"fast path slope {res['scaling']['slope']:.2f} per evaluation")
    ax.legend()
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    style.save(fig, path)
    plt.close(fig)
