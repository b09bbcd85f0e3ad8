"""Tables of loose files: CSV, whitespace-separated text or JSON, the format told by the content.

:func:`read_table` returns a :class:`Table`: an optional header, rows of text cells and the
line (or JSON item) each row came from, so that every later error names file and row.
"""
from __future__ import annotations

import csv
import dataclasses
import json
import math
import pathlib
import re

from handeye.model.readers.tables import MAX_FILE_BYTES, DatasetError

#: one way to match each number (``\d+(\.\d*)?``, not ``\d+\.?\d*``): linear in the cell's length, where a
#: cell of 20,000 digits and a letter took 9 s of CPU (issue 40's fuzz)
_NUMBER = re.compile(r"^[+-]?(\d+(\.\d*)?|\.\d+)([eE][+-]?\d+)?$|^[+-]?(nan|inf|infinity)$", re.IGNORECASE)


_DECIMAL_COMMA = re.compile(r"^[+-]?\d+,\d+([eE][+-]?\d+)?$")


def is_number(text):
    """True for a decimal number, ``nan`` or ``inf`` (not ``1_000``, not empty)."""
    return bool(_NUMBER.match(str(text).strip()))


@dataclasses.dataclass(frozen=True)
class Table:
    """Rows of a file as text.

    Attributes
    ----------
    file : pathlib.Path
    header : tuple of str or None
        The column names the file gives, None without a header.
    rows : tuple of tuple of str
    lines : tuple of int
        Line (text) or item number (JSON, 1-based) of each row, for error messages.
    kind : str
        What the content was: ``CSV``, ``semicolon-separated text``, ``whitespace-separated text``,
        ``JSON list of lists``, ``JSON list of objects``.
    """

    file: pathlib.Path
    header: tuple | None
    rows: tuple
    lines: tuple
    kind: str


#: the largest pose (or joint) file read, bytes: 64 MiB is some 300,000 pose rows; a larger file given
#: as ``--poses`` is refused by its size before a byte is read (issue 40: a 1 GiB file was read whole)
MAX_TABLE_BYTES = 64 * 2**20


def _mib(n):
    return f"{n / 2**20:,.0f} MiB" if n >= 2**20 else f"{n:,} bytes"


def not_a_file(path):
    """Why ``path``, which is no regular file, cannot be read (a folder, a FIFO, a device, a symlink loop)."""
    if path.exists():
        return "is not a regular file (a folder, a pipe or a device)"
    return "is a symbolic link to no file (a loop or a missing target)" if path.is_symlink() else "no such file"


def read_bytes(path, limit=None, what="an input file"):
    """The bytes of an input file; a missing, unreadable or huge file is a DatasetError.

    Parameters
    ----------
    path : path-like
    limit : int or None
        The largest size read, bytes (None: ``MAX_FILE_BYTES``, 2 GB); a larger file is refused
        by its size (``stat``) before it is opened, the limit named.
    what : str
        What the file is, for the message (``a pose file``).
    """
    path = pathlib.Path(path)
    limit = MAX_FILE_BYTES if limit is None else limit
    try:
        if not path.is_file():
            raise DatasetError(path, not_a_file(path))
        size = path.stat().st_size
        if size > limit:
            raise DatasetError(path, f"{_mib(size)}: larger than the {_mib(limit)} {what} may have; not read")
        with open(path, "rb") as fh:
            raw = fh.read(size + 1)  # a file that grew since: one byte more tells (read(n) allocates n)
    except OSError as exc:
        raise DatasetError(path, f"cannot be read: {exc.strerror or exc}") from None
    if len(raw) > limit:
        raise DatasetError(path, f"larger than the {_mib(limit)} {what} may have; not read")
    return raw



def check_text(path, raw, what):
    """A DatasetError unless ``raw`` may be text: no NUL byte (UTF-16, a binary or a sparse file), found
    before anything is decoded or parsed (250 MB of zeros cost the FileStorage and controller readers
    over 5 s of CPU and 1 GB; issue 40's fuzz)."""
    at = raw.find(b"\x00")
    if at < 0:
        return
    pairs = raw[:64]
    utf16 = raw[:2] in (b"\xff\xfe", b"\xfe\xff") or (len(pairs) >= 4 and 0 not in pairs[0::2]) != (0 not in pairs[1::2])
    raise DatasetError(path, f"UTF-16 text: save it as UTF-8 ({what})" if utf16 else
                       f"a NUL byte at byte {at}: not text, not {what}")


def decode(path, raw, what="a table this command reads"):
    """``raw`` as UTF-8 text (a byte-order mark dropped); else a DatasetError saying the file is not ``what``."""
    check_text(path, raw, what)
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise DatasetError(path, f"not UTF-8 text (byte {exc.start}): not {what}") from None


def read_table(path, known_name=None):
    """The table of a CSV, whitespace-separated or JSON file.

    Parameters
    ----------
    path : path-like
    known_name : callable or None
        ``known_name(text)`` is true for a column name the caller knows; a first row is a header
        when none of its cells after the first is a number and one is a known name (or, without
        ``known_name``, when none is a number). A first comment line (``# x y z``) of known
        names is a header too.
    """
    path = pathlib.Path(path)
    return parse_table(path, decode(path, read_bytes(path, MAX_TABLE_BYTES, "a pose or joint file")), known_name)


def parse_table(path, text, known_name=None):
    """The table of ``text``, the content of ``path`` (:func:`read_table`'s, once read)."""
    return _json_table(path, text) if text.lstrip()[:1] in ("[", "{") else _text_table(path, text, known_name)


def _split(line, sep):
    """The cells of a line: CSV quoting honoured for ',' and ';' (a quoted id may hold the separator)."""
    if sep is None:
        return [c.strip('"').strip("'") for c in line.split()]
    try:
        cells = next(csv.reader([line], delimiter=sep))
    except (csv.Error, StopIteration):
        cells = line.split(sep)
    return [c.strip() for c in cells]


def _text_table(path, text, known_name):
    lines = [(k, line.strip()) for k, line in enumerate(text.splitlines(), start=1)]
    body = [(k, line) for k, line in lines if line and not line.startswith(("#", "%", "//"))]
    comments = [line for k, line in lines if line.startswith("#")]
    if not body:
        raise DatasetError(path, "no data rows")
    first = body[0][1]
    sep, kind = ((",", "CSV") if "," in first else (";", "semicolon-separated text") if ";" in first
                 else (None, "whitespace-separated text"))
    rows = [(k, _split(line, sep)) for k, line in body]
    if sep == ";" and any(_DECIMAL_COMMA.match(c) for _, r in rows[1:3] for c in r):  # 12,5;7,25: a European export
        rows = [(k, [c.replace(",", ".") if _DECIMAL_COMMA.match(c) else c for c in r]) for k, r in rows]
        kind += ", decimal commas"
    header = None
    if _looks_like_header(rows[0][1], known_name):
        header = tuple(rows.pop(0)[1])
    elif comments and known_name is not None:
        candidate = _split(comments[-1].lstrip("#").strip(), sep)
        if len(candidate) == len(rows[0][1]) and known_name and sum(map(known_name, candidate)) >= 3:
            header = tuple(candidate)
    if not rows:
        raise DatasetError(path, "a header but no data rows", 1)
    return Table(path, header, tuple(tuple(r) for _, r in rows), tuple(k for k, _ in rows), kind)


def _looks_like_header(cells, known_name):
    if any(is_number(c) for c in cells[1:]) or (len(cells) == 1 and is_number(cells[0])):
        return False
    return known_name is None or any(known_name(c) for c in cells)


def _json_value(path, value, item):
    if isinstance(value, bool) or value is None:
        raise DatasetError(path, f"item {item}: {value!r} is not a number")
    if isinstance(value, int) and abs(value) >= 10**300:  # past every float: its size, not its 4,000 digits
        return f"{'-' if value < 0 else ''}1e+{int(abs(value).bit_length() * 0.30103)}"
    if isinstance(value, (int, float, str)):
        return str(value)
    raise DatasetError(path, f"item {item}: a nested {type(value).__name__} where a number or text was expected")


#: the id column's names (:func:`handeye.app.ingest.poses.canonical`'s ``id`` aliases): an object
#: under one is refused, not flattened into columns nobody reads (the poses then numbered silently)
ID_KEYS = frozenset({"id", "name", "index", "idx", "pose", "poseid", "no", "nr", "number", "n"})


def _flatten(obj, path, item, prefix=""):
    """``{"position": {"x": 1}}`` -> ``{"position.x": 1}``; an object as an id is an error naming the item."""
    out = {}
    for key, value in obj.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            if not prefix and str(key).strip().lower() in ID_KEYS:
                raise DatasetError(path, f"item {item}: {key!r} is an object; an id is a number or a text")
            out.update(_flatten(value, path, item, name + "."))
        else:
            out[name] = value
    return out


def _json_table(path, text):
    try:
        doc = json.loads(text, parse_constant=lambda c: {"NaN": math.nan, "Infinity": math.inf}.get(c, -math.inf))
    except json.JSONDecodeError as exc:
        raise DatasetError(path, f"not valid JSON: {exc.msg}", exc.lineno) from None
    except RecursionError:  # [[[[...: nested deeper than Python's parser goes
        raise DatasetError(path, "JSON nested too deep to be a table of poses") from None
    except ValueError as exc:  # a 5,000-digit integer: past Python's limit of int digits
        raise DatasetError(path, f"JSON holds a number that is no pose value ({str(exc)[:70]})") from None
    if isinstance(doc, dict):
        lists = [(k, v) for k, v in doc.items() if isinstance(v, list)]
        if len(lists) != 1:
            raise DatasetError(path, f"a JSON object must hold exactly one list of poses, it holds {len(lists)} "
                                     f"({', '.join(k for k, _ in lists) or 'none'})")
        doc = lists[0][1]
    if not isinstance(doc, list) or not doc:
        raise DatasetError(path, "JSON: expected a non-empty list of lists or of objects")
    if all(isinstance(d, dict) for d in doc):
        flat = [_flatten(d, path, item) for item, d in enumerate(doc, start=1)]
        header = list(flat[0])
        for d in flat[1:]:
            header += [k for k in d if k not in header]
        rows = []
        for item, d in enumerate(flat, start=1):
            missing = [k for k in header if k not in d]
            if missing:
                raise DatasetError(path, f"item {item}: no {missing[0]!r} (the first item has it)")
            rows.append(tuple(_json_value(path, d[k], item) for k in header))
        return Table(path, tuple(header), tuple(rows), tuple(range(1, len(rows) + 1)), "JSON list of objects")
    if all(isinstance(d, list) for d in doc):
        rows = [tuple(_json_value(path, v, item) for v in d) for item, d in enumerate(doc, start=1)]
        header = rows.pop(0) if rows and not any(is_number(c) for c in rows[0]) else None
        return Table(path, header, tuple(rows), tuple(range(1, len(rows) + 1)), "JSON list of lists")
    raise DatasetError(path, "JSON: expected a list of lists or a list of objects, not a mixture")
