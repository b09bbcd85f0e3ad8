#!/usr/bin/env python
"""Independent dataset generator for handeye (numpy only, written from the README's format by a helper who read
no source: its own rotations, UR kinematics, circle fit and pose designs -- caps and grids, tours; 2026-12-08).

python tests/indep_fresh.py --class CLASS --seed N --out DIR [--noise-free] [--check]

Writes DIR/setup.toml, DIR/measurements.csv [, DIR/profiles/*.csv] and the truth to DIR.truth.json
(beside the folder, so the tool never sees it).
"""
import argparse
import json
import os
import shutil
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import indep_fresh_geom as G  # noqa: E402

CLASSES = ["clean", "scale", "diameter", "taught", "gross", "joint_offsets", "link_lengths",
           "pairing", "nonarc", "slip"]


def cap_dir(rng, tilt_max_deg, axis=(0, 0, -1)):
    """unit vector within tilt_max of axis."""
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    ct = rng.uniform(np.cos(tilt_max_deg * G.D2R), 1.0)
    st = np.sqrt(1 - ct * ct)
    ph = rng.uniform(0, 2 * np.pi)
    # basis perpendicular to axis
    a = np.array([1.0, 0, 0]) if abs(axis[0]) < 0.9 else np.array([0, 1.0, 0])
    u = np.cross(axis, a)
    u /= np.linalg.norm(u)
    v = np.cross(axis, u)
    return ct * axis + st * (np.cos(ph) * u + np.sin(ph) * v)


def frame_looking(d, roll):
    """rotation whose z column is d, x column turned by roll about d."""
    d = d / np.linalg.norm(d)
    a = np.array([1.0, 0, 0]) if abs(d[0]) < 0.9 else np.array([0, 1.0, 0])
    x = a - d * (a @ d)
    x /= np.linalg.norm(x)
    y = np.cross(d, x)
    R0 = np.column_stack([x, y, d])
    return R0 @ G.rz(roll)


def revolute(point, direction, theta_deg):
    w = np.asarray(direction, float)
    w /= np.linalg.norm(w)
    R = G.expso3(w * theta_deg * G.D2R)
    q = np.asarray(point, float)
    return G.T_of(R, q - R @ q)


class Cell:
    pass


def draw_params(rng, cls):
    p = Cell()
    p.cls = cls
    robot_cls = cls in ("joint_offsets", "link_lengths")
    p.robot = None
    if robot_cls or (cls in ("clean", "gross", "slip", "pairing") and rng.uniform() < 0.2):
        p.robot = str(rng.choice(["ur5e", "ur10e"]))
    p.mount = "eih" if p.robot else str(rng.choice(["eih", "eth", "pos"], p=[0.45, 0.3, 0.25]))
    p.conv = str(rng.choice(["kuka", "abb", "ur", "fanuc"]))
    if cls in ("diameter", "nonarc"):
        p.data = "profiles"
    else:
        p.data = str(rng.choice(["centres", "profiles"]))
    p.centre_known = bool(rng.uniform() < 0.5)
    if cls == "taught":
        p.centre_known = True
    p.n = int(rng.integers(8, 51))
    if cls == "pairing":
        p.n = int(rng.integers(15, 51))
    p.noise = float(rng.uniform(0.01, 0.15))
    p.diameter = float(rng.uniform(20, 100))
    p.design = str(rng.choice(["cap", "grid"]))
    p.side = int(rng.choice([-1, 1]))
    p.state_noise = bool(rng.uniform() < 0.6)
    p.robot_sd = float(rng.uniform(0.0, 0.02)) if p.data == "profiles" else 0.0
    p.pitch = float(rng.uniform(0.05, 0.2))
    p.inc_max = float(rng.uniform(55, 80))
    p.tilt_max = float(rng.uniform(20, 50))
    p.z0 = float(rng.uniform(60, 130) if p.robot else rng.uniform(100, 250))
    p.L = max(100.0, 2 * p.diameter + 30)
    p.W = float(max(p.diameter + 20, rng.uniform(60, 150)))
    p.tour = cls == "pairing" or rng.uniform() < 0.3
    return p


def sensor_target(rng, p):
    R = p.diameter / 2
    xs = rng.uniform(-1, 1) * max(0.0, (p.W / 2 - R - 2)) * 0.6
    zs = rng.uniform(p.z0 + R + 2, p.z0 + p.L - 5)
    ys = p.side * rng.uniform(0.2, 0.8) * R
    return np.array([xs, ys, zs])


def draw_truth(rng, p):
    t = Cell()
    if p.robot:
        reach = 1.0 if p.robot == "ur5e" else 1.5
        ang = rng.uniform(-60, 60) * G.D2R + (np.pi if rng.uniform() < 0.5 else 0)
        rad = rng.uniform(330, 430) * reach
        t.c = np.array([rad * np.cos(ang), rad * np.sin(ang), rng.uniform(-150, 0) * reach])
        t.X = G.T_of(G.rz(rng.uniform(-np.pi, np.pi)) @ G.rx(rng.uniform(-0.4, 0.4)) @ G.ry(rng.uniform(-0.4, 0.4)),
                     [rng.uniform(-60, 60), rng.uniform(-60, 60), rng.uniform(40, 100)])
    else:
        rot = G.rz(rng.uniform(-np.pi, np.pi)) @ G.ry(rng.uniform(-0.8, 0.8)) @ G.rx(rng.uniform(-0.8, 0.8))
        if p.mount in ("eih", "pos"):
            t.X = G.T_of(rot, [rng.uniform(-100, 100), rng.uniform(-100, 100), rng.uniform(50, 250)])
        if p.mount == "eih":
            t.c = np.array([rng.uniform(600, 1400), rng.uniform(-600, 600), rng.uniform(-200, 600)])
        if p.mount == "eth":
            # sensor fixed in the cell, looking at a workspace point
            pos = np.array([rng.uniform(800, 1500), rng.uniform(-500, 500), rng.uniform(900, 1500)])
            w = np.array([rng.uniform(800, 1200), rng.uniform(-300, 300), rng.uniform(200, 500)])
            d = w - pos
            t.X = G.T_of(frame_looking(d, rng.uniform(-np.pi, np.pi)), pos)   # sensor2base
            t.c = np.array([rng.uniform(-50, 50), rng.uniform(-50, 50), rng.uniform(80, 250)])  # in flange
            t.nominal_flange_R = frame_looking(-d, rng.uniform(-np.pi, np.pi))  # flange z towards the sensor
        if p.mount == "pos":
            p1 = np.array([rng.uniform(1000, 1600), rng.uniform(-300, 300), rng.uniform(300, 700)])
            a = rng.uniform(0, 2 * np.pi)
            d1 = np.array([np.cos(a), np.sin(a), 0.0])
            p2 = p1 + np.array([0, 0, rng.uniform(150, 250)])
            d2 = np.array([0, 0, 1.0])
            t.axes = [("e1", p1, d1), ("e2", p2, d2)]
            rho, ph = rng.uniform(80, 200), rng.uniform(0, 2 * np.pi)
            t.c = p2 + np.array([rho * np.cos(ph), rho * np.sin(ph), rng.uniform(30, 100)])  # table frame
    return t


def ur_seed(c):
    base = np.arctan2(c[1], c[0]) / G.D2R
    return np.array([base, -100.0, 100.0, -90.0, -90.0, 0.0])


def design_poses(rng, p, t):
    """list of dicts: F_true (flange in base), angles (positioner), q (joints)."""
    out = []
    orients = None
    if p.design == "grid":
        k = int(rng.integers(3, 6))
        orients = [(cap_dir(rng, p.tilt_max), rng.uniform(-np.pi, np.pi)) for _ in range(k)]
    tries = 0
    q_prev = None
    while len(out) < p.n:
        tries += 1
        if tries > (300 if p.robot else 5000) + 10 * p.n:
            raise RuntimeError("cannot design poses")
        s = sensor_target(rng, p)
        if orients is not None:
            d, roll = orients[len(out) % len(orients)]
        else:
            d, roll = cap_dir(rng, p.tilt_max), rng.uniform(-np.pi, np.pi)
        rec = {}
        if p.mount == "eih":
            Rs = frame_looking(d, roll)
            S = G.T_of(Rs, t.c - Rs @ s)
            F = S @ G.inv(t.X)
        elif p.mount == "pos":
            th = np.array([rng.uniform(-45, 45), rng.uniform(-180, 180)])
            P = revolute(t.axes[0][1], t.axes[0][2], th[0]) @ revolute(t.axes[1][1], t.axes[1][2], th[1])
            cb = G.tr(P, t.c)
            Rs = frame_looking(d, roll)
            S = G.T_of(Rs, cb - Rs @ s)
            F = S @ G.inv(t.X)
            rec["angles"] = th
        else:  # eth: flange rotation from a cap about its nominal
            RF = G.expso3(rng.normal(size=3) * rng.uniform(0, 0.6) / np.sqrt(3)) @ t.nominal_flange_R
            b = G.tr(t.X, s)
            F = G.T_of(RF, b - RF @ t.c)
        if p.robot:
            seed = q_prev if q_prev is not None else ur_seed(t.c)
            q, ok = G.ik(p.robot, F, seed)
            if not ok:
                q, ok = G.ik(p.robot, F, ur_seed(t.c))
            if not ok:
                continue
            q = (q + 180) % 360 - 180
            if abs(np.sin(q[4] * G.D2R)) < 0.25 or abs(np.sin(q[2] * G.D2R)) < 0.15:
                continue
            if np.linalg.norm(G.fk(p.robot, q)[:3, 3] - F[:3, 3]) > 1e-6:
                continue
            rec["q"] = q
            q_prev = q
        rec["F"] = F
        rec["d"] = d
        out.append(rec)
    if p.tour:   # a smooth tour: order by the azimuth of the viewing direction
        az = [np.arctan2(r["d"][1], r["d"][0]) + 0.001 * r["F"][0, 3] for r in out]
        out = [out[i] for i in np.argsort(az)]
    return out


def sensor_point(p, t, F, rec):
    if p.mount == "eih":
        return G.tr(G.inv(t.X) @ G.inv(F), t.c)
    if p.mount == "eth":
        return G.tr(G.inv(t.X) @ F, t.c)
    th = rec["angles"]
    P = revolute(t.axes[0][1], t.axes[0][2], th[0]) @ revolute(t.axes[1][1], t.axes[1][2], th[1])
    return G.tr(G.inv(t.X) @ G.inv(F), G.tr(P, t.c))


def make_profile(rng, p, s, noise):
    R = p.diameter / 2
    xs, ys, zs = s
    if abs(ys) >= R:
        return None
    r = np.sqrt(R * R - ys * ys)
    x = np.arange(np.ceil((xs - r) / p.pitch) * p.pitch, xs + r, p.pitch)
    x = x[np.abs(x - xs) < r]
    z = zs - np.sqrt(r * r - (x - xs) ** 2)
    n = np.column_stack([x - xs, z - zs]) / r
    v = -np.column_stack([x, z])
    v /= np.linalg.norm(v, axis=1)[:, None]
    keep = (np.sum(n * v, axis=1) > np.cos(p.inc_max * G.D2R)) & (np.abs(x) <= p.W / 2) \
        & (z >= p.z0) & (z <= p.z0 + p.L)
    x, z = x[keep], z[keep]
    if len(x) < 30:
        return None
    x = x + rng.normal(0, noise, len(x))
    z = z + rng.normal(0, noise, len(z))
    return np.column_stack([x, z])


def nonarc_profile(rng, s, p, noise):
    """a plane corner or a step where the sphere should be."""
    R = p.diameter / 2
    x0, z0 = s[0], s[2] - np.sqrt(max(R * R - s[1] ** 2, 1.0))
    half = rng.uniform(0.5, 0.9) * R
    x = np.arange(x0 - half, x0 + half, p.pitch)
    kind = rng.choice(["corner", "step"])
    if kind == "corner":
        a1, a2 = np.tan(rng.uniform(10, 45) * G.D2R), np.tan(rng.uniform(10, 45) * G.D2R)
        z = z0 + np.where(x < x0, (x0 - x) * a1, (x - x0) * a2)   # a roof seen from above
        if rng.uniform() < 0.5:
            z = z0 + R * 0.3 - np.where(x < x0, (x0 - x) * a1, (x - x0) * a2)  # a valley / V
    else:
        h = rng.uniform(1, 10)
        z = z0 + np.where(x < x0, 0.0, h) + (x - x0) * np.tan(rng.uniform(-10, 10) * G.D2R)
    x = x + rng.normal(0, noise, len(x))
    z = z + rng.normal(0, noise, len(z))
    return np.column_stack([x, z]), str(kind)


def fmt(v):
    return repr(float(v))


def robot_errors(rng, cls, planted):
    offsets = np.zeros(6)
    dlen = {}
    if cls == "joint_offsets":
        js = rng.choice([1, 2, 3, 4], size=int(rng.integers(1, 3)), replace=False)
        for j in js:
            offsets[j] = rng.choice([-1, 1]) * rng.uniform(0.05, 0.1)
        planted["joint_offsets_deg"] = offsets.tolist()
    if cls == "link_lengths":
        names = rng.choice(["a2", "a3", "d4", "d5"], size=int(rng.integers(1, 3)), replace=False)
        for k in names:
            dlen[str(k)] = float(rng.choice([-1, 1]) * rng.uniform(0.3, 0.6))
        planted["link_lengths_mm"] = dlen
    return offsets, dlen


def generate(cls, seed, out, noise_free=False, legacy_order=False):
    rng = np.random.default_rng([seed, CLASSES.index(cls), 7771])
    p = draw_params(rng, cls)
    if noise_free:
        p.noise = 0.0
        p.robot_sd = 0.0
    planted = {}
    for attempt in range(1 if legacy_order else 6):   # a robot cell out of reach: draw the cell again
        t = draw_truth(rng, p)
        if legacy_order:
            break
        try:
            recs = design_poses(rng, p, t)
            break
        except RuntimeError:
            if attempt == 5:
                raise
    if legacy_order:   # the first run's order: robot errors drawn before the poses
        offsets, dlen = robot_errors(rng, cls, planted)
        recs = design_poses(rng, p, t)
    else:
        offsets, dlen = robot_errors(rng, cls, planted)
    rows = []
    for i, rec in enumerate(recs):
        F_rep = rec["F"]
        if p.robot:
            F_true = G.fk(p.robot, rec["q"], offsets, dlen)
            F_rep = G.fk(p.robot, rec["q"])
        else:
            F_true = rec["F"]
        if p.robot_sd > 0:   # robot repeatability: the reported pose is not where the flange was
            F_rep = F_rep.copy()
            F_rep[:3, 3] += rng.normal(0, p.robot_sd, 3)
        s = sensor_point(p, t, F_true, rec)
        rows.append(dict(id="p%02d" % (i + 1), F=F_rep, s_true=s, rec=rec))
    # sensor data
    scale = 1.0
    if cls == "scale":
        scale = 1 + rng.choice([-1, 1]) * rng.uniform(0.002, 0.005)
        planted["sensor_scale"] = scale - 1
    for row in rows:
        s = row["s_true"]
        if p.data == "centres":
            row["xs"] = (s + rng.normal(0, p.noise, 3)) * scale
        else:
            prof = make_profile(rng, p, s, p.noise)
            tries = 0
            while prof is None:   # should not happen: the targets are inside the window
                tries += 1
                if tries > 3:
                    raise RuntimeError("profile not seen at %s" % row["id"])
                prof = make_profile(rng, p, s, p.noise)
            row["profile"] = prof * scale
    # planted errors
    if cls == "gross":
        k = int(rng.integers(1, 4))
        idx = rng.choice(len(rows), size=k, replace=False)
        planted["gross_rows"] = []
        for i in idx:
            dvec = rng.normal(size=3)
            dvec *= rng.uniform(2, 5) / np.linalg.norm(dvec)
            rows[i]["F"] = rows[i]["F"].copy()
            rows[i]["F"][:3, 3] += dvec
            planted["gross_rows"].append([rows[i]["id"], float(np.linalg.norm(dvec))])
    if cls == "nonarc":
        mode = rng.choice(["all", "most", "few"], p=[0.4, 0.3, 0.3])
        k = {"all": len(rows), "most": int(np.ceil(0.7 * len(rows))), "few": int(rng.integers(1, 4))}[mode]
        idx = rng.choice(len(rows), size=k, replace=False)
        kinds = []
        for i in idx:
            rows[i]["profile"], kind = nonarc_profile(rng, rows[i]["s_true"], p, max(p.noise, 0.005))
            kinds.append(kind)
        planted["nonarc"] = {"mode": str(mode), "rows": [rows[i]["id"] for i in idx], "kinds": kinds}
    if cls == "pairing":
        shift = int(rng.choice([-1, 1]))
        planted["pairing_shift"] = shift
        # pose row i gets the measurement of pose i+shift; one row is lost
        new = []
        for i in range(len(rows)):
            j = i + shift
            if 0 <= j < len(rows):
                r = dict(rows[i])
                for key in ("xs", "profile"):
                    if key in rows[j]:
                        r[key] = rows[j][key]
                new.append(r)
        rows = new
    setup_diameter = p.diameter
    if cls == "diameter":
        f = rng.choice([-1, 1]) * rng.uniform(0.01, 0.03)
        setup_diameter = p.diameter * (1 + f)
        planted["diameter_error"] = float(f)
    centre_setup = t.c.copy()
    if cls == "taught":
        dv = rng.normal(size=3)
        dv *= rng.uniform(1, 2) / np.linalg.norm(dv)
        centre_setup = t.c + dv
        planted["taught_offset_mm"] = dv.tolist()
    side = p.side
    slip = None
    if cls == "slip":
        opts = ["metres", "inverted"]
        if p.conv in ("kuka", "fanuc"):
            opts += ["euler_order", "fanuc_as_kuka"]
        if p.conv == "ur":
            opts += ["fanuc_as_kuka"]   # here: the rotation vector in degrees
        if p.conv == "kuka":
            opts += ["kuka_radians"]
        if p.conv == "abb":
            opts += ["quat_xyzw"]
        if p.data == "profiles":
            opts += ["side", "side"]
        if p.mount == "pos":
            opts += ["pos_radians"]
        if p.robot:
            opts += ["joint_swap", "j5_sign"]
        slip = str(rng.choice(opts))
        planted["slip"] = slip
        if slip == "side":
            side = -p.side
    # ---- write ---------------------------------------------------------
    if os.path.exists(out):
        shutil.rmtree(out)
    os.makedirs(out)
    conv = p.conv
    cols = ["id", "x", "y", "z"] + G.COLUMNS[conv]
    if p.data == "centres":
        cols += ["xs", "ys", "zs"]
    else:
        cols += ["profile"]
        os.makedirs(os.path.join(out, "profiles"))
    if p.mount == "pos":
        cols += ["e1", "e2"]
    if p.robot:
        cols += ["j%d" % k for k in range(1, 7)]
    lines = [",".join(cols)]
    for row in rows:
        F = row["F"]
        if slip == "inverted":
            F = G.inv(F)
        vals = G.pose_cols(F, conv)
        if slip == "metres":
            vals[:3] = [v / 1000 for v in vals[:3]]
        if slip == "kuka_radians":
            vals[3:] = [v * G.D2R for v in vals[3:]]
        if slip == "quat_xyzw":
            vals[3:] = vals[4:] + vals[3:4]
        if slip == "fanuc_as_kuka":   # FANUC's W,P,R written under the declared columns
            A, B, C = G.zyx_from_R(F[:3, :3])
            v3 = [C, B, A]
            if conv == "kuka":
                vals[3:] = v3
            elif conv == "fanuc":   # KUKA's A,B,C written under FANUC's w,p,r
                vals[3:] = [A, B, C]
            elif conv == "ur":   # degrees instead of radians for the rotation vector
                vals[3:] = [v / G.D2R for v in vals[3:]]
            else:   # abb: quaternion of the inverse rotation (conjugate)
                vals[3:] = [vals[3], -vals[4], -vals[5], -vals[6]]
        if slip == "euler_order":   # X-Y-Z intrinsic (R = Rx Ry Rz) written as the convention's
            Rm = F[:3, :3]
            # angles with R = Rx(a) Ry(b) Rz(c)
            b = np.arcsin(np.clip(Rm[0, 2], -1, 1))
            a = np.arctan2(-Rm[1, 2], Rm[2, 2])
            c = np.arctan2(-Rm[0, 1], Rm[0, 0])
            e = [a / G.D2R, b / G.D2R, c / G.D2R]
            if conv in ("kuka", "fanuc"):
                vals[3:] = e
            elif conv == "ur":   # rotation vector of the transposed rotation
                vals[3:] = list(G.logso3(Rm.T))
            else:
                vals[3:] = [vals[3], -vals[4], -vals[5], -vals[6]]
        line = [row["id"]] + [fmt(v) for v in vals]
        if p.data == "centres":
            line += [fmt(v) for v in row["xs"]]
        else:
            fn = "profiles/%s.csv" % row["id"]
            with open(os.path.join(out, fn), "w") as f:
                f.write("x,z\n")
                for x, z in row["profile"]:
                    f.write("%s,%s\n" % (fmt(x), fmt(z)))
            line += [fn]
        if p.mount == "pos":
            th = row["rec"]["angles"]
            if slip == "pos_radians":
                th = th * G.D2R
            line += [fmt(v) for v in th]
        if p.robot:
            q = row["rec"]["q"].copy()
            if slip == "joint_swap":
                q[[3, 5]] = q[[5, 3]]
            if slip == "j5_sign":
                q[4] = -q[4]
            line += [fmt(v) for v in q]
        lines.append(",".join(line))
    with open(os.path.join(out, "measurements.csv"), "w") as f:
        f.write("\n".join(lines) + "\n")
    toml = ["[robot]", 'convention = "%s"' % conv]
    if p.robot:
        toml.append('model = "%s"' % p.robot)
    toml.append("[sensor]")
    toml.append('mount = "%s"' % ("world" if p.mount == "eth" else "flange"))
    toml.append("[sphere]")
    toml.append('mount = "%s"' % {"eih": "world", "eth": "flange", "pos": "positioner"}[p.mount])
    if p.data == "profiles" or rng.uniform() < 0.5:
        toml.append("diameter = %s" % fmt(setup_diameter))
    if p.centre_known:
        toml.append("center = [%s]" % ", ".join(fmt(v) for v in centre_setup))
    if p.data == "profiles":
        toml += ["[profile]", "side = %d" % side]
    if p.state_noise and not noise_free:
        if p.data == "centres":
            toml += ["[noise]", "centre_mm = %s" % fmt(p.noise)]
        elif p.robot_sd > 0.002:
            toml += ["[noise]", "robot_mm = %s" % fmt(p.robot_sd)]
    if p.mount == "pos":
        toml.append("[positioner]")
        ax = ", ".join('{ name = "%s", point = [%s], direction = [%s] }'
                       % (n, ", ".join(fmt(v) for v in pt), ", ".join(fmt(v) for v in d)) for n, pt, d in t.axes)
        toml.append("axes = [ %s ]" % ax)
    with open(os.path.join(out, "setup.toml"), "w") as f:
        f.write("\n".join(toml) + "\n")
    truth = dict(cls=cls, seed=seed, mount=p.mount, convention=p.conv, data=p.data,
                 centre_known=p.centre_known, n_rows=len(rows), noise=p.noise, robot_sd=p.robot_sd,
                 diameter=p.diameter, design=p.design, tour=p.tour, robot=p.robot, side=p.side,
                 state_noise=p.state_noise, X=t.X.tolist(), centre=t.c.tolist(),
                 sensor_pose=G.pose_cols(t.X, p.conv), planted=planted,
                 unknowns="sensor" if p.centre_known else "sensor+sphere")
    with open(out.rstrip("/") + ".truth.json", "w") as f:
        json.dump(truth, f, indent=1)
    return truth


# ---- independent check: the chain closes at the truth -------------------
def read_back(out):
    import csv
    truth = json.load(open(out.rstrip("/") + ".truth.json"))
    conv = truth["convention"]
    rows = list(csv.DictReader(open(os.path.join(out, "measurements.csv"))))
    X = np.array(truth["X"])
    c = np.array(truth["centre"])
    R = truth["diameter"] / 2
    res = []
    for r in rows:
        v = [float(r[k]) for k in ["x", "y", "z"] + G.COLUMNS[conv]]
        F = G.T_from_cols(v, conv)
        if "xs" in r:
            s = np.array([float(r["xs"]), float(r["ys"]), float(r["zs"])])
        else:
            P = np.loadtxt(os.path.join(out, r["profile"]), delimiter=",", skiprows=1)
            cx, cz, rr = G.circle_fit(P[:, 0], P[:, 1])
            s = np.array([cx, truth["side"] * np.sqrt(max(R * R - rr * rr, 0)), cz])
        if truth["mount"] == "eih":
            e = G.tr(F @ X, s) - c
        elif truth["mount"] == "eth":
            e = G.tr(X, s) - G.tr(F, c)
        else:
            import tomllib
            st = tomllib.load(open(os.path.join(out, "setup.toml"), "rb"))
            P = np.eye(4)
            for ax in st["positioner"]["axes"]:
                P = P @ revolute(ax["point"], ax["direction"], float(r[ax["name"]]))
            e = G.tr(F @ X, s) - G.tr(P, c)
        res.append(e)
    res = np.array(res)
    return res


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--class", dest="cls", required=True, choices=CLASSES)
    ap.add_argument("--seed", type=int, required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--noise-free", action="store_true")
    ap.add_argument("--check", action="store_true")
    ap.add_argument("--legacy-order", action="store_true",
                    help="the first run's draw order for joint_offsets/link_lengths (robot errors before poses)")
    a = ap.parse_args()
    tr_ = generate(a.cls, a.seed, a.out, a.noise_free, a.legacy_order)
    print(json.dumps({k: v for k, v in tr_.items() if k not in ("X",)}))
    if a.check:
        e = read_back(a.out)
        rms = np.sqrt(np.mean(np.sum(e**2, axis=1)))
        print("closure at the truth: RMS per centre %.6g mm (max %.6g); noise %.3g (x sqrt3 = %.3g)"
              % (rms, np.abs(e).max(), tr_["noise"], tr_["noise"] * np.sqrt(3)))
