"""A process's own peak memory, for ``handeye bench``'s measurements of child processes.

``resource.getrusage(...).ru_maxrss`` is no such figure on Linux: the kernel carries the
largest resident size over ``fork`` and ``exec`` (``RUSAGE_SELF`` of a freshly started
``python -c pass`` reports its parent's size), and ``RUSAGE_CHILDREN`` (or ``os.wait4``) is a
maximum over every child, each at least as large. The high-water mark of the address space
(``VmHWM`` in ``/proc/self/status``) starts afresh at ``exec``: that is the child's own peak.
This module imports nothing heavy, so that a child measuring itself stays small. It also
says which machine a measurement was taken on (:func:`machine`): a time or a memory figure
means little without it; and times calls (:func:`timed`, the bench's one timing loop, and :func:`once`).
"""
from __future__ import annotations

import datetime
import os
import platform
import resource
import sys
import time


def timed(function, reps):
    """``(wall times of reps calls of function in s, what the last call returned)``."""
    times, value = [], None
    for _ in range(reps):
        t0 = time.perf_counter()
        value = function()
        times.append(time.perf_counter() - t0)
    return times, value


def once(function):
    """``(wall time of one call of function in s, what it returned)``."""
    (seconds,), value = timed(function, 1)
    return seconds, value


def own_peak_kb():
    """Peak resident memory of this process since it was exec'd, kB (1024 bytes).

    Returns
    -------
    int
        ``VmHWM`` from ``/proc/self/status`` on Linux; elsewhere ``ru_maxrss`` of
        ``RUSAGE_SELF`` (bytes on macOS, converted), which is the process's own there.
    """
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1])
    except OSError:
        pass
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return peak // 1024 if sys.platform == "darwin" else peak


def machine():
    """Where and when a benchmark runs: the record ``handeye bench`` prints beside its figures.

    Returns
    -------
    dict
        ``host``, ``system`` (kernel and machine), ``processor``, ``cpus`` (``os.cpu_count``),
        ``load`` (the 1, 5 and 15 minute load averages, or None where the system has none),
        ``python``, ``date`` (UTC, ISO 8601, to the second).
    """
    try:
        load = [round(x, 2) for x in os.getloadavg()]
    except (OSError, AttributeError):
        load = None
    return {"host": platform.node(), "system": f"{platform.system()} {platform.release()} {platform.machine()}",
            "processor": platform.processor() or platform.machine(), "cpus": os.cpu_count(), "load": load,
            "python": platform.python_version(),
            "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")}


def machine_line(record):
    """:func:`machine`'s record as one line of a report."""
    load = "n/a" if record.get("load") is None else ", ".join(f"{x:.2f}" for x in record["load"])
    return (f"machine: {record['host']} ({record['system']}, {record['cpus']} cpus, Python {record['python']}), "
            f"load {load}, {record['date']}")
