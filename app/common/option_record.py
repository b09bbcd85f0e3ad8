"""The option record (:class:`Opt`), a command's table (:class:`Command`), and what is made from
the tables of :mod:`handeye.app.common.options`: the public function's keywords from the parsed
arguments, the values it was given, its docstring's ``Parameters``, the provenance record and
the README's markdown table. Imports only the standard library.
"""
from __future__ import annotations

import dataclasses
import re
import textwrap


@dataclasses.dataclass(frozen=True)
class Opt:
    """One option of one command, as the parser, the public function, the request, the
    provenance record and the README see it.

    Attributes
    ----------
    flag : str
        ``--max-iter``, or a positional's name (``dataset``).
    default : object
        The default of the command line and of the public function's keyword (immutable).
    type : {'int', 'float'} or None
        How the command line reads the text (None: kept as text).
    unit : str or None
        Unit of the value (``mm``, ``deg``), shown in the docs.
    choices : tuple, callable or None
        The values allowed (a callable gives them when the parser is built).
    help : str or None
        What it does: the command line's help (plain text), the docstring's (reST) and the
        README's (markdown) alike; ``code`` is written in double backquotes.
    metavar, nargs, required
        As argparse's.
    action : {'store_true', 'append', 'extend'} or None
        ``extend`` with ``nargs='+'``: one option takes many values (a shell glob's files) and may be
        given again.
    keyword : str or None
        The public function's keyword; None: the flag's name (``max_iter``); ``''``: none
        (``--json`` is the command line's own).
    check : tuple
        What the request validates: ``('number', low, high)``, ``('integer', low, high)``.
    kind : {'value', 'path', 'pose'}
        How the provenance record saves it: as given, as text (a path, a dataset's folder), or
        as text or a flat list of numbers (a pose).
    pytype : str or None
        The keyword's type in the function's docstring, where :meth:`python_type`'s guess is not it.
    """

    flag: str
    default: object = None
    type: str | None = None
    unit: str | None = None
    choices: object = None
    metavar: str | None = None
    help: str | None = None
    nargs: str | None = None
    action: str | None = None
    required: bool = False
    keyword: str | None = None
    check: tuple = ()
    kind: str = "value"
    pytype: str | None = None

    def __post_init__(self):
        if self.action == "store_true":  # a flag is False until given
            object.__setattr__(self, "default", False)

    @property
    def dest(self):
        """The argparse attribute (``max_iter``)."""
        return self.flag.lstrip("-").replace("-", "_")

    @property
    def name(self):
        """The public function's keyword, or ``''`` for an option of the command line's own."""
        return self.dest if self.keyword is None else self.keyword

    def python_type(self):
        """The keyword's type as the docstring states it (``float, optional``)."""
        choices = None if callable(self.choices) else self.choices
        guess = ("bool" if self.action == "store_true" else "str or sequence of str" if self.action in ("append", "extend")
                 else "{" + ", ".join(map(repr, choices)) + "}" if choices else {"int": "int", "float": "float"}.get(
                     self.type, {"path": "str or pathlib.Path", "pose": "str or array_like"}.get(self.kind, "str")))
        optional = self.default is None and not self.required and self.flag.startswith("-")
        return self.pytype or guess + (", optional" if optional else "")

    def argument(self):
        """``(flags, keywords)`` of :meth:`argparse.ArgumentParser.add_argument`."""
        given = {"action": self.action, "help": _plain(self.help), "metavar": self.metavar, "nargs": self.nargs,
                 "type": {"int": int, "float": float}.get(self.type), "required": self.required or None,
                 "choices": self.choices() if callable(self.choices) else self.choices,
                 "default": list(self.default) if self.action in ("append", "extend") else self.default}
        return (self.flag,), {key: value for key, value in given.items() if value is not None}


def _saved(opt, value):
    """``value`` of ``opt`` as the provenance record keeps it (plain JSON types)."""
    if opt.action == "store_true":
        return bool(value)
    if value is None or isinstance(value, str) or opt.kind == "value":
        return value
    if opt.kind == "path":
        return str(getattr(value, "path", value))  # a Dataset given instead of its name: its folder
    value = value.tolist() if hasattr(value, "tolist") else value  # a pose as numbers: a flat list
    return [x for v in value for x in _saved(opt, v)] if isinstance(value, (list, tuple)) else [value]


def _rst(text):
    """A help text as the docstring's reST: code in double backquotes, links as their text."""
    return re.sub(r"\[([^]]+)\]\(#[^)]+\)", r"\1", re.sub(r"(?<![`:])`([^`]+)`(?!`)", r"``\1``", text or ""))


def _plain(text):
    """A help text as the command line prints it: no markup (argparse's ``%`` escaped)."""
    return None if text is None else re.sub(r":\w+:`~?([^`]+)`", r"\1", _rst(text)).replace("``", "").replace("%", "%%")


def _markdown(text):
    """A help text as the README's markdown: a reST role as code."""
    return re.sub(r":\w+:`~?([^`]+)`", r"`\1`", text or "")


def _cell(opt):
    """The option column of the docs: ``--method ipopt|gn|...``, ``--sigma MM``, ``DATASET``."""
    choices = opt.choices() if callable(opt.choices) else opt.choices
    if not opt.flag.startswith("-"):
        return f"`{opt.metavar or opt.flag.upper()}`"
    if opt.action == "store_true":
        return f"`{opt.flag}`"
    value = "|".join(map(str, choices)) if choices else opt.metavar or opt.dest.upper()
    many = f" [{value} ...]" if opt.nargs == "+" else ""
    return f"`{opt.flag} {value}{many}`" + (" (repeatable)" if opt.action in ("append", "extend") else "")


@dataclasses.dataclass(frozen=True)
class Command:
    """A command's help line, its options (its table) and the public function they are the
    keywords of (``'module:name'``, imported when the command runs; None: the command line's
    own); what is made from the table is made by its methods."""

    help: str
    options: tuple
    function: str | None = None

    @property
    def keyword_options(self):
        """The options that are keywords of the public function (not ``--json``)."""
        return tuple(opt for opt in self.options if opt.name)

    def keywords(self, values):
        """The public function's keywords from ``values``, the parsed arguments (``vars(args)``)."""
        return {opt.name: values[opt.dest] for opt in self.keyword_options}

    def given(self, scope):
        """The values the public function was called with: its keywords picked from ``scope``
        (its ``locals()``), in the table's order."""
        return {opt.name: scope[opt.name] for opt in self.keyword_options}

    def defaults(self):
        """The public function's keywords at their defaults (the table's)."""
        return {opt.name: opt.default for opt in self.keyword_options}

    def record(self, values):
        """The options saved with ``--out`` (``provenance['options']``): every keyword but
        ``out`` itself, as JSON values."""
        return {opt.name: _saved(opt, values[opt.name]) for opt in self.keyword_options if opt.name != "out"}

    def parameters(self):
        """The numpydoc ``Parameters`` section of the public function (options in a row with the
        same text and type share an entry)."""
        entries = []
        for opt in self.keyword_options:
            text, kind = _rst(opt.help), opt.python_type()
            if entries and entries[-1][1:] == [text, kind] and text:
                entries[-1][0] += f", {opt.name}"
            else:
                entries.append([opt.name, text, kind])
        lines = ["Parameters", "----------"]
        for names, text, kind in entries:
            lines += [f"{names} : {kind}"] + textwrap.wrap(text, 92, initial_indent="    ", subsequent_indent="    ",
                                                             break_on_hyphens=False)
        return "\n    ".join(lines)

    def documented(self, function):
        """Decorator: the ``{parameters}`` line of the public function's docstring becomes its
        ``Parameters`` section (:meth:`parameters`)."""
        if function.__doc__:  # None under python -OO, which strips docstrings
            function.__doc__ = function.__doc__.replace("{parameters}", self.parameters())
        return function

    def markdown(self):
        """The options as the README's markdown table: option, default, meaning (the README's
        tables are this text; tests/test_options.py checks that they are)."""
        rows = ["| option | default | meaning |", "|---|---|---|"]
        for opt in self.options:
            default = "" if opt.default in (None, ()) or opt.default is False else f"`{opt.default}`"
            cells = (_cell(opt), default, _markdown(opt.help) + (f" ({opt.unit})" if opt.unit else ""))
            rows.append("| " + " | ".join(cell.replace("|", "\\|") for cell in cells) + " |")
        return "\n".join(rows)
