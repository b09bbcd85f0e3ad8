"""OpenCV FileStorage files (YAML, XML, JSON) read without OpenCV or a YAML library.

Only what a profile needs: every ``opencv-matrix`` node (``rows``, ``cols``, ``dt``, ``data``; a
``dt`` with a channel count such as ``3f`` gives one point per element), its values with
FileStorage's ``.Nan``, ``.Inf`` and ``-.Inf``. A file without matrices may hold points as a flat
sequence (``fs << "scan_line" << std::vector<cv::Point3f>`` writes ``scan_line: [x, y, z, ...]``):
each top-level key holding only numbers is read as (x, y, z) triplets when their count divides
by 3 and one coordinate of the triplets is constant (a laser plane), else as (x, z) pairs.
Anything else in the file is left alone.
"""
from __future__ import annotations

import json
import re
import xml.etree.ElementTree as ElementTree

import numpy as np

from handeye.app.ingest.tables import check_text
from handeye.model.readers.tables import PARSE_ERRORS, DatasetError, parse_problem

_SPECIAL = {".nan": np.nan, ".inf": np.inf, "-.inf": -np.inf, "+.inf": np.inf}
#: keys of a profile file that are no profile, left alone (lower case): a newer sensor SDK writes the
#: feature it found (``feature_point: [x, y, z]``, the sphere's apex) and the file's ``type`` beside
#: the ``scan_line`` (issue 40); the calibration fits the profile itself, so neither is used
IGNORED_KEYS = frozenset({"feature_point", "feature_points", "type"})


def sniff(head):
    """The FileStorage flavour of a file's first bytes: 'yaml', 'xml', 'json' or None."""
    text = head.lstrip(b"\xef\xbb\xbf").lstrip()
    if text.startswith(b"%YAML"):
        return "yaml"
    if (text.startswith(b"<?xml") or text.startswith(b"<opencv_storage")) and b"opencv_storage" in head:
        return "xml"
    if text.startswith(b"{") and b"opencv-matrix" in head:
        return "json"
    return None


#: the largest ``rows`` or ``cols`` a matrix node may state (a larger count is a corrupt header)
MAX_COUNT = 10**9


def _count(value):
    """A matrix's ``rows`` or ``cols`` as an int, None unless a whole number in 0..:data:`MAX_COUNT`
    (``1e400`` is none: JSON reads it as infinity)."""
    if isinstance(value, bool):
        return None
    if isinstance(value, str):
        value = value.strip()
        return int(value) if value.isdigit() and len(value) <= 10 and int(value) <= MAX_COUNT else None
    if isinstance(value, (int, float)) and 0 <= value <= MAX_COUNT and float(value).is_integer():
        return int(value)
    return None


def _value(token, file):
    t = token.strip()
    if t.lower() in _SPECIAL:
        return _SPECIAL[t.lower()]
    try:
        return float(t)
    except ValueError:
        raise DatasetError(file, f"FileStorage matrix: not a number: {t[:30]!r}") from None


def _matrix(name, node, file, numbers):
    """The points of one matrix node (``rows``, ``cols``, ``dt``, ``data``; ``numbers(data)`` its values):
    (K, c) with c the columns (or channels)."""
    missing = [k for k in ("rows", "cols", "dt", "data") if k not in node]
    if missing:
        raise DatasetError(file, f"FileStorage matrix {name!r}: no {missing[0]}")
    values, dt = numbers(node["data"]), node["dt"]
    rows, cols = _count(node["rows"]), _count(node["cols"])
    if rows is None or cols is None:
        shown = str(node["rows"] if rows is None else node["cols"])[:30]
        raise DatasetError(file, f"FileStorage matrix {name!r}: rows and cols must be integers from 0 to "
                                 f"{MAX_COUNT:,}, not {shown}")
    match = re.fullmatch(r"(\d*)([ucwsifdh])", str(dt).strip())
    if match is None:
        raise DatasetError(file, f"FileStorage matrix {name!r}: unknown dt {dt!r}")
    channels = int(match.group(1) or 1)
    data = np.asarray(values, float)
    if data.size != rows * cols * channels:
        raise DatasetError(file, f"FileStorage matrix {name!r}: {data.size} values for {rows} x {cols} x {channels}")
    out = data.reshape(rows * cols, channels) if channels > 1 else data.reshape(rows, cols)
    if out.shape[0] in (2, 3) and out.shape[1] > 3:  # one point per column
        out = out.T
    return name, out


def flat_points(name, values, file):
    """(name, points) of a flat number sequence: (K, 3) triplets when the count divides by 3 and
    one coordinate is constant, else (K, 2) pairs."""
    data = np.asarray(values, float)
    if data.size % 3 == 0 and data.size >= 9:
        triplets = data.reshape(-1, 3)
        with np.errstate(invalid="ignore"):
            spread = [np.nanmax(c) - np.nanmin(c) if np.isfinite(c).any() else np.inf for c in triplets.T]
        if min(spread) == 0:
            return name, triplets
    if data.size % 2 == 0:
        return name, data.reshape(-1, 2)
    raise DatasetError(file, f"FileStorage sequence {name!r}: {data.size} numbers are neither (x, z) pairs nor "
                             "(x, y, z) triplets in a plane")


#: a top-level ``key: [`` (the ``[`` on the key's line); ``[ \t]`` so that no match runs over lines
_SEQUENCE_KEY = re.compile(r"^([A-Za-z_][\w.-]*)[ \t]*:[ \t]*\[", re.MULTILINE)
_TOKEN = re.compile(r"\s*[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?\s*|\s*[-+]?\.(Nan|Inf)\s*")


def _line(text, pos):
    return text.count("\n", 0, pos) + 1


def _yaml_sequences(text, file):
    """Top-level ``key: [ numbers ]`` sequences of a FileStorage YAML file (the keys of
    :data:`IGNORED_KEYS` and sequences that are not all numbers left alone). One pass: each key's
    ``]`` is found with ``str.find`` from its ``[`` and the next key searched after it, so the cost
    is linear in the file (issue 40: a lazy ``\\[(.*?)\\]`` over lines was quadratic); a ``[``
    never closed is a cut file, refused naming its line."""
    out, pos = [], 0
    while (m := _SEQUENCE_KEY.search(text, pos)) is not None:
        end = text.find("]", m.end())
        if end < 0:
            raise DatasetError(file, f"FileStorage sequence {m.group(1)!r}: its '[' is never closed (a cut file?)",
                               _line(text, m.start()))
        pos = end + 1
        if m.group(1).lower() in IGNORED_KEYS:
            continue
        tokens = [t for t in text[m.end():end].split(",") if t.strip()]
        if tokens and all(_TOKEN.fullmatch(t) for t in tokens):
            out.append(flat_points(m.group(1), [_value(t, file) for t in tokens], file))
    return out


def _yaml(text, file):
    if "!!opencv-matrix" not in text:
        return _yaml_sequences(text, file)
    parts = text.split("!!opencv-matrix")
    out = []
    for k, block in enumerate(parts[1:], start=1):
        before = parts[k - 1].rsplit("\n", 1)[-1].strip().rstrip(":").strip()
        name = before.lstrip("-").strip() or f"item{k}"
        fields = {}
        for key in ("rows", "cols", "dt"):
            m = re.search(rf"^[ \t]*{key}[ \t]*:[ \t]*(\S+)", block, re.MULTILINE)
            if m is None:
                raise DatasetError(file, f"FileStorage matrix {name!r}: no {key}")
            fields[key] = m.group(1).strip("\"'")
        m = re.search(r"^[ \t]*data[ \t]*:[ \t]*\[", block, re.MULTILINE)
        end = -1 if m is None else block.find("]", m.end())
        if end < 0:
            raise DatasetError(file, f"FileStorage matrix {name!r}: no data [ ... ]" if m is None else
                               f"FileStorage matrix {name!r}: its data '[' is never closed (a cut file?)")
        if name.lower() in IGNORED_KEYS:
            continue
        values = [_value(v, file) for v in block[m.end():end].split(",") if v.strip()]
        out.append(_matrix(name, {**fields, "data": values}, file, list))
    return out


def _xml(text, file):
    try:
        root = ElementTree.fromstring(text)
    except ElementTree.ParseError as exc:
        raise DatasetError(file, f"FileStorage XML: {exc}") from None
    out = []
    for node in root.iter():
        if node.get("type_id") != "opencv-matrix" or node.tag.lower() in IGNORED_KEYS:
            continue
        get = {child.tag: (child.text or "").strip() for child in node}
        out.append(_matrix(node.tag, get, file, lambda data: [_value(v, file) for v in data.split()]))
    return out


def _json(text, file):
    fixed = text if ".Nan" not in text and ".Inf" not in text else re.sub(  # a scan of every character: only when needed
        r'(?<![\w"])([+-]?)\.(Nan|Inf)\b',
        lambda m: "NaN" if m.group(2) == "Nan" else ("-Infinity" if m.group(1) == "-" else "Infinity"), text)
    try:
        doc = json.loads(fixed)
    except PARSE_ERRORS as exc:
        raise DatasetError(file, f"FileStorage JSON: {parse_problem(exc)}", getattr(exc, "lineno", None)) from None
    out = []

    def walk(node, name):
        if isinstance(node, dict):
            if node.get("type_id") == "opencv-matrix":
                if name.lower() in IGNORED_KEYS:
                    return
                out.append(_matrix(name, node, file, lambda data: [_value(v, file) if isinstance(v, str) else v
                                                                   for v in data]))
                return
            for key, value in node.items():
                walk(value, key)
        elif isinstance(node, list):
            for k, value in enumerate(node):
                walk(value, f"{name}[{k}]")

    walk(doc, "root")
    return out


def read(file, raw):
    """Every matrix of a FileStorage file as ``[(name, (K, c) array)]``, in file order."""
    flavour = sniff(raw[:4096])
    check_text(file, raw, "a FileStorage file")
    text = raw.decode("utf-8-sig", errors="replace")
    matrices = {"yaml": _yaml, "xml": _xml, "json": _json}[flavour](text, file)
    if not matrices:
        raise DatasetError(file, "an OpenCV FileStorage file without an opencv-matrix or a sequence of numbers")
    return matrices
