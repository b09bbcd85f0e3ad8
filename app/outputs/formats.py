"""A calibration written for the robot controller, ROS 2 or URDF (``handeye export``).

Every format is computed from the one 4x4 sensor matrix (mm) through
:mod:`handeye.model.chain.conventions`, never from another format's numbers. The calibration's
``sensor_mount`` decides what is written: a sensor on the flange (``sensor2flange``) is a TOOL,
a sensor fixed in the cell (``"world"``: ``sensor2base``, the sensor frame in the robot base)
a BASE / user frame:

==========  ==========================================================================
format      what is written (units)
==========  ==========================================================================
ur          flange: URScript ``set_tcp(p[x, y, z, rx, ry, rz])``; world: a feature pose
            ``global sensor_frame = p[..]`` in the base (a point measured by the sensor is
            ``pose_trans(sensor_frame, p)``): metres, rotation vector (rad)
ros2        ``ros2 run tf2_ros static_transform_publisher --x .. --qw ..``: metres,
            quaternion in ROS order x, y, z, w; parent ``flange`` / world: ``base_link``
urdf        a fixed ``<joint>`` with ``<origin xyz=".." rpy=".."/>``: metres, URDF's
            fixed-axis roll, pitch, yaw (R = Rz(yaw) Ry(pitch) Rx(roll)), rad; parent link
            ``flange`` / world: ``base_link``
kuka        ``TOOL_DATA[n]={X .., Y .., Z .., A .., B .., C ..}`` / world:
            ``BASE_DATA[n]={..}`` ($config.dat, n = ``--tool`` / ``--base``): mm, deg,
            Rz(A) Ry(B) Rx(C)
abb         RAPID ``PERS tooldata``: tframe ``[[x, y, z], [q1, q2, q3, q4]]`` / world:
            ``PERS wobjdata`` with that uframe (robhold FALSE, ufprog TRUE, ufmec "",
            oframe identity): mm, quaternion w, x, y, z
fanuc       UTOOL / world: UFRAME Direct Entry values and a TP program setting
            ``UTOOL[n]`` / ``UFRAME[n]`` through a position register: mm, deg,
            W, P, R = fixed X, Y, Z
matrix      the 4x4 homogeneous transform, mm
json        all of the above as numbers, with the 1-sd and the covariance (world: with
            ``"sensor_mount": "world"``)
==========  ==========================================================================

The 1-sd uncertainty of the calibration (translation in the flange / base frame, rotation
about the sensor's axes) is written as a comment in every text format. Numbers carry enough
digits that reading them back reproduces the 4x4 within 1e-6 mm and 1e-6 deg (tested with an
independent parser); a controller that stores 32-bit reals keeps about seven significant digits
of them. Near a format's singularity (KUKA B = +-90 deg, FANUC and URDF pitch = +-90 deg, a
half turn for UR's rotation vector) the angles are one valid choice among many; the transform
they make is the calibrated one. KUKA's BASE_DATA, ABB's uframe and FANUC's UFRAME are given in
the controller's world frame: the robot base as long as that is the world (the default).
"""
from __future__ import annotations

import dataclasses
import re
import textwrap

import numpy as np

from handeye.app.common.choices import FORMATS  # noqa: F401 - the names, defined without numpy
from handeye.app.common.jsonio import dumps
from handeye.model.chain import conventions

#: Default parent frame (ros2, urdf) by sensor mount.
DEFAULT_PARENT = {"flange": "flange", "world": "base_link"}


@dataclasses.dataclass(frozen=True)
class Names:
    """What an export names and numbers (checked for its format by
    :class:`handeye.app.outputs.request.ExportRequest`).

    Attributes
    ----------
    parent, child : str
        Frame names (ros2, urdf; the child names the ABB tooldata / wobjdata, the KUKA tool /
        base and the UR variable). ``parent`` None: ``flange``, or ``base_link`` (world).
    number : int
        Tool number of a sensor on the flange (KUKA ``TOOL_DATA[n]``, FANUC ``UTOOL[n]``), or
        base / user frame number of one fixed in the cell (KUKA ``BASE_DATA[n]``, FANUC ``UFRAME[n]``).
    register : int
        FANUC position register the TP program writes (overwritten).
    """

    parent: str | None = None
    child: str = "sensor"
    number: int = 1
    register: int = 99


def representations(sensor2flange):
    """The pose in every format's numbers: a dict of arrays (mm, deg, m, rad as named).

    Parameters
    ----------
    sensor2flange : array_like, shape (4, 4)
        The sensor frame in its mount's frame (flange or robot base), mm.
    """
    t = np.asarray(sensor2flange, float)
    fanuc, abb = conventions.pose_from("fanuc", t), conventions.pose_from("abb", t)
    return {
        "translation_mm": t[:3, 3].copy(),
        "translation_m": t[:3, 3] / 1000.0,
        "kuka_abc_deg": conventions.pose_from("kuka", t)[3:],
        "fanuc_wpr_deg": fanuc[3:],
        "ur_rotvec_rad": conventions.pose_from("ur", t)[3:],
        "quaternion_wxyz": abb[3:],
        "quaternion_xyzw": np.r_[abb[4:], abb[3]],
        "rpy_rad": np.radians(fanuc[3:]),  # URDF: fixed-axis roll, pitch, yaw == FANUC's W, P, R
    }


def _sd_lines(calibration, unit="mm"):
    sd = calibration.sd()
    if sd is None:
        return ["1 sd: unknown (no covariance in the calibration)"]
    tr, rot = sd
    scale = 1e-3 if unit == "m" else 1.0
    trans = ", ".join(f"{v * scale:.3g}" for v in tr)
    return [f"1 sd: translation +-({trans}) {unit} along the {calibration.frame}'s x, y, z;",
            f"      rotation +-({', '.join(f'{v:.3g}' for v in rot)}) deg about the sensor's x, y, z"]


def _world(calibration):
    return getattr(calibration, "sensor_mount", "flange") == "world"


def one_line(text, limit=200):
    """Text safe inside a one-line comment of any format: no control characters (a newline in a
    file name or a hand-edited dataset name would end the comment and start robot code), at most
    ``limit`` characters."""
    return re.sub(r"[\x00-\x1f\x7f]", " ", str(text))[:limit]


#: A verdict line in a comment holds at most this many characters (the status and the shortened
#: warnings of :mod:`handeye.app.outputs.verdict` fit; a FANUC TP comment line holds 29).
VERDICT_CHARS = 240
#: FANUC TP comments: 29 characters a line; a verdict line is wrapped over at most this many.
FANUC_LINES_PER_NOTE = 3


def _verdict_parts(lines):
    """The verdict's comment lines (:func:`handeye.app.outputs.verdict.comment_lines`): the
    ``FORCED`` line, which goes first, and the others, after the header."""
    first = [one_line(line, VERDICT_CHARS) for line in lines if line.startswith("FORCED")]
    return first, [line for line in lines if not line.startswith("FORCED")]


def _comment(prefix, lines, suffix=""):
    return "\n".join(f"{prefix}{line}{suffix}" for line in lines)


def _f(values, digits):
    return [f"{v + 0.0:.{digits}f}".replace("-0." + "0" * digits, "0." + "0" * digits) for v in values]


@dataclasses.dataclass(frozen=True)
class _Job:
    """One export: the calibration, its numbers and its :class:`Names` (the parent resolved)."""

    calibration: object
    rep: dict
    names: Names
    verdict: tuple = ()

    @property
    def world(self):
        return _world(self.calibration)

    def header(self, what, unit="mm"):
        cal = self.calibration
        source = one_line(cal.source) + (f" (dataset {one_line(cal.dataset)})" if cal.dataset else "")
        where = "in the robot base, fixed in the cell" if self.world else "on the robot flange"
        first, rest = _verdict_parts(self.verdict)
        return (first + [f"handeye: the sensor frame {where} ({what})", f"from {source}"] + _sd_lines(cal, unit)
                + [one_line(line, VERDICT_CHARS) for line in rest])


def _ur(job):
    values = ", ".join(_f(job.rep["translation_m"], 10) + _f(job.rep["ur_rotvec_rad"], 10))
    head = job.header("URScript pose: x, y, z in metres, rotation vector rx, ry, rz in radians", "m")
    if not job.world:
        return _comment("# ", head) + f"\nset_tcp(p[{values}])\n"
    name = f"{job.names.child}_frame"
    head += ["a feature pose in the robot base, not a TCP (set_tcp is for a sensor on the flange): a point",
             f"(x, y, z) in the sensor frame (metres) is pose_trans({name}, p[x, y, z, 0, 0, 0]) in the base;",
             f"pose_inv({name}) takes base poses into the sensor frame"]
    return _comment("# ", head) + f"\nglobal {name} = p[{values}]\n"


def _ros2(job):
    parent, child = job.names.parent, job.names.child
    x, y, z = _f(job.rep["translation_m"], 10)
    qx, qy, qz, qw = _f(job.rep["quaternion_xyzw"], 12)
    head = job.header(f"tf2 static transform {parent} -> {child}: metres, quaternion x, y, z, w", "m")
    return (_comment("# ", head) + f"\nros2 run tf2_ros static_transform_publisher --x {x} --y {y} --z {z} "
            f"--qx {qx} --qy {qy} --qz {qz} --qw {qw} --frame-id {parent} --child-frame-id {child}\n")


def _urdf(job):
    parent, child = job.names.parent, job.names.child
    head = job.header("URDF fixed joint: xyz in metres, rpy = fixed-axis roll, pitch, yaw in radians", "m")
    xyz, rpy = " ".join(_f(job.rep["translation_m"], 10)), " ".join(_f(job.rep["rpy_rad"], 12))
    return ("<!--\n" + _comment("  ", [h.replace("--", "- -") for h in head]) + "\n-->\n"
            f'<joint name="{parent}_to_{child}" type="fixed">\n  <parent link="{parent}"/>\n'
            f'  <child link="{child}"/>\n  <origin xyz="{xyz}" rpy="{rpy}"/>\n</joint>\n')


def _kuka(job):
    n, child = job.names.number, job.names.child
    kind = "BASE" if job.world else "TOOL"
    x, y, z = _f(job.rep["translation_mm"], 6)
    a, b, c = _f(job.rep["kuka_abc_deg"], 8)
    head = job.header(f"KRL FRAME for $config.dat, {kind}_DATA[{n}]: X, Y, Z mm, A, B, C deg (Rz(A) Ry(B) Rx(C))")
    if job.world:
        head += ["BASE_DATA is given in $WORLD: the robot base while $ROBROOT is the null frame (the default)"]
    return (_comment("; ", head) + f'\n{kind}_DATA[{n}]={{X {x},Y {y},Z {z},A {a},B {b},C {c}}}\n'
            f'{kind}_NAME[{n},]="{child[:24]}"\n')


def _abb(job):
    child = job.names.child
    name = f"wobj_{child}" if job.world else "t" + child
    frame = f"[[{', '.join(_f(job.rep['translation_mm'], 6))}], [{', '.join(_f(job.rep['quaternion_wxyz'], 12))}]]"
    if job.world:
        head = job.header("RAPID wobjdata, uframe: [x, y, z] mm, [q1, q2, q3, q4] = quaternion w, x, y, z")
        head += ["a fixed user frame (robhold FALSE, ufprog TRUE, oframe identity) in the world frame: the robot",
                 "base while the base frame is the world (the default)"]
        return (_comment("! ", head) + f'\nPERS wobjdata {name} := [FALSE, TRUE, "", {frame}, '
                "[[0, 0, 0], [1, 0, 0, 0]]];\n")
    head = job.header("RAPID tooldata, tframe: [x, y, z] mm, [q1, q2, q3, q4] = quaternion w, x, y, z")
    head += ["tload is load0's placeholder: set the sensor's mass (kg) and centre of gravity (LoadIdentify)"]
    return (_comment("! ", head) + f"\nPERS tooldata {name} := [TRUE, {frame}, "
            "[0.001, [0, 0, 0.001], [1, 0, 0, 0], 0, 0, 0]];\n")


def _fanuc(job):
    n, register = job.names.number, job.names.register
    kind = "UFRAME" if job.world else "UTOOL"
    values = _f(job.rep["translation_mm"], 6) + _f(job.rep["fanuc_wpr_deg"], 8)
    sd = job.calibration.sd()
    where = "fixed in cell" if job.world else "on flange"
    first, rest = _verdict_parts(job.verdict)
    notes = [*_wrapped(first), f"handeye: sensor {where}", f"frame {job.names.child}"[:29], f"{kind}: X Y Z mm, W P R deg",
             "Direct Entry: the PR values"]
    if sd is not None:  # a TP comment holds 32 characters: one number per line, rounded
        notes += [f"1sd {a} {v:.3g} mm" for a, v in zip("XYZ", sd[0])]
        notes += [f"1sd rot {a} {v:.3g} deg" for a, v in zip("xyz", sd[1])]
    notes += _wrapped(rest)
    prog = [f"! {note[:29]} ;" for note in notes]
    constants = [f"({v})" if v.startswith("-") else v for v in values]  # TP writes a negative constant (-1)
    prog += [f"PR[{register}]=LPOS-LPOS ;"] + [f"PR[{register},{k}]={v} ;" for k, v in enumerate(constants, 1)]
    prog += [f"{kind}[{n}]=PR[{register}] ;"]
    body = "\n".join(f"{k:4d}:  {line}" for k, line in enumerate(prog, 1))
    title = "handeye sensor frame" if job.world else "handeye sensor tool"
    return f"/PROG HANDEYE_{kind}{n}\n/ATTR\nCOMMENT = \"{title}\";\n/MN\n{body}\n/POS\n/END\n"


def _wrapped(lines):
    """Verdict lines as FANUC TP comments: each wrapped at 29 characters over at most
    :data:`FANUC_LINES_PER_NOTE` lines (``..`` where cut); ``;`` and ``!`` out (TP syntax)."""
    out = []
    for line in lines:
        parts = textwrap.wrap(one_line(line).replace(";", ",").replace("!", "."), 29) or [""]
        cut = len(parts) > FANUC_LINES_PER_NOTE
        parts = parts[:FANUC_LINES_PER_NOTE]
        out += parts[:-1] + [parts[-1][:26] + " .." if cut else parts[-1]]
    return out


def _matrix(job):
    rows = "\n".join(" ".join(_f(row, 10)) for row in job.calibration.sensor2flange)
    head = job.header(f"4x4 homogeneous transform, sensor -> {job.calibration.frame}, mm")
    return _comment("# ", head) + "\n" + rows + "\n"


_WRITERS = {"ur": _ur, "ros2": _ros2, "urdf": _urdf, "kuka": _kuka, "abb": _abb, "fanuc": _fanuc, "matrix": _matrix}


def text(calibration, fmt, names=Names(), verdict=()):
    """The calibration as ``fmt`` text (module docstring), ending with a newline.

    Parameters
    ----------
    calibration : handeye.app.outputs.saved.Calibration
        Its ``sensor_mount`` chooses a tool (flange) or a base / user frame (world); written in the
        user's frame (the sensor's own when the profiles were turned: ``Calibration.user_frame``).
    fmt : str
        One of :data:`FORMATS`.
    names : Names
        The frame names, the tool or base number and the FANUC register (default: ``sensor`` on
        the mount's parent, number 1, register 99).
    verdict : sequence of str
        The calibration's verdict and failed checks, one comment line each
        (:func:`handeye.app.outputs.verdict.comment_lines`; a ``FORCED`` line is the first comment
        line); JSON: the key ``verdict``.
    """
    parent = DEFAULT_PARENT[calibration.sensor_mount] if names.parent is None else names.parent
    if fmt == "json":
        out = data(calibration, parent, names.child)
        return dumps({**out, "verdict": list(verdict)} if verdict else out) + "\n"
    user = calibration.user_frame()
    job = _Job(user, representations(user.sensor2flange), dataclasses.replace(names, parent=parent), tuple(verdict))
    return _WRITERS[fmt](job)


def data(calibration, parent, child):
    """Every format's numbers as one JSON-ready dict (``--format json``) of the user's frame (``own_axes``
    and ``sensor_frame`` "own" when that is the sensor's own), with the frame names; a sensor fixed in the
    cell adds ``"sensor_mount": "world"`` (the matrix is then sensor2base)."""
    matrix = calibration.user_frame().sensor2flange
    mount = {"sensor_mount": "world"} if _world(calibration) else {}
    own = {} if calibration.own_axes is None else {"sensor_frame": "own", "own_axes": np.asarray(calibration.own_axes).tolist()}
    out = {**mount, **own, "parent": parent, "child": child, "sensor_matrix": matrix.tolist()}
    out.update({k: v.tolist() for k, v in representations(matrix).items()})
    out["calibration"] = calibration.to_dict()
    return out
