"""Compile C (a hand-written driver plus CasADi-generated functions) once, cache the library.

The compiled paths (:mod:`handeye.model.compiled.fast`, :mod:`handeye.model.compiled.fast_starts`) write no
derivative by hand: CasADi generates C for the functions of the one symbolic source, and a
small driver in C runs the iteration around them. :func:`cached_library` compiles both with
the system C compiler (``$CC``, else ``gcc``, else ``cc``) into a shared library in the
generated-code cache (``<cache>/c``), keyed by a hash of the sources and flags, and loads it
through ctypes. A library is cached only when it loads and has the driver's symbols; its
SHA-256 is written beside it, so a damaged file is rebuilt, never opened. No compiler, or a
failed build: None (the callers then run their Python path, and say so).
"""
from __future__ import annotations

import ctypes
import hashlib
import os
import pathlib
import shutil
import subprocess
import time

from handeye.model.chain import codegen
from handeye.model.common import scratch

#: A build folder older than this (s) was left by a killed compile: removed.
STALE_BUILD_S = 3600.0
#: -ffp-contract=off: no fused multiply-adds, so that the C rounds where numpy rounds
CFLAGS = ("-O3", "-fPIC", "-shared", "-ffp-contract=off")


def _load(path, symbols):
    """The library at ``path`` when it loads and has every one of ``symbols``, else None."""
    try:
        dll = ctypes.CDLL(str(path))
        for name in symbols:
            getattr(dll, name)
    except (OSError, AttributeError):
        return None
    return dll


def _digest(path):
    return hashlib.sha256(pathlib.Path(path).read_bytes()).hexdigest()


def _intact(lib):
    """True when ``lib`` is the file its build recorded (the SHA-256 written beside it)."""
    try:
        return lib.is_file() and lib.with_name(lib.name + ".sha256").read_text().strip() == _digest(lib)
    except OSError:
        return False


def _remove_stale_builds(folder):
    try:
        for entry in folder.glob("tmp*"):
            if entry.is_dir() and time.time() - entry.stat().st_mtime > STALE_BUILD_S:
                shutil.rmtree(entry, ignore_errors=True)
    except OSError:
        pass


def compiler():
    """Path of the C compiler (``$CC``, ``gcc`` or ``cc``), or None."""
    return shutil.which(os.environ.get("CC", "gcc")) or shutil.which("cc")


def _build(lib, sources, flags, symbols):
    """Compile ``sources`` ({file name: text}) into ``lib``; a library that does not load is never cached."""
    cc = compiler()
    if cc is None:
        return None
    try:
        lib.parent.mkdir(parents=True, exist_ok=True)
        with scratch.temporary_folder(dir=lib.parent) as tmp:  # an interrupted build leaves no folder behind
            for name, text in sources.items():
                (pathlib.Path(tmp) / name).write_text(text)
            out = pathlib.Path(tmp) / "lib.so"
            subprocess.run([cc, *flags, *sources, "-o", str(out), "-lm"], cwd=tmp, check=True, capture_output=True,
                           timeout=300)
            if _load(out, symbols) is None:  # a compiler that exits 0 but writes a broken library
                return None
            digest = pathlib.Path(tmp) / "lib.sha256"
            digest.write_text(_digest(out))
            os.replace(out, lib)  # atomic: parallel workers never load a half-written library
            os.replace(digest, lib.with_name(lib.name + ".sha256"))
    except (OSError, subprocess.CalledProcessError, subprocess.TimeoutExpired):
        return None
    return _load(lib, symbols)


def cached_library(stem, sources, flags, symbols):
    """The compiled library of ``sources`` (ctypes), from the cache or built now; None without a compiler.

    Parameters
    ----------
    stem : str
        File name stem in the cache (``<stem>_<hash>.so``).
    sources : dict
        C file name -> text, compiled together in this order.
    flags : sequence of str
        Compiler flags (``-O3 -fPIC -shared`` and defines).
    symbols : sequence of str
        Functions the library must export.

    Returns
    -------
    ctypes.CDLL or None
    """
    key = hashlib.sha256("\0".join([*sources.values(), *flags]).encode()).hexdigest()[:16]
    for folder in codegen.cache_dirs():  # a read-only cache's library is as good as the user's
        lib = folder / "c" / f"{stem}_{key}.so"
        dll = _load(lib, symbols) if _intact(lib) else None  # a damaged file is never even opened (dlopen may crash)
        if dll is not None:
            return dll
    folder = codegen.cache_dir()
    if folder is None:  # no writable cache (said once by codegen): no compiled path
        return None
    _remove_stale_builds(folder / "c")  # missing, or damaged (truncated, emptied): build it again
    return _build(folder / "c" / f"{stem}_{key}.so", sources, flags, symbols)
