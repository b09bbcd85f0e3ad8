"""A rate check over many seeded cells, run as shards that pool their results.

A statistical rate (a false-alarm rate over 50 clean cells, a coverage over 100 seeds) needs all
its cells to keep its power, but one test that computes them all runs for minutes on one core.
Split into shards (``@pytest.mark.parametrize("shard", range(K))``), each computes its part and
checks what holds cell by cell; :func:`pool` stores the part in the run's shared folder (the one
parent of every pytest-xdist worker's temporary folder) and, once every shard of the check has
stored its part, returns all of them, in shard order, to the shard that completed the set, which
asserts the rate over the whole. Shards run in any order, on any worker; a run that selects only
some shards (``-k``) checks those cell by cell and leaves the rate unasserted, saying so.
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
        (folder / f"{shard}.json").write_text(json.dumps(part))
        stored = sorted(folder.glob("*.json"), key=lambda p: int(p.stem))
        if len(stored) < n_shards:
            return None
        done = folder / ".asserted"
        if done.exists():  # completed by another shard already (its assertion ran once)
            return None
        done.touch()
        return [json.loads(p.read_text()) for p in stored]
