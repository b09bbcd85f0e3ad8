"""Study: bias and spread of circle fits on a laser profile against arc length and noise.

Story. A laser line cuts the sphere in a circle; the sensor sees an arc of it. Kasa's
algebraic fit (the seed's C15) minimises a radius-weighted distance and is biased towards
small circles on short arcs; Hyper removes the essential bias; the geometric (orthogonal
distance) fit is the maximum-likelihood estimate. We fit each to many noisy arcs of a 25 mm
circle (arc 20-180 deg, point noise 0.01-0.1 mm, 200 points) and report bias and spread of r.

Claims: on a 30 deg arc with 0.05 mm noise Kasa's bias is below -5 standard errors (too
small), while Hyper's and the geometric fit's biases are within 4 standard errors of zero.
"""
from __future__ import annotations

import numpy as np

from handeye.model.geometry import circle
from handeye.studies.study import claim, figure, save, write_summary, write_table

RADIUS = 25.0


def fit_errors(arc_deg, sigma, reps, rng):
    errs = {m: [] for m in circle.FITS}
    half = np.radians(arc_deg) / 2
    for _ in range(reps):
        phi = np.linspace(-np.pi / 2 - half, -np.pi / 2 + half, 200)
        x = 3.0 + RADIUS * np.cos(phi) + rng.normal(0, sigma, phi.size)
        z = 235.0 + RADIUS * np.sin(phi) + rng.normal(0, sigma, phi.size)
        for m in circle.FITS:
            errs[m].append(circle.fit_circle(x, z, m).r - RADIUS)
    return {m: np.array(v) for m, v in errs.items()}


def run(out, quick=False):
    rng = np.random.default_rng(2024)
    reps = 60 if quick else 400
    arcs = [20, 30, 45, 90, 180]
    sigmas = [0.01, 0.05, 0.1]
    rows = []
    for sigma in sigmas:
        for arc in arcs:
            errs = fit_errors(arc, sigma, reps, rng)
            for m, e in errs.items():
                rows.append((m, arc, sigma, float(e.mean()), float(e.std()), float(e.std() / np.sqrt(reps))))
    write_table(out, "circle_fits", ["fit", "arc_deg", "noise_mm", "bias_mm", "spread_mm", "se_mm"], rows)
    fig, axes = figure().subplots(1, 2, figsize=(10, 4))
    for m in circle.FITS:
        sel = [r for r in rows if r[0] == m and r[2] == 0.05]
        axes[0].plot([r[1] for r in sel], [r[3] for r in sel], "o-", label=m)
        axes[1].plot([r[1] for r in sel], [r[4] for r in sel], "o-", label=m)
    axes[0].set(xlabel="arc length (deg)", ylabel="bias of r (mm)", title="bias, noise 0.05 mm")
    axes[1].set(xlabel="arc length (deg)", ylabel="spread of r (mm)", title="spread, noise 0.05 mm", yscale="log")
    for ax in axes:
        ax.axhline(0, color="grey", lw=0.5)
        ax.legend()
    save(fig, out / "circle_fits.png")
    pick = {m: next(r for r in rows if r[0] == m and r[1] == 30 and r[2] == 0.05) for m in circle.FITS}
    summary = {m: {"bias_mm": r[3], "spread_mm": r[4], "se_mm": r[5]} for m, r in pick.items()}
    write_summary(out, {"arc30_noise005": summary, "replicates": reps})
    claim(pick["kasa"][3] < -5 * pick["kasa"][5], "Kasa shrinks circles on a 30 deg arc")
    for m in ("hyper", "geometric"):
        claim(abs(pick[m][3]) < 4 * pick[m][5], f"{m} is unbiased on a 30 deg arc")
    return summary
