"""Issue 36 item 1: the ``ocp`` memory estimate from the whole problem (every phase's intervals, steps and
width, the check solve's finer mesh), held within 2x of the peak measured in a child process
(``benchmarks/ocp_memory.py``) for a wide single-phase and a multi-phase case."""
from __future__ import annotations

import pytest

from app.service.job_memory import measured_mb
from benchmarks.ocp_memory import measure, phased, single


def test_every_phase_counts():
    one = measured_mb("ocp", single(4, 2, 300))
    three = measured_mb("ocp", phased(3, 4, 2, 300))
    assert one is not None and three is not None
    double = measured_mb("ocp", single(4, 2, 600))
    assert double is not None
    assert three - one == pytest.approx(2 * (double - one), rel=1e-9)   # each phase adds its own NLP


@pytest.mark.slow
@pytest.mark.parametrize("params", [single(20, 8, 100), phased(3, 4, 2, 300)], ids=["wide", "three-phase"])
def test_the_estimate_is_within_2x_of_the_measured_peak(params):
    peak = measure(params, timeout_s=900)
    assert peak["status"] == "succeeded"
    estimate = measured_mb("ocp", params)
    assert estimate is not None
    assert 0.5 <= estimate / peak["peak_mb"] <= 2.0, (estimate, peak)
