"""The test tiers hold (README, "Run the tests"): ``python -m pytest -q`` runs every test (CI);
``python -m pytest -q -m "not slow"`` leaves out the tests marked ``slow``.

One mechanism, the ``slow`` mark: no test decides for itself whether it runs (no environment
variable, no reading of ``-m``). Every slow test names its sibling in the default tier, which
keeps its point on a smaller problem, and every test file keeps tests in the default tier.
No time is measured here; the durations that chose the marks are in the README.
"""
import json
import pathlib
import re
import subprocess
import sys

import conftest
import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
TESTS = ROOT / "tests"

#: Slow by design: the independent generator's 200 cells and 12 seeds per slip (a minute each).
MUST_BE_SLOW = ["tests/test_independent_cells.py::test_200_correct_cells_converge_at_the_truth",
                "tests/test_independent_cells.py::test_slips_never_exit_0_at_a_wrong_pose_many_seeds"]


def _tiers():
    """node id -> (file, sibling, slow) for every test of tests/, whatever this run selected."""
    files = {p.relative_to(ROOT).as_posix() for p in TESTS.glob("test_*.py")}
    if files <= {f for f, _, _ in conftest.TIERS.values()}:
        return dict(conftest.TIERS)
    # this run collected part of the suite: collect all of it in a fresh process
    code = ("import json, sys, pytest; "
            "code = pytest.main(['--collect-only', '-q', '-p', 'no:cacheprovider', '-n', '0', 'tests']); "
            "import conftest; print('TIERS=' + json.dumps(conftest.TIERS)); sys.exit(code)")
    p = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stdout[-2000:] + p.stderr[-2000:]
    line = next(ln for ln in p.stdout.splitlines() if ln.startswith("TIERS="))
    return {k: tuple(v) for k, v in json.loads(line[len("TIERS="):]).items()}


@pytest.fixture(scope="module")
def tiers():
    return _tiers()


def test_the_slow_mark_is_registered(pytestconfig):
    assert any(m.split(":")[0].split("(")[0].strip() == "slow" for m in pytestconfig.getini("markers"))
    assert "-m" not in pytestconfig.getini("addopts")  # no tier is left out by default: CI runs every test


def test_the_independent_generators_long_runs_are_slow(tiers):
    for nodeid in MUST_BE_SLOW:
        assert tiers[nodeid][2], f"{nodeid} is not marked slow"


def test_every_slow_test_names_a_fast_sibling_in_its_file(tiers):
    for nodeid, (file, sibling, slow) in tiers.items():
        if not slow:
            continue
        assert sibling, f"{nodeid}: @pytest.mark.slow(sibling=...) names no default-tier test"
        matches = [n for n in tiers if n == f"{file}::{sibling}" or n.startswith(f"{file}::{sibling}[")]
        assert matches, f"{nodeid}: its sibling {sibling} is not a test of {file}"
        assert not any(tiers[n][2] for n in matches), f"{nodeid}: its sibling {sibling} is slow too"


def test_every_test_file_has_tests_in_the_default_tier(tiers):
    files = {f for f, _, _ in tiers.values()}
    fast = {f for f, _, slow in tiers.values() if not slow}
    assert files == fast, f"only slow tests in {sorted(files - fast)}"
    assert sum(not slow for *_, slow in tiers.values()) > 0.9 * len(tiers)


def test_no_test_decides_its_own_tier():
    for path in TESTS.glob("*.py"):
        if path.name == pathlib.Path(__file__).name:
            continue
        text = path.read_text()
        assert "HANDEYE_SLOW" not in text and 'getoption("markexpr")' not in text, path.name


def test_the_readme_names_both_tiers_and_ci_runs_its_command():
    readme = (ROOT / "README.md").read_text()
    section = readme.split("## Run the tests", 1)[1].split("\n## ", 1)[0]
    command = re.search(r"```bash\n(.*?)\n```", section, flags=re.S).group(1).strip()
    ci = [ln for ln in (ROOT / ".ci" / "run").read_text().splitlines() if ln.strip() and not ln.startswith(("#", "set ", "cd "))]
    assert ci == ["bash .ci/browser", command]  # headless Chromium when missing, then the README's command, verbatim
    assert "bash .ci/browser" in section and "chromium-driver" in section  # and the README says so
    assert command.endswith("python -m pytest -q")  # the full suite
    assert 'python -m pytest -q -m "not slow"' in section  # the default tier


def test_a_rate_check_in_shards_is_asserted_once_and_only_when_every_shard_ran(tmp_path):
    """tests/shards.py: the shard that completes the set gets every part, in shard order, once; until
    then the check is listed as unasserted (which fails the run, conftest.pytest_sessionfinish)."""
    import shards

    class Factory:  # where the run's folder is: a test's own, not this run's (whose checks must all be asserted)
        def getbasetemp(self):
            return tmp_path / "worker"

    root = shards.run_root(Factory())
    assert [len(s) for s in shards.shards(10, 3)] == [3, 4, 3] and sum(map(len, shards.shards(7, 7))) == 7
    assert shards.pool(Factory(), "rate", 1, 2, ["b"]) is None
    assert shards.unasserted(root) == [("rate", 1, "2")]
    assert shards.pool(Factory(), "rate", 0, 2, ["a"]) == [["a"], ["b"]]
    assert shards.unasserted(root) == [] and shards.pool(Factory(), "rate", 0, 2, ["a"]) is None
