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
from handeye.app.present import figure_style
from handeye.model.common import scratch
from handeye.model.datasets.dataset import load
from handeye.model.simulation import simulate
from handeye.studies.study import claim, figure, save, write_summary, write_table

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
    """The study (module docstring); ``quick``: 8 datasets per size at every other size of each grid (its
    smallest, middle and largest: the claims' ends), 40 at every size otherwise."""
    seeds = 8 if quick else 40
    rows, summary = [], {"datasets_per_size": seeds, "effects": {}}
    with scratch.temporary_folder() as tmp:
        for name, grid in GRIDS.items():
            grid = grid[::2] if quick else grid
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
    _draw(out, summary, seeds)
    write_summary(out, summary)
    for name, s in summary["effects"].items():
        claim(s["rates"][-1] >= 0.9, f"{name} at {s['sizes'][-1]} is detected in >= 90 % of datasets")
        claim(all(b >= a - 2 * np.sqrt(0.25 / seeds) for a, b in zip(s["rates"], s["rates"][1:])),
              f"{name}: detection does not fall with size")
    return summary


#: axis label and tick scale per effect (the sensor scale in units of 1e-4, so that ticks stay short)
UNITS = {"sphere_center": ("offset (mm)", 1.0), "sensor_scale": ("scale error s (x 1e-4)", 1e4),
         "sphere_radius": ("radius error dr (mm)", 1.0)}


def _draw(out, summary, seeds):
    """Detection rate against size per effect, with Wilson 95 % intervals (n = seeds per size)."""
    effects = summary["effects"]
    fig, axes = figure().subplots(1, len(effects), figsize=(4.4 * len(effects), 4.0), sharey=True, squeeze=False)
    for ax, (name, s) in zip(axes[0], effects.items()):
        label, scale = UNITS[name]
        sizes, rates = np.asarray(s["sizes"]) * scale, np.asarray(s["rates"])
        low, high = figure_style.binomial_interval(np.round(rates * seeds), seeds)
        ax.errorbar(sizes, rates, yerr=[rates - low, high - rates], fmt="o-", capsize=3)
        ax.axhline(0.9, color="0.5", lw=0.8, ls="--")
        ax.set_xscale("log")
        ax.set_xticks(sizes, [f"{v:g}" for v in sizes])
        ax.minorticks_off()
        ax.set(xlabel=label, ylim=(-0.04, 1.06), title=name)
    axes[0, 0].set_ylabel("detection rate")
    fig.suptitle(f"power of handeye diagnose ({seeds} datasets per size, 36 thesis poses; "
                 "bars: Wilson 95 % intervals; dashed: 90 %)")
    save(fig, out / "power.png")
