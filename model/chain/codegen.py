"""Generate numpy and CasADi functions from the symbolic source, with a disk cache.

A symbolic expression set from :mod:`handeye.model.chain.symbolic` is turned into the source text of one
Python function (common subexpressions eliminated by ``sympy.cse``). The *same* text is
executed twice: once in a namespace where ``sin``, ``cos``, ``sqrt`` are numpy's (a function
vectorised over any batch of inputs), once where they are CasADi's (a function of SX
symbols). Nothing is written twice by hand.

Deriving and printing takes about a second; the source text is therefore cached on disk,
keyed by a hash of the symbolic module, this module, the module that chose the expressions
and the sympy version, so a warm
``handeye calibrate`` never touches sympy's differentiation. The cache lives in
``$HANDEYE_CACHE``, else ``$XDG_CACHE_HOME/handeye``, else ``~/.cache/handeye``. A
``$HANDEYE_CACHE`` that cannot be written (a read-only install's pre-filled cache) is still read,
and what it lacks goes to the user's cache; when no folder can be written the functions are
derived again on every run, and a :class:`CacheWarning` says so, once per process.
"""
from __future__ import annotations

import contextlib
import fcntl
import functools
import hashlib
import math
import os
import pathlib
import tempfile
import warnings
from importlib.metadata import version

import numpy as np

from handeye.model.common import scratch

_HERE = pathlib.Path(__file__).parent


class CacheWarning(UserWarning):
    """The generated-code cache cannot be written: every run derives the code again."""


def _user_cache():
    return pathlib.Path(os.environ.get("XDG_CACHE_HOME") or pathlib.Path.home() / ".cache") / "handeye"


def _writable(folder):
    """Could a file be made in ``folder`` (or in the existing folder it would be made under)?"""
    path = pathlib.Path(folder)
    while not path.exists():
        if path.parent == path:
            return False
        path = path.parent
    return path.is_dir() and os.access(path, os.W_OK | os.X_OK)


def cache_dirs():
    """Folders of the generated-code cache, in the order they are read: ``$HANDEYE_CACHE`` alone
    when it is set and writable; the user's cache after it when it is set but cannot be written;
    else the user's cache (see module docstring)."""
    env = os.environ.get("HANDEYE_CACHE")
    if not env:
        return [_user_cache()]
    if _writable(env):
        return [pathlib.Path(env)]
    return list(dict.fromkeys([pathlib.Path(env), _user_cache()]))


def cache_dir():
    """The folder the cache writes to: the first of :func:`cache_dirs` that can be written; None
    (after a :class:`CacheWarning`, once) when none can."""
    folders = cache_dirs()
    for folder in folders:
        if _writable(folder):
            return folder
    warn_unwritable(folders)
    return None


_WARNED = []


def warn_unwritable(folders, reason=None):
    """Say once per process that no cache folder can be written, which ones and why."""
    if _WARNED:
        return
    _WARNED.append(True)
    tried = ", ".join(str(f) for f in folders)
    warnings.warn(f"the generated-code cache cannot be written ({tried}: {reason or 'not writable'}): the code is "
                  "derived again on every run, several times slower; set HANDEYE_CACHE to a writable folder",
                  CacheWarning, stacklevel=3)


@functools.lru_cache(maxsize=None)
def _source_fingerprint(caller_file):
    """Hash of sympy's version, the symbolic source, this module and the module whose
    ``build`` chose the expressions (so a change to any of them invalidates the cache)."""
    h = hashlib.sha256(version("sympy").encode())
    for path in (_HERE / "symbolic.py", _HERE / "codegen.py", pathlib.Path(caller_file)):
        try:
            h.update(path.read_bytes())
        except OSError:
            h.update(str(path).encode())
    return h.hexdigest()[:16]


def _print_function(inputs, outputs):
    """Source text of ``def generated(<inputs>): ... return [<outputs>]``."""
    import sympy as sp

    printer = sp.printing.str.StrPrinter({"full_prec": True})
    flat = [sp.sympify(e) for e in outputs]
    subs, reduced = sp.cse(flat, symbols=sp.numbered_symbols("_c"))
    lines = [f"def generated({', '.join(str(s) for s in inputs)}):"]
    lines += [f"    {s} = {printer.doprint(v)}" for s, v in subs]
    lines.append("    return [" + ", ".join(printer.doprint(v) for v in reduced) + "]")
    return "\n".join(lines) + "\n"


def generated_source(name, build):
    """Source text of a generated function, from the cache or freshly derived.

    Parameters
    ----------
    name : str
        Cache key (unique per expression set).
    build : callable
        ``build() -> (inputs, outputs)``: the sympy input symbols (in argument order) and the
        flat list of output expressions. Called only on a cache miss.
    """
    file = f"{name}-{_source_fingerprint(build.__code__.co_filename)}.py"
    for folder in cache_dirs():
        cached = _read_checked(folder / file)
        if cached is not None:
            return cached
    folder = cache_dir()
    with _deriving(folder, file):  # processes that miss the same file at once: one derives, the others read it
        cached = None if folder is None else _read_checked(folder / file)
        if cached is not None:
            return cached
        inputs, outputs = build()
        text = _print_function(inputs, outputs)
        if folder is not None:
            _store(folder / file, text)
    return text


@contextlib.contextmanager
def _deriving(folder, file):
    """An exclusive lock on ``file``'s derivation in ``folder`` (a sweep's workers or a test run's
    processes starting on an empty cache derive each function once, not once each); no lock
    where the folder cannot be written or locked."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
        handle = open(folder / f".{file}.lock", "w")
    except (OSError, AttributeError):  # no folder (None), or one that cannot be written
        yield
        return
    with handle:
        try:
            fcntl.flock(handle, fcntl.LOCK_EX)
        except OSError:
            pass
        yield


def _store(path, text):
    """Write a cache file atomically (with its checksum); a failure only costs the next run time."""
    name_tmp = None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with scratch.signals_held():
            fh = tempfile.NamedTemporaryFile("w", dir=path.parent, delete=False, suffix=".tmp")
            name_tmp = fh.name
            scratch.register(name_tmp)
        with fh:
            fh.write(f"{_CHECK}{hashlib.sha256(text.encode()).hexdigest()}\n{text}")
        os.replace(name_tmp, path)
    except OSError as exc:
        if name_tmp is not None and os.path.exists(name_tmp):
            os.unlink(name_tmp)
        warn_unwritable([path.parent], exc.strerror or str(exc))
    finally:
        if name_tmp is not None:
            scratch.forget(name_tmp)


#: First line of a cache file: the SHA-256 of the rest, so that a truncated, emptied or edited
#: file is derived again instead of failing every later run.
_CHECK = "# sha256: "


def _read_checked(path):
    """The cached source text when it is whole (its checksum matches and it compiles), else None."""
    try:
        raw = path.read_text()
    except (OSError, UnicodeDecodeError):
        return None
    head, sep, text = raw.partition("\n")
    if not (sep and head.startswith(_CHECK) and head[len(_CHECK):] == hashlib.sha256(text.encode()).hexdigest()):
        return None
    try:
        compile(text, "<handeye-generated>", "exec")
    except (SyntaxError, ValueError):
        return None
    return text


def _compile(text, namespace):
    scope = dict(namespace)
    exec(compile(text, "<handeye-generated>", "exec"), scope)  # noqa: S102 - our own generated code
    return scope["generated"]


def numpy_function(text):
    """Compile generated source with numpy's elementary functions (flat list of outputs)."""
    return _compile(text, {"sin": np.sin, "cos": np.cos, "sqrt": np.sqrt, "sign": np.sign, "pi": math.pi,
                           "sinc": lambda x: np.sinc(np.asarray(x) / math.pi)})  # numpy's sinc is normalised


def math_function(text):
    """Compile generated source with the ``math`` module's functions: for one point given as
    Python floats it is several times faster than numpy's (no array overhead)."""
    return _compile(text, {"sin": math.sin, "cos": math.cos, "sqrt": math.sqrt, "pi": math.pi,
                           "sign": lambda v: math.copysign(1.0, v) if v else 0.0,
                           "sinc": lambda v: math.sin(v) / v if v else 1.0})


def casadi_function(text):
    """Compile generated source with CasADi's elementary functions (flat list of SX)."""
    import casadi as ca

    return _compile(text, {"sin": ca.sin, "cos": ca.cos, "sqrt": ca.sqrt, "sign": ca.sign, "pi": math.pi})


def stack_outputs(values, batch_shape):
    """Stack a flat list of scalars/arrays into one array of shape ``batch_shape + (len,)``.

    Filled output by output into a ``(len,) + batch_shape`` block and returned as a view with
    the outputs last (not C-contiguous): contiguous writes, several times faster than writing
    each output with a stride of ``len`` across a million rows."""
    out = np.empty((len(values),) + tuple(batch_shape))
    for k, v in enumerate(values):
        out[k] = v
    return np.moveaxis(out, 0, -1)
