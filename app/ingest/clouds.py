"""Profile files of any common kind, the format told by the content (magic bytes), not the name.

==========================  ===============================================================
format                      read
==========================  ===============================================================
OpenCV FileStorage          YAML, XML, JSON (:mod:`handeye.app.ingest.opencv_storage`)
NumPy                       ``.npy`` (one array), ``.npz`` (each array one profile)
PLY                         ascii, binary_little_endian, binary_big_endian: ``vertex`` x, y, z
PCD                         ascii, binary: fields x, y, z (binary_compressed: re-save as binary)
text                        CSV or whitespace, 2 (x, z) or 3 (x, y, z) columns, header optional
==========================  ===============================================================

Each reader returns ``[(name, (K, 2 or 3) array)]``: a file may hold several profiles (a
FileStorage file or an ``.npz`` with several arrays), each named by its key.
"""
from __future__ import annotations

import io
import re
import zipfile

import numpy as np

from handeye.app.ingest import opencv_storage
from handeye.app.ingest.poses import canonical
from handeye.app.ingest.tables import check_text, decode, is_number, parse_table, read_bytes
from handeye.model.readers.tables import DatasetError

_PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2", "ushort": "u2",
              "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4", "float": "f4", "float32": "f4",
              "double": "f8", "float64": "f8"}


#: the largest profile file read, bytes: 256 MiB holds 10^7 points of three float64 (a 10^6-point CSV is
#: some 30 MB); a larger file is refused by its size before a byte is read (in a folder: skipped and
#: listed), so a stray 1 GiB file costs nothing (issue 40: 1.08 GB to skip one)
MAX_PROFILE_BYTES = 256 * 2**20
#: the lines of a text profile read in Python to find its header, separator and columns; the rest is
#: parsed by numpy's C reader (no Python object per line)
HEAD_LINES = 64

#: the first bytes of the binary formats (and PLY's header)
_MAGIC = ((b"\x93NUMPY", "npy"), (b"PK\x03\x04", "npz"), (b"ply\n", "ply"), (b"ply\r\n", "ply"))


def detect(raw):
    """The format of a profile file's bytes (table above)."""
    head = raw[:4096]
    for magic, fmt in _MAGIC:
        if head.startswith(magic):
            return fmt
    flavour = opencv_storage.sniff(head)
    if flavour is not None:
        return "FileStorage " + flavour.upper()
    text = head.lstrip().upper()
    if text.startswith(b"# .PCD") or text.startswith(b"VERSION") or re.match(rb"(#[^\n]*\n)*\s*FIELDS", text):
        return "pcd"
    return None if b"\x00" in head else "text"


def read_profile_file(path):
    """``(format, [(name, points)])`` of a profile file; points (K, 2) as (x, z) or (K, 3)."""
    raw = read_bytes(path, MAX_PROFILE_BYTES, "a profile file")
    fmt = detect(raw)
    if fmt is None:
        raise DatasetError(path, "unknown format: not FileStorage YAML/XML/JSON, .npy/.npz, PLY, PCD, CSV or text")
    reader = {"npy": _npy, "npz": _npz, "ply": _ply, "pcd": _pcd, "text": _text}.get(fmt, opencv_storage.read)
    try:
        return fmt, reader(path, raw)
    except DatasetError:
        raise
    except (ValueError, IndexError, KeyError, TypeError, EOFError, OSError, NotImplementedError, zipfile.BadZipFile,
            RecursionError, OverflowError) as exc:  # a truncated or corrupt file: bad input, named, not a traceback
        raise DatasetError(path, f"a malformed {fmt} file ({type(exc).__name__}: {str(exc)[:80]})") from None


def _numeric(path, name, array):
    a = np.asarray(array)
    if a.dtype.names:  # a structured array: its x, y, z fields
        return name, _fields(path, {n: a[n] for n in a.dtype.names}, a.dtype.names)
    if a.dtype.kind not in "iuf" or a.ndim != 2 or not (a.shape[1] in (2, 3) or a.shape[0] in (2, 3)):
        raise DatasetError(path, f"array {name!r} of shape {a.shape} and type {a.dtype}: a profile is K x 2 (x, z) "
                                 "or K x 3 (x, y, z) numbers")
    a = a.astype(float)
    return name, a if a.shape[1] in (2, 3) else a.T


def _npy(path, raw):
    try:
        array = np.load(io.BytesIO(raw), allow_pickle=False)
    except Exception as exc:  # noqa: BLE001 - numpy's header parser raises what it meets (a TokenError too)
        raise DatasetError(path, f"not a readable .npy file ({type(exc).__name__}: {str(exc)[:80]})") from None
    return [_numeric(path, "array", array)]


def _npz(path, raw):
    try:
        with np.load(io.BytesIO(raw), allow_pickle=False) as z:
            arrays = [(name, z[name]) for name in z.files]
    except Exception as exc:  # noqa: BLE001 - a corrupt zip or header raises anything zipfile or numpy meets
        raise DatasetError(path, f"not a readable .npz file ({type(exc).__name__}: {str(exc)[:80]})") from None
    return [_numeric(path, name, a) for name, a in arrays]


def _fields(path, columns, names):
    """(K, 3) of the x, y, z columns (case-insensitive); (K, 2) when only x and z are there."""
    lower = {n.lower(): n for n in names}
    want = ["x", "y", "z"] if "y" in lower else ["x", "z"]
    missing = [w for w in want if w not in lower]
    if missing:
        raise DatasetError(path, f"no field {missing[0]!r} (fields: {', '.join(names)})")
    return np.column_stack([np.asarray(columns[lower[w]], float) for w in want])


def _header(path, raw, end_marker):
    """The header lines up to and including the one starting with ``end_marker``; the data offset."""
    lines, pos = [], 0
    while True:
        nl = raw.find(b"\n", pos)
        if nl < 0:
            raise DatasetError(path, f"header without {end_marker.decode()}")
        line = raw[pos:nl].decode("ascii", errors="replace").strip()
        lines.append(line)
        pos = nl + 1
        if line.split(" ")[0].upper() == end_marker.decode().upper():
            return lines, pos


def _ply(path, raw):
    lines, offset = _header(path, raw, b"end_header")
    fmt, elements = None, []
    for line in lines:
        words = line.split()
        if words[:1] == ["format"]:
            fmt = words[1]
        elif words[:1] == ["element"]:
            elements.append([words[1], _header_count(path, words[2], f"PLY element {words[1]}"), []])
        elif words[:1] == ["property"] and elements:
            elements[-1][2].append((words[-1], None) if words[1] == "list" else (words[2], _PLY_TYPES.get(words[1])))
    if fmt not in ("ascii", "binary_little_endian", "binary_big_endian"):
        raise DatasetError(path, f"PLY format {fmt!r} unknown")
    names = [e[0] for e in elements]
    if "vertex" not in names:
        raise DatasetError(path, "PLY without a vertex element")
    before = elements[:names.index("vertex")]
    name, count, props = elements[names.index("vertex")]
    if any(t is None for _, t in props) or (fmt != "ascii" and any(n for _, n, _ in before)):
        raise DatasetError(path, "PLY: list properties in or before the vertices are not read; write the vertices first")
    last = all(n == 0 for _, n, _ in elements[names.index("vertex") + 1:])
    if fmt == "ascii":
        check_text(path, raw, "an ascii PLY")  # a NUL (a sparse file) found before the body is decoded and split
        skip = sum(n for _, n, _ in before)
        lines = [line for line in raw[offset:].decode("ascii", errors="replace").splitlines() if line.strip()]
        _counts_agree(path, ("PLY", "vertices", "lines"), count, len(lines) - skip, exact=last)
        data = _loadtxt(path, lines[skip:skip + count], len(props))
        cols = {p: data[:, k] for k, (p, _) in enumerate(props)}
    else:
        order = "<" if fmt == "binary_little_endian" else ">"
        dtype = np.dtype([(p, order + t) for p, t in props])
        _counts_agree(path, ("PLY", "vertices", "records"), count, (len(raw) - offset) // dtype.itemsize, exact=last)
        data = np.frombuffer(raw, dtype, count=count, offset=offset)
        cols = {p: data[p] for p, _ in props}
    return [("vertex", _fields(path, cols, [p for p, _ in props]))]


def _header_count(path, word, what):
    """A count of a PLY or PCD header (a whole number up to 10^9), else a DatasetError naming it."""
    if not (word.isdigit() and len(word) <= 10 and int(word) <= 10**9):
        raise DatasetError(path, f"{what}: count {word[:20]!r} is not a whole number from 0 to 10^9")
    return int(word)


def _counts_agree(path, what, announced, found, exact=True):
    """A header's count against the data (``what``: ``(format, items, units)``, ``PLY``, ``vertices``,
    ``lines``): fewer there, or (``exact``: nothing follows them) more, is a header that lies, refused
    naming the file (issue 40: they were read silently)."""
    fmt, items, unit = what
    if found < announced or (exact and found > announced):
        raise DatasetError(path, f"{fmt} header announces {announced:,} {items}, the data hold {found:,} {unit}: a cut "
                                 "file or a header that does not match its data")


def _loadtxt(path, lines, width):
    """Numbers of ASCII point lines (K, width); a bad line is a DatasetError naming the file."""
    if not lines:
        return np.zeros((0, width))
    try:
        data = np.loadtxt(lines, ndmin=2, dtype=float)
    except ValueError as exc:
        raise DatasetError(path, f"ASCII points: {str(exc).splitlines()[0]}") from None
    if data.shape[1] < width:
        raise DatasetError(path, f"ASCII points: {data.shape[1]} numbers per line, the header names {width}")
    return data


def _pcd(path, raw):
    lines, offset = _header(path, raw, b"DATA")
    head = {}
    for line in lines:
        if line and not line.startswith("#"):
            key, _, rest = line.partition(" ")
            head[key.upper()] = rest.split()
    fields, data = head.get("FIELDS", []), (head.get("DATA") or [""])[0].lower()
    sizes = [int(s) for s in head.get("SIZE", [])]
    types = head.get("TYPE", [])
    counts = [int(c) for c in head.get("COUNT", ["1"] * len(fields))]
    points = _pcd_points(path, head)
    if not fields or len(sizes) != len(fields) or len(types) != len(fields):
        raise DatasetError(path, "PCD header needs FIELDS, SIZE and TYPE of equal length")
    if data == "ascii":
        check_text(path, raw, "an ascii PCD")  # a NUL (a sparse file) found before the body is decoded and split
        body = [b for b in raw[offset:].decode("ascii", errors="replace").splitlines() if b.strip()]
        _counts_agree(path, ("PCD", "points", "lines"), points, len(body))
        table = _loadtxt(path, body, sum(counts))
        starts = np.cumsum([0] + counts[:-1])
        cols = {f: table[:, s] for f, s in zip(fields, starts)}
    elif data == "binary":
        dtype = np.dtype([(f, f"<{t.lower()}{s}", (c,) if c > 1 else ())
                          for f, s, t, c in zip(fields, sizes, types, counts)])
        _counts_agree(path, ("PCD", "points", "records"), points, (len(raw) - offset) // dtype.itemsize)
        table = np.frombuffer(raw, dtype, count=points, offset=offset)
        cols = {f: table[f] for f in fields}
    else:
        raise DatasetError(path, f"PCD DATA {data!r} is not read (binary_compressed: re-save it as binary or ascii)")
    return [("points", _fields(path, cols, fields))]


def _profile_names(c):
    return canonical(c) in ("x", "y", "z")


def _pcd_points(path, head):
    """POINTS of a PCD header, which must be WIDTH x HEIGHT where those are given."""
    width, height = (_header_count(path, (head.get(k) or ["1"])[0], f"PCD {k}") for k in ("WIDTH", "HEIGHT"))
    if "POINTS" not in head:
        return width * height
    points = _header_count(path, (head["POINTS"] or [""])[0], "PCD POINTS")
    if "WIDTH" in head and points != width * height:
        raise DatasetError(path, f"PCD header: POINTS {points:,} but WIDTH x HEIGHT {width:,} x {height:,}: a header that "
                                 "does not match itself")
    return points


def _text(path, raw):
    """A CSV or whitespace profile: its head (:data:`HEAD_LINES`) read as a table to find the header,
    separator and columns, the body streamed by ``numpy.loadtxt`` (issue 40: a 10^6-point profile took
    13 s and 674 MB as Python rows); a body numpy refuses (a ``%`` or ``//`` comment in it too) is
    read again row by row, which names the row and column at fault."""
    text = decode(path, raw)
    cut = -1
    for _ in range(HEAD_LINES):
        cut = text.find("\n", cut + 1)
        if cut < 0:
            break
    if cut < 0 or len(text[:cut + 1].splitlines()) != text.count("\n", 0, cut + 1):  # short, or \r or \f lines
        return _text_rows(parse_table(path, text, _profile_names))
    try:
        head = parse_table(path, text[:cut], _profile_names)
    except DatasetError:  # a head of comments only: the whole file tells
        return _text_rows(parse_table(path, text, _profile_names))
    if head.kind.startswith("JSON"):
        raise DatasetError(path, "a JSON table is not a profile (FileStorage JSON has opencv-matrix nodes)")
    names = [canonical(h) or h for h in head.header] if head.header is not None else None
    cols = (tuple(names.index(n) for n in ("x", "y", "z") if n in names) if names else tuple(range(len(head.rows[0]))))
    if head.kind not in ("CSV", "whitespace-separated text") or len(cols) not in (2, 3) or (names and "x" not in names):
        return _text_rows(parse_table(path, text, _profile_names))
    start = max(_line_start(raw, head.lines[0]), 3 if raw.startswith(b"\xef\xbb\xbf") else 0)
    try:
        body = np.loadtxt(io.BytesIO(raw[start:]), delimiter="," if head.kind == "CSV" else None,
                          comments="#", usecols=cols, ndmin=2, dtype=float, encoding="utf-8")  # one char: C only
    except ValueError:
        return _text_rows(parse_table(path, text, _profile_names))
    return [("table", body)]


def _line_start(raw, line):
    """The byte offset of 1-based ``line`` of ``raw`` (within the head: a few lines searched)."""
    pos = 0
    for _ in range(line - 1):
        pos = raw.find(b"\n", pos) + 1
    return pos


def _text_rows(table):
    """The profile of a table read row by row (every cell checked, errors name row and column)."""
    if table.kind.startswith("JSON"):
        raise DatasetError(table.file, "a JSON table is not a profile (FileStorage JSON has opencv-matrix nodes)")
    if table.header is not None:  # names as the poses' (``X [mm]``, ``pos_z``): x, y, z by the canonical name
        names = [canonical(h) or h for h in table.header]
        return [("table", _fields(table.file, {n: _column(table, k) for k, n in enumerate(names) if n in ("x", "y", "z")},
                                  names))]
    width = len(table.rows[0])
    if width not in (2, 3):
        raise DatasetError(table.file, f"{width} columns: a profile has 2 (x, z) or 3 (x, y, z); name them in a header",
                           table.lines[0])
    return [("table", np.column_stack([_column(table, k) for k in range(width)]))]


def _column(table, k):
    out = np.empty(len(table.rows))
    for r, (row, line) in enumerate(zip(table.rows, table.lines)):
        if len(row) <= k:
            raise DatasetError(table.file, f"expected {len(table.rows[0])} fields, got {len(row)}", line)
        cell = row[k]
        if not is_number(cell):
            raise DatasetError(table.file, f"not a number: {cell[:30]!r}", line, table.header[k] if table.header else None)
        out[r] = float(cell)
    return out
