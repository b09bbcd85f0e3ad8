"""An independent generator of profile-only cells whose laser-line sensor has a depth linearity error
(numpy and the standard library only; no code of ``handeye``).

Written from the README's "Dataset format" section (``setup.toml``, ``measurements.csv``, profile CSVs
with header ``x,z`` in the sensor frame, the laser plane y = 0, ``[profile] side`` the sign of the
centre's sensor-y, ``[sphere] diameter`` / ``center``, ``[noise]``, KUKA poses ``x,y,z,a,b,c`` with
``R = Rz(A) Ry(B) Rx(C)``, ``[truth] sensor_pose`` "simulated data only") and from its "Any cell"
section (``[sensor] mount = "world"``, ``[sphere] mount = "flange"``: the centre in the flange frame,
the pose calibrated ``sensor2base``).  Rotation helpers and the random sensor mounts are imported from
``tests/indep_mounts.py`` (itself handeye-free).

The sensor (everything mm):

* Sensor frame: laser plane y = 0, x along the line, z the measuring direction.  Measuring range
  ``z in [z_lo, z_hi]`` (stand-off 60-250 mm, range 40-150 mm, at least 1.6 R + 10 mm); field of view
  a fan, ``|x| <= x_half(z) = x0 * z / z_lo`` (x0 = 0.7-1.3 R + 5 mm at the stand-off).
* The laser leaves the origin; the camera sits off the laser plane at ``(0, camera_y, 0)``,
  ``camera_y = -side * (25..80 mm)`` (the sphere's centre lies on the far side of the plane from the
  camera: that is what ``[profile] side`` records).  A point of the cut is seen where the sphere's
  outward normal makes less than ``max_incidence`` (65-80 deg) with the ray to the laser origin
  **and** less than 85 deg with the ray to the camera.
* The sensor samples the line on a grid of x (pixel columns): spacing 0.05-0.2 mm, each column
  jittered by 10 % of it; a column gives the front point of the cut circle,
  ``z = zs - sqrt(r^2 - (x - xs)^2)``.
* Reported: ``x + n_x``, ``z + b(z) + l(x) + n_z`` with ``b`` the depth bend (a function of the true
  depth over the measuring range), ``l`` the lateral bend (class ``lateral``), ``n`` point noise of sd
  0.005-0.03 mm, either isotropic (``n_x`` and ``n_z``) or along the sensor's z only (``n_x = 0``).
  Points whose reported (x, z) fall outside the measuring range / fan are dropped (clipping).
* The robot's repeatability moves each pose's true centre by N(0, robot_sd^2) per component,
  robot_sd 0-0.015 mm.

Bend classes (:data:`CLASSES`; ``u = (z - z_lo) / (z_hi - z_lo)`` in [0, 1] over the measuring range;
every shape scaled to a peak-to-peak ``A`` over [0, 1], A drawn 0-0.3 mm; class ``clean`` A = 0):

``quadratic``  ``(u - u0)^2``, u0 in [-0.3, 1.3];
``cubic``      ``(u - a)(u - b)(u - c)``, roots drawn in [-0.2, 1.2];
``sine``       ``sin(2 pi u / P + phi)``, period P = 0.5-2.0 ranges, any phase;
``piecewise``  two parabolas joined with equal value and slope at u0 in [0.25, 0.75] (curvatures of
               either sign, ratio 0.2-5), or (half the seeds) a smooth step ``tanh((u - u0) / w)``,
               w = 0.12-0.35;
``lateral``    no depth bend; ``l(x) = A * shape(x / x0)``, ``shape = s^2 + k s^3`` (k in [-1, 1]),
               the line bowed across its length (scaled to peak-to-peak A over |x| <= x0).

Pose sets (``depth`` option): ``varied`` -- the sphere's nearest point drawn over the whole measuring
range; ``one`` -- every pose sees the sphere's nearest point within +-1.5 mm of one depth (drawn in the
range).  Cut distance |ys| 0.1-0.85 R, ``ys`` of the sign ``side`` (drawn per cell).

Mounts: ``eye_in_hand`` (sensor on the flange, sphere fixed) and ``eye_to_hand`` (sensor fixed in the
cell, sphere on a stick on the flange).  The centre is written (``[sphere] center``) in half the cells;
otherwise calibrate with ``unknowns="sensor+sphere"``.

Public: :func:`make` (draw a cell, write its folder, return the truth), :func:`bend_function`,
:func:`check` (the chain and the profiles at the truth, this module's own circle fit).
"""
from __future__ import annotations

import json
import math
import pathlib

import indep_mounts as im
import numpy as np

CLASSES = ("clean", "quadratic", "cubic", "sine", "piecewise", "lateral")
MOUNTS = ("eye_in_hand", "eye_to_hand")
DEPTHS = ("varied", "one")


# ----------------------------------------------------------------------------- the bend
def _scaled(f, lo=0.0, hi=1.0):
    """``f`` shifted to mean 0 and scaled to peak-to-peak 1 over [lo, hi] (a callable of an array)."""
    grid = np.linspace(lo, hi, 2001)
    v = f(grid)
    span, mean = float(v.max() - v.min()), float(v.mean())
    if span < 1e-12:
        return lambda s: np.zeros_like(np.asarray(s, float))
    return lambda s: (f(np.asarray(s, float)) - mean) / span


def bend_function(rng, kind):
    """``(shape, description)``: shape a callable of ``u`` (depth classes) or ``s = x / x0`` (lateral),
    peak-to-peak 1 over [0, 1] (depth) or [-1, 1] (lateral)."""
    if kind == "quadratic":
        u0 = rng.uniform(-0.3, 1.3)
        return _scaled(lambda u: (u - u0) ** 2), f"(u-{u0:.2f})^2"
    if kind == "cubic":
        r = np.sort(rng.uniform(-0.2, 1.2, 3))
        return _scaled(lambda u: (u - r[0]) * (u - r[1]) * (u - r[2])), "cubic roots " + ",".join(f"{x:.2f}" for x in r)
    if kind == "sine":
        period, phase = rng.uniform(0.5, 2.0), rng.uniform(0, 2 * math.pi)
        return _scaled(lambda u: np.sin(2 * math.pi * u / period + phase)), f"sin P={period:.2f} phi={phase:.2f}"
    if kind == "piecewise":
        u0 = rng.uniform(0.25, 0.75)
        if rng.uniform() < 0.5:
            k1 = rng.choice([-1, 1]) * 1.0
            k2 = rng.choice([-1, 1]) * math.exp(rng.uniform(math.log(0.2), math.log(5.0)))
            g = rng.uniform(-1, 1)  # the common slope at u0, in units of |k1|

            def f(u):
                d = u - u0
                return g * d + np.where(d < 0, k1, k2) * d * d
            return _scaled(f), f"two parabolas at u0={u0:.2f} k={k1:.0f},{k2:.2f} g={g:.2f}"
        w = rng.uniform(0.12, 0.35)
        return _scaled(lambda u: np.tanh((u - u0) / w)), f"tanh step u0={u0:.2f} w={w:.2f}"
    if kind == "lateral":
        k = rng.uniform(-1, 1)
        return _scaled(lambda s: s ** 2 + k * s ** 3, -1.0, 1.0), f"lateral s^2{k:+.2f}s^3"
    if kind == "clean":
        return (lambda u: np.zeros_like(np.asarray(u, float))), "none"
    raise ValueError(f"unknown class {kind!r}; one of {CLASSES}")


# ----------------------------------------------------------------------------- the sensor
def _sensor(rng, radius, side):
    """The sensor's geometry: measuring range, fan, camera baseline, sampling, noise."""
    z_lo = rng.uniform(60.0, 250.0)
    width = max(rng.uniform(40.0, 150.0), 1.6 * radius + 10.0)
    return dict(z_lo=z_lo, z_hi=z_lo + width, x0=rng.uniform(0.7, 1.3) * radius + 5.0,
                camera_y=-side * rng.uniform(25.0, 80.0), max_incidence=rng.uniform(65.0, 80.0),
                spacing=rng.uniform(0.05, 0.2), point_sd=rng.uniform(0.005, 0.03),
                noise_along="z" if rng.uniform() < 0.5 else "isotropic")


def _x_half(sensor, z):
    return sensor["x0"] * np.asarray(z, float) / sensor["z_lo"]


def _in_range(sensor, x, z):
    return (z >= sensor["z_lo"]) & (z <= sensor["z_hi"]) & (np.abs(x) <= _x_half(sensor, z))


def _visible(sensor, centre, radius, x, z):
    """Which front points (x, 0, z) of the sphere (centre, radius) the sensor sees: the sphere's outward
    normal there within ``max_incidence`` of the ray back to the laser's origin and within 85 deg of the
    ray to the camera at ``(0, camera_y, 0)``."""
    xs, ys, zs = centre
    nx, ny, nz = (x - xs) / radius, -ys / radius, (z - zs) / radius
    cos_laser = -(nx * x + nz * z) / np.hypot(x, z)
    cy = sensor["camera_y"]
    cos_cam = (-nx * x + ny * cy - nz * z) / np.sqrt(x * x + cy * cy + z * z)
    return (cos_laser > math.cos(math.radians(sensor["max_incidence"]))) & (cos_cam > math.cos(math.radians(85.0)))


def _columns(rng, sensor, lo, hi):
    """The pixel columns' x over [lo, hi] (sorted, jittered grid)."""
    h = sensor["spacing"]
    grid = np.arange(math.floor(lo / h), math.ceil(hi / h) + 1) * h
    return np.sort(grid + rng.uniform(-0.1 * h, 0.1 * h, grid.size))


def profile(rng, sensor, centre, radius, depth_shape, lateral_shape, amplitude):
    """One profile (K, 2: reported x, z) of the sphere whose true centre in the sensor frame is ``centre``.

    Returns ``(points, true_points, arc_deg)`` or None when the plane misses the sphere.
    """
    xs, ys, zs = centre
    if abs(ys) >= radius:
        return None
    r = math.sqrt(radius**2 - ys**2)
    x = _columns(rng, sensor, xs - r, xs + r)
    x = x[np.abs(x - xs) < r]
    z = zs - np.sqrt(r**2 - (x - xs) ** 2)
    seen = _visible(sensor, centre, radius, x, z)
    x, z = x[seen], z[seen]
    if x.size < 2:
        return None
    arc = math.degrees(math.asin(min(1.0, (x.max() - xs) / r)) - math.asin(max(-1.0, (x.min() - xs) / r)))
    u = (z - sensor["z_lo"]) / (sensor["z_hi"] - sensor["z_lo"])
    zr = z + amplitude * depth_shape(u) + amplitude * lateral_shape(x / sensor["x0"])
    sd = sensor["point_sd"]
    xr = x + (rng.normal(scale=sd, size=x.size) if sensor["noise_along"] == "isotropic" else 0.0)
    zr = zr + rng.normal(scale=sd, size=x.size)
    keep = _in_range(sensor, xr, zr)
    return np.column_stack([xr[keep], zr[keep]]), np.column_stack([x[keep], z[keep]]), arc


def _centre_in_sensor(rng, sensor, radius, side, depth, z_one):
    """A true centre (sensor frame) whose profile lies in the measuring range."""
    ys = side * rng.uniform(0.1, 0.85) * radius
    r = math.sqrt(radius**2 - ys**2)
    if depth == "one":
        front = z_one + rng.uniform(-1.5, 1.5)
    else:
        front = rng.uniform(sensor["z_lo"] + 0.5, sensor["z_hi"] - 0.35 * r)
    zs = front + r
    half = float(_x_half(sensor, front)) - 0.6 * r
    xs = rng.uniform(-max(half, 0.0), max(half, 0.0))
    return np.array([xs, ys, zs])


# ----------------------------------------------------------------------------- the robot
def _eye_in_hand_pose(rng, X, centre_base, p):
    """A flange pose (4x4) whose sensor (X on the flange) sees the base point ``centre_base`` at ``p``."""
    for _ in range(200):
        Rs = im._look(im._tilted(rng, np.array([0.0, 0.0, -1.0]), 50.0), rng.uniform(-180.0, 180.0))
        F = im.transform(Rs, centre_base - Rs @ p) @ im.inverse(X)
        if im._reachable(F):
            return F
    return None


def _eye_to_hand_pose(rng, S, c_f, p):
    """A flange pose (4x4) carrying the sphere (``c_f`` in the flange) to ``S p`` in the base."""
    c_base = S[:3, :3] @ p + S[:3, 3]
    for _ in range(200):
        u = im._tilted(rng, -S[:3, 2], 50.0)
        R = im.rodrigues(u, rng.uniform(-180.0, 180.0)) @ im._align(im.unit(c_f), u)
        F = im.transform(R, c_base - R @ c_f)
        if im._reachable(F):
            return F
    return None


# ----------------------------------------------------------------------------- writing
def _vec(v, digits=9):
    return "[" + ", ".join(f"{float(x):.{digits}f}" for x in v) + "]"


def make(folder, seed, kind, *, mount=None, depth=None, n=None, centre_known=None, amplitude=None):
    """Draw one cell and write it as a dataset folder (profile-only rows).

    Parameters
    ----------
    folder : path
    seed : int
    kind : one of :data:`CLASSES`
    mount, depth, n, centre_known, amplitude : drawn when None (mount eye_to_hand in a third of the
        cells; depth ``varied`` for even seeds, ``one`` for odd; n 12-40; the centre given in half;
        amplitude 0-0.3 mm, 0 for ``clean``).

    Returns
    -------
    dict
        ``truth`` (4x4: sensor2flange, or sensor2base for eye_to_hand), ``centre`` (its mount's frame),
        ``mount``, ``depth``, ``n`` (rows written), ``centre_known``, ``amplitude`` (mm p-p over the
        measuring range, or over |x| <= x0 for lateral), ``shape`` (text), ``bend_on_profiles_mm`` (the
        true bend's peak-to-peak over the profiles' true depths, depth classes), ``sensor`` (dict),
        ``diameter``, ``side``, ``robot_sd``, ``arcs_deg`` (per row).
    """
    if kind not in CLASSES:
        raise ValueError(f"unknown class {kind!r}; one of {CLASSES}")
    rng = np.random.default_rng([seed, CLASSES.index(kind), 7919])
    mount = mount or ("eye_to_hand" if rng.uniform() < 1 / 3 else "eye_in_hand")
    depth = depth or DEPTHS[seed % 2]
    n = int(n or rng.integers(12, 41))
    centre_known = bool(rng.uniform() < 0.5) if centre_known is None else bool(centre_known)
    if amplitude is None:
        amplitude = 0.0 if kind == "clean" else float(rng.uniform(0.0, 0.3))
    shape, shape_text = bend_function(rng, kind)
    depth_shape = (lambda u: np.zeros_like(u)) if kind in ("clean", "lateral") else shape
    lateral_shape = shape if kind == "lateral" else (lambda s: np.zeros_like(s))
    diameter = round(float(rng.uniform(25.0, 80.0)), 3)
    radius = diameter / 2
    side = int(rng.choice([-1, 1]))
    sensor = _sensor(rng, radius, side)
    robot_sd = float(rng.uniform(0.0, 0.015))
    z_one = rng.uniform(sensor["z_lo"] + 1.5, sensor["z_hi"] - 0.35 * radius - 1.5)

    if mount == "eye_in_hand":
        X = im._sensor_on_flange(rng)
        az, rho = math.radians(rng.uniform(-70.0, 70.0)), rng.uniform(800.0, 1250.0)
        centre = np.array([rho * math.cos(az), rho * math.sin(az), rng.uniform(-150.0, 400.0)])
    else:
        X = im._fixed_sensor(rng)
        centre = im.unit([rng.uniform(-0.4, 0.4), rng.uniform(-0.4, 0.4), 1.0]) * rng.uniform(100.0, 250.0)

    flanges, profiles, trues, arcs, depths_seen = [], [], [], [], []
    tries = 0
    while len(flanges) < n:
        tries += 1
        if tries > 50 * n:
            raise RuntimeError(f"seed {seed} {kind}: could not draw {n} poses")
        p = _centre_in_sensor(rng, sensor, radius, side, depth, z_one)
        F = _eye_in_hand_pose(rng, X, centre, p) if mount == "eye_in_hand" else _eye_to_hand_pose(rng, X, centre, p)
        if F is None:
            continue
        p_true = p + rng.normal(scale=robot_sd, size=3)  # the robot did not quite reach F
        got = profile(rng, sensor, p_true, radius, depth_shape, lateral_shape, amplitude)
        if got is None or len(got[0]) < 40 or got[2] < 40.0:
            continue
        pts, true_pts, arc = got
        flanges.append(F)
        profiles.append(pts)
        trues.append(p_true)
        arcs.append(arc)
        depths_seen.append((float(true_pts[:, 1].min()), float(true_pts[:, 1].max())))

    folder = pathlib.Path(folder)
    (folder / "profiles").mkdir(parents=True, exist_ok=True)
    rows = ["id,x,y,z,a,b,c,profile"]
    for i, (F, pts) in enumerate(zip(flanges, profiles)):
        name = f"profiles/p{i + 1:03d}.csv"
        (folder / name).write_text("x,z\n" + "\n".join(f"{a:.6f},{b:.6f}" for a, b in pts) + "\n")
        rows.append(",".join([f"m{i + 1:03d}", *(f"{v:.9f}" for v in im.pose_values(F)), name]))
    (folder / "measurements.csv").write_text("\n".join(rows) + "\n")

    lines = [f"# tests/indep_linearity.py: class {kind}, seed {seed}, {mount}, depths {depth}", "[robot]",
             'convention = "kuka"', "[sensor]"]
    if mount == "eye_to_hand":
        lines.append('mount = "world"')
    lines += ["[sphere]", f"diameter = {diameter}"]
    if mount == "eye_to_hand":
        lines.append('mount = "flange"')
    if centre_known:
        lines.append(f"center = {_vec(centre)}")
    lines += ["[profile]", f"side = {side}"]
    if seed % 4 >= 2:  # a stated repeatability (a bound) in half the cells
        lines += ["[noise]", f"robot_mm = {max(0.01, round(1.5 * robot_sd, 3))}"]
    lines += ["[truth]", f"sensor_pose = {_vec(im.pose_values(X))}"]
    (folder / "setup.toml").write_text("\n".join(lines) + "\n")

    lo = min(d[0] for d in depths_seen)
    hi = max(d[1] for d in depths_seen)
    if kind in ("clean", "lateral"):
        on_profiles = 0.0
    else:
        grid = (np.linspace(lo, hi, 501) - sensor["z_lo"]) / (sensor["z_hi"] - sensor["z_lo"])
        v = amplitude * depth_shape(grid)
        on_profiles = float(v.max() - v.min())
    info = dict(truth=X, centre=centre, mount=mount, depth=depth, n=n, centre_known=centre_known,
                amplitude=amplitude, shape=shape_text, bend_on_profiles_mm=on_profiles, depths_seen=(lo, hi),
                sensor=sensor, diameter=diameter, side=side, robot_sd=robot_sd, arcs_deg=arcs, kind=kind, seed=seed,
                flanges=np.array(flanges), true_centres=np.array(trues))
    (folder.parent / f"{folder.name}.truth.json").write_text(json.dumps(
        {k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in info.items() if k not in ("flanges", "true_centres")},
        default=float, indent=1))
    return info


# ----------------------------------------------------------------------------- a self-check
def _circle_fit(x, z):
    """Algebraic (Kasa) then Gauss-Newton geometric circle fit: (xc, zc, r)."""
    A = np.column_stack([x, z, np.ones_like(x)])
    a, b, c = np.linalg.lstsq(A, x * x + z * z, rcond=None)[0]
    p = np.array([a / 2, b / 2, math.sqrt(c + a * a / 4 + b * b / 4)])
    for _ in range(20):
        dx, dz = x - p[0], z - p[1]
        d = np.hypot(dx, dz)
        J = np.column_stack([-dx / d, -dz / d, -np.ones_like(d)])
        p = p - np.linalg.lstsq(J, d - p[2], rcond=None)[0]
    return p


def check(info, folder):
    """Chain residual at the truth (mm, max over rows) of the centres rebuilt from the written profiles with
    this module's own circle fit, and the same from the true (noise-free, unbent) centres."""
    folder = pathlib.Path(folder)
    radius = info["diameter"] / 2
    X, c = info["truth"], info["centre"]
    worst_true, worst_fit = 0.0, 0.0
    for i, F in enumerate(info["flanges"]):
        pts = np.loadtxt(folder / f"profiles/p{i + 1:03d}.csv", delimiter=",", skiprows=1)
        xc, zc, r = _circle_fit(pts[:, 0], pts[:, 1])
        y = info["side"] * math.sqrt(max(radius**2 - r**2, 0.0))
        for p, which in ((info["true_centres"][i], "true"), (np.array([xc, y, zc]), "fit")):
            if info["mount"] == "eye_in_hand":
                e = np.linalg.norm((F @ X @ np.append(p, 1))[:3] - c)
            else:
                e = np.linalg.norm((X @ np.append(p, 1))[:3] - (F @ np.append(c, 1))[:3])
            if which == "true":
                worst_true = max(worst_true, e)
            else:
                worst_fit = max(worst_fit, e)
    return worst_true, worst_fit
