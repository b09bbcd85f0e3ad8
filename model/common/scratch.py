"""Temporary files and folders in flight, so that an interrupted run leaves none behind.

Whatever writes a temporary file or folder registers it while it exists (:func:`register`, or
:func:`temporary_folder` for a folder); the command line's handler of SIGINT and SIGTERM
(:mod:`handeye.app.command.cli`) ends the process at once -- ``os._exit``, as IPOPT and worker
pools would swallow a ``KeyboardInterrupt`` -- and first removes what is registered
(:func:`remove_all`). Creating and registering, and renaming and unregistering, happen with
those signals held back (:func:`signals_held`), so no moment leaves a temporary file unknown to
the handler.
"""
from __future__ import annotations

import contextlib
import os
import shutil
import signal
import tempfile
import threading

#: path -> True for a folder, False for a file (insertion order: removed newest first)
_PENDING = {}
_HELD = (signal.SIGINT, signal.SIGTERM)


@contextlib.contextmanager
def signals_held():
    """Hold SIGINT and SIGTERM back (on the main thread, where Python runs their handlers)
    until the block ends; they are delivered then."""
    if threading.current_thread() is not threading.main_thread() or not hasattr(signal, "pthread_sigmask"):
        yield
        return
    old = signal.pthread_sigmask(signal.SIG_BLOCK, _HELD)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


def register(path, folder=False):
    """Remember ``path`` (a temporary file, or a ``folder``) until :func:`forget`."""
    _PENDING[os.fspath(path)] = folder


def forget(path):
    """``path`` is gone or is no longer temporary (renamed into place)."""
    _PENDING.pop(os.fspath(path), None)


def remove_all():
    """Remove every registered file and folder (from a signal handler: never raises)."""
    for path, folder in reversed(list(_PENDING.items())):
        try:
            if folder:
                shutil.rmtree(path, ignore_errors=True)
            else:
                os.unlink(path)
        except OSError:
            pass
    _PENDING.clear()


@contextlib.contextmanager
def temporary_folder(**kwargs):
    """``tempfile.TemporaryDirectory(**kwargs)``, registered from its first moment to its last:
    the folder's path for the block, removed after it or by the signal handler."""
    with signals_held():
        folder = tempfile.TemporaryDirectory(**kwargs)
        register(folder.name, folder=True)
    try:
        with folder as path:
            yield path
    finally:
        forget(folder.name)
