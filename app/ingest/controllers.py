"""Poses from the robot controller's own files: which reader, and what they share.

``handeye dataset new --poses FILE`` reads a controller file as the controller writes it: a FANUC
TP program (``.ls``: its ``/POS`` section), a KUKA program (``.src`` with its ``.dat``, or a
``.dat`` alone), an ABB RAPID module (``.mod``: its ``robtarget`` declarations and ``Move``
instructions), a URScript program (``p[...]`` poses) or a UR RTDE log (``actual_TCP_pose_0..5``
columns; one pose per row, or per stop of a log streamed while the robot moves:
:mod:`handeye.app.ingest.controller_rtde`). :func:`read_controller` tells them by suffix and content (None: not a controller file;
:func:`handeye.app.ingest.poses.read_poses` reads it as a table) and returns
:class:`ControllerPoses`: the flange poses in the robot base in the file's own convention (mm;
FANUC W,P,R and KUKA A,B,C degrees, ABB quaternions w first, UR rotation vectors radians), the
order of motion, the joint angles where the file has them and the arm configuration where it
gives one (FANUC ``CONFIG``, kept as the dataset's ``cfx`` column).

A pose is of the flange in the robot base only when the file says so: FANUC ``UT : 0`` and
``UF : 0``, KUKA ``TOOL_NO 0`` and ``BASE_NO 0``, ABB ``tool0`` (or a ``tooldata`` declared in
the module with a zero TCP) and ``wobj0`` (or a ``wobjdata`` declared as the base), a URScript
``set_tcp`` of zero. Any other tool or frame, or one the file does not name, is refused naming
file, line and field, unless ``accept_frames`` (``--accept-frames``: the user states those tools
are zero and those frames the base); even then every pose must be of one tool and one frame.
Positions in joint form (FANUC ``J1 =``, KUKA ``E6AXIS``/``AXIS``) among the poses are refused;
joint moves that are other instructions (ABB ``MoveAbsJ``, URScript ``movej([...])``, KUKA's
``HOME`` declared in ``$config.dat``) are left out and named in the notes.
"""
from __future__ import annotations

import pathlib
import re

from handeye.app.ingest import controller_abb_ur, controller_fanuc_kuka, controller_rtde
from handeye.app.ingest.controller_common import ControllerPoses  # noqa: F401  (re-exported: the result)

#: suffixes of controller programs (other files are told by their content)
SUFFIXES = {".ls": "fanuc", ".src": "kuka", ".dat": "kuka", ".mod": "abb", ".modx": "abb", ".prg": "abb",
            ".sys": "abb", ".script": "urscript", ".urscript": "urscript"}


#: what a file of each kind has near its start (a ``.dat`` of numbers is a table, not KUKA's)
MARKERS = {"fanuc": re.compile(r"^\s*/(PROG|POS)\b", re.M), "abb": re.compile(r"^\s*MODULE\s", re.M | re.I),
           "kuka": re.compile(r"^\s*(DEFDAT|DEF\s|DECL\s|&ACCESS|E6POS\s|E6AXIS\s)", re.M | re.I),
           "urscript": re.compile(r"\bp\["), "rtde": re.compile(r"\b(actual|target)_TCP_pose_0\b")}


def kind_of(path):
    """The reader of a controller file (``fanuc``, ``kuka``, ``abb``, ``urscript``, ``rtde``) or
    None: the suffix's kind when the first 4 kB have its marks, else the kind those 4 kB show."""
    path = pathlib.Path(path)
    try:
        if not path.is_file():  # a FIFO would block the open; the reader names what it is
            return SUFFIXES.get(path.suffix.lower())
        with open(path, "rb") as fh:
            head = fh.read(4096).decode("utf-8", errors="replace")
    except OSError:
        return SUFFIXES.get(path.suffix.lower())  # the reader names the file that cannot be read
    by_suffix = SUFFIXES.get(path.suffix.lower())
    if by_suffix is not None and MARKERS[by_suffix].search(head):
        return by_suffix
    if MARKERS["rtde"].search(head):
        return "rtde"
    if head.lstrip().startswith("/PROG") or "/POS" in head and re.search(r"\bP\[\d+", head):
        return "fanuc"
    if re.search(r"^\s*(DEFDAT|DECL\s+E6POS)\b", head, re.M | re.I):
        return "kuka"
    if re.search(r"^\s*MODULE\s+\w+", head, re.M) and "robtarget" in head:
        return "abb"
    if re.search(r"\bmove[ljp]\s*\(\s*p\[", head) or re.search(r"=\s*\[?\s*p\[", head):
        return "urscript"
    return None


def read_controller(path, accept_frames=False, still=None):
    """The poses of a controller file, or None when ``path`` is no controller file.

    Parameters
    ----------
    path : path-like
    accept_frames : bool
        Read poses in a named tool other than the flange, or a frame other than the robot base,
        as flange poses in the base (``--accept-frames``; module docstring).
    still : controller_rtde.Still or None
        What a stop of an RTDE log streamed while the robot moves is (``--still``; None: the default,
        :data:`handeye.app.ingest.controller_rtde.STILL`).

    Returns
    -------
    ControllerPoses or None
    """
    kind = kind_of(path)
    if kind is None:
        return None
    if kind == "rtde":
        return controller_rtde.read_rtde(path, accept_frames, still)
    reader = {"fanuc": controller_fanuc_kuka.read_fanuc, "kuka": controller_fanuc_kuka.read_kuka,
              "abb": controller_abb_ur.read_abb, "urscript": controller_abb_ur.read_urscript}[kind]
    return reader(path, accept_frames)
