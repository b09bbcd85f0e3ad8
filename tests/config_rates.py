"""The configuration-group and nominal-gate rates over seeds: ``python tests/config_rates.py [SEEDS] [CLASS,...]``.

Cells from tests/indep_config.py (an IRB 4600-like arm, 32 poses, 8 of them with the wrist flipped,
0.03 mm noise); each is calibrated by ``handeye.calibrate`` with its defaults and judged by
:func:`outcome`. Prints one line per class: cells, exit 0 at the truth, exit 0 away from it, named,
refused (exit 1), exit 2, false alarms. The README quotes its output.
"""
from __future__ import annotations

import pathlib
import sys
import tempfile

import indep_config as ic
import numpy as np

import handeye
from handeye.model.common.rotation import pose_distance

#: Narrow pose sets (tilt, turn in deg) for the offset classes: the spread of a real set's views of
#: one sphere, where the sensor pose absorbs an offset's mean in one wrist and the other looks wrong.
NARROW = {"tilt": 15.0, "turn": 20.0}


def _offset(rng, joint):
    delta = np.zeros(6)
    delta[joint] = rng.choice([-1, 1]) * rng.uniform(0.3, 0.5)
    return delta


#: class -> (what make() gets for seed s, what the verdict must name: a text in the warnings or the refusal)
CLASSES = {
    "clean": (lambda rng: {}, None),
    "clean-nojoints": (lambda rng: {"joints": False}, None),
    "clean-cfx": (lambda rng: {"joints": False, "cfx": True}, None),
    "j5": (lambda rng: {"offsets": _offset(rng, 4), **NARROW}, "j5 < 0 (the wrist flipped)"),
    "j5-nojoints": (lambda rng: {"offsets": _offset(rng, 4), "joints": False, **NARROW}, None),
    "j5-cfx": (lambda rng: {"offsets": _offset(rng, 4), "joints": False, "cfx": True, **NARROW},
               "j5 < 0 (the wrist flipped, cfx bit 0)"),
    "j4": (lambda rng: {"offsets": _offset(rng, 3), **NARROW}, "joint_offsets"),
    "j6": (lambda rng: {"offsets": _offset(rng, 5), **NARROW}, None),
    "turn": (lambda rng: {"flange_turn": -0.35}, "constant transform"),
    "order": (lambda rng: {"order": [0, 1, 2, 5, 4, 3]}, "another order"),
    "sign": (lambda rng: {"signs": [1, 1, 1, 1, -1, 1]}, "sign of j5"),
}


def effective_sensor(truth):
    """The sensor pose on the *reported* flange that closes the chain: the true one moved by a j6 offset
    (a constant turn about the flange's axis, which no pose set separates from the sensor's rotation)."""
    q = truth["joints"][0]
    turn = ic.inverse(ic.forward(q)) @ ic.forward(q + np.eye(6)[5] * truth["offsets"][5])
    return turn @ truth["sensor"]


def outcome(kind, seed, folder):
    """One cell's verdict: ``{"exit", "at_truth", "named", "alarm"}``."""
    rng = np.random.default_rng([seed, 39])
    make, name = CLASSES[kind]
    truth = ic.make(folder, seed, **make(rng))
    try:
        r = handeye.calibrate(str(folder))
    except handeye.InputError as exc:
        return {"exit": 2, "at_truth": False, "named": name is not None and name in str(exc), "alarm": True,
                "text": str(exc)}
    text = " ".join([r.message, *r.warnings])
    d = pose_distance(effective_sensor(truth), np.asarray(r.sensor2flange, float), r.covariance, r.parameter_names)
    at = d["sd"] is not None and (d["sd"] <= 3 or (d["translation_mm"] <= 0.2 and d["rotation_deg"] <= 0.05))
    said = "configuration group" in text or "constant transform" in text
    return {"exit": 0 if r.converged else 1, "at_truth": bool(at), "named": name is not None and name in text,
            "alarm": (not r.converged) or bool(r.outliers) or said, "text": text, "sd": d["sd"]}


def rates(kinds, seeds, root):
    """Per class: ``{"cells", "exit0_truth", "exit0_away", "named", "refused", "exit2", "alarms"}``."""
    out = {}
    for kind in kinds:
        rows = [outcome(kind, s, pathlib.Path(root) / f"{kind}-{s}") for s in range(seeds)]
        out[kind] = {"cells": len(rows), "exit0_truth": sum(r["exit"] == 0 and r["at_truth"] for r in rows),
                     "exit0_away": sum(r["exit"] == 0 and not r["at_truth"] for r in rows),
                     "named": sum(r["named"] for r in rows), "refused": sum(r["exit"] == 1 for r in rows),
                     "exit2": sum(r["exit"] == 2 for r in rows), "alarms": sum(r["alarm"] for r in rows)}
    return out


if __name__ == "__main__":
    seeds = int(sys.argv[1]) if len(sys.argv) > 1 else 20
    kinds = sys.argv[2].split(",") if len(sys.argv) > 2 else list(CLASSES)
    with tempfile.TemporaryDirectory() as root:
        for kind, row in rates(kinds, seeds, root).items():
            print(kind, row, flush=True)
