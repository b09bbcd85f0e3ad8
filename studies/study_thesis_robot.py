"""Study: how much of the thesis's residual can the robot's own errors explain?

Story. The seed blames what remains after its calibration on "systematic robot errors" (7.3,
Table 7-5), but its data hold only the flange poses the KR 60 HA reported, not its joint angles.
Here the angles are *reconstructed*: the inverse kinematics of the KR 60 HA's nominal model
(:mod:`handeye.model.simulation.simulate_robot`) for each printed pose. Then ``handeye diagnose`` runs twice on
the same samples -- without the angles, and with them (so that the robot's errors,
``joint_offsets``, ``link_lengths`` and ``joint_compliance``, are in the catalogue, compared as
alternatives by :mod:`handeye.app.engine.robot_choice`) -- and the gap each leaves is compared.

What this can and cannot show. The reconstruction is exact for the nominal model, so a joint-offset
pattern that lowers the held-out error is *consistent* with the residual: the residual has the
shape offsets of those joints would give. It cannot show the robot's actual offsets: the robot's
own (calibrated) kinematics, its wrist configuration (A4/A6 flipped give the same pose) and its
other errors are unknown, and the printed poses are rounded; the robot effects that explain the
data about as well as the one named are reported beside it (``robot_alternatives``).

Claims: the inverse kinematics reproduces at least 90 % of the printed poses (1e-6 mm); with the
reconstructed angles diagnose's held-out error is not worse than without them; the study reports
the offsets it names and the gap left.
"""
from __future__ import annotations

import csv
import pathlib
import shutil

import numpy as np

import handeye
from handeye.model.common import scratch
from handeye.model.robot import robots
from handeye.model.simulation import simulate_robot as sr
from handeye.studies.study import claim, figure, save, write_summary, write_table


def _with_joints(src, folder, joints, keep):
    """A copy of the dataset ``src`` with the rows ``keep`` (ids -> angles) and their j1..j6; and one
    with the same rows without the angles (the baseline on the same samples)."""
    rows = list(csv.reader((src / "measurements.csv").read_text().splitlines()))
    head, at = rows[0], rows[0].index("id")
    out = {}
    for name, with_joints in (("joints", True), ("plain", False)):
        dst = folder / name
        shutil.copytree(src, dst)
        text = (dst / "setup.toml").read_text()
        if with_joints:
            text = '[robot]\nmodel = "kr60ha"\n' + text.replace("[robot]\n", "[robot-]\n") if "[robot]" in text \
                else '[robot]\nmodel = "kr60ha"\n' + text
        (dst / "setup.toml").write_text(text.replace("[robot-]\n", ""))
        body = [head + (list(robots.JOINTS) if with_joints else [])]
        body += [r + ([f"{v:.6f}" for v in keep[r[at]]] if with_joints else []) for r in rows[1:] if r and r[at] in keep]
        with open(dst / "measurements.csv", "w", newline="") as fh:
            csv.writer(fh).writerows(body)
        out[name] = dst
    return out


def run(out, quick=False):
    data = handeye.load_dataset("thesis-real")
    joints, ok = sr.inverse_kinematics(robots.load("kr60ha"), np.asarray(data.flange2base()), "kr60ha")
    claim(ok.mean() >= 0.9, f"the KR 60 HA's inverse kinematics reproduces {ok.sum()} of {len(ok)} printed poses")
    keep = {i: q for i, q, k in zip(data.ids, joints, ok) if k}
    with scratch.temporary_folder() as tmp:
        folders = _with_joints(pathlib.Path(data.path), pathlib.Path(tmp), joints, keep)
        plain, with_joints = (handeye.diagnose(folders[k]) for k in ("plain", "joints"))
    rows, summary = [], {"reconstructed": int(ok.sum()), "poses": len(ok),
                         "unreachable": [i for i, k in zip(data.ids, ok) if not k]}
    for label, res in (("without joint angles", plain), ("with reconstructed joint angles", with_joints)):
        named = "; ".join(f"{e.name}: " + ", ".join(f"{k} {v:+.4g}" for k, v in e.parameters.items())
                          for e in res.effects if e.std is not None) or "none"
        rows.append((label, res.rms_before_mm, res.rms_after_mm, res.heldout_rms_after_mm, res.chi2_dof_after, named))
        summary[label] = {"rms_after_mm": res.rms_after_mm, "heldout_rms_after_mm": res.heldout_rms_after_mm,
                          "effects": [e.to_dict() for e in res.effects], "robot_alternatives": res.robot_alternatives}
    claim(with_joints.heldout_rms_after_mm <= plain.heldout_rms_after_mm + 1e-9,
          "the reconstructed joint angles do not make the held-out error worse")
    _draw(out, plain, with_joints)
    write_table(out, "thesis_robot", ["data", "rms_before_mm", "rms_after_mm", "heldout_rms_after_mm", "chi2_dof_after",
                                      "effects named"], rows)
    write_summary(out, summary)
    return summary


def _draw(out, plain, with_joints):
    """Each sample's residual after diagnose without and with the reconstructed joint angles."""
    fig, ax = figure().subplots(figsize=(10, 4))
    ids = [r.id for r in plain.residuals]
    after = {r.id: r.after_mm for r in with_joints.residuals}
    k = np.arange(len(ids))
    ax.bar(k - 0.2, [r.after_mm for r in plain.residuals], 0.4, label=f"without joint angles (RMS {plain.rms_after_mm:.3f})")
    ax.bar(k + 0.2, [after[i] for i in ids], 0.4,
           label=f"with reconstructed joint angles: + joint_offsets (RMS {with_joints.rms_after_mm:.3f})")
    ax.axhline(with_joints.nominal_sigma_mm * np.sqrt(3), color="k", lw=0.8, ls="--", label="stated noise (3-D)")
    ax.set_xticks(k, ids, rotation=90)
    ax.set(ylabel="|e_i| after diagnose (mm, log; the tall bars are the gross errors diagnose excludes)", yscale="log",
           title="thesis-real: what joint offsets can explain (angles reconstructed)")
    ax.legend()
    save(fig, out / "thesis_robot.png")
