"""Study: the power of the discrepancy tests -- how small an effect they find.

Story. With the thesis's strategy (36 poses) and the simulator's noise (robot 0.025 mm,
profile points 0.01 mm), each continuous effect of the catalogue is hidden at a range of
sizes, alone, in many seeded datasets; ``diagnose`` runs on each. The detection rate (the
effect named, nothing else) is plotted against the size, and the smallest size detected in at
least 90 % of datasets is reported.

Claims: at the largest size of each grid the effect is detected in at least 90 % of datasets,
and the detection rate does not fall as the size grows (beyond two binomial standard errors).
"""
from __future__ import annotations

import numpy as np

import handeye
from handeye.model import scratch, simulate
from handeye.model.dataset import load
from handeye.studies.study import claim, figure, write_summary, write_table

GRIDS = {
    "sphere_center": [0.01, 0.02, 0.04, 0.08, 0.16],  # mm, along a fixed unit direction
    "sensor_scale": [1e-4, 2e-4, 4e-4, 8e-4, 1.6e-3],
    "sphere_radius": [0.005, 0.01, 0.02, 0.04, 0.08],  # mm
}
DIRECTION = np.array([0.6, -0.48, 0.64])


def _hidden(name, size):
    if name == "sphere_center":
        return {name: (size * DIRECTION).tolist()}
    return {name: size}


def run(out, quick=False):
    seeds = 8 if quick else 40
    rows, summary = [], {"datasets_per_size": seeds, "effects": {}}
    with scratch.temporary_folder() as tmp:
        for name, grid in GRIDS.items():
            rates = []
            for size in grid:
                hits = 0
                for seed in range(seeds):
                    sim = simulate.simulate(simulate.Setup(), seed=2000 + seed, effects=_hidden(name, size))
                    res = handeye.diagnose(load(simulate.write(sim, f"{tmp}/{name}-{size}-{seed}")))
                    hits += [e.name for e in res.effects] == [name]
                rates.append(hits / seeds)
                rows.append((name, size, hits / seeds))
            detect = [s for s, r in zip(grid, rates) if r >= 0.9]
            summary["effects"][name] = {"sizes": grid, "rates": rates, "smallest_90": detect[0] if detect else None}
    write_table(out, "power", ["effect", "size", "detection_rate"], rows)
    plt = figure()
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.5))
    units = {"sphere_center": "offset (mm)", "sensor_scale": "scale error s", "sphere_radius": "dr (mm)"}
    for ax, (name, s) in zip(axes, summary["effects"].items()):
        ax.semilogx(s["sizes"], s["rates"], "o-")
        ax.axhline(0.9, color="grey", lw=0.8, ls="--")
        ax.set(xlabel=units[name], ylabel="detection rate", ylim=(-0.05, 1.05), title=name)
    fig.suptitle(f"power of handeye diagnose ({seeds} datasets per size, 36 thesis poses)")
    fig.tight_layout()
    fig.savefig(out / "power.png", dpi=120)
    plt.close(fig)
    write_summary(out, summary)
    for name, s in summary["effects"].items():
        claim(s["rates"][-1] >= 0.9, f"{name} at {s['sizes'][-1]} is detected in >= 90 % of datasets")
        claim(all(b >= a - 2 * np.sqrt(0.25 / seeds) for a, b in zip(s["rates"], s["rates"][1:])),
              f"{name}: detection does not fall with size")
    return summary
