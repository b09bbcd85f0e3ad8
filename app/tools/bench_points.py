"""``handeye bench``'s points section: the ``points`` model against the default one (issue 26).

A simulated scan the size of a real one (robcalibrator's scan-2023-10-31: 15 poses, about
2,200 points per profile, 33,000 in all) is calibrated in process with the full default
pipeline (screening, fit, global check, covariance, leave-one-out), once with the default
residual and once with ``model='points'``, alternately; the medians and their ratio are
reported. The requirement is a ratio of at most 5 (:data:`TARGET_RATIO`).

Timing is measured here, never in tests.
"""
from __future__ import annotations

import dataclasses
import tempfile
import warnings

import numpy as np

from handeye.app.tools.peak import once
from handeye.model.simulation import simulate

POSES = 15
#: points along the simulated laser line: about 2,200 of them see the sphere (some 33,000 per scan)
LINE_POINTS = 4950
TARGET_RATIO = 5.0


def write_scan(folder, seed=0, poses=POSES, line_points=LINE_POINTS):
    """A simulated dataset with profiles (``poses`` x about 2,200 points) in ``folder``; its points."""
    setup = dataclasses.replace(simulate.Setup(), n_points=line_points)
    sim = simulate.simulate(setup, seed=seed, n_poses=poses)
    simulate.write(sim, folder, profiles=True)
    return int(sum(len(p) for p in sim.profiles))


def measure(quick=False, reps=None, seed=0):
    """Median seconds of ``calibrate(path)`` and ``calibrate(path, model='points')`` and their ratio.

    Parameters
    ----------
    quick : bool
        Fewer repetitions (3 instead of 5).
    reps : int, optional
        Repetitions of each (alternating, after one untimed warm-up of each).
    seed : int

    Returns
    -------
    dict
        ``poses``, ``points``, ``default_s``, ``points_s`` (medians), ``ratio``, ``target``,
        ``converged`` (both), ``models`` (the default's residual name), ``reps``.
    """
    from handeye.app.public.api import calibrate

    reps = reps or (3 if quick else 5)
    times = {"default": [], "points": []}
    with tempfile.TemporaryDirectory() as tmp:
        n_points = write_scan(f"{tmp}/scan", seed)
        runs = {"default": lambda: calibrate(f"{tmp}/scan"), "points": lambda: calibrate(f"{tmp}/scan", model="points")}
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            results = {name: run() for name, run in runs.items()}  # warm: generated code, imports
            for _ in range(reps):
                for name, run in runs.items():
                    times[name].append(once(run)[0])
    med = {name: float(np.median(t)) for name, t in times.items()}
    return {"poses": POSES, "points": n_points, "default_s": med["default"], "points_s": med["points"],
            "ratio": med["points"] / med["default"], "target": TARGET_RATIO, "reps": reps,
            "converged": all(r.converged for r in results.values()), "default_model": results["default"].model}


def text(res):
    """One line: both medians and the ratio against the target."""
    verdict = "within" if res["ratio"] <= res["target"] else "ABOVE"
    return (f"calibrate --model points vs the default ({res['default_model']}), full pipeline, {res['poses']} poses x "
            f"{res['points'] / res['poses']:.0f} points ({res['points']:,}): {res['points_s']:.2f} s vs "
            f"{res['default_s']:.2f} s (medians of {res['reps']}), ratio {res['ratio']:.1f} ({verdict} the target "
            f"{res['target']:g}x){'' if res['converged'] else '; NOT converged'}")
