"""ABB RAPID modules (``.mod``) and URScript programs as flange poses (UR RTDE logs:
:mod:`handeye.app.ingest.controller_rtde`).

ABB: ``CONST|PERS|VAR robtarget name := [[x, y, z], [q1, q2, q3, q4], [cf...], [extax...]];``
(mm; a unit quaternion, w first: convention ``abb``), arrays ``name{n}`` included, and inline
targets of ``Move`` instructions. The order is that of the first ``MoveL``/``MoveJ``/``MoveC``
(and their ``DO``/``Sync``/``Trigg`` kin) to each target, else declaration order. Each target is
of the tool and work object of its first motion (``MoveL p10, v100, fine, tool1\\WObj:=wobj1;``):
``tool0`` and ``wobj0`` are the flange and the base; a ``tooldata`` declared in the module with
a zero TCP held by the robot (``[TRUE, [[0,0,0],[1,0,0,0]], ...]``) is the flange, a ``wobjdata`` with zero user
and object frames the base. ``MoveAbsJ`` (joint moves) and computed targets (``Offs``,
``RelTool``) are left out and named.

URScript: poses ``p[x, y, z, rx, ry, rz]`` (metres, a rotation vector in radians: convention
``ur``) assigned to variables (``global Waypoint_1_p=p[...]``), in lists
(``poses = [p[...], ...]``) or written in ``movel``/``movej``/``movep``/``movec``; the order is
that of the moves that reach them, else of the assignments. A ``set_tcp`` other than zero is a
TCP that is not the flange; without ``set_tcp`` the poses are of the installation's TCP, which
the script does not say (the summary says so).
"""
from __future__ import annotations

import dataclasses
import math
import re

import numpy as np

from handeye.app.ingest.controller_common import Point, Text, frames_checked, in_motion_order, number, poses_of

#: deepest RAPID aggregate read (a robtarget is 2 deep, a tooldata 3)
_MAX_DEPTH = 6
_RAPID_DECL = re.compile(r"\b(?:(?:LOCAL|TASK)\s+)*(?:CONST|PERS|VAR)\s+(robtarget|tooldata|wobjdata)\s+(\w+)"
                         r"\s*(\{[^}\n]*\})?\s*:=\s*(?=\[)", re.I)
_RAPID_MOVE = re.compile(r"\b(Move(?:L|J|C|AbsJ|ExtJ)\w*|Trigg[LJC]\w*|Search[LC]\w*)\b", re.I)
_SWITCH = re.compile(r"\\\s*(\w+)(?:\s*:=\s*([^\\]*))?")
_SCALAR = re.compile(r'\s*("[^"\n]*"|[^,\[\]"]*)')
_COMMENT = re.compile(r'"[^"\n]*"|!.*')


def read_abb(path, accept_frames=False):
    """The poses of an ABB RAPID module (module docstring); convention ``abb``."""
    src = Text(path)
    clean = _COMMENT.sub(lambda m: m.group(0) if m.group(0).startswith('"') else " " * len(m.group(0)), src.text)
    targets, tools, wobjs = _rapid_declarations(src, clean)
    moved, frames, notes = _rapid_moves(src, clean, targets)
    chosen, order_notes = in_motion_order(targets, moved, src, "targets")
    out = []
    for p in chosen:
        tool, wobj = frames.get(p.name.lower(), (None, None))
        tool_ok, wobj_ok = _tool_is_flange(tool, tools), _wobj_is_base(wobj, wobjs)
        out.append(Point(p.name, p.line, p.values, tool, wobj or "wobj0", tool_ok, wobj_ok, "tool", "wobj"))
    used = {q.tool for q in out} | {q.base for q in out}
    said = [f"{n} declared in the module as the flange (zero TCP)" for n in sorted(used, key=str)
            if n in tools and tools[n] and n.lower() != "tool0"]
    said += [f"{n} declared in the module as the base (zero frames)" for n in sorted(used, key=str)
             if n in wobjs and wobjs[n] and n.lower() != "wobj0"]
    notes = order_notes + notes + said + frames_checked(out, src, accept_frames, _abb_refusal)
    return poses_of(out, src, "ABB RAPID module (.mod)", "abb", notes)


def _aggregate(src, text, at, depth=0):
    """A RAPID aggregate ``[a, [b, c], "s"]`` at ``text[at] == '['`` as nested lists of text;
    ``(value, end)``. Linear; nesting beyond :data:`_MAX_DEPTH` or an unclosed bracket is refused."""
    if depth > _MAX_DEPTH:
        raise src.error(at, f"an aggregate nested deeper than {_MAX_DEPTH}")
    items, i = [], at + 1
    while True:
        while i < len(text) and text[i] in " \t\r\n":
            i += 1
        if i < len(text) and text[i] == "[":
            value, i = _aggregate(src, text, i, depth + 1)
        else:
            m = _SCALAR.match(text, i)
            value, i = m.group(1).strip(), m.end()
        items.append(value)
        while i < len(text) and text[i] in " \t\r\n":
            i += 1
        if i < len(text) and text[i] == ",":
            i += 1
        elif i < len(text) and text[i] == "]":
            return items, i + 1
        else:
            raise src.error(at, "an aggregate [...] that does not close")


def _numbers(src, at, items, count, name, field):
    if not isinstance(items, list) or len(items) != count or any(isinstance(v, list) for v in items):
        raise src.error(at, f"{name}: {field} must be [{count} numbers]", field)
    return [number(v, src, at, field) for v in items]


def _robtarget(src, at, value, name):
    """x, y, z (mm), q1..q4 (normalised) of a robtarget aggregate."""
    if not isinstance(value, list) or len(value) < 2:
        raise src.error(at, f"{name}: a robtarget is [[x,y,z],[q1,q2,q3,q4],[cf1,cf4,cf6,cfx],[extax]]", "trans")
    trans = _numbers(src, at, value[0], 3, name, "trans")
    rot = np.array(_numbers(src, at, value[1], 4, name, "rot"))
    norm = float(np.linalg.norm(rot))
    if abs(norm - 1.0) > 0.01:
        raise src.error(at, f"{name}: quaternion of norm {norm:.4g}, not a unit quaternion", "rot")
    return np.array(trans + list(rot / norm))


def _rapid_declarations(src, clean):
    """robtargets (name -> Point), tooldata and wobjdata (name -> True when the flange / base)."""
    targets, tools, wobjs = {}, {}, {}
    for m in _RAPID_DECL.finditer(clean):
        kind, name, dims = m.group(1).lower(), m.group(2), m.group(3)
        value, _ = _aggregate(src, clean, m.end())
        if kind == "robtarget":
            elements = value if dims else [value]
            for k, element in enumerate(elements, start=1):
                label = f"{name}{{{k}}}" if dims else name
                if label.lower() in targets:
                    raise src.error(m.start(), f"{label} declared twice", "robtarget")
                targets[label.lower()] = Point(label, src.line(m.start()), _robtarget(src, m.start(), element, label))
        elif kind == "tooldata":
            tools[name] = _is_zero_frame(value, 1) and str(value[0]).upper() == "TRUE"  # held by the robot
        else:
            wobjs[name] = (len(value) == 5 and str(value[0]).upper() == "FALSE" and value[2] in ('""', "")
                           and _is_zero_frame(value, 3) and _is_zero_frame(value, 4))
    return targets, tools, wobjs


def _is_zero_frame(value, index):
    """True when ``value[index]`` is the pose ``[[0, 0, 0], [1, 0, 0, 0]]``."""
    try:
        trans, rot = value[index]
        numbers = [float(v) for v in trans] + [float(v) for v in rot]
    except (TypeError, ValueError, IndexError):
        return False
    return len(numbers) == 7 and max(map(abs, numbers[:3])) < 1e-9 and abs(abs(numbers[3]) - 1) < 1e-9


def _split_args(text):
    """Top-level comma-separated arguments (brackets, parentheses and strings kept whole)."""
    out, depth, start, quoted = [], 0, 0, False
    for i, c in enumerate(text):
        if c == '"':
            quoted = not quoted
        elif not quoted and c in "[(":
            depth += 1
        elif not quoted and c in "])":
            depth -= 1
        elif not quoted and c == "," and depth == 0:
            out.append(text[start:i])
            start = i + 1
    return out + [text[start:]]


def _rapid_moves(src, clean, targets):
    """``(moved, frames, notes)``: the targets moved to in order, the (tool, wobj) of the first
    motion to each, what was left out. Inline targets are added to ``targets``."""
    moved, frames, skipped, joint_moves, at = [], {}, [], 0, 0
    while (m := _RAPID_MOVE.search(clean, at)) is not None:
        end = clean.find(";", m.end())
        if end < 0:
            raise src.error(m.start(), f"{m.group(1)} has no closing ';'")
        instruction, at = m.group(1), end + 1  # the next instruction after this one's ';': linear
        if instruction.lower().startswith(("moveabsj", "moveextj")):
            joint_moves += 1
            continue
        wobj, positional = None, []
        for arg in _split_args(clean[m.end():end]):
            for s in _SWITCH.finditer(arg):
                wobj = s.group(2).strip() if s.group(1).lower() == "wobj" and s.group(2) else wobj
            rest = _SWITCH.sub("", arg).strip()
            if rest:
                positional.append(rest)
        count = 2 if instruction.lower().startswith(("movec", "triggc", "searchc")) else 1
        if len(positional) < count + 1:
            raise src.error(m.start(), f"{instruction}: no target and tool", instruction)
        for target in positional[:count]:
            key = _target_key(src, m.start(), target, targets)
            if key is None:
                skipped.append(f"{target[:30]} (line {src.line(m.start())})")
                continue
            moved.append((key, m.start()))
            frames.setdefault(key.lower(), (positional[-1], wobj))
    notes = [f"left out, computed or undeclared targets: {', '.join(skipped[:6])}"
             + (" ..." if len(skipped) > 6 else "")] if skipped else []
    if joint_moves:
        notes.append(f"left out, {joint_moves} joint move{'s' if joint_moves > 1 else ''} (MoveAbsJ: no robtarget)")
    return moved, frames, notes


def _target_key(src, at, text, targets):
    """The key of a Move's target in ``targets`` (an inline aggregate added as ``line N``), or None."""
    if text.startswith("["):
        value, _ = _aggregate(src, text, 0)
        label = f"line {src.line(at)}"
        targets.setdefault(label.lower(), Point(label, src.line(at), _robtarget(src, at, value, label)))
        return label
    key = re.sub(r"\s+", "", text)
    return key if key.lower() in targets else None


def _tool_is_flange(tool, tools):
    return tool is not None and (tool.lower() == "tool0" or tools.get(tool, False))


def _wobj_is_base(wobj, wobjs):
    return wobj is None or wobj.lower() == "wobj0" or wobjs.get(wobj, False)


def _abb_refusal(point, which):
    if which == "tool":
        if point.tool is None:
            return f"{point.name} is moved to by no Move instruction: its tool is not named, not tool0"
        return f"{point.name} is of tool {point.tool} (not declared in this module with a zero TCP), not tool0"
    return f"{point.name} is in work object {point.base} (not declared here with zero frames), not wobj0"


# --- UR ---------------------------------------------------------------------------------------

_UR_COMMENT = re.compile(r'"[^"\n]*"|#.*')
_UR_POSE = re.compile(r"p\[([^\]\n]*)\]")
_UR_VAR = re.compile(r"^[ \t]*(?:global[ \t]+|local[ \t]+)?(\w+)[ \t]*=[ \t]*(p\[|\[[ \t\r\n]*p\[)", re.M)
_UR_MOVE = re.compile(r"\b(movel|movej|movep|movec)\s*\(")
#: positions beyond this (m) are no metres
_UR_METRES_MAX = 50.0


def _ur_pose(src, at, text, name):
    """x, y, z (mm) and the rotation vector (rad) of a ``p[...]`` body."""
    parts = text.split(",")
    if len(parts) != 6:
        raise src.error(at, f"{name}: p[...] holds {len(parts)} values; a pose has x, y, z, rx, ry, rz", "p")
    values = [number(v, src, at, f) for v, f in zip(parts, ("x", "y", "z", "rx", "ry", "rz"))]
    if max(map(abs, values[:3])) > _UR_METRES_MAX:
        raise src.error(at, f"{name}: a position of {max(map(abs, values[:3])):g}: URScript poses are metres", "x")
    if math.sqrt(sum(v * v for v in values[3:])) > 2 * math.pi + 1e-6:
        raise src.error(at, f"{name}: a rotation vector longer than 2 pi: URScript rotations are radians", "rx")
    return np.array([v * 1000.0 for v in values[:3]] + values[3:])


def read_urscript(path, accept_frames=False):
    """The poses of a URScript program (module docstring); convention ``ur``."""
    src = Text(path)
    clean = _UR_COMMENT.sub(lambda m: m.group(0) if m.group(0).startswith('"') else " " * len(m.group(0)), src.text)
    declared = {}
    for m in _UR_VAR.finditer(clean):
        name, listed = m.group(1), m.group(2).startswith("[")
        for k, (at, body) in enumerate(_ur_literals(src, clean, m.end() - 2, listed, name)):
            label = f"{name}[{k}]" if listed else name
            declared[label.lower()] = Point(label, src.line(at), _ur_pose(src, at, body, label))
    moved, notes = _ur_moves(src, clean, declared)
    points, order_notes = in_motion_order(declared, moved, src, "poses")
    joints = _ur_joints(src, clean, points)
    if joints is not None:
        notes.append("joint angles of each Waypoint_k_q rad -> deg")
    tcps = list(re.finditer(r"\bset_tcp\s*\(\s*p\[([^\]\n]*)\]", clean))
    if not tcps:
        notes.append("no set_tcp in the script: the poses are of the installation's TCP, the flange only if that "
                     "TCP is zero")
        tool, ok = "the installation's", True
    else:  # every set_tcp must be zero for the poses to be the flange's
        offsets = [_ur_pose(src, t.start(), t.group(1), "set_tcp") for t in tcps]
        tool = " and ".join(dict.fromkeys(f"p[{t.group(1).strip()}]" for t in tcps))
        ok = all(bool(np.all(np.abs(o) < 1e-9)) for o in offsets)
        notes += ["set_tcp zero: the poses are the flange's"] if ok else []
    points = [Point(p.name, p.line, p.values, tool, "base", ok, True, "set_tcp", "base") for p in points]
    notes = order_notes + notes + ["positions m -> mm (x1000)"] + frames_checked(
        points, src, accept_frames, lambda p, w: f"the script sets a TCP {p.tool} (set_tcp), not the flange")
    return dataclasses.replace(poses_of(points, src, "URScript program", "ur", notes), joints=joints)


def _ur_joints(src, clean, points):
    """Degrees of the ``name_q = [6 numbers]`` (radians) that Polyscope writes beside each
    ``name_p`` pose, when every pose has one; else None."""
    found = {m.group(1).lower(): (m.start(), m.group(2)) for m in re.finditer(
        r"^[ \t]*(?:global[ \t]+)?(\w+)_q[ \t]*=[ \t]*\[([^\]\n]*)\]", clean, re.M)}
    keys = [p.name.lower()[:-2] for p in points if p.name.lower().endswith("_p")]
    if not points or len(keys) < len(points) or any(k not in found for k in keys):
        return None
    out = []
    for key in keys:
        at, body = found[key]
        parts = body.split(",")
        if len(parts) != 6:
            raise src.error(at, f"{key}_q holds {len(parts)} joint angles, not 6", f"{key}_q")
        out.append([math.degrees(number(v, src, at, f"{key}_q")) for v in parts])
    return np.array(out)


def _ur_literals(src, clean, at, listed, name):
    """``(offset, body)`` of the ``p[...]`` at ``at`` (``listed``: of the list ``[p[...], ...]`` it starts)."""
    out = []
    while True:
        pm = _UR_POSE.match(clean, at)
        if pm is None:
            raise src.error(at, f"{name}: a p[...] that does not close", "p")
        out.append((pm.start(), pm.group(1)))
        at = pm.end()
        while listed and at < len(clean) and clean[at] in " \t\r\n":
            at += 1
        if not (listed and clean.startswith(",", at)):
            return out
        at += 1
        while at < len(clean) and clean[at] in " \t\r\n":
            at += 1


def _call_args(clean, start, limit=4000):
    """``(text, end)``: a call's arguments from ``start`` (after its ``(``) to the matching ``)``
    (at most ``limit`` characters), and where the scan ended."""
    depth = 0
    for i in range(start, min(len(clean), start + limit)):
        if clean[i] in "([":
            depth += 1
        elif clean[i] in ")]":
            if depth == 0:
                return clean[start:i], i
            depth -= 1
    return clean[start:start + limit], min(len(clean), start + limit)


def _ur_moves(src, clean, declared):
    """The declared poses moved to, in order (literal poses in moves added as ``line N``)."""
    moved, skipped, at = [], [], 0
    while (m := _UR_MOVE.search(clean, at)) is not None:
        args, at = _call_args(clean, m.end())
        for arg in _split_args(args)[:2 if m.group(1) == "movec" else 1]:
            arg = arg.strip()
            inner = re.match(r"get_inverse_kin\s*\(\s*(\w+)", arg)
            key = (inner.group(1) if inner else arg).lower()
            if arg.startswith("p["):
                label = f"line {src.line(m.start())}"
                declared[label.lower()] = Point(label, src.line(m.start()), _ur_pose(src, m.start(), arg[2:-1], label))
                moved.append((label, m.start()))
            elif key in declared:
                moved.append((key, m.start()))
            else:
                skipped.append(f"{m.group(1)}({arg[:24]}) (line {src.line(m.start())})")
    return moved, ([f"left out, joint or computed targets: {', '.join(skipped[:6])}"
                    + (" ..." if len(skipped) > 6 else "")] if skipped else [])
