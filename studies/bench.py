"""``handeye bench``: the calibration's speed, method by method, in one process and one run.

Cases: thesis-real with its flagged samples removed, and simulated datasets of 30, 300,
3,000 and 30,000 measurements (thesis orientations, new sphere placements, noise 0.02 mm).
Methods, each from the same start (the setup's, 40 mm and a few degrees off for simulations):

* ``thesis`` -- the seed's pipeline: Gauss-Newton on Euler angles, forward-difference
  Jacobian with step 5e-7 (C4), stop when the cost no longer changes (C5's tol = 1e-20);
* ``scipy-2point`` -- ``scipy.optimize.least_squares`` (trf, 2-point differences) on the
  vectorised numpy residual: what a Python user would write;
* ``scipy-exact`` -- the same with our exact Jacobian;
* ``ipopt-matrix`` -- CasADi IPOPT on the rotation-matrix parametrisation (up to 3,000);
* ``fast`` -- Levenberg-Marquardt on the local chart with the normal equations from one
  compiled CasADi call per iteration (:mod:`model.fast`).

Per method: median and minimum time per calibration over the repetitions, iterations, final
cost, and whether it lands on the fast path's transform within 1e-6 mm and 1e-6 deg. Ratios
are to ``scipy-2point`` in the same run. Timing is measured here, never in tests.
"""
from __future__ import annotations

import time

import numpy as np

import solvers
from model import fast, simulate
from model.calibration import CalibrationModel
from model.dataset import load
from model.pose import pose_from_transform, transform_from_pose
from model.rotation import nearest_transform, transform_distance
from studies import robust

SIZES = (30, 300, 3000, 30000)


def simulated_case(n, seed=0):
    """Flange poses, centres, sphere centre, truth and start of a simulated dataset of n."""
    rng = np.random.default_rng(seed)
    setup = simulate.Setup()
    t_x = transform_from_pose(setup.sensor_pose)
    rots = [r for _, r in simulate.thesis_orientations(36)]
    centre = np.asarray(setup.sphere_centre)
    flanges, xs = [], []
    for k in range(n):
        rot = rots[k % 36]
        seen_at = np.array([rng.uniform(-10, 10), setup.side * rng.uniform(3, 20), rng.uniform(210, 270)])
        sensor = np.eye(4)
        sensor[:3, :3] = rot
        sensor[:3, 3] = centre - rot @ seen_at
        flanges.append(sensor @ np.linalg.inv(t_x))
        xs.append(seen_at + rng.normal(0, 0.02, 3))
    start = transform_from_pose(np.asarray(setup.sensor_pose) + [40, -30, 20, 3, 2, -3])
    return np.array(flanges), np.array(xs), centre, start


def real_case():
    d = load("thesis-real")
    start = transform_from_pose(d.start_pose)
    s = robust.screen(d.flange2base(), d.centre_in_sensor, d.sphere_centre, "sensor", start, d.ids, d.rows)
    return d.flange2base()[s.inliers], d.centre_in_sensor[s.inliers], d.sphere_centre, start


def _methods(f2b, xs, centre, start, n):
    euler = CalibrationModel(f2b, xs, centre, "euler")
    x0 = euler.point_from_pose(pose_from_transform(start))
    out = {}

    def thesis():
        res = solvers.solve(solvers.Problem(n=6, residual=euler.residual, jacobian=euler.jacobian), x0, "gn",
                            {"jacobian": "forward", "fd_step": 5e-7, "ftol": 1e-20, "gtol": 0.0, "xtol": 0.0,
                             "max_iter": 250})
        return euler.sensor2flange(res.x), res.iterations, res.cost

    def scipy_fit(jac):
        from scipy.optimize import least_squares

        res = least_squares(euler.residual, x0, jac=jac, method="trf", xtol=1e-12, ftol=1e-12, gtol=1e-12)
        return euler.sensor2flange(res.x), res.nfev, 0.5 * float(res.fun @ res.fun)

    out["thesis"] = thesis
    out["scipy-2point"] = lambda: scipy_fit("2-point")
    out["scipy-exact"] = lambda: scipy_fit(lambda x: euler.jacobian(x))
    if n <= 3000:
        matrix = CalibrationModel(f2b, xs, centre, "matrix")
        problem = solvers.Problem(n=12, nlp=matrix.nlp())
        xm = matrix.point_from(start)

        def ipopt():
            res = solvers.solve(problem, xm, "ipopt")
            return nearest_transform(matrix.sensor2flange(res.x)), res.iterations, res.cost

        out["ipopt-matrix"] = ipopt

    def fastest():
        t, its, cost, _ = fast.calibrate_fast(f2b, xs, centre, start, compile=True)
        return t, its, cost

    out["fast"] = fastest
    return out


def run(quick=False, reps=None, sizes=None, throughput_n=None):
    """Run the benchmark; returns the JSON-ready result."""
    reps = reps or (3 if quick else 20)
    cases = {"thesis-real": real_case()}
    for n in sizes if sizes is not None else (SIZES[:2] if quick else SIZES):
        cases[f"sim-{n}"] = simulated_case(n)
    result = {"cases": {}, "reps": reps}
    for name, (f2b, xs, centre, start) in cases.items():
        methods = _methods(f2b, xs, centre, start, len(xs))
        methods["fast"]()  # build and compile outside the timing
        ref = None
        table = {}
        for method in ("fast", "thesis", "scipy-2point", "scipy-exact", "ipopt-matrix"):
            if method not in methods:
                continue
            n_reps = reps if len(xs) <= 3000 else max(3, reps // 5)
            times = []
            for _ in range(n_reps):
                t0 = time.perf_counter()
                t, its, cost = methods[method]()
                times.append(time.perf_counter() - t0)
            if ref is None:
                ref = t
            dt, dr = transform_distance(t, ref)
            table[method] = {"median_ms": float(np.median(times) * 1e3), "min_ms": float(np.min(times) * 1e3),
                             "iterations": int(its), "cost": float(cost), "agrees": bool(dt < 1e-6 and dr < 1e-6),
                             "distance_mm": float(dt), "distance_deg": float(dr)}
        result["cases"][name] = table
    real = result["cases"]["thesis-real"]
    result["speedup_vs_scipy"] = real["scipy-2point"]["median_ms"] / real["fast"]["median_ms"]
    result["throughput_per_s"] = throughput(quick, throughput_n)
    return result


def _many(seeds):
    out = 0
    for seed in seeds:
        f2b, xs, centre, start = simulated_case(31, seed)
        fast.calibrate_fast(f2b, xs, centre, start, compile=True)
        out += 1
    return out


def throughput(quick=False, n=None):
    """Independent calibrations (31 measurements, fast path) per second on all cores."""
    from studies import sweep

    n = n or (40 if quick else 2000)
    chunks = [range(k, n, sweep.n_jobs()) for k in range(sweep.n_jobs())]
    _many([10_000])  # compile once in this process (workers load the cached library)
    t0 = time.perf_counter()
    done = sum(sweep.run(_many, [(list(c),) for c in chunks], label="throughput"))
    return done / (time.perf_counter() - t0)


def text(res):
    lines = [f"{'case':<12} {'method':<13} {'median ms':>10} {'min ms':>9} {'x scipy':>8} {'iters':>6} "
             f"{'cost':>12} agrees"]
    for case, table in res["cases"].items():
        base = table["scipy-2point"]["median_ms"]
        for method, row in table.items():
            lines.append(f"{case:<12} {method:<13} {row['median_ms']:10.3f} {row['min_ms']:9.3f} "
                         f"{base / row['median_ms']:8.1f} {row['iterations']:6d} {row['cost']:12.6g} "
                         f"{'yes' if row['agrees'] else 'NO (%.1e mm, %.1e deg)' % (row['distance_mm'], row['distance_deg'])}")
    lines += ["", f"fast path vs scipy (thesis-real): {res['speedup_vs_scipy']:.1f}x",
              f"Monte Carlo throughput: {res['throughput_per_s']:.0f} calibrations per second (all cores)"]
    return "\n".join(lines)
