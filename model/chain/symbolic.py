"""The one symbolic source of the workbench's mathematics.

Everything numeric in :mod:`handeye.model` -- the pose transform, the calibration residual with its
exact Jacobian and second derivatives, the thesis's test function -- is derived here, once,
with sympy. :mod:`handeye.model.chain.codegen` turns these expressions into numpy (vectorised) and CasADi
functions; nothing is copied by hand.

Conventions
-----------
A pose ``p = (x, y, z, A, B, C)`` is in mm and degrees, KUKA convention (seed 2.1.2, C2)::

    T(p) = Trans(x, y, z) . Rz(A) . Ry(B) . Rx(C)

i.e. intrinsic Z-Y'-X'' angles. (The seed's formula (2-6) names the angles the other way round,
``Rz(C) Ry(B) Rx(A)``; its code C2 and its text in 6.1.2 use ``Rz(A) Ry(B) Rx(C)``, which is
KUKA's definition and the one the seed's data obey.)

The calibration residual (seed 4-3) of measurement ``i`` is::

    e_i = R1_i (R2 xs_i + t2) + t1_i - c

with ``(R1_i, t1_i)`` the flange pose in the robot base, ``(R2, t2)`` the unknown sensor pose
on the flange, ``xs_i`` the sphere centre measured in the sensor frame and ``c`` the sphere
centre in the robot base.
"""
from __future__ import annotations

import functools

import sympy as sp

# the names of rotations, residual kinds and conventions are defined once, in a leaf module
from handeye.model.chain.names import CONVENTIONS, KINDS, ROTATIONS


def rot_x(angle):
    """Elementary rotation about x by ``angle`` (radians), 3x3 sympy matrix."""
    c, s = sp.cos(angle), sp.sin(angle)
    return sp.Matrix([[1, 0, 0], [0, c, -s], [0, s, c]])


def rot_y(angle):
    """Elementary rotation about y by ``angle`` (radians), 3x3 sympy matrix."""
    c, s = sp.cos(angle), sp.sin(angle)
    return sp.Matrix([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def rot_z(angle):
    """Elementary rotation about z by ``angle`` (radians), 3x3 sympy matrix."""
    c, s = sp.cos(angle), sp.sin(angle)
    return sp.Matrix([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def matrix_from_kuka_deg(a, b, c):
    """Rotation ``Rz(A) Ry(B) Rx(C)`` for angles given in degrees (symbolic)."""
    k = sp.pi / 180
    return rot_z(a * k) * rot_y(b * k) * rot_x(c * k)


def skew(v):
    """The cross-product matrix ``[v]x`` of a 3-vector (symbolic)."""
    return sp.Matrix([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])




@functools.lru_cache(maxsize=None)
def rotation_from(convention):
    """Symbolic rotation matrix of a robot brand's orientation parameters.

    Returns
    -------
    symbols : tuple of sympy.Symbol
        The parameters, named as in :data:`CONVENTIONS`.
    rotation : sympy.Matrix, shape (3, 3)

    Notes
    -----
    ``ur`` uses ``R = I + sinc(t) [r]x + sinc(t/2)^2 / 2 [r]x^2`` with ``t = |r|``, which is
    Rodrigues' formula written without a division by t, so it is exact and finite at t = 0.
    """
    sym = sp.symbols(" ".join(CONVENTIONS[convention]), real=True)
    k = sp.pi / 180
    if convention == "kuka":
        a, b, c = sym
        return sym, rot_z(a * k) * rot_y(b * k) * rot_x(c * k)
    if convention == "fanuc":
        w, p, r = sym
        return sym, rot_z(r * k) * rot_y(p * k) * rot_x(w * k)
    if convention == "abb":
        w, x, y, z = sym
        return sym, sp.Matrix([
            [1 - 2 * (y**2 + z**2), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x**2 + z**2), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x**2 + y**2)],
        ])
    r = sp.Matrix(sym)
    t = sp.sqrt(r.dot(r))
    w = skew(r)
    return sym, sp.eye(3) + sp.sinc(t) * w + sp.sinc(t / 2) ** 2 / 2 * w * w


@functools.lru_cache(maxsize=None)
def pose_transform():
    """Symbolic homogeneous transform of a KUKA pose.

    Returns
    -------
    inputs : tuple of sympy.Symbol
        ``(x, y, z, A, B, C)``; mm and degrees.
    transform : sympy.Matrix, shape (4, 4)
        ``Trans(x, y, z) Rz(A) Ry(B) Rx(C)``.
    """
    x, y, z, a, b, c = sp.symbols("x y z A B C", real=True)
    rot = matrix_from_kuka_deg(a, b, c)
    t = sp.eye(4)
    t[:3, :3] = rot
    t[:3, 3] = sp.Matrix([x, y, z])
    return (x, y, z, a, b, c), t


def _sensor_rotation(rotation):
    """Parameters ``q`` and the rotation ``R2(q)`` (plus extra inputs) of one parametrisation.

    * ``euler``: q = (A, B, C) in degrees, ``R2 = Rz(A) Ry(B) Rx(C)``.
    * ``matrix``: q = the nine entries of R2, row-major (orthogonality is a constraint).
    * ``local``: q = delta (radians), ``R2 = Rref exp([delta]x)``. Only the value, first and
      second derivatives at delta = 0 are used, and for those the second-order series
      ``I + [d]x + [d]x^2 / 2`` is exact; ``Rref`` (nine entries) is an extra input.
    """
    if rotation == "euler":
        q = sp.symbols("A2 B2 C2", real=True)
        return q, matrix_from_kuka_deg(*q), ()
    if rotation == "matrix":
        q = sp.symbols("r2_0:9", real=True)
        return q, sp.Matrix(3, 3, q), ()
    if rotation == "local":
        q = sp.symbols("d2_0:3", real=True)
        ref = sp.symbols("ref_0:9", real=True)
        w = skew(q)
        return q, sp.Matrix(3, 3, ref) * (sp.eye(3) + w + w * w / 2), ref
    raise ValueError(f"unknown rotation parametrisation {rotation!r}; choose one of {ROTATIONS}")


#: Residual models: what one row of data says, and how many residual components it gives.


@functools.lru_cache(maxsize=None)
def calibration_residual(rotation, kind="centre"):
    """Symbolic residual of one row of data with its exact first and second derivatives.

    Parameters
    ----------
    rotation : {'euler', 'matrix', 'local'}
        Parametrisation of the sensor rotation R2.
    kind : {'centre', 'measurement', 'points'}
        * ``centre`` (seed 4-3): data ``xs`` (the centre measured in the sensor, 3);
          ``e = R1 (R2 xs + t2) + t1 - c`` (mm, base frame).
        * ``measurement``: data ``(xc, zc, r)``, the circle fitted to the profile in the laser
          plane; the model predicts the centre in the sensor, ``p = R2^T (R1^T (c - t1) - t2)``,
          and ``e = (p_x - xc, p_z - zc, (R^2 - p_y^2 - r^2) / (2 r))``. The third component is
          the radius error to first order (``sqrt(R^2 - p_y^2) - r``) but stays finite when
          ``|p_y| > R``; it depends on ``p_y^2`` only, so the side of the laser plane needs no
          sign. Extra input: the sphere radius R.
        * ``points``: data ``(x, z)``, one profile point in the laser plane (sensor y = 0);
          ``e = |R1 (R2 (x, 0, z) + t2) + t1 - c| - R`` (mm). Extra input: R.

    Returns
    -------
    dict
        ``theta``: the unknowns in order ``(t2 (3, mm), q (rotation), c (3, mm))``;
        ``data``: per-row inputs ``(R1 row-major (9), t1 (3, mm), <kind's data>)``;
        ``extra``: further scalar inputs (``Rref`` (9) for ``local``, then ``R`` for
        ``measurement`` and ``points``);
        ``e`` (m,), ``jac`` (m, n) and ``hess`` (list of m n x n matrices): residual and its
        derivatives with respect to ``theta``. For ``local`` they are evaluated at delta = 0.
    """
    if kind not in KINDS:
        raise ValueError(f"unknown residual kind {kind!r}; choose one of {tuple(KINDS)}")
    t2 = sp.symbols("tx2 ty2 tz2", real=True)
    q, r2, extra = _sensor_rotation(rotation)
    c = sp.symbols("cx cy cz", real=True)
    r1 = sp.symbols("r1_0:9", real=True)
    t1 = sp.symbols("tx1 ty1 tz1", real=True)
    theta = tuple(t2) + tuple(q) + tuple(c)
    rot1 = sp.Matrix(3, 3, r1)
    if kind == "centre":
        row = sp.symbols("xs ys zs", real=True)
        e = rot1 * (r2 * sp.Matrix(row) + sp.Matrix(t2)) + sp.Matrix(t1) - sp.Matrix(c)
    elif kind == "measurement":
        row = sp.symbols("xc zc rc", real=True)
        radius = sp.Symbol("R", positive=True)
        extra = tuple(extra) + (radius,)
        p = r2.T * (rot1.T * (sp.Matrix(c) - sp.Matrix(t1)) - sp.Matrix(t2))
        e = sp.Matrix([p[0] - row[0], p[2] - row[1], (radius**2 - p[1] ** 2 - row[2] ** 2) / (2 * row[2])])
    else:
        row = sp.symbols("xp zp", real=True)
        radius = sp.Symbol("R", positive=True)
        extra = tuple(extra) + (radius,)
        d = rot1 * (r2 * sp.Matrix([row[0], 0, row[1]]) + sp.Matrix(t2)) + sp.Matrix(t1) - sp.Matrix(c)
        e = sp.Matrix([sp.sqrt(d.dot(d)) - radius])
    jac = e.jacobian(theta)
    hess = [sp.hessian(e[k], theta) for k in range(e.shape[0])]
    if rotation == "local":
        at0 = {d: 0 for d in q}
        e, jac = e.xreplace(at0), jac.xreplace(at0)
        hess = [h.xreplace(at0) for h in hess]
    return {
        "theta": theta,
        "data": tuple(r1) + tuple(t1) + tuple(row),
        "extra": tuple(extra),
        "e": e,
        "jac": jac,
        "hess": hess,
    }


@functools.lru_cache(maxsize=None)
def axxb_linear(form="matrix"):
    """Kim & Cho's relative-motion equation ``A X = X B`` (seed 2-44) as linear ``D U = F``.

    ``X`` is the unknown sensor pose on the flange with ``U = (x11, x12, x13, x14, x21, ...,
    x34)`` its first three rows, row-major (seed Appendix A). With row-major vectorisation,
    ``vec(A X) = (A (x) I4) vec X`` and ``vec(X B) = (I3 (x) B^T) vec X`` (Kronecker products;
    Magnus & Neudecker), and the fourth row of ``X`` is the constant ``(0 0 0 1)``, so

    * ``form="matrix"`` (Appendix A, 12 equations): ``D = A33 (x) I4 - I3 (x) B^T`` and
      ``F = -(0, 0, 0, a14, 0, 0, 0, a24, 0, 0, 0, a34)``, from the first three rows of
      ``A X - X B = 0``. ``B = (X_S^P X_W^T)(X_S^Q X_W^T)^-1`` needs at least four non-coplanar
      points measured at both poses (Kim & Cho's cube corners).
    * ``form="point"`` (3 equations): ``A X p = X q`` for one point measured as ``p`` and ``q``
      (homogeneous, last entry 1) at the two poses: ``D = A33 (x) p^T - I3 (x) q^T``,
      ``F = -(a14, a24, a34)``. It is the matrix form multiplied by the point matrix, and what
      one sphere provides: every pair of samples of a fixed sphere is a motion pair.

    Returns
    -------
    dict
        ``a`` (12 symbols a11..a34), ``b`` (16 symbols b11..b44) or ``p``, ``q`` (3 symbols
        each), ``D`` (12 x 12 or 3 x 12), ``F`` (12 or 3), ``U`` (12 symbols u1..u12).
    """
    a = sp.Matrix(3, 4, sp.symbols("a11:15 a21:25 a31:35", real=True))
    a4 = a.col_join(sp.Matrix([[0, 0, 0, 1]]))
    u = sp.symbols("u1:13", real=True)
    out = {"a": tuple(a), "U": u}
    if form == "matrix":
        b = sp.Matrix(4, 4, sp.symbols("b11:15 b21:25 b31:35 b41:45", real=True))
        d = sp.kronecker_product(a4[:3, :3], sp.eye(4)) - sp.kronecker_product(sp.eye(3), b.T)
        f = -sp.Matrix([a4[i, 3] if j == 3 else 0 for i in range(3) for j in range(4)])
        out.update(b=tuple(b), D=d, F=f)
    elif form == "point":
        p = sp.Matrix(sp.symbols("p1:4", real=True))
        q = sp.Matrix(sp.symbols("q1:4", real=True))
        d = (sp.kronecker_product(a4[:3, :3], p.col_join(sp.Matrix([1])).T)
             - sp.kronecker_product(sp.eye(3), q.col_join(sp.Matrix([1])).T))
        out.update(p=tuple(p), q=tuple(q), D=d, F=-a4[:3, 3])
    else:
        raise ValueError(f"unknown AX = XB form {form!r} (matrix or point)")
    return out


def sphere_centre_from_plate():
    """Symbolic sphere centre ``c = T(p3) x_p'`` and its Jacobian with respect to ``p3``.

    This is the left-hand side of the seed's (4-1). Its 3x6 Jacobian has rank 3 at most:
    through the calibration model only ``c`` is observable, never the plate pose ``p3`` itself.

    Returns
    -------
    dict
        ``p3`` (6 symbols, mm and degrees), ``xp`` (3 symbols, mm, plate frame),
        ``c`` (3,) and ``jac`` (3, 6).
    """
    p3, t = pose_transform()
    xp = sp.symbols("xp yp zp", real=True)
    c = (t * sp.Matrix([*xp, 1]))[:3, 0]
    return {"p3": p3, "xp": xp, "c": c, "jac": c.jacobian(p3)}


@functools.lru_cache(maxsize=None)
def test_function():
    """The seed's test function (6-16) and its least-squares form.

    ``f(x) = -100 / q1 - 200 / q2`` with ``q1 = (x1-1)^2 + (x2-1)^2 + 1`` and
    ``q2 = (x1+1)^2 + (x2+2)^2 + 1``.

    Since ``300 - 100/q1 - 200/q2 = 100 (q1-1)/q1 + 200 (q2-1)/q2`` and
    ``(q1-1) = |x-a|^2``, ``(q2-1) = |x-b|^2``, the shifted function is exactly a sum of squares
    ``f + 300 = |r|^2`` with the 4-vector residual
    ``r(x) = [10 (x-a) / sqrt(q1) ; sqrt(200) (x-b) / sqrt(q2)]``, ``a = (1, 1)``,
    ``b = (-1, -2)``.

    Returns
    -------
    dict
        ``x`` (2 symbols), ``f``, ``grad`` (2,), ``hess`` (2, 2), ``r`` (4,), ``rjac`` (4, 2).
    """
    x1, x2 = sp.symbols("x1 x2", real=True)
    q1 = (x1 - 1) ** 2 + (x2 - 1) ** 2 + 1
    q2 = (x1 + 1) ** 2 + (x2 + 2) ** 2 + 1
    f = -100 / q1 - 200 / q2
    x = sp.Matrix([x1, x2])
    r = sp.Matrix(
        [
            10 * (x1 - 1) / sp.sqrt(q1),
            10 * (x2 - 1) / sp.sqrt(q1),
            sp.sqrt(200) * (x1 + 1) / sp.sqrt(q2),
            sp.sqrt(200) * (x2 + 2) / sp.sqrt(q2),
        ]
    )
    grad = sp.Matrix([f]).jacobian(x).T
    return {
        "x": (x1, x2),
        "f": f,
        "grad": grad,
        "hess": sp.hessian(f, x),
        "r": r,
        "rjac": r.jacobian(x),
    }


def _axis_rotation(direction, angle):
    """Rodrigues' rotation by ``angle`` (radians) about the unit ``direction`` (symbolic)."""
    w = skew(direction)
    return sp.cos(angle) * sp.eye(3) + sp.sin(angle) * w + (1 - sp.cos(angle)) * direction * direction.T


@functools.lru_cache(maxsize=None)
def cell_residual(n_axes):
    """Residual of the whole cell ``M_i X xs_i - P(th_i) c`` with positioner axes, and its Jacobian.

    The chain of :mod:`handeye.model.chain.mounts` with the positioner's axes as unknowns (product of
    exponentials): ``P(th) = A_1(th_1) ... A_k(th_k)``, ``A_j(th) x = R(d_j, th)(x - p_j) + p_j``.
    Every unknown is a local chart around a reference, evaluated at zero:

    * sensor ``X = (Xref_R exp([dr]x), Xref_t + dt)``: ``dt`` mm, ``dr`` rad (6);
    * sphere centre ``c`` in the table (or mount) frame, mm (3);
    * axis j: direction ``d_j = (d0_j + a_j e1_j + b_j e2_j) / |.|`` (``a, b`` rad: tilts about two
      directions normal to ``d0_j``) and point ``p_j = p0_j + u_j e1_j + v_j e2_j`` (mm: moves
      normal to the axis; a move along it changes no rotation and is no parameter) (4 each).

    Parameters
    ----------
    n_axes : int
        Positioner axes (0: no positioner, ``P = I``).

    Returns
    -------
    dict
        ``theta`` (6 + 3 + 4 k), ``extra`` (``Xref`` R row-major (9), t (3), then per axis p0, d0,
        e1, e2 (12)), ``data`` (``M`` R row-major (9), t (3), ``xs`` (3), angles (k, degrees)),
        ``e`` (3,), ``jac`` (3, n) at theta = 0.
    """
    dt = sp.Matrix(sp.symbols("dtx dty dtz", real=True))
    dr = sp.Matrix(sp.symbols("drx dry drz", real=True))
    c = sp.Matrix(sp.symbols("cx cy cz", real=True))
    xr = sp.symbols("xr_0:9", real=True)
    xt = sp.Matrix(sp.symbols("xt_0:3", real=True))
    m_r = sp.symbols("m_0:9", real=True)
    m_t = sp.Matrix(sp.symbols("mt_0:3", real=True))
    xs = sp.Matrix(sp.symbols("xs ys zs", real=True))
    w = skew(dr)
    sensor_point = sp.Matrix(3, 3, xr) * (sp.eye(3) + w + w * w / 2) * xs + xt + dt
    per_axis = {}  # axis j -> (its 4 unknowns, its 12 extra inputs, its angle), in the order j = 0, 1, ...
    point = c
    for j in reversed(range(n_axes)):  # A_1(A_2(c)): the last axis acts first
        a, b, u, v = sp.symbols(f"a{j} b{j} u{j} v{j}", real=True)
        p0, d0, e1, e2 = (sp.Matrix(sp.symbols(f"{k}{j}_0:3", real=True)) for k in ("p0_", "d0_", "e1_", "e2_"))
        th = sp.Symbol(f"th{j}", real=True)
        d = d0 + a * e1 + b * e2
        d = d / sp.sqrt(d.dot(d))
        p = p0 + u * e1 + v * e2
        point = _axis_rotation(d, th * sp.pi / 180) * (point - p) + p
        per_axis[j] = ([a, b, u, v], list(p0) + list(d0) + list(e1) + list(e2), th)
    order = [per_axis[j] for j in range(n_axes)]
    theta = list(dt) + list(dr) + list(c) + [s for unknowns, _, _ in order for s in unknowns]
    extra = list(xr) + list(xt) + [s for _, inputs, _ in order for s in inputs]
    angles = [th for _, _, th in order]
    e = sp.Matrix(3, 3, m_r) * sensor_point + m_t - point
    jac = e.jacobian(theta)
    at0 = {s: 0 for s in list(dt) + list(dr) + [s for s in theta[9:]]}
    return {"theta": tuple(theta), "extra": tuple(extra), "data": tuple(m_r) + tuple(m_t) + tuple(xs) + tuple(angles),
            "e": e.xreplace(at0), "jac": jac.xreplace(at0)}
