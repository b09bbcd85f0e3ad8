"""``handeye bench``'s peers: Ceres and GTSAM on the fast path's problem, side by side.

The problem is the bench's thesis-real case (:func:`handeye.app.tools.bench.real_case`): the
unweighted ``centre`` model with the sphere centre known, six unknowns. In one run:

* ``fast`` and ``scipy-exact`` -- the bench's own callables (:func:`handeye.app.tools.bench._methods`):
  the compiled Levenberg-Marquardt and ``scipy.optimize.least_squares`` with our exact Jacobian;
* ``ceres`` -- Ceres' Levenberg-Marquardt (``pyceres``) on the same residual: one residual
  block of all rows over the six Euler-angle unknowns, its values and Jacobian from the same
  generated code as scipy's (:class:`handeye.model.fit.calibration.CalibrationModel`, ``euler``);
* ``gtsam-align`` -- GTSAM's closed form ``Pose3.Align``: with the centre known, the residual
  ``R1_i (R2 xs_i + t2) + t1_i - c`` has the length of ``R2 xs_i + t2 - q_i`` (``q_i`` the
  sphere centre in flange i's frame), so the least-squares pose is the point-set alignment of
  the measured centres ``xs_i`` onto ``q_i``: the same minimum, without iterations.

A peer that is not installed (the ``bench`` extra: ``pip install handeye[bench]``) is reported
as such, not timed. Every peer's pose is compared with the fast path's. Then one line puts the
fast path against the memory-bandwidth floor: the bytes of data its evaluations read per solve
at the bandwidth of a large numpy copy.

Timing is measured here, never in tests.
"""
from __future__ import annotations

import numpy as np

from handeye.app.tools.peak import timed
from handeye.model.chain.pose import pose_from_transform
from handeye.model.common.rotation import transform_distance
from handeye.model.fit.calibration import CalibrationModel

#: peers in report order: name -> the Python package it needs
PEERS = {"ceres": "pyceres", "gtsam-align": "gtsam"}
#: doubles the compiled fast path reads per measurement and evaluation (R1 9, t1 3, xs 3)
ROW_DOUBLES = 15


def _ceres(f2b, xs, centre, start):
    """Callable: Ceres' LM on the Euler model (exact generated Jacobian), returning ``(pose, iterations, None,
    cost)`` as the bench's methods do (Ceres reports no evaluations); ImportError without pyceres."""
    import pyceres

    euler = CalibrationModel(f2b, xs, centre, "euler")
    x0 = euler.point_from_pose(pose_from_transform(start))

    class Rows(pyceres.CostFunction):
        def __init__(self):
            pyceres.CostFunction.__init__(self)
            self.set_num_residuals(3 * len(xs))
            self.set_parameter_block_sizes([6])

        def Evaluate(self, parameters, residuals, jacobians):  # noqa: N802 - Ceres' name
            x = np.asarray(parameters[0])
            residuals[:] = euler.residual(x)
            if jacobians is not None and jacobians[0] is not None:
                jacobians[0][:] = euler.jacobian(x).ravel()  # row-major, as Ceres wants
            return True

    options = pyceres.SolverOptions()
    options.linear_solver_type = pyceres.LinearSolverType.DENSE_QR
    options.function_tolerance = options.gradient_tolerance = options.parameter_tolerance = 1e-15
    options.max_num_iterations = 200

    def solve():
        x = x0.copy()
        problem = pyceres.Problem()
        problem.add_residual_block(Rows(), None, [x])
        summary = pyceres.SolverSummary()
        pyceres.solve(options, problem, summary)
        return euler.sensor2flange(x), summary.num_successful_steps + summary.num_unsuccessful_steps, None, float(
            summary.final_cost)

    return solve


def _gtsam_align(f2b, xs, centre, start):
    """Callable: GTSAM's ``Pose3.Align`` of the measured centres onto the flange-frame centres, returning
    ``(pose, None, None, cost)``: a closed form has no iterations and no evaluations."""
    import gtsam

    euler = CalibrationModel(f2b, xs, centre, "euler")
    sensor_points = np.ascontiguousarray(np.asarray(xs, float).T)

    def solve():
        flange_points = np.einsum("nji,nj->in", f2b[:, :3, :3], centre - f2b[:, :3, 3])  # R1^T (c - t1)
        pose = gtsam.Pose3.Align(np.ascontiguousarray(flange_points), sensor_points)  # flange = pose * sensor
        t = pose.matrix()
        return t, None, None, euler.cost(euler.point_from(t))  # closed form: no iterations

    return solve


def memory_bandwidth(megabytes=256, reps=5):
    """Bytes per second of a large numpy copy (read and write counted), the best of ``reps``."""
    a = np.ones(megabytes * 2**20 // 8)
    b = np.empty_like(a)
    return 2 * a.nbytes / min(timed(lambda: np.copyto(b, a), reps)[0])


def measure(case, own, reps=20):
    """Fast path, scipy with the exact Jacobian and every installed peer on one case.

    Parameters
    ----------
    case : tuple
        ``(flange2base, centre_in_sensor, sphere_centre, start)`` (the bench's thesis-real:
        :func:`handeye.app.tools.bench.peers`).
    own : dict
        The bench's own timed callables of the case, ``'fast'`` and ``'scipy-exact'`` among them.
    reps : int
        Timed repetitions (median reported).

    Returns
    -------
    dict
        ``rows``: per method ``name``, ``installed``, ``median_ms``, ``iterations``, ``cost``,
        ``distance_mm`` and ``distance_deg`` to the fast path's pose; ``n``; ``bandwidth``:
        ``bytes_per_solve``, ``bytes_per_s``, ``floor_us`` and ``fast_us``.
    """
    f2b, xs, centre, start = case
    methods = {"fast": own["fast"], "scipy-exact": own["scipy-exact"]}
    missing = {}
    for name, build in {"ceres": _ceres, "gtsam-align": _gtsam_align}.items():
        try:
            methods[name] = build(f2b, xs, centre, start)
        except ImportError:
            missing[name] = PEERS[name]
    rows, ref, evaluations = [], None, 0
    for name, solve in methods.items():
        solve()  # warm: compile or load the fast path, import and set up the peer
        times, (t, its, evals, cost) = timed(solve, reps)
        if name == "fast":
            ref, evaluations = t, evals
        dt, dr = transform_distance(t, ref)
        rows.append({"name": name, "installed": True, "median_ms": float(np.median(times)) * 1e3, "iterations": its, "cost": cost,
                     "distance_mm": float(dt), "distance_deg": float(dr)})
    rows += [{"name": name, "installed": False, "package": package} for name, package in missing.items()]
    bytes_per_solve = evaluations * len(xs) * ROW_DOUBLES * 8
    bandwidth = memory_bandwidth()
    return {"n": len(xs), "rows": rows, "bandwidth": {
        "bytes_per_solve": bytes_per_solve, "evaluations": evaluations, "bytes_per_s": bandwidth,
        "floor_us": bytes_per_solve / bandwidth * 1e6, "fast_us": rows[0]["median_ms"] * 1e3}}


def text(res):
    """The peers' table, times as ratios to the fast path and to scipy, and the bandwidth line."""
    by = {r["name"]: r for r in res["rows"] if r["installed"]}
    fast_ms, scipy_ms = by["fast"]["median_ms"], by["scipy-exact"]["median_ms"]
    lines = [f"peers on thesis-real (n = {res['n']}, centre model, sensor pose; the fast path's pose is the reference):",
             f"  {'method':<12} {'median ms':>10} {'x fast':>8} {'x scipy':>8} {'iters':>6} {'cost':>12}  pose difference"]
    for r in res["rows"]:
        if not r["installed"]:
            lines.append(f"  {r['name']:<12} not installed (pip install {r['package']}, or the bench extra)")
            continue
        its = "-" if r["iterations"] is None else r["iterations"]
        lines.append(f"  {r['name']:<12} {r['median_ms']:10.3f} {r['median_ms'] / fast_ms:8.1f} "
                     f"{r['median_ms'] / scipy_ms:8.2f} {its:>6} {r['cost']:12.6g}  "
                     f"{r['distance_mm']:.1e} mm, {r['distance_deg']:.1e} deg")
    b = res["bandwidth"]
    lines.append(f"  bandwidth floor: {b['bytes_per_solve']:,} bytes of data per solve ({b['evaluations']} evaluations x "
                 f"{res['n']} rows x {ROW_DOUBLES} doubles) at {b['bytes_per_s'] / 1e9:.1f} GB/s (numpy copy) = "
                 f"{b['floor_us']:.3f} us; the fast path takes {b['fast_us']:.1f} us, "
                 f"{b['fast_us'] / b['floor_us']:.0f}x the floor (its data fit in cache: the time is arithmetic and "
                 "call overhead, not memory)")
    return "\n".join(lines)
