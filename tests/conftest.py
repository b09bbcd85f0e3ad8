"""Shared fixtures: a small seeded generator of simulated datasets, a private code cache, and
an import blocker for optional dependencies; and the record of the test tiers.

Tiers (README, "Run the tests"): ``python -m pytest -q`` runs every test (CI); ``python -m
pytest -q -m "not slow"`` leaves out the tests marked ``slow``, each of which names the fast
test of the default tier that keeps its point: ``@pytest.mark.slow(sibling="test_name")``.
tests/test_tiers.py checks the marks from the record kept here."""
from __future__ import annotations

import builtins
import os
import pathlib
import time

import numpy as np
import pytest
import shards

from handeye.model.chain.pose import pose_from_transform, transform_from_pose

#: Every collected test (before ``-m``/``-k`` deselect any): node id -> (file, the ``slow``
#: mark's sibling or None when not slow, whether slow). Filled by the hook below.
TIERS = {}


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config, items):
    """Record every test's tier before ``-m "not slow"`` deselects the slow ones, and run the
    slow tests last (a stable sort: the default tier keeps its order), so that the time the last
    default-tier test ends is the default tier's own wall time, measured inside the full run."""
    for item in items:
        mark = item.get_closest_marker("slow")
        TIERS[item.nodeid] = (item.nodeid.split("::")[0], mark.kwargs.get("sibling") if mark else None, mark is not None)
    items.sort(key=lambda item: item.get_closest_marker("slow") is not None)


#: How many tests of the default tier this run selected (each pytest-xdist worker collects them all).
SELECTED = {"default": 0}
#: A slow test waits for the default tier to end, unless no default test has ended for this long
#: (s; a worker lost mid-test must not hang the run): the longest default test takes ~12 s.
STALL = 120.0


def pytest_collection_finish(session):
    SELECTED["default"] = sum(item.get_closest_marker("slow") is None for item in session.items)


def _ended(config):
    """The file in which each worker marks, a byte a test, the default-tier tests it ended."""
    return shards.run_root(config._tmp_path_factory) / "default-tier.ended"


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    """The slow tests start when every default-tier test has ended, on every worker: the time
    printed for the default tier inside the full run is then its own, as when it runs alone (a
    worker idles at most as long as the other's last default tests; CPU-heavy slow tests
    started beside them took up to a minute off them)."""
    slow = item.get_closest_marker("slow") is not None
    if slow and _waits(item.config):
        _wait_for_the_default_tier(_ended(item.config))
    yield
    if not slow:
        with open(_ended(item.config), "ab") as fh:  # one byte, appended: workers never overwrite each other
            fh.write(b".")


def _waits(config):
    """Only a pytest-xdist worker waits (in one process the tests run in their sorted order), and
    not when ``--ff``/``--nf`` put tests before the sort's order (a worker would hold default tests
    queued behind the slow one it waits in)."""
    reordered = config.getoption("failedfirst", False) or config.getoption("newfirst", False)
    return bool(os.environ.get("PYTEST_XDIST_WORKER")) and not reordered


def _wait_for_the_default_tier(path):
    seen, since = -1, time.monotonic()
    while True:
        count = path.stat().st_size if path.exists() else 0
        if count >= SELECTED["default"] or time.monotonic() - since > STALL:
            return
        if count != seen:
            seen, since = count, time.monotonic()
        time.sleep(0.2)


#: The run's clock (on the controller, which every pytest-xdist worker reports to): when the
#: session started, and per test its tier, its time (setup, call and teardown) and when it ended.
CLOCK = {"start": None, "tests": {}}


def pytest_sessionstart(session):
    CLOCK["start"] = time.monotonic()


def pytest_runtest_logreport(report):
    slow, seconds, _ = CLOCK["tests"].get(report.nodeid, ("slow" in report.keywords, 0.0, None))
    CLOCK["tests"][report.nodeid] = (slow, seconds + report.duration, time.monotonic())
    if report.when == "call":  # measured figures a test prints in CI's summary (record_property("printed", ...))
        CLOCK.setdefault("printed", []).extend(v for k, v in report.user_properties if k == "printed")


@pytest.hookimpl(trylast=True)
def pytest_sessionfinish(session, exitstatus):
    """A rate check run in shards (tests/shards.py) whose rate no shard asserted fails the run."""
    factory = getattr(session.config, "_tmp_path_factory", None)
    if os.environ.get("PYTEST_XDIST_WORKER") or factory is None or factory._basetemp is None:
        return
    CLOCK["unasserted"] = shards.unasserted(factory.getbasetemp())
    if CLOCK["unasserted"] and session.exitstatus == 0:
        session.exitstatus = pytest.ExitCode.TESTS_FAILED


def pytest_terminal_summary(terminalreporter, config):
    """The tiers' times (README, "Run the tests"): wall time of the default tier (its last test's
    end; the slow tests run after it) and of the whole run, and the test time in each tier."""
    line = terminalreporter.write_line
    for name, stored, expected in CLOCK.get("unasserted", ()):
        line(f"rate check {name}: {stored} of {expected} shards stored their part: its rate was NOT asserted "
             "(run every shard: tests/shards.py)", red=True)
    for text in CLOCK.get("printed", ()):
        line(text)
    if not CLOCK["tests"] or CLOCK["start"] is None:
        return
    workers = getattr(config.option, "numprocesses", None) or 1
    for slow, name in ((False, "default tier"), (True, "slow tests")):
        runs = [(s, end) for k, (is_slow, s, end) in CLOCK["tests"].items() if is_slow == slow]
        if runs:
            wall = max(end for _, end in runs) - CLOCK["start"]
            line(f"tier time: {name}: {len(runs)} tests, {sum(s for s, _ in runs):.0f} s of test time, "
                 f"done {wall:.0f} s ({wall / 60:.1f} min) after the start")
    wall = time.monotonic() - CLOCK["start"]
    line(f"tier time: this run: {len(CLOCK['tests'])} tests, {wall:.0f} s ({wall / 60:.1f} min) wall, "
         f"{workers} worker(s)")


def simulated_poses(rng, n):
    """Flange poses looking at a sphere near (1500, -600, 1100) from varied orientations."""
    poses = []
    for _ in range(n):
        a = rng.uniform(-180, 180)
        b = rng.uniform(-60, 60)
        c = rng.uniform(-180, 180)
        poses.append([rng.uniform(1100, 1800), rng.uniform(-900, -300), rng.uniform(1200, 1550), a, b, c])
    return np.array(poses)


def write_dataset(folder, poses, centres, start, centre, diameter=59.94507, truth=None, ids=None):
    """Write a dataset folder in our format; returns the folder."""
    folder = pathlib.Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    ids = ids or [f"m{k}" for k in range(len(poses))]
    lines = ["id,x,y,z,a,b,c,xs,ys,zs"]
    for i, p, xs in zip(ids, poses, centres):
        lines.append(",".join([i] + [repr(float(v)) for v in p] + [repr(float(v)) for v in xs]))
    (folder / "measurements.csv").write_text("\n".join(lines) + "\n")
    toml = [
        "[sensor]",
        f"start_pose = [{', '.join(repr(float(v)) for v in start)}]",
        "[sphere]",
        f"diameter = {diameter}",
        f"center = [{', '.join(repr(float(v)) for v in centre)}]",
    ]
    if truth is not None:
        toml += ["[truth]", f"sensor_pose = [{', '.join(repr(float(v)) for v in truth)}]"]
    (folder / "setup.toml").write_text("\n".join(toml) + "\n")
    return folder


def simulate(folder, seed=0, n=20, noise_mm=0.05, truth=(190.0, 100.0, 130.0, 178.0, -88.0, 0.5), start_offset=None):
    """A simulated dataset with known truth; noise added to the measured centres (mm, sd)."""
    rng = np.random.default_rng(seed)
    t_true = transform_from_pose(truth)
    centre = np.array([1534.0, -603.0, 1119.0])
    # poses whose sensor sees the sphere within its range: the centre lies at a varied point
    # of the sensor frame (|y| below the radius, z in the 190-290 mm measuring range)
    poses = []
    for _ in range(n):
        rot = transform_from_pose([0, 0, 0, *rng.uniform([-180, -70, -180], [180, 70, 180])])[:3, :3]
        seen_at = rng.uniform([-20.0, -25.0, 190.0], [20.0, -3.0, 290.0])
        sensor_in_base = np.eye(4)
        sensor_in_base[:3, :3] = rot
        sensor_in_base[:3, 3] = centre - rot @ seen_at
        flange = sensor_in_base @ np.linalg.inv(t_true)
        poses.append(pose_from_transform(flange))
    poses = np.array(poses)
    f2b = transform_from_pose(poses)
    xs = np.linalg.solve(f2b @ t_true, np.append(centre, 1.0))[:, :3]
    xs = xs + rng.normal(0.0, noise_mm, xs.shape)
    start = np.array(truth) + (np.array(start_offset) if start_offset is not None else np.array([8, -6, 5, 3, 2, -3.0]))
    return write_dataset(folder, poses, xs, start, centre, truth=truth)


def run_cache(tmp_path_factory):
    """The generated-code cache of this test run: apart from the user's, built once per run and
    shared by every pytest-xdist worker of the run (in the folder they share,
    :func:`shards.run_root`; one derivation per file, each written atomically)."""
    folder = shards.run_root(tmp_path_factory) / "handeye-cache"
    folder.mkdir(exist_ok=True)
    return folder


@pytest.fixture(autouse=True, scope="session")
def _private_cache(tmp_path_factory):
    """Keep the generated-code cache of the test run apart from the user's (:func:`run_cache`)."""
    old = os.environ.get("HANDEYE_CACHE")
    os.environ["HANDEYE_CACHE"] = str(run_cache(tmp_path_factory))
    yield
    if old is None:
        os.environ.pop("HANDEYE_CACHE", None)
    else:
        os.environ["HANDEYE_CACHE"] = old


@pytest.fixture
def break_solver(monkeypatch):
    """Call to make every solve of a calibration end at a non-finite point (a numerical failure)."""
    import dataclasses

    from handeye.app.engine import fitting as engine  # the final fit's solver calls

    real_solve = engine.solvers.solve

    def broken(problem, x0, method, options=None):
        res = real_solve(problem, x0, method=method, options=options)
        return dataclasses.replace(res, x=np.full_like(res.x, np.nan), converged=False, status=-1,
                                   message="numerical failure (injected)")

    return lambda: monkeypatch.setattr(engine.solvers, "solve", broken)


@pytest.fixture
def without_package(monkeypatch):
    """``without_package("name")`` makes ``import name`` (and its submodules) fail for the test,
    as on a machine where the optional dependency is not installed."""
    real_import = builtins.__import__

    def block(package):
        def importer(name, *args, **kwargs):
            if name.split(".")[0] == package:
                raise ImportError(f"{package} is not installed here")
            return real_import(name, *args, **kwargs)

        monkeypatch.setattr(builtins, "__import__", importer)

    return block
