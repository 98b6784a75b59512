"""Shared fixtures (an embedded SQLite database for unit tests) and the time each marker took."""
from __future__ import annotations

import os
import sys
import time
from collections import defaultdict

import pytest

# The service defaults to TRAJLAB_AUTH=required (production); the suite runs
# with auth off unless a test builds its app with auth required
# (tests/integration/test_security.py). Worker subprocesses inherit this too.
os.environ.setdefault("TRAJLAB_AUTH", "off")
# No C compiles in the suite's solves (solvers/transcription/jit.py: `trajlab serve` turns them on
# for its worker); tests/unit/test_jit.py sets the mode itself.
os.environ.setdefault("TRAJLAB_JIT", "off")
# Bytecode caches (__pycache__, ignored by git) on for this process and every process it starts, whatever
# the shell says (some shells and CI images set PYTHONDONTWRITEBYTECODE), by make test/check or pytest run
# directly: under it each worker, recovery loop and CLI the suite starts (a few hundred, the fault tests'
# services among them) compiles its imports from source (7.4 s of CPU against 3.0 s for the worker's
# imports), and collection recompiles every test module.  Here once, for both ways of running the suite.
os.environ.pop("PYTHONDONTWRITEBYTECODE", None)
sys.dont_write_bytecode = False

from app.runtime.db import get_database  # noqa: E402 (after the environment above)
from app.runtime.migrate import upgrade  # noqa: E402


@pytest.fixture()
def sqlite_db(tmp_path):
    url = f"sqlite:///{tmp_path / 'trajlab.db'}"
    upgrade(url)
    db = get_database(url)
    yield db
    db.dispose()


# ----------------------------------------------------------------------------- one process per core
# `make test` and `make check` run the suite in pytest-xdist workers, a group of tests whole in one worker,
# one test after another: each test file is a group, so its module fixtures (a solve, a started service)
# are built once, as in one process.  Files that share something beyond their own servers and databases
# are one group: the guide's build writes app/static/guide, which the browser test serves; the files that
# read the presets' solves (tests/preset_results.py, cached per process) share them as in one process.
# The fault tests are one group, run one after another as in one process: two outages at once on 2 cores
# pushed their recovery past the stated bounds, and the worker-host tests hold fixed subnets.  Mostly
# waiting, they overlap the other worker's solves.  Everything else a test holds is its own: a PostgreSQL
# and a Redis database per worker's session (the integration conftest), servers on free ports, tmp dirs.
# (A scheduler of ours rather than xdist_group marks: xdist 3.8 writes the group into Node._nodeid, which
# pytest 9 no longer reads, so --dist loadgroup ran every test on its own.)
SHARED_GROUPS = {
    "tests/unit/test_docs_site.py": "guide",
    "tests/integration/test_guide_browser.py": "guide",
    **{f"tests/{path}.py": "presets" for path in (
        "unit/test_result_files", "unit/test_result_models", "unit/test_headlines", "unit/test_robust_objective",
        "unit/test_intercept_thrust", "integration/test_generated_client", "unit/test_ocp_catalogue",
        "unit/test_ocp_golden", "unit/test_progress_stages", "unit/test_ocp_robust_presets")},
}


def group_of(nodeid: str) -> str:
    """The group a test runs in (its file, unless :data:`SHARED_GROUPS` or the fault tests say otherwise)."""
    path = nodeid.split("::", 1)[0]
    return "faults" if path.startswith("tests/faults/") else SHARED_GROUPS.get(path, path)


@pytest.hookimpl(optionalhook=True)  # a hook of pytest-xdist, called only when it distributes
def pytest_xdist_make_scheduler(config, log):
    from xdist.scheduler import LoadScopeScheduling

    class ByGroup(LoadScopeScheduling):
        def _split_scope(self, nodeid: str) -> str:
            return group_of(nodeid)

    return ByGroup(config, log)


# ----------------------------------------------------------------------------- time per marker
# `make test` ends with where its minutes went.  A test counts under the first of these markers it
# carries (a slow browser test is a browser test), "unit" if none; setup and teardown included,
# so a session fixture's start-up (the integration service) counts where it is first used.  Under xdist the
# figures add up every worker's time, so together they exceed the wall clock.
_CATEGORIES = ("faults", "browser", "slow", "integration")
_spent: dict[str, list[float]] = defaultdict(lambda: [0.0, 0])
_started = time.monotonic()


def _category(keywords) -> str:
    return next((c for c in _CATEGORIES if c in keywords), "unit")


def pytest_runtest_logreport(report):
    entry = _spent[_category(report.keywords)]
    entry[0] += report.duration
    if report.when == "call" or (report.when == "setup" and report.outcome != "passed"):
        entry[1] += 1


def pytest_terminal_summary(terminalreporter):
    if not _spent:
        return
    tr = terminalreporter
    tr.section("time per marker")
    for name in ("unit", "integration", "browser", "faults", "slow"):
        seconds, count = _spent.get(name, (0.0, 0))
        tr.write_line(f"{name:<12} {count:5d} tests {seconds:8.1f} s")
    tr.write_line(f"{'wall clock':<12} {'':11} {time.monotonic() - _started:8.1f} s")
