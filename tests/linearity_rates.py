"""Depth-bend rates over seeds: ``python tests/linearity_rates.py [SEEDS] [CLASS,...] [--json FILE]``.

Cells from tests/indep_linearity.py (an independent generator: numpy only, written from the README's dataset
format); each is loaded (``handeye.load_dataset``: the bend handeye found) and calibrated by
``handeye.calibrate(folder)`` (``unknowns="sensor+sphere"`` where the cell gives no centre).  Every cell whose
bend was applied is calibrated again with the correction disabled (``profile_bend.MIN_BEND_MM = inf``).

Exit codes as the CLI's: converged 0, not converged 1, ``handeye.InputError`` 2, anything else 3 (a crash).
"Wrong": exit 0, more than 3 reported sd *and* more than 0.2 mm or 0.05 deg from the truth.
"""
from __future__ import annotations

import json
import math
import pathlib
import sys
import tempfile
import time
import traceback

import indep_linearity as il
import numpy as np

import handeye
from handeye.model.common.rotation import pose_distance
from handeye.model.geometry import profile_bend


def _calibrate(folder, unknowns):
    """``(exit, result or None, message)``."""
    try:
        r = handeye.calibrate(str(folder), unknowns=unknowns)
    except handeye.InputError as exc:
        return 2, None, str(exc)
    except Exception:  # a crash: exit 3 for the CLI
        return 3, None, traceback.format_exc()
    return (0 if r.converged else 1), r, r.message


def _distance(truth, r):
    if r is None or r.sensor2flange is None:
        return None
    cov = r.covariance
    if cov is not None and not np.isfinite(np.asarray(cov, float)).all():  # a fit that did not converge: NaN
        cov = None  # (pose_distance's pinv raises LinAlgError on it)
    d = pose_distance(truth, np.asarray(r.sensor2flange, float), cov, r.parameter_names if cov is not None else None)
    return {"mm": d["translation_mm"], "deg": d["rotation_deg"], "sd": d["sd"]}


def _wrong(code, d):
    if code != 0 or d is None:
        return False
    sd = math.inf if d["sd"] is None else d["sd"]
    return sd > 3 and (d["mm"] > 0.2 or d["deg"] > 0.05)


def cell(kind, seed, root):
    """One cell's row (dict)."""
    folder = pathlib.Path(root) / f"{kind}-{seed}"
    info = il.make(folder, seed, kind)
    unknowns = "sensor" if info["centre_known"] else "sensor+sphere"
    row = {"kind": kind, "seed": seed, "mount": info["mount"], "depth": info["depth"], "n": info["n"],
           "diameter": info["diameter"], "amplitude": info["amplitude"], "shape": info["shape"],
           "true_on_profiles_mm": info["bend_on_profiles_mm"], "noise": info["sensor"]["point_sd"],
           "noise_along": info["sensor"]["noise_along"], "centre_known": info["centre_known"], "unknowns": unknowns}
    t0 = time.time()
    try:
        bend = handeye.load_dataset(str(folder)).bend
        row.update(bend_found=bend is not None, applied=bool(bend is not None and bend.applied),
                   bend_mm=None if bend is None else bend.bend_mm, bend_p=None if bend is None else bend.p_value,
                   bend_degree=None if bend is None else bend.degree, bend_slope=None if bend is None else bend.slope)
    except handeye.InputError as exc:
        row.update(bend_found=False, applied=False, bend_mm=None, load_error=str(exc))
    except Exception:
        row.update(bend_found=False, applied=False, bend_mm=None, load_crash=traceback.format_exc())
    code, r, message = _calibrate(folder, unknowns)
    d = _distance(info["truth"], r)
    warn = [w for w in (r.warnings if r is not None else []) if "bend" in w or "linearity" in w]
    row.update(exit=code, dist=d, wrong=_wrong(code, d), at_truth=code == 0 and not _wrong(code, d),
               message=message[:400] if code else "", crash=message if code == 3 else None,
               bend_warning=warn[0] if warn else None,
               effects=[e.name for e in (r.effects or [])] if r is not None else [],
               excluded=len(r.excluded or []) if r is not None and getattr(r, "excluded", None) is not None else None)
    if row["applied"]:
        keep = profile_bend.MIN_BEND_MM
        profile_bend.MIN_BEND_MM = float("inf")
        try:
            code0, r0, message0 = _calibrate(folder, unknowns)
        finally:
            profile_bend.MIN_BEND_MM = keep
        d0 = _distance(info["truth"], r0)
        row["uncorrected"] = {"exit": code0, "dist": d0, "wrong": _wrong(code0, d0), "message": message0[:400] if code0 else ""}
    row["seconds"] = time.time() - t0
    return row


def _fmt(d):
    if d is None:
        return "-"
    sd = "-" if d["sd"] is None else f"{d['sd']:.1f}"
    return f"{d['mm']:.3f} mm {d['deg']:.4f} deg {sd} sd"


def table(rows, kinds):
    print("| class | cells | bend applied | bend warning | exit 0 at truth | exit 0 wrong (bend applied / not) | exit 1 |"
          " exit 2 (of them 'diameter') | crash (3) | where applied, uncorrected: exit 0 wrong / at truth / cells |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for kind in kinds:
        rs = [r for r in rows if r["kind"] == kind]
        un = [r["uncorrected"] for r in rs if "uncorrected" in r]
        wrong = [r for r in rs if r["wrong"]]
        e2 = [r for r in rs if r["exit"] == 2]
        print(f"| {kind} | {len(rs)} | {sum(r['applied'] for r in rs)} | {sum(r['bend_warning'] is not None for r in rs)} | "
              f"{sum(r['at_truth'] for r in rs)} | {len(wrong)} ({sum(r['applied'] for r in wrong)} / "
              f"{sum(not r['applied'] for r in wrong)}) | {sum(r['exit'] == 1 for r in rs)} | "
              f"{len(e2)} ({sum('[sphere] diameter' in r['message'] for r in e2)}) | {sum(r['exit'] == 3 for r in rs)} | "
              f"{sum(u['wrong'] for u in un)} / {sum(u['exit'] == 0 and not u['wrong'] for u in un)} / {len(un)} |")
    print()
    print("by pose set (every class): depth | cells | applied | at truth | wrong | exit 1 | exit 2")
    for depth in il.DEPTHS:
        for bent in (False, True):
            rs = [r for r in rows if r["depth"] == depth and (r["kind"] != "clean") == bent]
            if rs:
                print(f"  {depth:6s} {'bent ' if bent else 'clean'} | {len(rs)} | {sum(r['applied'] for r in rs)} | "
                      f"{sum(r['at_truth'] for r in rs)} | {sum(r['wrong'] for r in rs)} | {sum(r['exit'] == 1 for r in rs)} | "
                      f"{sum(r['exit'] == 2 for r in rs)}")


def _describe(r):
    bend = "-" if r["bend_mm"] is None else f"{r['bend_mm']:.3f}{'' if r['applied'] else ' (not applied)'}"
    return (f"{r['kind']} seed {r['seed']} ({r['mount']}, {r['depth']}, n {r['n']}, D {r['diameter']:.1f}, "
            f"noise {r['noise']:.3f} {r['noise_along']}, {r['unknowns']}): true bend {r['amplitude']:.3f} mm over the range, "
            f"{r['true_on_profiles_mm']:.3f} over the profiles' depths [{r['shape']}]; handeye bend_mm {bend}")


def report(rows, kinds):
    table(rows, kinds)
    wrong = sorted((r for r in rows if r["wrong"]), key=lambda r: -(r["dist"]["sd"] or math.inf))
    print(f"\nwrong exits 0 ({len(wrong)}), worst first:")
    for r in wrong[:12]:
        un = r.get("uncorrected")
        print(f"  {_describe(r)}\n     corrected: {_fmt(r['dist'])}"
              + (f"; uncorrected: exit {un['exit']} {_fmt(un['dist'])}" if un else "")
              + (f"; effects {r['effects']}" if r["effects"] else ""))
    print("\ncorrection's effect where applied (corrected -> uncorrected, exit 0 both):")
    for kind in kinds:
        pairs = [(r["dist"], r["uncorrected"]["dist"]) for r in rows if r["kind"] == kind and "uncorrected" in r
                 and r["exit"] == 0 and r["uncorrected"]["exit"] == 0]
        if pairs:
            c, u = np.array([[a["mm"], a["deg"]] for a, _ in pairs]), np.array([[b["mm"], b["deg"]] for _, b in pairs])
            better = sum(a["mm"] < b["mm"] for a, b in pairs)
            print(f"  {kind}: {len(pairs)} cells; median mm {np.median(c[:, 0]):.3f} -> {np.median(u[:, 0]):.3f}, "
                  f"max mm {c[:, 0].max():.3f} -> {u[:, 0].max():.3f}; median deg {np.median(c[:, 1]):.4f} -> "
                  f"{np.median(u[:, 1]):.4f}; translation closer with the correction in {better} of {len(pairs)}")
    others = [r for r in rows if r["exit"] in (1, 2)]
    print(f"\nexit 1 / 2 ({len(others)}):")
    for r in others:
        print(f"  exit {r['exit']} {r['kind']} seed {r['seed']} applied {r['applied']} bend_mm "
              f"{'-' if r['bend_mm'] is None else round(r['bend_mm'], 3)}: {r['message'][:260]}")
    crashes = [r for r in rows if r["exit"] == 3 or r.get("load_crash")]
    print(f"\ncrashes ({len(crashes)}):")
    for r in crashes:
        print(f"  {r['kind']} seed {r['seed']}:\n{r.get('crash') or r.get('load_crash')}")
    false = [r for r in rows if r["kind"] in ("clean", "lateral") and r["applied"]]
    print(f"\nbend applied on cells with no depth bend ({len(false)}):")
    for r in false:
        print(f"  {_describe(r)}; p {r['bend_p']:.2g}, degree {r['bend_degree']}, slope {r['bend_slope']:.3f}; "
              f"{_fmt(r['dist'])} (exit {r['exit']}); uncorrected {_fmt(r['uncorrected']['dist'])}")
    print(f"\nbend warnings: {sum(r['bend_warning'] is not None for r in rows)} cells; applied: "
          f"{sum(r['applied'] for r in rows)}; e.g. {next((r['bend_warning'] for r in rows if r['bend_warning']), None)}")
    print(f"time: {sum(r['seconds'] for r in rows):.0f} s over {len(rows)} cells")


def main(argv):
    args = [a for a in argv if not a.startswith("--")]
    out = argv[argv.index("--json") + 1] if "--json" in argv else None
    if out in args:
        args.remove(out)
    seeds = int(args[0]) if args else 15
    kinds = args[1].split(",") if len(args) > 1 else list(il.CLASSES)
    rows = []
    with tempfile.TemporaryDirectory() as root:
        for kind in kinds:
            for seed in range(seeds):
                rows.append(cell(kind, seed, root))
                r = rows[-1]
                print(f"{kind} {seed}: exit {r['exit']} applied {r['applied']} {_fmt(r['dist'])} "
                      f"({r['seconds']:.1f} s)", file=sys.stderr, flush=True)
    if out:
        pathlib.Path(out).write_text(json.dumps(rows, indent=1, default=float))
    report(rows, kinds)
    return rows


if __name__ == "__main__":
    main(sys.argv[1:])
