"""Controller program files written as the controllers write them, and read back independently.

The writers put an :mod:`ingest_truth` cell's flange poses into a FANUC TP program (``.ls``), a
KUKA program (``.src`` + ``.dat``), an ABB RAPID module (``.mod``), a URScript program and a UR
RTDE log, from the vendors' documented formats and formulas (scipy's rotations, not handeye's).
The readers here are separate regular expressions over the same formats, so that handeye's
readers are checked against an independent reading of the real files in
``tests/data/controllers``.
"""
import re

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

#: the real files (README.md beside them says where from)
HOME_JOINTS = "[[0,0,0,0,30,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]]"


def matrix(convention, values):
    """Rotation matrix of orientation values, from the vendors' definitions via scipy."""
    v = np.asarray(values, float)
    if convention == "kuka":  # A, B, C: Rz(A) Ry(B) Rx(C), intrinsic Z-Y'-X''
        return Rotation.from_euler("ZYX", v, degrees=True).as_matrix()
    if convention == "fanuc":  # W, P, R: fixed X, Y, Z: Rz(R) Ry(P) Rx(W)
        return Rotation.from_euler("xyz", v, degrees=True).as_matrix()
    if convention == "abb":  # q1..q4 = w, x, y, z
        return Rotation.from_quat([v[1], v[2], v[3], v[0]]).as_matrix()
    return Rotation.from_rotvec(v).as_matrix()  # ur


def transforms(convention, poses):
    """4x4 transforms (mm) of pose rows in a convention."""
    out = np.tile(np.eye(4), (len(poses), 1, 1))
    for k, p in enumerate(np.asarray(poses, float)):
        out[k, :3, :3], out[k, :3, 3] = matrix(convention, p[3:]), p[:3]
    return out


def _angles(f, seq):
    return Rotation.from_matrix(f[:3, :3]).as_euler(seq, degrees=True)


# --- writers ------------------------------------------------------------------------------------

def write_ls(path, flanges, ut=0, uf=0, joint_form=(), configs=None):
    """A FANUC TP program: ``/MN`` moves to every ``P[n]``, ``/POS`` holds them (3 decimals); ``configs``:
    each position's ``CONFIG`` (default ``'N U T, 0, 0, 0'``)."""
    mn = "".join(f"  {k + 1:3d}:{'J' if k == 0 else 'L'} P[{k + 1}] 100% FINE    ;\n" for k in range(len(flanges)))
    pos = []
    for k, f in enumerate(flanges):
        if k in joint_form:
            body = "\tJ1=     0.000 deg,\tJ2=   -30.000 deg,\tJ3=    15.000 deg,\n" \
                   "\tJ4=      .500 deg,\tJ5=   -90.000 deg,\tJ6=   180.000 deg"
            pos.append(f"P[{k + 1}]{{\n   GP1:\n\tUF : {uf}, UT : {ut},\n{body}\n}};\n")
            continue
        w, p, r = _angles(f, "xyz")
        x, y, z = f[:3, 3]
        config = "N U T, 0, 0, 0" if configs is None else configs[k]
        pos.append(f"P[{k + 1}]{{\n   GP1:\n\tUF : {uf}, UT : {ut},\t\tCONFIG : '{config}',\n"
                   f"\tX = {x:9.3f}  mm,\tY = {y:9.3f}  mm,\tZ = {z:9.3f}  mm,\n"
                   f"\tW = {w:9.3f} deg,\tP = {p:9.3f} deg,\tR = {r:9.3f} deg\n}};\n")
    text = ("/PROG  CALIB\n/ATTR\nOWNER\t\t= MNEDITOR;\nCOMMENT\t\t= \"\";\nDEFAULT_GROUP\t= 1,*,*,*,*;\n"
            f"/MN\n   0:  UTOOL_NUM={ut} ;\n{mn}/POS\n{''.join(pos)}/END\n")
    path.write_text(text, newline="\r\n")
    return path


def write_krl(folder, flanges, name="calib", tool=0, base=0):
    """A KUKA program: the ``.dat`` declares the points backwards, the ``.src`` moves to them in
    order between two ``PTP XHOME`` (declared in ``$config.dat``, not here)."""
    dat = [f"&ACCESS RVP\n&REL 1\nDEFDAT  {name}\n"]
    src = [f"&ACCESS RVP\n&REL 1\nDEF {name}( )\n;FOLD PTP HOME  Vel= 100 % DEFAULT;%{{PE}}\n"
           "$BWDSTART = FALSE\nPDAT_ACT=PDEFAULT\nFDAT_ACT=FHOME\nBAS (#PTP_PARAMS,100 )\nPTP  XHOME\n;ENDFOLD\n"]
    for k in range(len(flanges))[::-1]:
        f = flanges[k]
        a, b, c = _angles(f, "ZYX")
        x, y, z = f[:3, 3]
        dat.append(f"DECL E6POS XP{k + 1}={{X {x:.5f},Y {y:.5f},Z {z:.5f},A {a:.5f},B {b:.5f},C {c:.5f},S 2,T 35,"
                   "E1 0.0,E2 0.0,E3 0.0,E4 0.0,E5 0.0,E6 0.0}\n"
                   f"DECL FDAT FP{k + 1}={{TOOL_NO {tool},BASE_NO {base},IPO_FRAME #BASE,POINT2[] \" \",TQ_STATE FALSE}}\n"
                   f"DECL PDAT PPDAT{k + 1}={{VEL 100.000,ACC 100.000,APO_DIST 100.000}}\n")
    for k in range(len(flanges)):
        move = "PTP" if k % 2 == 0 else "LIN"
        src.append(f";FOLD {move} P{k + 1} Vel=100 % PDAT{k + 1} Tool[{tool}] Base[{base}];%{{PE}}%R 8.3.38\n"
                   f"$BWDSTART=FALSE\nPDAT_ACT=PPDAT{k + 1}\nFDAT_ACT=FP{k + 1}\nBAS(#PTP_PARAMS,100)\n"
                   f"{move} XP{k + 1} \n;ENDFOLD\n")
    src.append(";FOLD PTP HOME  Vel= 100 % DEFAULT;%{PE}\nPTP  XHOME\n;ENDFOLD\nEND\n")
    dat.append("ENDDAT\n")
    (folder / f"{name}.dat").write_text("".join(dat), newline="\r\n")
    (folder / f"{name}.src").write_text("".join(src), newline="\r\n")
    return folder / f"{name}.src"


def write_mod(path, flanges, tool="tool0", tooldata=None, wobj=None):
    """An ABB RAPID module: robtargets declared, a MoveAbsJ home, MoveL/MoveJ to each target."""
    decl, moves = [], []
    for k, f in enumerate(flanges):
        x, y, z, w = Rotation.from_matrix(f[:3, :3]).as_quat()
        t = f[:3, 3]
        decl.append(f"    CONST robtarget p{10 * (k + 1)}:=[[{t[0]:.4f},{t[1]:.4f},{t[2]:.4f}],"
                    f"[{w:.8f},{x:.8f},{y:.8f},{z:.8f}],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];\n")
        wo = f"\\WObj:={wobj}" if wobj else ""
        moves.append(f"        Move{'J' if k % 3 == 0 else 'L'} p{10 * (k + 1)},v100,fine,{tool}{wo};\n")
    tools = f"    PERS tooldata {tool}:={tooldata};\n" if tooldata else ""
    text = (f"MODULE Calib\n    ! the sphere poses\n{tools}{''.join(decl)}"
            f"    CONST jointtarget jhome:={HOME_JOINTS};\n    PROC main()\n        MoveAbsJ jhome,v200,z50,tool0;\n"
            f"{''.join(moves)}        MoveAbsJ jhome,v200,z50,tool0;\n    ENDPROC\nENDMODULE\n")
    path.write_text(text, newline="\r\n")
    return path


def write_urscript(path, flanges, tcp=None):
    """A URScript program as Polyscope writes one: ``global Waypoint_k_p=p[...]`` then
    ``movel(Waypoint_k_p, ...)``, a ``movej`` home in joints first (metres, rotation vectors)."""
    lines = ["def calib():", "  set_standard_analog_input_domain(0, 1)"]
    if tcp is not None:
        lines.append(f"  set_tcp(p[{', '.join(map(str, tcp))}])")
    for k, f in enumerate(flanges):
        t, r = f[:3, 3] / 1000.0, Rotation.from_matrix(f[:3, :3]).as_rotvec()
        lines.append(f"  global Waypoint_{k + 1}_p=p[{', '.join(f'{v:.7f}' for v in (*t, *r))}]")
        lines.append(f"  global Waypoint_{k + 1}_q=[{', '.join(f'{0.1 * k + 0.01 * j:.6f}' for j in range(6))}]")
    lines.append("  movej([0.0, -1.5708, 1.5708, -1.5708, -1.5708, 0.0], a=1.4, v=1.05)  # home")
    for k in range(len(flanges)):
        lines.append(f"  movel(Waypoint_{k + 1}_p, a=1.2, v=0.25)")
    path.write_text("\n".join(lines + ["end", ""]))
    return path


def write_rtde(path, flanges, sep=" ", tcp_offset=None):
    """A UR RTDE log as ``record.py`` writes one: header, one row per pose (metres, rad)."""
    head = ["timestamp", *(f"actual_q_{k}" for k in range(6)), *(f"actual_TCP_pose_{k}" for k in range(6))]
    head += [f"tcp_offset_{k}" for k in range(6)] if tcp_offset is not None else []
    rows = []
    for k, f in enumerate(flanges):
        pose = [*(f[:3, 3] / 1000.0), *Rotation.from_matrix(f[:3, :3]).as_rotvec()]
        row = [100.0 + 0.008 * k, *np.linspace(-1, 1, 6), *pose] + (list(tcp_offset) if tcp_offset is not None else [])
        rows.append(sep.join(f"{v:.9g}" for v in row))
    path.write_text(sep.join(head) + "\n" + "\n".join(rows) + "\n")
    return path


def write_rtde_stream(path, flanges, rng, hz=500.0, dwell=(0.3, 2.0), noise_mm=0.01):
    """A UR RTDE log as record.py streams it while the robot moves from stop to stop (module docstring):
    from a home pose to each flange pose in turn and back home, every move a minimum-jerk profile
    (accelerating, then decelerating to rest) of peak speed 250 mm/s and 45 deg/s (at least 0.4 s), a stop
    of ``dwell`` seconds (uniform; 0: none) at each pose (None: a sweep through the poses at constant speed,
    never at rest); ``hz`` rows a second, the TCP with Gaussian noise
    of ``noise_mm`` a coordinate and 1e-5 rad, the joints (a made-up arm's, moving with the same profile)
    1e-5 rad. The recording starts halfway through the move from home and stops halfway back (the robot
    waiting at home would be two stops more). Returns ``(path, stop rows [(first, end)], rows)``."""
    home = np.eye(4)
    home[:3, 3] = flanges[:, :3, 3].mean(axis=0) + [0.0, 0.0, 150.0]
    home[:3, :3] = flanges[0, :3, :3]
    poses = [home, *flanges, home]
    joints = rng.uniform(-2.5, 2.5, (len(poses), 6))
    holds = [0.0] + list(rng.uniform(*dwell, len(flanges)) if np.ndim(dwell) else [float(dwell or 0)] * len(flanges)) + [0.0]
    seg_p, seg_q, stops, at, moves = [], [], [], 0, []
    for k, (pose, hold) in enumerate(zip(poses, holds)):
        n = int(round(hold * hz))
        seg_p.append(np.repeat(pose[None], n, 0))
        seg_q.append(np.repeat(joints[k][None], n, 0))
        if 0 < k < len(poses) - 1 and n:
            stops.append((at, at + n))
        at += n
        if k + 1 < len(poses):
            p, q, m = _min_jerk(pose, poses[k + 1], (joints[k], joints[k + 1]), hz, sweep=dwell is None)
            seg_p.append(p)
            seg_q.append(q)
            moves.append(at + m // 2)
            at += m
    first, last = moves[0], moves[-1]
    frames, q = np.concatenate(seg_p)[first:last], np.concatenate(seg_q)[first:last]
    stops = [(a - first, b - first) for a, b in stops]
    seg_t = np.arange(len(frames)) / hz + 4156.212
    tcp = np.column_stack([frames[:, :3, 3] / 1000.0 + rng.normal(0, noise_mm / 1000.0, (len(frames), 3)),
                           Rotation.from_matrix(frames[:, :3, :3]).as_rotvec() + rng.normal(0, 1e-5, (len(frames), 3))])
    q = q + rng.normal(0, 1e-5, q.shape)
    head = ["timestamp", *(f"actual_q_{k}" for k in range(6)), *(f"actual_TCP_pose_{k}" for k in range(6))]
    np.savetxt(path, np.column_stack([seg_t, q, tcp]), fmt="%.10g", delimiter=",", header=",".join(head), comments="")
    return path, stops, len(frames)


def _min_jerk(a, b, q, hz, sweep=False):
    """The rows strictly between two rests: flange frames (m, 4, 4), joints (m, 6) and m (``sweep``: at
    constant speed, rows at both ends)."""
    qa, qb = q
    dist = np.linalg.norm(b[:3, 3] - a[:3, 3])
    turn = np.degrees(Rotation.from_matrix(a[:3, :3].T @ b[:3, :3]).magnitude())
    duration = max(0.4, 1.875 * dist / 250.0, 1.875 * turn / 45.0)  # peak speed of 10t^3 - 15t^4 + 6t^5: 1.875 D/T
    tau = np.arange(0 if sweep else 1, int(round(duration * hz))) / (duration * hz)
    s = tau if sweep else 10 * tau**3 - 15 * tau**4 + 6 * tau**5
    out = np.tile(np.eye(4), (len(s), 1, 1))
    out[:, :3, 3] = a[:3, 3] + s[:, None] * (b[:3, 3] - a[:3, 3])
    out[:, :3, :3] = Slerp([0.0, 1.0], Rotation.from_matrix([a[:3, :3], b[:3, :3]]))(s).as_matrix()
    return out, qa + s[:, None] * (qb - qa), len(s)


# --- independent readings of the real files ------------------------------------------------------

def fanuc_reading(text):
    """(names in /MN order, X..R rows) of a FANUC program by plain regular expressions."""
    mn, pos = text.split("/MN", 1)[1].split("/POS", 1)
    order = list(dict.fromkeys(int(n) for n in re.findall(r"\bP\[(\d+)", mn)))
    rows = {}
    for n, body in re.findall(r"P\[(\d+)[^\]]*\]\{(.*?)\};", pos, re.S):
        rows[int(n)] = [float(re.search(rf"\b{f}\s*=\s*(\S+)\s*(?:mm|deg)", body).group(1)) for f in "XYZWPR"]
    return [f"P{n}" for n in order], np.array([rows[n] for n in order])


def fanuc_configs(text):
    """Each position's ``CONFIG`` (or ``KONFIG``) in ``/MN`` order: ``(letters, (t4, t5, t6))``, by a regular expression."""
    mn, pos = text.split("/MN", 1)[1].split("/POS", 1)
    order = list(dict.fromkeys(int(n) for n in re.findall(r"\bP\[(\d+)", mn)))
    found = {int(n): (w + e + b, (int(t4), int(t5), int(t6))) for n, w, e, b, t4, t5, t6 in re.findall(
        r"P\[(\d+)[^\]]*\]\{\s*GP1:[^}]*?[CK]ONFIG : '([NF]) ([UD]) ([TB]), (-?\d), (-?\d), (-?\d)'", pos)}
    return [found[n] for n in order]


def kuka_reading(src_text, dat_text):
    """(names in motion order, X..C rows) of a KUKA program by plain regular expressions."""
    decl = {m.group(1).lower(): [float(v) for v in m.groups()[1:]] for m in re.finditer(
        r"DECL E6POS (\w+)=\{X ([^,]+),Y ([^,]+),Z ([^,]+),A ([^,]+),B ([^,]+),C ([^,]+),", dat_text)}
    order = [n for n in re.findall(r"^\s*(?:PTP|LIN)\s+(\w+)", src_text, re.M | re.I) if n.lower() in decl]
    return [n[1:] for n in order], np.array([decl[n.lower()] for n in order])


def abb_reading(text):
    """(names in motion order, x, y, z, q1..q4 rows) of an ABB module by plain regular expressions."""
    decl = {n.lower(): [float(v) for v in re.split(r"[\[\],]+", body) if v] for n, body in re.findall(
        r"robtarget (\w+):=\[(\[[^\]]*\],\[[^\]]*\])", text)}
    moved = []
    for kind, first, second in re.findall(r"Move([LJC])\s+(\w+)\s*,\s*(\w+)", text):
        moved += [first, second] if kind == "C" else [first]
    order = list(dict.fromkeys(n for n in moved if n.lower() in decl))
    return order, np.array([decl[n.lower()] for n in order])
