"""A process's own peak memory, for ``handeye bench``'s measurements of child processes.

``resource.getrusage(...).ru_maxrss`` is no such figure on Linux: the kernel carries the
largest resident size over ``fork`` and ``exec`` (``RUSAGE_SELF`` of a freshly started
``python -c pass`` reports its parent's size), and ``RUSAGE_CHILDREN`` (or ``os.wait4``) is a
maximum over every child, each at least as large. The high-water mark of the address space
(``VmHWM`` in ``/proc/self/status``) starts afresh at ``exec``: that is the child's own peak.
This module imports nothing heavy, so that a child measuring itself stays small.
"""
from __future__ import annotations

import resource
import sys


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
