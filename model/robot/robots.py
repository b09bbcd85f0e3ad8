"""Nominal robot kinematics: joint angles to the flange pose the controller reports.

A model is a TOML file (``model/data/robots/NAME.toml`` built in, or the user's own) in one of
two formats, lengths in mm and angles in degrees:

``format = "chain"`` -- a URDF-like chain (ROS-Industrial's support packages give these for most
arms): per joint ``xyz`` and ``rpy`` of its origin in the previous link (URDF's fixed-axis roll,
pitch, yaw: ``R = Rz(yaw) Ry(pitch) Rx(roll)``) and its ``axis``; an optional ``base``
(the controller's base frame in the chain's) and ``flange`` (the flange in the last link)::

    T(q) = base . prod_j [Trans(xyz_j) R(rpy_j) Rot(axis_j, q_j)] . flange

``format = "dh"`` -- standard Denavit-Hartenberg ``d``, ``a``, ``alpha`` (and optional ``theta``
offsets), six each::

    T(q) = prod_j Rz(q_j + theta_j) Tz(d_j) Tx(a_j) Rx(alpha_j)

``coupling`` maps a joint to a linear combination of the reported angles (FANUC's J2/J3
linkage: ``j3 = { j3 = 1, j2 = 1 }``). Built in (each file names its source): ``kr60ha`` (KUKA
KR 60 HA, the thesis's), ``ur5e``, ``ur10e``, ``irb4600`` (ABB IRB 4600-60/2.05), ``m20ia``
(FANUC M-20iA).
"""
from __future__ import annotations

import dataclasses
import pathlib
import tomllib

import numpy as np

from handeye.model.chain.pose import kuka_from_matrix, matrix_from_kuka
from handeye.model.common.rotation import matrix_from_rotvec
from handeye.model.readers.tables import MAX_LINE_BYTES, PARSE_ERRORS, DatasetError, parse_problem
from handeye.model.robot import nominal_gate

ROBOTS_DIR = pathlib.Path(__file__).parent.parent / "data" / "robots"
#: Joint columns of measurements.csv (degrees).
JOINTS = ("j1", "j2", "j3", "j4", "j5", "j6")


def builtin_names():
    """Names of the built-in nominal models."""
    return sorted(p.stem for p in ROBOTS_DIR.glob("*.toml"))


@dataclasses.dataclass(frozen=True)
class RobotModel:
    """A nominal model (module docstring): name, source and the per-joint transforms.

    Attributes
    ----------
    name, source : str
    origins : ndarray, shape (6, 4, 4)
        Fixed transform before each joint (chain: ``Trans(xyz) R(rpy)``; DH: identity).
    axes : ndarray, shape (6, 3)
        Joint axes in their link (DH: z).
    after : ndarray, shape (6, 4, 4)
        Fixed transform after each joint's rotation (DH: ``Tz(d) Tx(a) Rx(alpha)``; chain: identity).
    offsets : ndarray, shape (6,)
        Angle offsets, degrees (DH ``theta``).
    base, flange : ndarray, shape (4, 4)
    coupling : ndarray, shape (6, 6)
        Joint angles of the chain = ``coupling @ reported angles``.
    spec : str
        How it was named: the built-in name, or the model file's absolute path.
    absorbed : str
        What the nominal-model gate absorbed into ``base`` and ``flange`` (a controller's calibrated
        model, a mounting offset: :mod:`handeye.model.robot.nominal_gate`), said; "" when nothing.
    """

    name: str
    source: str
    origins: np.ndarray
    axes: np.ndarray
    after: np.ndarray
    offsets: np.ndarray
    base: np.ndarray
    flange: np.ndarray
    coupling: np.ndarray
    spec: str = ""
    absorbed: str = ""

    def corrected(self, offsets_deg):
        """The model with zero offsets (degrees, on the chain's joints) added."""
        return dataclasses.replace(self, offsets=self.offsets + np.asarray(offsets_deg, float))

    def flange2base(self, joints_deg):
        """Forward kinematics: flange poses (N, 4, 4), mm, for joint angles (N, 6), degrees."""
        q = np.radians(np.asarray(joints_deg, float).reshape(-1, 6) @ self.coupling.T + self.offsets)
        out = np.broadcast_to(self.base, (len(q), 4, 4)).copy()
        for j in range(6):
            turn = np.broadcast_to(np.eye(4), (len(q), 4, 4)).copy()
            turn[:, :3, :3] = matrix_from_rotvec(self.axes[j][None, :] * q[:, j:j + 1])
            out = out @ self.origins[j] @ turn @ self.after[j]
        return out @ self.flange


def _transform(xyz, rpy_deg):
    roll, pitch, yaw = rpy_deg
    t = np.eye(4)
    t[:3, :3] = matrix_from_kuka(np.array([yaw, pitch, roll]))  # Rz(yaw) Ry(pitch) Rx(roll)
    t[:3, 3] = xyz
    return t


def _numbers(value, n, file, key):
    if not isinstance(value, list) or len(value) != n or not all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and np.isfinite(v) for v in value):
        raise DatasetError(file, f"needs a list of {n} finite numbers, got {str(value)[:60]!r}", column=key)
    return np.array(value, float)


def _chain(doc, file):
    joints = doc.get("joints")
    if not isinstance(joints, list) or len(joints) != 6 or not all(isinstance(j, dict) for j in joints):
        raise DatasetError(file, "needs six joints { name, xyz, rpy, axis }", column="joints")
    origins = np.array([_transform(_numbers(j.get("xyz"), 3, file, f"joints[{k}].xyz"),
                                   _numbers(j.get("rpy"), 3, file, f"joints[{k}].rpy")) for k, j in enumerate(joints)])
    axes = np.array([_numbers(j.get("axis"), 3, file, f"joints[{k}].axis") for k, j in enumerate(joints)])
    if np.any(np.abs(np.linalg.norm(axes, axis=1) - 1.0) > 1e-9):
        raise DatasetError(file, "every joint axis must be a unit vector", column="joints")
    return origins, axes, np.broadcast_to(np.eye(4), (6, 4, 4)).copy(), np.zeros(6)


def _dh(doc, file):
    d, a, alpha = (_numbers(doc.get(k), 6, file, k) for k in ("d", "a", "alpha"))
    theta = _numbers(doc.get("theta", [0] * 6), 6, file, "theta")
    after = np.array([_transform([0, 0, dj], [0, 0, 0]) @ _transform([aj, 0, 0], [al, 0, 0])
                      for dj, aj, al in zip(d, a, alpha)])
    return np.broadcast_to(np.eye(4), (6, 4, 4)).copy(), np.tile([0.0, 0.0, 1.0], (6, 1)), after, theta


def _frame(doc, key, file):
    value = doc.get(key, {"xyz": [0, 0, 0], "rpy": [0, 0, 0]})
    if not isinstance(value, dict):
        raise DatasetError(file, "needs { xyz, rpy }", column=key)
    return _transform(_numbers(value.get("xyz"), 3, file, f"{key}.xyz"), _numbers(value.get("rpy"), 3, file, f"{key}.rpy"))


def _coupling(doc, file):
    out = np.eye(6)
    for joint, terms in doc.get("coupling", {}).items():
        if joint not in JOINTS or not isinstance(terms, dict) or set(terms) - set(JOINTS):
            raise DatasetError(file, f"needs joint = {{ j.. = factor }} over {', '.join(JOINTS)}", column="coupling")
        out[JOINTS.index(joint)] = 0.0
        for name, factor in terms.items():
            out[JOINTS.index(joint), JOINTS.index(name)] = float(factor)
    return out


#: The keys a model file may have, by format (a typo is named, never silently a different robot).
KEYS = {"chain": {"joints", "base", "flange"}, "dh": {"d", "a", "alpha", "theta", "base", "flange"}}
COMMON_KEYS = {"name", "source", "format", "coupling"}


def _known_keys(doc, fmt, file):
    allowed = COMMON_KEYS | KEYS.get(fmt, set().union(*KEYS.values()))
    unknown = sorted(set(doc) - allowed)
    if unknown:
        raise DatasetError(file, f"unknown key {unknown[0]!r} (a {fmt or 'robot'} model has "
                                 f"{', '.join(sorted(allowed))})", column=unknown[0])
    for k, joint in enumerate(doc.get("joints") or []):
        extra = sorted(set(joint) - {"name", "xyz", "rpy", "axis"}) if isinstance(joint, dict) else []
        if extra:
            raise DatasetError(file, f"unknown key {extra[0]!r} in a joint (it has name, xyz, rpy, axis)",
                               column=f"joints[{k}]")


def load(name_or_file):
    """A :class:`RobotModel` by built-in name or TOML file; raises DatasetError naming the key."""
    path = pathlib.Path(str(name_or_file))
    file = ROBOTS_DIR / f"{name_or_file}.toml" if f"{name_or_file}" in builtin_names() else path
    if not file.is_file():
        raise DatasetError(path, f"no robot model of that name or file (built in: {', '.join(builtin_names())})",
                           column="[robot] model")
    try:
        if file.stat().st_size > MAX_LINE_BYTES:  # a model is a few kB: a large file is not read whole
            raise DatasetError(file, f"more than {MAX_LINE_BYTES // 2**20} MiB: not a robot model")
        doc = tomllib.loads(file.read_text(encoding="utf-8"))
    except OSError as exc:
        raise DatasetError(file, f"not a robot model: {exc}") from None
    except PARSE_ERRORS as exc:  # UnicodeDecodeError too
        raise DatasetError(file, f"not a robot model: {parse_problem(exc)}") from None
    fmt = doc.get("format")
    _known_keys(doc, fmt, file)
    if fmt not in ("chain", "dh"):
        raise DatasetError(file, f"format must be \"chain\" or \"dh\", got {fmt!r}", column="format")
    origins, axes, after, offsets = (_chain if fmt == "chain" else _dh)(doc, file)
    spec = str(name_or_file) if f"{name_or_file}" in builtin_names() else str(file.resolve())
    return RobotModel(str(doc.get("name", file.stem)), str(doc.get("source", "")), origins, axes, after, offsets,
                      _frame(doc, "base", file), _frame(doc, "flange", file), _coupling(doc, file), spec)


def check_reported(model, joints_deg, flange2base, file):
    """The model as the controller's: constant base and flange transforms against the reported flange
    poses absorbed and said, or DatasetError naming why the nominal forward kinematics does not
    reproduce them (angles in radians, a TCP, joint columns in another order or sign, another model):
    :func:`handeye.model.robot.nominal_gate.gated`; the other built-in models are tried on a refusal."""
    return nominal_gate.gated(model, joints_deg, flange2base, file,
                              others=lambda: [(name, load(name)) for name in builtin_names()])


def offset_derivatives(model, joints_deg, offsets_deg):
    """Flange poses with joint offsets and their exact derivatives (product rule of the chain,
    :func:`handeye.model.robot.robot_errors.perturbed`).

    Parameters
    ----------
    model : RobotModel
    joints_deg : array_like, shape (N, 6)
        Reported joint angles, degrees.
    offsets_deg : array_like, shape (6,)
        Zero offsets added to the chain's joint angles, degrees.

    Returns
    -------
    fk : ndarray, shape (N, 4, 4)
        ``T(q + offsets)``, mm.
    dfk : ndarray, shape (N, 6, 4, 4)
        ``dT / d offset_j`` per degree.
    """
    from handeye.model.robot.robot_errors import perturbed

    fk, d = perturbed(model, joints_deg, {"joint_offsets": np.asarray(offsets_deg, float)})
    return fk, d["joint_offsets"]


def chain_origins(model):
    """The model as a URDF-like chain: per joint the 4x4 origin in the previous link (its angle
    offset turned into the origin), and the flange in the last link; DH models converted."""
    origins, flange = [], model.flange
    carry = np.eye(4)
    for j in range(6):
        turn = np.eye(4)
        turn[:3, :3] = matrix_from_rotvec(model.axes[j] * np.radians(model.offsets[j]))
        origins.append(carry @ model.origins[j] @ turn)
        carry = model.after[j]
    return np.array(origins), carry @ flange


def _xyz_rpy(t):
    """``xyz`` (mm) and URDF ``rpy`` (deg: roll, pitch, yaw) of a 4x4."""
    a, b, c = kuka_from_matrix(t[:3, :3])  # Rz(A) Ry(B) Rx(C): yaw A, pitch B, roll C
    return t[:3, 3], np.array([c, b, a])


def _vec(v, digits=9):
    return "[" + ", ".join(f"{x:.{digits}f}".rstrip("0").rstrip(".") if "." in f"{x:.{digits}f}" else f"{x}"
                           for x in np.asarray(v, float)) + "]"


def to_toml(model, note=""):
    """The model as a ``format = "chain"`` TOML file (offsets folded into the joint origins)."""
    origins, flange = chain_origins(model)
    lines = [f"# {note}" if note else "# handeye robot model", f'name = "{model.name}"',
             f'source = "{model.source}"', 'format = "chain"']
    bx, br = _xyz_rpy(model.base)
    lines.append(f"base = {{ xyz = {_vec(bx)}, rpy = {_vec(br)} }}")
    coupled = {f"j{i + 1}": {f"j{k + 1}": float(model.coupling[i, k]) for k in range(6) if model.coupling[i, k]}
               for i in range(6) if not np.array_equal(model.coupling[i], np.eye(6)[i])}
    if coupled:
        inner = ", ".join(f"{j} = {{ " + ", ".join(f"{k} = {v:g}" for k, v in terms.items()) + " }"
                          for j, terms in coupled.items())
        lines.append(f"coupling = {{ {inner} }}")
    lines.append("joints = [")
    for j, t in enumerate(origins):
        xyz, rpy = _xyz_rpy(t)
        lines.append(f'  {{ name = "j{j + 1}", xyz = {_vec(xyz)}, rpy = {_vec(rpy)}, axis = {_vec(model.axes[j])} }},')
    fx, fr = _xyz_rpy(flange)
    lines += ["]", f"flange = {{ xyz = {_vec(fx)}, rpy = {_vec(fr)} }}"]
    return "\n".join(lines) + "\n"


def to_urdf(model, robot_name="robot"):
    """The model as a URDF (metres, radians): links ``base`` (the controller's base frame),
    ``base_link``, ``link_1``..``link_6``, ``tool0`` (the flange), joints ``joint_1``..``joint_6``
    with the (corrected) origins. A coupled joint (FANUC's J3) is the chain's joint: its URDF angle
    is the coupled combination of the controller's angles."""
    origins, flange = chain_origins(model)

    def origin(t):
        xyz, rpy = _xyz_rpy(t)
        return (f'<origin xyz="{" ".join(f"{v / 1000:.9f}" for v in xyz)}" '
                f'rpy="{" ".join(f"{np.radians(v):.12f}" for v in rpy)}"/>')

    lines = ['<?xml version="1.0"?>', f'<robot name="{robot_name}">', '  <link name="base"/>', '  <link name="base_link"/>']
    lines += [f'  <link name="link_{j}"/>' for j in range(1, 7)] + ['  <link name="tool0"/>']
    lines.append(f'  <joint name="base-base_link" type="fixed"><parent link="base"/><child link="base_link"/>'
                 f'{origin(model.base)}</joint>')
    parent = "base_link"
    for j, t in enumerate(origins, start=1):
        axis = " ".join(f"{v:g}" for v in model.axes[j - 1])
        lines.append(f'  <joint name="joint_{j}" type="revolute"><parent link="{parent}"/><child link="link_{j}"/>'
                     f'{origin(t)}<axis xyz="{axis}"/><limit effort="0" lower="-6.2832" upper="6.2832" velocity="1"/>'
                     '</joint>')
        parent = f"link_{j}"
    lines.append(f'  <joint name="link_6-tool0" type="fixed"><parent link="link_6"/><child link="tool0"/>'
                 f'{origin(flange)}</joint>')
    return "\n".join(lines + ["</robot>"]) + "\n"
