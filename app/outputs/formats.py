"""A calibration written for the robot controller, ROS 2 or URDF (``handeye export``).

Every format is computed from the one 4x4 ``sensor2flange`` (mm) through
:mod:`handeye.model.conventions`, never from another format's numbers:

==========  ==========================================================================
format      what is written (units)
==========  ==========================================================================
ur          URScript ``set_tcp(p[x, y, z, rx, ry, rz])``: metres, rotation vector (rad)
ros2        ``ros2 run tf2_ros static_transform_publisher --x .. --qw ..``: metres,
            quaternion in ROS order x, y, z, w
urdf        a fixed ``<joint>`` with ``<origin xyz=".." rpy=".."/>``: metres, URDF's
            fixed-axis roll, pitch, yaw (R = Rz(yaw) Ry(pitch) Rx(roll)), rad
kuka        ``TOOL_DATA[n]={X .., Y .., Z .., A .., B .., C ..}`` ($config.dat): mm, deg,
            Rz(A) Ry(B) Rx(C)
abb         RAPID ``PERS tooldata``: tframe ``[[x, y, z], [q1, q2, q3, q4]]``, mm,
            quaternion w, x, y, z
fanuc       UTOOL Direct Entry values and a TP program setting ``UTOOL[n]`` through a
            position register: mm, deg, W, P, R = fixed X, Y, Z
matrix      the 4x4 homogeneous transform, mm
json        all of the above as numbers, with the 1-sd and the covariance
==========  ==========================================================================

The 1-sd uncertainty of the calibration (translation in the flange frame, rotation about the
sensor's axes) is written as a comment in every text format. Numbers carry enough digits that
reading them back reproduces the 4x4 within 1e-6 mm and 1e-6 deg (tested with an independent
parser); a controller that stores 32-bit reals keeps about seven significant digits of them.
Near a format's singularity (KUKA B = +-90 deg, FANUC and URDF pitch = +-90 deg, a half turn
for UR's rotation vector) the angles are one valid choice among many; the transform they
make is the calibrated one.
"""
from __future__ import annotations

import re

import numpy as np

from handeye.app.choices import FORMATS  # noqa: F401 - the names, defined without numpy
from handeye.app.errors import RequestError
from handeye.model import conventions

#: Frame names: what ROS, URDF and the controllers accept as an identifier.
_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_/.-]{0,63}$")
_RAPID_NAME = re.compile(r"[^A-Za-z0-9_]")


def representations(sensor2flange):
    """The pose in every format's numbers: a dict of arrays (mm, deg, m, rad as named)."""
    t = np.asarray(sensor2flange, float)
    kuka = conventions.pose_from("kuka", t)
    fanuc = conventions.pose_from("fanuc", t)
    ur = conventions.pose_from("ur", t)
    abb = conventions.pose_from("abb", t)
    return {
        "translation_mm": t[:3, 3].copy(),
        "translation_m": t[:3, 3] / 1000.0,
        "kuka_abc_deg": kuka[3:],
        "fanuc_wpr_deg": fanuc[3:],
        "ur_rotvec_rad": ur[3:],
        "quaternion_wxyz": abb[3:],
        "quaternion_xyzw": np.r_[abb[4:], abb[3]],
        "rpy_rad": np.radians(fanuc[3:]),  # URDF: fixed-axis roll, pitch, yaw == FANUC's W, P, R
    }


def _check_name(option, name):
    if not _NAME.match(name):
        raise RequestError(f"{option} {name!r}: a frame name is letters, digits and _ / . - (at most 64), "
                           "starting with a letter or _")
    return name


def _sd_lines(calibration, unit="mm"):
    sd = calibration.sd()
    if sd is None:
        return ["1 sd: unknown (no covariance in the calibration)"]
    tr, rot = sd
    scale = 1e-3 if unit == "m" else 1.0
    trans = ", ".join(f"{v * scale:.3g}" for v in tr)
    return [f"1 sd: translation +-({trans}) {unit} along the flange's x, y, z;",
            f"      rotation +-({', '.join(f'{v:.3g}' for v in rot)}) deg about the sensor's x, y, z"]


def _one_line(text):
    """Text safe inside a one-line comment of any format: no control characters (a newline in a
    file name or a hand-edited dataset name would end the comment and start robot code)."""
    return re.sub(r"[\x00-\x1f\x7f]", " ", str(text))[:200]


def _header(calibration, what, unit="mm"):
    source = _one_line(calibration.source) + (f" (dataset {_one_line(calibration.dataset)})" if calibration.dataset
                                              else "")
    return [f"handeye: the sensor frame on the robot flange ({what})", f"from {source}"] + _sd_lines(calibration, unit)


def _comment(prefix, lines, suffix=""):
    return "\n".join(f"{prefix}{line}{suffix}" for line in lines)


def _f(values, digits):
    return [f"{v + 0.0:.{digits}f}".replace("-0." + "0" * digits, "0." + "0" * digits) for v in values]


def text(calibration, fmt, parent="flange", child="sensor", tool=1, register=99):
    """The calibration as ``fmt`` text (module docstring), ending with a newline.

    Parameters
    ----------
    calibration : handeye.app.outputs.saved.Calibration
    fmt : str
        One of :data:`FORMATS` except ``json`` (see :func:`data`).
    parent, child : str
        Frame names (ros2, urdf; the child names the ABB tooldata and the KUKA tool).
    tool : int
        Tool number (KUKA ``TOOL_DATA[tool]``, FANUC ``UTOOL[tool]``), 1..16 / 1..10.
    register : int
        FANUC position register the TP program writes (overwritten), 1..100.
    """
    if fmt not in FORMATS:
        raise RequestError(f"--format {fmt!r}: choose one of {', '.join(FORMATS)}")
    _check_name("--parent", parent)
    _check_name("--child", child)
    if fmt == "json":
        from handeye.app.present.jsonio import dumps

        return dumps(data(calibration, parent, child)) + "\n"
    rep = representations(calibration.sensor2flange)
    mm, m = rep["translation_mm"], rep["translation_m"]
    if fmt == "ur":
        values = ", ".join(_f(m, 10) + _f(rep["ur_rotvec_rad"], 10))
        head = _header(calibration, "URScript pose: x, y, z in metres, rotation vector rx, ry, rz in radians", "m")
        return _comment("# ", head) + f"\nset_tcp(p[{values}])\n"
    if fmt == "ros2":
        x, y, z = _f(m, 10)
        qx, qy, qz, qw = _f(rep["quaternion_xyzw"], 12)
        head = _header(calibration, f"tf2 static transform {parent} -> {child}: metres, quaternion x, y, z, w", "m")
        return (_comment("# ", head) + f"\nros2 run tf2_ros static_transform_publisher --x {x} --y {y} --z {z} "
                f"--qx {qx} --qy {qy} --qz {qz} --qw {qw} --frame-id {parent} --child-frame-id {child}\n")
    if fmt == "urdf":
        head = _header(calibration, "URDF fixed joint: xyz in metres, rpy = fixed-axis roll, pitch, yaw in radians",
                       "m")
        xyz, rpy = " ".join(_f(m, 10)), " ".join(_f(rep["rpy_rad"], 12))
        return ("<!--\n" + _comment("  ", [h.replace("--", "- -") for h in head]) + "\n-->\n"
                f'<joint name="{parent}_to_{child}" type="fixed">\n  <parent link="{parent}"/>\n'
                f'  <child link="{child}"/>\n  <origin xyz="{xyz}" rpy="{rpy}"/>\n</joint>\n')
    if fmt == "kuka":
        if not 1 <= tool <= 16:
            raise RequestError(f"--tool {tool}: a KUKA tool number is 1..16")
        if len(child) > 24 or '"' in child:
            raise RequestError(f"--child {child!r}: KUKA's TOOL_NAME holds at most 24 characters")
        x, y, z = _f(mm, 6)
        a, b, c = _f(rep["kuka_abc_deg"], 8)
        head = _header(calibration, f"KRL FRAME for $config.dat, TOOL_DATA[{tool}]: X, Y, Z mm, A, B, C deg "
                                    "(Rz(A) Ry(B) Rx(C))")
        return (_comment("; ", head) + f'\nTOOL_DATA[{tool}]={{X {x},Y {y},Z {z},A {a},B {b},C {c}}}\n'
                f'TOOL_NAME[{tool},]="{child[:24]}"\n')
    if fmt == "abb":
        name = "t" + child
        if _RAPID_NAME.search(child) or len(name) > 32:
            raise RequestError(f"--child {child!r}: the ABB tooldata is named t{child}, a RAPID identifier: letters, "
                               "digits and _, at most 32 characters")
        pos = ", ".join(_f(mm, 6))
        quat = ", ".join(_f(rep["quaternion_wxyz"], 12))
        head = _header(calibration, "RAPID tooldata, tframe: [x, y, z] mm, [q1, q2, q3, q4] = quaternion w, x, y, z")
        head += ["tload is load0's placeholder: set the sensor's mass (kg) and centre of gravity (LoadIdentify)"]
        return (_comment("! ", head) + f"\nPERS tooldata {name} := [TRUE, [[{pos}], [{quat}]], "
                "[0.001, [0, 0, 0.001], [1, 0, 0, 0], 0, 0, 0]];\n")
    if fmt == "fanuc":
        if not 1 <= tool <= 10:
            raise RequestError(f"--tool {tool}: a FANUC tool frame number is 1..10")
        if not 1 <= register <= 100:
            raise RequestError(f"--register {register}: a FANUC position register is 1..100")
        values = _f(mm, 6) + _f(rep["fanuc_wpr_deg"], 8)
        sd = calibration.sd()
        notes = ["handeye: sensor on flange", f"frame {child}"[:29], "UTOOL: X Y Z mm, W P R deg",
                 "Direct Entry: the PR values"]
        if sd is not None:  # a TP comment holds 32 characters: one number per line, rounded
            notes += [f"1sd {a} {v:.3g} mm" for a, v in zip("XYZ", sd[0])]
            notes += [f"1sd rot {a} {v:.3g} deg" for a, v in zip("xyz", sd[1])]
        prog = [f"! {n[:29]} ;" for n in notes]
        constants = [f"({v})" if v.startswith("-") else v for v in values]  # TP writes a negative constant (-1)
        prog += [f"PR[{register}]=LPOS-LPOS ;"] + [f"PR[{register},{k}]={v} ;" for k, v in enumerate(constants, 1)]
        prog += [f"UTOOL[{tool}]=PR[{register}] ;"]
        body = "\n".join(f"{k:4d}:  {line}" for k, line in enumerate(prog, 1))
        return (f"/PROG HANDEYE_UTOOL{tool}\n/ATTR\nCOMMENT = \"handeye sensor tool\";\n"
                f"/MN\n{body}\n/POS\n/END\n")
    rows = "\n".join(" ".join(_f(row, 10)) for row in calibration.sensor2flange)
    return _comment("# ", _header(calibration, "4x4 homogeneous transform, sensor -> flange, mm")) + "\n" + rows + "\n"


def data(calibration, parent="flange", child="sensor"):
    """Every format's numbers as one JSON-ready dict (``--format json``)."""
    rep = representations(calibration.sensor2flange)
    out = {"parent": parent, "child": child, "sensor_matrix": calibration.sensor2flange.tolist()}
    out.update({k: v.tolist() for k, v in rep.items()})
    out["calibration"] = calibration.to_dict()
    return out
