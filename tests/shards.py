"""A rate check over many seeded cells, run as shards that pool their results.

A statistical rate (a false-alarm rate over 50 clean cells, a coverage over 100 seeds) needs all
its cells to keep its power, but one test that computes them all runs for minutes on one core.
Split into shards (``@pytest.mark.parametrize("shard", range(K))``), each computes its part and
checks what holds cell by cell; :func:`pool` stores the part in the run's shared folder (the one
parent of every pytest-xdist worker's temporary folder) and, once every shard of the check has
stored its part, returns all of them, in shard order, to the shard that completed the set, which
asserts the rate over the whole. Shards run in any order, on any worker. A run that ran only some
shards of a check (``-k``, ``--lf``, a shard that failed) has not asserted its rate: the run fails,
naming the check (:func:`unasserted`, called by tests/conftest.py at the end of the session).
"""
from __future__ import annotations

import fcntl
import json
import os


def run_root(tmp_path_factory):
    """The folder every worker of this test run shares (a run without workers: its own)."""
    base = tmp_path_factory.getbasetemp()
    return base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base


def shards(n_items, n_shards):
    """The items (``range(n_items)``) of each of ``n_shards`` shards: contiguous, sizes within one."""
    bounds = [round(k * n_items / n_shards) for k in range(n_shards + 1)]
    return [range(bounds[k], bounds[k + 1]) for k in range(n_shards)]


def pool(tmp_path_factory, name, shard, n_shards, part):
    """Store this shard's ``part`` (JSON-able) of check ``name``; every shard's part, in shard
    order, when this call completed the set, else None."""
    folder = run_root(tmp_path_factory) / "shards" / name
    folder.mkdir(parents=True, exist_ok=True)
    with open(folder / ".lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        (folder / ".expected").write_text(str(n_shards))
        (folder / f"{shard}.json").write_text(json.dumps(part))
        stored = sorted(folder.glob("*.json"), key=lambda p: int(p.stem))
        if len(stored) < n_shards:
            return None
        done = folder / ".asserted"
        if done.exists():  # completed by another shard already (its assertion ran once)
            return None
        done.touch()
        return [json.loads(p.read_text()) for p in stored]


def unasserted(root):
    """``[(check, shards stored, shards expected)]`` of the checks in the run folder ``root`` whose
    rate no shard asserted (not every shard ran, or one failed before storing its part)."""
    out = []
    for folder in sorted((root / "shards").glob("*")):
        if folder.is_dir() and not (folder / ".asserted").exists():
            expected = (folder / ".expected").read_text() if (folder / ".expected").exists() else "?"
            out.append((folder.name, len(list(folder.glob("*.json"))), expected))
    return out
