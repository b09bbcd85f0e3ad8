"""Study: every cell is one chain -- a sensor on the flange or fixed in the cell, a sphere fixed,
on the flange or on a 2-axis positioner.

Story. For each of the three observable cells (:mod:`handeye.model.chain.mounts`) ``handeye simulate``
makes datasets with known truth (the sphere centre left to be estimated; for the positioner, set-up
axes 1 mm and 0.2 deg off the true ones, calibrated with ``--unknowns sensor+sphere+positioner``),
and ``handeye calibrate`` estimates them. Over the replicates we compare the errors with the 1-sd
each calibration reports: the ratio of the observed RMS error to the RMS predicted sd, per part,
and how often the truth lies within 3 sd. A figure per cell shows what is calibrated: the robot's
base, the flange and sensor frames of a few poses, the laser planes, the sphere where it was
measured, and the positioner's axes.

Claims: every calibration exits 0; the observed/predicted ratios lie in 0.8-1.25 (0.6-1.6 for the
quick run's few replicates); at least 95 % of the components lie within 3 sd (85 % quick).
"""
from __future__ import annotations

import numpy as np

import handeye
from handeye.app.present import figure_style
from handeye.model.chain.mounts import table2base
from handeye.model.chain.pose import transform_from_pose
from handeye.model.common import scratch
from handeye.studies.study import claim, figure, pose_error, save, write_summary, write_table

#: (label, sensor mount, sphere mount, unknowns)
CELLS = (
    ("eye-in-hand", "flange", "world", "sensor+sphere"),
    ("eye-to-hand", "world", "flange", "sensor+sphere"),
    ("positioner", "flange", "positioner", "sensor+sphere+positioner"),
)


def _errors(res, truth):
    """Errors and reported sd of one calibration: (parts -> (errors, sd)) in mm and degrees."""
    est, sd = res.sensor2flange, res.std
    dt, dr = pose_error(est, truth["sensor"])
    out = {"sensor t (mm)": (dt, sd.sensor_translation_mm), "sensor r (deg)": (dr, sd.sensor_rotation_deg),
           "sphere (mm)": (res.sphere_centre - truth["centre"], sd.sphere_center_mm)}
    if res.positioner is not None and res.positioner.calibrated:
        dist, pred = [], []
        for j, (axis, true) in enumerate(zip(res.positioner.axes, truth["axes"])):
            v = axis.point - true.point
            d = true.direction
            off = v - (v @ d) * d  # the estimated point's offset from the true line (any point of it is right)
            dist += list(off[np.argsort(np.abs(d))[:2]])
            pred += list(res.positioner.point_sd[j][np.argsort(np.abs(d))[:2]])
        out["axis points (mm)"] = (np.array(dist), np.array(pred))
    return out


def _one(folder, seed, sensor, sphere, unknowns):
    made = handeye.simulate(folder, seed=seed, sensor_mount=sensor, sphere_mount=sphere, no_start=seed % 2 == 0)
    data = made.dataset
    res = handeye.calibrate(data, unknowns=unknowns, no_loo=True)
    truth = {"sensor": transform_from_pose(data.truth["sensor_pose"]), "centre": data.truth["sphere_center"],
             "axes": data.truth.get("axes", ())}
    return data, res, truth


def run(out, quick=False):
    reps = 6 if quick else 50
    low, high = (0.6, 1.6) if quick else (0.8, 1.25)
    cover = 0.85 if quick else 0.95  # of 3 x 6 components in the quick run one outside 3 sd happens
    rows, summary = [], {"replicates": reps}
    with scratch.temporary_folder() as tmp:
        for label, sensor, sphere, unknowns in CELLS:
            parts, exits = {}, 0
            for seed in range(reps):
                data, res, truth = _one(f"{tmp}/{label}-{seed}", seed, sensor, sphere, unknowns)
                exits += 0 if res.converged else 1
                for name, (err, sd) in _errors(res, truth).items():
                    parts.setdefault(name, []).append((err, sd))
                if seed == 0:
                    draw(out, label, data, res)
            claim(exits == 0, f"every {label} calibration exits 0 ({exits} of {reps} did not)")
            summary[label] = {}
            for name, pairs in parts.items():
                err, sd = np.array([p[0] for p in pairs]), np.array([p[1] for p in pairs])
                ratio = float(np.sqrt(np.mean(err**2)) / np.sqrt(np.mean(sd**2)))
                inside = float(np.mean(np.abs(err) <= 3 * sd))
                rows.append((label, name, float(np.sqrt(np.mean(err**2))), float(np.sqrt(np.mean(sd**2))), ratio, inside))
                summary[label][name] = {"ratio": ratio, "within_3sd": inside}
                claim(low <= ratio <= high, f"{label} {name}: observed/predicted sd {ratio:.3f} in [{low}, {high}]")
                claim(inside >= cover, f"{label} {name}: {inside:.1%} of the components within 3 sd (>= {cover:.0%})")
    write_table(out, "mounts", ["cell", "part", "observed_rms", "predicted_sd", "ratio", "within_3sd"], rows)
    write_summary(out, summary)
    return summary


def _frame(ax, t, size, alpha=1.0):
    for k, colour in enumerate((figure_style.VERMILLION, figure_style.GREEN, figure_style.BLUE)):
        ax.plot(*np.c_[t[:3, 3], t[:3, 3] + size * t[:3, k]], color=colour, alpha=alpha, lw=1.2)


def _fan(ax, sensor2base, z=(190.0, 290.0), half=50.0):
    """The laser plane's measuring window (sensor y = 0) as a translucent quadrilateral."""
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    corners = np.array([[-half, 0, z[0], 1], [half, 0, z[0], 1], [half, 0, z[1], 1], [-half, 0, z[1], 1]])
    pts = (sensor2base @ corners.T).T[:, :3]
    ax.add_collection3d(Poly3DCollection([pts], alpha=0.15, color=figure_style.ORANGE))


def _sphere_centres(data, res):
    """The sphere centre in the robot base at every pose (the calibrated chain's)."""
    f2b = data.flange2base()
    c = np.append(res.sphere_centre, 1.0)
    if data.mounts.sphere == "flange":
        return (f2b @ c)[:, :3]
    if data.mounts.sphere == "positioner":
        return (table2base(res.positioner.axes, data.axis_angles) @ c)[:, :3]
    return np.broadcast_to(res.sphere_centre, (len(data), 3))


def _sphere(ax, centre, radius):
    u, v = np.meshgrid(np.linspace(0, 2 * np.pi, 24), np.linspace(0, np.pi, 12))
    ax.plot_wireframe(centre[0] + radius * np.cos(u) * np.sin(v), centre[1] + radius * np.sin(u) * np.sin(v),
                      centre[2] + radius * np.cos(v), color="0.4", lw=0.4)


def draw(out, label, data, res, n_show=8):
    """The cell in 3-D (robot base, mm), around where it measures: flange and sensor frames and laser
    windows of ``n_show`` poses, the sphere at each pose (one drawn), the positioner's axes, and the
    direction to the robot's base."""
    fig = figure().figure(figsize=(7.5, 6.5))
    ax = fig.add_subplot(projection="3d")
    f2b = data.flange2base()
    show = np.linspace(0, len(data) - 1, min(n_show, len(data))).round().astype(int)
    x = res.sensor2flange
    sensors = [f2b[i] @ x if data.mounts.sensor == "flange" else x for i in show]
    for i, s2b in zip(show, sensors):
        _frame(ax, f2b[i], 60.0, alpha=0.7)
        _frame(ax, s2b, 50.0)
        _fan(ax, s2b)
    centres = _sphere_centres(data, res)
    _sphere(ax, centres[show[0]], data.sphere_diameter / 2)
    ax.scatter(*centres.T, color="k", s=10, label="sphere centre at each pose")
    ax.scatter(*f2b[:, :3, 3].T, color=figure_style.PURPLE, s=8, label="flange origins")
    if res.positioner is not None:
        for axis in res.positioner.axes:
            ax.plot(*(axis.point + np.outer([-250.0, 250.0], axis.direction)).T, color=figure_style.BLACK, lw=2.5)
            ax.text(*(axis.point + 270 * axis.direction), f"axis {axis.name}", fontsize=9)
    every = np.vstack([f2b[:, :3, 3], centres, [s[:3, 3] for s in sensors]])
    mid, span = every.mean(axis=0), (every.max(axis=0) - every.min(axis=0)).max() / 2 + 60
    towards = -mid / np.linalg.norm(mid)  # the robot's base, as an arrow from the middle
    ax.quiver(*mid, *(0.8 * span * towards), color="0.3", lw=1.5, arrow_length_ratio=0.15)
    ax.text(*(mid + 0.85 * span * towards), f"robot base ({np.linalg.norm(mid):.0f} mm)", fontsize=9)
    ax.set(xlim=(mid[0] - span, mid[0] + span), ylim=(mid[1] - span, mid[1] + span),
           zlim=(mid[2] - span, mid[2] + span), xlabel="x (mm)", ylabel="y (mm)", zlabel="z (mm)")
    ax.set_title(f"{label}: {data.mounts.describe()}\n(frames: x vermillion, y green, z blue; laser window orange; "
                 "robot base frame)", fontsize=10)
    ax.legend(loc="upper left")
    save(fig, out / f"cell_{label}.png")
