"""Own rotation / pose / robot code (numpy only), independent of handeye."""
import numpy as np

D2R = np.pi / 180.0


def rx(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def ry(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def rz(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def skew(w):
    return np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])


def expso3(w):
    w = np.asarray(w, float)
    th = np.linalg.norm(w)
    K = skew(w)
    if th < 1e-12:
        return np.eye(3) + K
    return np.eye(3) + np.sin(th) / th * K + (1 - np.cos(th)) / th**2 * K @ K


def logso3(R):
    c = np.clip((np.trace(R) - 1) / 2, -1, 1)
    th = np.arccos(c)
    if th < 1e-8:
        return np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]]) / 2
    if th > np.pi - 1e-6:
        # axis from the symmetric part
        B = (R + np.eye(3)) / 2
        i = int(np.argmax(np.diag(B)))
        v = B[:, i] / np.sqrt(B[i, i])
        v /= np.linalg.norm(v)
        w = th * v
        if np.linalg.norm(expso3(w) - R) > np.linalg.norm(expso3(-w) - R):
            w = -w
        return w
    return th / (2 * np.sin(th)) * np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])


def T_of(R, t):
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = t
    return T


def inv(T):
    R, t = T[:3, :3], T[:3, 3]
    return T_of(R.T, -R.T @ t)


def tr(T, p):
    return T[:3, :3] @ p + T[:3, 3]


# --- conventions -----------------------------------------------------------
def zyx_from_R(R):
    """R = Rz(A) Ry(B) Rx(C); returns degrees A, B, C."""
    B = np.arcsin(np.clip(-R[2, 0], -1, 1))
    A = np.arctan2(R[1, 0], R[0, 0])
    C = np.arctan2(R[2, 1], R[2, 2])
    return np.array([A, B, C]) / D2R


def R_from_zyx(A, B, C):
    return rz(A * D2R) @ ry(B * D2R) @ rx(C * D2R)


def quat_from_R(R):
    """w, x, y, z (w >= 0)."""
    tr_ = np.trace(R)
    if tr_ > 0:
        s = np.sqrt(tr_ + 1.0) * 2
        q = [0.25 * s, (R[2, 1] - R[1, 2]) / s, (R[0, 2] - R[2, 0]) / s, (R[1, 0] - R[0, 1]) / s]
    elif R[0, 0] > R[1, 1] and R[0, 0] > R[2, 2]:
        s = np.sqrt(1.0 + R[0, 0] - R[1, 1] - R[2, 2]) * 2
        q = [(R[2, 1] - R[1, 2]) / s, 0.25 * s, (R[0, 1] + R[1, 0]) / s, (R[0, 2] + R[2, 0]) / s]
    elif R[1, 1] > R[2, 2]:
        s = np.sqrt(1.0 + R[1, 1] - R[0, 0] - R[2, 2]) * 2
        q = [(R[0, 2] - R[2, 0]) / s, (R[0, 1] + R[1, 0]) / s, 0.25 * s, (R[1, 2] + R[2, 1]) / s]
    else:
        s = np.sqrt(1.0 + R[2, 2] - R[0, 0] - R[1, 1]) * 2
        q = [(R[1, 0] - R[0, 1]) / s, (R[0, 2] + R[2, 0]) / s, (R[1, 2] + R[2, 1]) / s, 0.25 * s]
    q = np.array(q)
    q /= np.linalg.norm(q)
    return q if q[0] >= 0 else -q


def R_from_quat(q):
    w, x, y, z = np.asarray(q, float) / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


COLUMNS = {"kuka": ["a", "b", "c"], "abb": ["q1", "q2", "q3", "q4"],
           "ur": ["rx", "ry", "rz"], "fanuc": ["w", "p", "r"]}


def rot_cols(R, conv):
    if conv == "kuka":
        return list(zyx_from_R(R))
    if conv == "fanuc":   # fixed X-Y-Z: R = Rz(r) Ry(p) Rx(w)
        A, B, C = zyx_from_R(R)
        return [C, B, A]
    if conv == "abb":
        return list(quat_from_R(R))
    if conv == "ur":
        return list(logso3(R))
    raise ValueError(conv)


def R_from_cols(v, conv):
    if conv == "kuka":
        return R_from_zyx(*v)
    if conv == "fanuc":
        return R_from_zyx(v[2], v[1], v[0])
    if conv == "abb":
        return R_from_quat(v)
    if conv == "ur":
        return expso3(v)
    raise ValueError(conv)


def pose_cols(T, conv):
    return list(T[:3, 3]) + rot_cols(T[:3, :3], conv)


def T_from_cols(v, conv):
    return T_of(R_from_cols(v[3:], conv), np.asarray(v[:3], float))


# --- robots (standard DH, UR's published parameters, mm) ------------------
DH = {
    "ur5e": dict(d=[162.5, 0, 0, 133.3, 99.7, 99.6], a=[0, -425.0, -392.2, 0, 0, 0],
                 alpha=[np.pi / 2, 0, 0, np.pi / 2, -np.pi / 2, 0]),
    "ur10e": dict(d=[180.7, 0, 0, 174.15, 119.85, 116.55], a=[0, -612.7, -571.55, 0, 0, 0],
                  alpha=[np.pi / 2, 0, 0, np.pi / 2, -np.pi / 2, 0]),
}


def fk(model, q_deg, offsets=None, dlen=None):
    """flange in base; offsets: joint zero errors (deg, 6); dlen: {'a2': mm, 'd4': mm ...} (1-based)."""
    p = DH[model]
    d = list(p["d"])
    a = list(p["a"])
    if dlen:
        for k, v in dlen.items():
            i = int(k[1:]) - 1
            if k[0] == "a":
                a[i] += v
            else:
                d[i] += v
    q = np.asarray(q_deg, float) * D2R
    if offsets is not None:
        q = q + np.asarray(offsets, float) * D2R
    T = np.eye(4)
    for i in range(6):
        A = T_of(rz(q[i]), [0, 0, 0]) @ T_of(np.eye(3), [0, 0, d[i]]) @ T_of(rx(p["alpha"][i]), [a[i], 0, 0])
        T = T @ A
    return T


def pose_err(T, Td):
    e = np.zeros(6)
    e[:3] = Td[:3, 3] - T[:3, 3]
    e[3:] = logso3(Td[:3, :3] @ T[:3, :3].T) * 500.0   # rad -> comparable to mm
    return e


def ik(model, Td, q0, iters=200):
    q = np.array(q0, float)
    for _ in range(iters):
        T = fk(model, q)
        e = pose_err(T, Td)
        if np.linalg.norm(e[:3]) < 1e-9 and np.linalg.norm(e[3:]) / 500 < 1e-11:
            return q, True
        J = np.zeros((6, 6))
        h = 1e-6
        for j in range(6):
            dq = np.zeros(6)
            dq[j] = h
            J[:, j] = -(pose_err(fk(model, q + dq), Td) - e) / h
        lam = 1e-3
        step = np.linalg.solve(J.T @ J + lam * np.eye(6), J.T @ e)
        n = np.linalg.norm(step)
        if n > 10:
            step *= 10 / n
        q = q + step
    T = fk(model, q)
    e = pose_err(T, Td)
    return q, (np.linalg.norm(e[:3]) < 1e-7 and np.linalg.norm(e[3:]) / 500 < 1e-9)


# --- circle fit (own check) -----------------------------------------------
def circle_fit(x, z):
    A = np.column_stack([x, z, np.ones_like(x)])
    b = x**2 + z**2
    sol = np.linalg.lstsq(A, b, rcond=None)[0]
    cx, cz = sol[0] / 2, sol[1] / 2
    r = np.sqrt(sol[2] + cx**2 + cz**2)
    p = np.array([cx, cz, r])
    for _ in range(50):   # geometric Gauss-Newton
        dx, dz = x - p[0], z - p[1]
        rho = np.hypot(dx, dz)
        res = rho - p[2]
        J = np.column_stack([-dx / rho, -dz / rho, -np.ones_like(x)])
        step = np.linalg.lstsq(J, -res, rcond=None)[0]
        p = p + step
        if np.linalg.norm(step) < 1e-13:
            break
    return p
