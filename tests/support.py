"""Test doubles of the service side (never of a solver): a job context without a worker."""
from __future__ import annotations

import time

from app.kinds.base import InProcessContext


class RecordingContext(InProcessContext):
    """:class:`app.kinds.base.InProcessContext` under the name the tests use (job id ``test``)."""

    def __init__(self, stored: dict | None = None, stop_after: int | None = None):
        super().__init__(stored, stop_after, job_id="test")


# How long a freshly started service process may take to answer.  It is a wait for a state, not a speed
# bound: the API's start imports CasADi-free FastAPI in 2-3 s on a quiet machine and took 46 s at load 14
# on 2 cores (a 60 s bound failed there).  A process that exits fails the wait at once, with its log.
START_TIMEOUT_S = 300.0


def wait_serving(url: str, *, proc, what: str, log=None, status: int | None = None,
                 timeout: float = START_TIMEOUT_S):
    """The first answer of ``url`` (of HTTP ``status`` if given, else any) from the process ``proc`` (a
    ``subprocess.Popen``), polled until ``timeout``; an assertion naming ``what`` (and the tail of ``log``, a
    path) when the process exits first or the time runs out."""
    import time
    from pathlib import Path

    import httpx

    def tail() -> str:
        return Path(log).read_text(errors="replace")[-3000:] if log is not None and Path(log).exists() else ""

    deadline = time.monotonic() + timeout
    while True:
        assert proc.poll() is None, f"{what} exited with {proc.returncode} before answering\n{tail()}"
        try:
            r = httpx.get(url, timeout=5)
            if status is None or r.status_code == status:
                return r
        except httpx.HTTPError:
            pass
        assert time.monotonic() < deadline, f"{what} did not answer {url} within {timeout:.0f} s\n{tail()}"
        time.sleep(0.3)


# A bound on a wait for a state in a test of our own threads: it only ends a test that would otherwise hang.
UNTIL_BOUND_S = 30.0


def until(predicate, what: str, bound_s: float = UNTIL_BOUND_S):
    """Poll ``predicate`` every 20 ms until it is truthy (its value is returned); past ``bound_s``, fail naming ``what``."""
    deadline = time.monotonic() + bound_s
    while not (value := predicate()):
        assert time.monotonic() < deadline, what
        time.sleep(0.02)
    return value


def robust_confirmed(body: dict, seed: int = 4):
    """A robust ``ocp`` body designed and confirmed in this process, as the kind runs it (the design, the
    result's ``robust`` block, the Monte Carlo summary): ``solvers.ocp.robust.solver.design_and_confirm``."""
    import copy

    from solvers.ocp import parse_problem
    from solvers.ocp.robust.solver import design_and_confirm
    from solvers.uncertainty.montecarlo import run_monte_carlo

    return design_and_confirm(parse_problem(copy.deepcopy(body)), params=body, run_monte_carlo=run_monte_carlo,
                              seed=seed)
