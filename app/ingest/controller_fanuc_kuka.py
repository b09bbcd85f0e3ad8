"""FANUC TP programs (``.ls``) and KUKA programs (``.src`` / ``.dat``) as flange poses.

FANUC: each ``P[n]{ GP1: UF : u, UT : t, CONFIG : '...', X = ... mm, Y, Z, W = ... deg, P, R };``
of the ``/POS`` section; W, P, R are fixed-axis X-Y-Z rotations, ``R = Rz(R) Ry(P) Rx(W)``
(convention ``fanuc``). ``CONFIG`` (``KONFIG`` in a German export) ``'N U T, 0, 0, 0'`` is the
arm configuration: the wrist no-flip or flip (``N``: J5 < 0, ``F``: J5 > 0), the elbow up or down,
the wrist centre in front of axis 1 (top, ``T``) or behind it (``B``), then the turn numbers of
J4, J5, J6. It is kept as ABB's ``cfx`` (bit 0 ``N``, bit 1 ``D``, bit 2 ``B``), the dataset's
configuration column (:mod:`handeye.model.robot.configuration`); any other form is refused
naming its line. The order is that of the positions' first use in ``/MN`` (``/POS``
order when ``/MN`` uses none). A position in joint form (``J1 = ... deg``) is refused; other
motion groups (``GP2``...) and extended axes (``E1``) are not read and said not to be.

KUKA: ``DECL E6POS|POS|FRAME name={X, Y, Z, A, B, C, ...}`` of the ``.dat``; A, B, C give
``R = Rz(A) Ry(B) Rx(C)`` (convention ``kuka``). The order is that of the ``PTP``/``LIN``/
``CIRC`` (and spline ``S...``) motions of the ``.src`` when it is there, else declaration
order. Each point's tool and base come from its ``FDAT`` (``FDAT_ACT=FP1`` in the fold, or the
``.dat``'s ``DECL FDAT FP1={TOOL_NO t,BASE_NO b,...}``), else the fold's ``Tool[t] Base[b]``,
else the last ``BAS(#TOOL,t)`` / ``$TOOL=TOOL_DATA[t]`` before the motion. ``E6AXIS``/``AXIS``
points moved to are refused (joint form); motions to points the ``.dat`` does not declare
(``XHOME`` of ``$config.dat``) are left out and named.
"""
from __future__ import annotations

import dataclasses
import pathlib
import re

import numpy as np

from handeye.app.ingest.controller_common import Point, Text, frames_checked, in_motion_order, number, poses_of

_FANUC_FIELDS = ("X", "Y", "Z", "W", "P", "R")
_FIELD = re.compile(r"\b([A-Z]+\d?)\s*(=|:)\s*([^\s,;']+)\s*(mm|deg)?", re.I)
_P_START = re.compile(r"\bP\[\s*([^\]\n]*)\]\s*\{")
_MN_USE = re.compile(r"\bP\[\s*(\d{1,9})\s*(?::[^\]\n]*)?\]")
_CONFIG_KEY = re.compile(r"\b(CONFIG|KONFIG)\s*:\s*(?:'([^'\n]*)')?", re.I)
_CONFIG = re.compile(r"\s*([NF])\s*([UD])\s*([TB])\s*,\s*([+-]?\d)\s*,\s*([+-]?\d)\s*,\s*([+-]?\d)\s*")


def read_fanuc(path, accept_frames=False):
    """The poses of a FANUC ``.ls`` program (module docstring); a
    :class:`~handeye.app.ingest.controllers.ControllerPoses` in convention ``fanuc``."""
    src = Text(path)
    text = src.text
    pos_at = text.find("/POS")
    if pos_at < 0:
        raise src.error(0, "no /POS section: not a FANUC TP program with positions (export it as .ls)")
    end = text.find("/END", pos_at)
    declared, notes = {}, []
    for block_at, name, body in _fanuc_blocks(src, pos_at, len(text) if end < 0 else end):
        point, more = _fanuc_point(src, block_at, name, body)
        if point.name.lower() in declared:
            raise src.error(block_at, f"{name} declared twice (first on line {declared[point.name.lower()].line})", "P")
        declared[point.name.lower()] = point
        notes += [n for n in more if n not in notes]
    mn_at = text.find("/MN")
    mn = text[mn_at:pos_at] if 0 <= mn_at < pos_at else ""
    moved = [(f"P{int(m.group(1))}", m.start()) for m in _MN_USE.finditer(mn)]
    untaught = sorted({n for n, _ in moved if n.lower() not in declared}, key=lambda n: int(n[1:]))
    if untaught:
        notes.append(f"motions to positions not in /POS left out: {', '.join(untaught[:6])}")
    moved = [(n, o) for n, o in moved if n.lower() in declared]
    points, order_notes = in_motion_order(declared, moved, src, "positions")
    if re.search(r"\bPR\[", mn):
        notes.append("motions to position registers PR[...] left out (their values are not in the program)")
    notes = order_notes + notes + frames_checked(points, src, accept_frames, _fanuc_refusal)
    return poses_of(points, src, "FANUC TP program (.ls)", "fanuc", notes)


def _fanuc_blocks(src, start, stop):
    """``(offset, name, body)`` of every ``P[n]{...};`` between ``start`` and ``stop`` (linear)."""
    at = start
    while True:
        m = _P_START.search(src.text, at, stop)
        if m is None:
            return
        close = src.text.find("};", m.end(), stop)
        if close < 0:
            raise src.error(m.start(), f"P[{m.group(1)}] has no closing '}};'")
        label = m.group(1).split(":")[0].strip()
        if not (label.isdigit() and len(label) <= 9):
            raise src.error(m.start(), f"P[{m.group(1)[:20]}]: not a position number", "P")
        yield m.start(), f"P{int(label)}", src.text[m.end():close]
        at = close + 2


def _fanuc_point(src, at, name, body):
    """One position's GP1 group as a :class:`Point` (fields named on error) and its notes."""
    offset = src.text.find("{", at) + 1
    groups = [(m.start(), m.end(), m.group(1)) for m in re.finditer(r"\bGP(\d+)\s*:", body)]
    if not groups or groups[0][2] != "1":
        raise src.error(at, f"{name}: no GP1 group (the robot's position)", "GP1")
    gp1 = body[groups[0][1]:groups[1][0] if len(groups) > 1 else len(body)]
    fields = {}
    for m in _FIELD.finditer(gp1):
        fields.setdefault(m.group(1).upper(), (m.group(3), m.group(4), offset + groups[0][1] + m.start()))
    notes = ["motion groups GP2.. (positioners, rails) not read"] if len(groups) > 1 else []
    if "J1" in fields and "X" not in fields:
        raise src.error(fields["J1"][2], f"{name} is in joint form (J1..J6): no flange pose in the program; "
                                         "record it as a Cartesian position (X, Y, Z, W, P, R) or leave it out", "J1")
    values = []
    for field in _FANUC_FIELDS:
        if field not in fields:
            raise src.error(at, f"{name}: no {field} (a Cartesian position has X, Y, Z in mm and W, P, R in deg)",
                            field)
        token, unit, where = fields[field]
        want = "mm" if field in "XYZ" else "deg"
        if (unit or "").lower() != want:
            raise src.error(where, f"{name}: {field} in {unit or 'no unit'!r}, expected {want}", field)
        values.append(number(token, src, where, field))
    if any(k.startswith("E") and k[1:].isdigit() for k in fields):
        notes.append("extended axes E1.. of GP1 not read (the pose is the robot's)")
    tool, base = (_frame_number(src, fields, k, name) for k in ("UT", "UF"))
    frame_line = src.line(fields["UT"][2]) if "UT" in fields else None
    config, cfx = _fanuc_config(src, gp1, offset + groups[0][1], name)
    return Point(name, src.line(at), np.array(values), tool, base, tool == 0, base == 0, "UT", "UF", frame_line,
                 config, cfx), notes


def _fanuc_config(src, gp1, offset, name):
    """``(text, cfx)`` of a position's ``CONFIG : 'N U T, 0, 0, 0'`` (module docstring; ``offset``: of
    ``gp1`` in the file), ``(None, None)`` without one; any other form a DatasetError naming its line."""
    m = _CONFIG_KEY.search(gp1)
    if m is None:
        return None, None
    key, value = m.group(1).upper(), m.group(2)
    form = _CONFIG.fullmatch(value) if value is not None else None
    if form is None:
        shown = "no quoted value" if value is None else repr(value[:40])
        raise src.error(offset + m.start(), f"{name}: {key} {shown} is not a FANUC arm configuration ('N U T, 0, 0, 0': "
                                            "N or F, U or D, T or B, and the turn numbers of J4, J5, J6)", key)
    wrist, elbow, base, *turns = form.groups()
    text = f"{wrist} {elbow} {base}, {', '.join(str(int(t)) for t in turns)}"
    return text, (wrist == "N") + 2 * (elbow == "D") + 4 * (base == "B")


def _frame_number(src, fields, key, name):
    if key not in fields:
        return None
    token, _, where = fields[key]
    if not (token.isdigit() and len(token) <= 9):
        raise src.error(where, f"{name}: {key} {token[:20]!r} is not a frame number", key)
    return int(token)


def _fanuc_refusal(point, which):
    if which == "tool":
        what = "names no tool frame (UT)" if point.tool is None else f"is of tool frame UT {point.tool}"
        return f"{point.name} {what}, not the flange (UT 0)"
    what = "names no user frame (UF)" if point.base is None else f"is in user frame UF {point.base}"
    return f"{point.name} {what}, not the robot's world frame (UF 0)"


# --- KUKA -----------------------------------------------------------------------------------

_KRL_DECL = re.compile(r"^[ \t]*(?:DECL[ \t]+)?(?:GLOBAL[ \t]+)?(E6POS|POS|FRAME|E6AXIS|AXIS|FDAT)[ \t]+(\w+)"
                       r"[ \t]*=[ \t]*(\{[^}\n]*\}?)", re.M | re.I)
_KRL_MOVE = re.compile(r"^[ \t]*(PTP|LIN|CIRC|SPTP|SLIN|SCIRC|PTP_REL|LIN_REL|SPTP_REL|SLIN_REL)[ \t]+([^\n;]*)",
                       re.M | re.I)
_KRL_FRAME = re.compile(r"^[ \t]*(?:FDAT_ACT[ \t]*=[ \t]*(\w+)|BAS[ \t]*\([ \t]*#(TOOL|BASE)[ \t]*,[ \t]*(\d{1,9})"
                        r"|\$(TOOL|BASE)[ \t]*=[ \t]*(?:(?:TOOL|BASE)_DATA\[[ \t]*(\d{1,9})[ \t]*\]|(\$NULLFRAME)))",
                        re.M | re.I)
_KRL_FOLD = re.compile(r"^[ \t]*;FOLD[^\n]*?\bTool\[(\d{1,9})\][^\n]*?\bBase\[(\d{1,9})\]", re.M | re.I)


def read_kuka(path, accept_frames=False):
    """The poses of a KUKA program, ``.src`` and ``.dat`` of the same name (either given; the
    other read when it is beside it); convention ``kuka`` (module docstring)."""
    path = pathlib.Path(path)
    dat_path, src_path = _krl_pair(path)
    if dat_path is None:
        raise Text(path).error(0, "no .dat beside this .src: the KUKA points are declared in the program's .dat")
    dat = Text(dat_path)
    points, fdats = _krl_declarations(dat)
    prog = Text(src_path) if src_path is not None else None
    moved, frames, notes = _krl_motions(prog, points) if prog is not None else ([], {}, [])
    chosen, order_notes = in_motion_order(points, moved, dat, "points")
    spelled = {name.lower(): _shown(name) for name, _ in moved}  # the .src's spelling (KRL ignores case)
    chosen = [dataclasses.replace(p, name=spelled.get(p.tool_field.lower(), p.name)) if p.values is not None else p
              for p in chosen]
    out = []
    for p in chosen:
        if p.values is None:
            raise dat.error(_offset_of_line(dat, p.line), f"{p.name} is in joint form ({p.tool}): no flange pose in the "
                            "program; teach it as E6POS (Cartesian) or leave it out of the poses", p.tool)
        out.append(_with_frames(p, frames.get(p.tool_field.lower()), fdats))
    notes = order_notes + notes + frames_checked(out, dat, accept_frames, _kuka_refusal)
    companions = [f for f in (src_path, dat_path) if f is not None and f.resolve() != path.resolve()]
    fmt = "KUKA program (.src + .dat)" if src_path is not None else "KUKA data list (.dat)"
    return dataclasses.replace(poses_of(out, dat, fmt, "kuka", notes), file=path, companions=tuple(companions))


def _krl_pair(path):
    """``(dat, src)`` of a KUKA program given by either file (None where it is not there)."""
    siblings = {f.name.lower(): f for f in path.parent.iterdir() if f.is_file()} if path.parent.is_dir() else {}
    stem = path.stem.lower()
    if path.suffix.lower() == ".src":
        return siblings.get(stem + ".dat"), path
    return path, siblings.get(stem + ".src")


def _offset_of_line(src, line):
    return src._starts[line - 1]


def _krl_aggregate(src, at, text, names, field_of):
    """The numbers of ``names`` in a KRL aggregate ``{X 1.0,Y 2.0,...}`` (a DatasetError naming
    the missing or bad component)."""
    if not text.endswith("}"):
        raise src.error(at, "no closing '}' on the line", field_of)
    parts = {}
    for item in text[1:-1].split(","):
        bits = item.split(None, 1)
        if bits:
            parts.setdefault(bits[0].upper(), bits[1] if len(bits) > 1 else "")
    out = []
    for name in names:
        if name not in parts:
            raise src.error(at, f"{field_of}: no component {name}", name)
        out.append(number(parts[name], src, at, name))
    return out, parts


def _krl_declarations(dat):
    """Declared points (name -> Point, ``values`` None for joint form with ``tool`` the type) and
    FDATs (name -> (tool, base, line)) of a ``.dat``."""
    points, fdats = {}, {}
    for m in _KRL_DECL.finditer(dat.text):
        kind, name, body = m.group(1).upper(), m.group(2), m.group(3)
        if name.lower() in points or name.lower() in fdats:
            raise dat.error(m.start(), f"{name} declared twice", kind)
        if kind == "FDAT":
            _, parts = _krl_aggregate(dat, m.start(), body, (), name)
            fdats[name.lower()] = (*(_int_part(dat, m.start(), parts, k) for k in ("TOOL_NO", "BASE_NO")),
                                   dat.line(m.start()))
        elif kind in ("E6AXIS", "AXIS"):
            _krl_aggregate(dat, m.start(), body, ("A1", "A2", "A3", "A4", "A5", "A6"), name)
            points[name.lower()] = Point(_shown(name), dat.line(m.start()), None, kind)
        else:
            values, _ = _krl_aggregate(dat, m.start(), body, ("X", "Y", "Z", "A", "B", "C"), name)
            points[name.lower()] = Point(_shown(name), dat.line(m.start()), np.array(values), tool_field=name)
    return points, fdats


def _int_part(src, at, parts, key):
    if key not in parts:
        return None
    token = parts[key].strip()
    if not (token.isdigit() and len(token) <= 9):
        raise src.error(at, f"{key} {token[:20]!r} is not a frame number", key)
    return int(token)


def _shown(name):
    """A KRL point's name as the pendant shows it: ``XP12`` -> ``P12``."""
    return name[1:] if len(name) > 1 and name[0] in "xX" else name


def _krl_motions(prog, points):
    """Motions of a ``.src``: ``(moved, frames, notes)``; ``moved`` the declared names in order,
    ``frames`` name -> (FDAT name, fold (tool, base), state (tool, base)) of the first motion to each."""
    events = sorted([(m.start(), "move", m) for m in _KRL_MOVE.finditer(prog.text)]
                    + [(m.start(), "frame", m) for m in _KRL_FRAME.finditer(prog.text)]
                    + [(m.start(), "fold", m) for m in _KRL_FOLD.finditer(prog.text)], key=lambda e: e[0])
    state, fdat, fold, moved, frames, skipped = [None, None], None, None, [], {}, []
    for at, kind, m in events:
        if kind == "fold":
            fold, fdat = (int(m.group(1)), int(m.group(2))), None
        elif kind == "frame":
            fdat = m.group(1) or fdat
            if m.group(2):
                state["TB".index(m.group(2).upper()[0])] = int(m.group(3))
            elif m.group(4):
                state["TB".index(m.group(4).upper()[0])] = 0 if m.group(6) else int(m.group(5))
        else:
            for target in _krl_targets(m.group(1), m.group(2)):
                if target.lower() in points:
                    moved.append((target, at))
                    frames.setdefault(target.lower(), (fdat, fold, tuple(state)))
                else:
                    skipped.append(f"{target} (line {prog.line(at)})")
            fdat = fold = None
    notes = [f"left out, not declared in the .dat (a $config.dat point, a system variable, an inline or "
             f"relative target): {', '.join(skipped[:6])}" + (" ..." if len(skipped) > 6 else "")] if skipped else []
    return moved, frames, notes


def _krl_targets(instruction, args):
    """The point names a motion moves to (CIRC: auxiliary and end point); inline aggregates,
    relative motions and system variables give their text."""
    if instruction.upper().endswith("_REL") or args.lstrip().startswith("{"):
        return [f"{instruction} {args.strip()[:30]}"]
    names = re.findall(r"[$\w]+", args)
    count = 2 if instruction.upper() in ("CIRC", "SCIRC") else 1
    return names[:count]


def _with_frames(point, found, fdats):
    """The point with the tool and base its motion (or its ``.dat`` FDAT) names."""
    fdat_name, fold, state = found or (None, None, (None, None))
    fdat = fdats.get((fdat_name or "").lower()) or fdats.get(("f" + point.tool_field[1:]).lower())
    tool, base = fdat[:2] if fdat is not None else fold if fold is not None else state
    return Point(point.name, point.line, point.values, None if tool is None else f"{tool}",
                 None if base is None else f"{base}", tool == 0, base == 0, "TOOL_NO", "BASE_NO",
                 fdat[2] if fdat is not None else None)


def _kuka_refusal(point, which):
    if which == "tool":
        what = "names no tool (no FDAT, fold or $TOOL)" if point.tool is None else f"is of tool {point.tool}"
        return f"{point.name} {what}, not the flange (TOOL_NO 0)"
    what = "names no base (no FDAT, fold or $BASE)" if point.base is None else f"is in base {point.base}"
    return f"{point.name} {what}, not the robot's world frame (BASE_NO 0)"
