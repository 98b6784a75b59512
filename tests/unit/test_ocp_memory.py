"""Issue 36 item 1: the ``ocp`` memory estimate from the whole problem (every phase's intervals, steps and
width, the check solve's finer mesh), held within 2x of the peak measured in a child process
(``benchmarks/ocp_memory.py``) for a wide single-phase and a multi-phase case."""
from __future__ import annotations

import copy
import json

import pytest

from app.kinds import PRESETS
from app.kinds.ocp.footprint import BLOCK, FLOOR_MB, PER_CHECK_NUMBER_MB, candidates_mb, check_block_numbers
from app.kinds.ocp.kind import cost
from app.kinds.ocp.size import phase_sizes
from app.service.job_memory import measured_mb
from benchmarks.ocp_memory import measure, phased, single
from benchmarks.results import LATEST


def test_every_phase_counts_and_the_checks_hold_one_phase_at_a_time():
    """Each phase adds its own NLP; the minimum-principle check's candidates are one phase's (the largest)."""
    one, three = single(4, 2, 300), phased(3, 4, 2, 300)
    one_mb, three_mb = measured_mb("ocp", one), measured_mb("ocp", three)
    assert one_mb is not None and three_mb is not None
    (ph,) = phase_sizes(one)
    nlp = one_mb - FLOOR_MB - candidates_mb(ph) - PER_CHECK_NUMBER_MB * check_block_numbers(ph)
    assert nlp > 0
    assert three_mb - one_mb == pytest.approx(2 * nlp, rel=1e-9)


def test_the_estimate_grows_with_the_expressions_at_equal_grid():
    """wider (50 x 20) > wide (30 x 10) on the same 150 intervals, and the same problem with a longer
    integrand (same states, controls and grid) is larger too: the expressions' parse-tree nodes count."""
    wide, wider = measured_mb("ocp", single(30, 10, 150)), measured_mb("ocp", single(50, 20, 150))
    assert wide is not None and wider is not None and wider > wide
    plain = single(4, 2, 300)
    longer = {**plain, "objective": {**plain["objective"],
                                     "integrand": plain["objective"]["integrand"] + " + 0.1*sin(x0)*cos(u1)" * 20}}
    (p,), (q,) = phase_sizes(plain), phase_sizes(longer)
    assert q.nodes > p.nodes + 20 * 10
    plain_mb, longer_mb = measured_mb("ocp", plain), measured_mb("ocp", longer)
    assert plain_mb is not None and longer_mb is not None and longer_mb > plain_mb


def test_the_estimate_grows_with_the_robust_sensitivities():
    """A robust design adds CADET's sensitivity states (states x (states + draws) per step): the robust
    shuttle is larger than its deterministic twin, and one more uncertain quantity makes it larger still;
    the cost counts the same sizes."""
    twin, robust = PRESETS["betts-shuttle-heat-limit-ocp"].params, PRESETS["betts-shuttle-robust-ocp"].params
    more = copy.deepcopy(robust)
    more["uncertainty"]["initial"] = {"h": {"sigma": 100.0}}
    twin_mb, robust_mb, more_mb = (measured_mb("ocp", p) for p in (twin, robust, more))
    assert twin_mb is not None and robust_mb is not None and more_mb is not None
    assert twin_mb < robust_mb < more_mb
    assert cost(twin) < cost(robust) < cost(more)


def test_the_check_is_bounded_whatever_the_width_and_length():
    """The minimum-principle check takes its candidates a block at a time (solvers.ocp.minimum_principle):
    its share of the estimate stays under one BLOCK of candidates and one of evaluated numbers from 2 to 20
    controls, 100 to 1,600 intervals, piecewise-constant controls included."""
    from benchmarks.ocp_memory import on_intervals

    tumor = PRESETS["tumor-antiangiogenesis"].params
    bodies = [single(n, m, k) for n, m in ((4, 2), (30, 10), (50, 20)) for k in (100, 400, 1600)]
    bodies += [on_intervals(tumor, k) for k in (400, 800, 1600)]
    bound = 8 * BLOCK / 1e6 + PER_CHECK_NUMBER_MB * BLOCK
    for body in bodies:
        for ph in phase_sizes(body):
            assert candidates_mb(ph) + PER_CHECK_NUMBER_MB * check_block_numbers(ph) <= bound


def test_the_check_sizes_are_the_solvers():
    """The footprint mirrors the minimum-principle check's constants so the API needs no CasADi: they agree."""
    from app.kinds.ocp import footprint
    from solvers.ocp import minimum_principle, verify

    assert (footprint.GRID, footprint.ZOOM, footprint.BLOCK, footprint.CORNERS) == (
        minimum_principle.GRID, minimum_principle.ZOOM, minimum_principle.BLOCK, minimum_principle.CORNERS)
    assert footprint.SAMPLES_PER_INTERVAL == verify.SAMPLES_PER_INTERVAL


def _recorded() -> list[tuple[str, dict, float]]:
    """Every peak the two benchmarks recorded (benchmarks/results/latest.json), with the body it ran."""
    from benchmarks.ocp_memory import CASES

    data = json.loads(LATEST.read_text())
    out = [(name, CASES[name](), f["peak_mb"]) for name, f in data["ocp_memory"]["figures"].items() if name in CASES]
    out += [(name, PRESETS[name].params, f["peak_mb"])
            for name, f in data["ocp_preset_memory"]["figures"].items() if name in PRESETS]
    return out


def test_the_estimate_is_within_2x_of_every_recorded_peak():
    """The model as it is now against every peak measured (every ocp preset and the wide, long, multi-phase
    and robust cases): within 2x each way, as issue 36 asks."""
    recorded = _recorded()
    assert len(recorded) >= 30
    off = {name: round(est / peak, 2) for name, body, peak in recorded
           if not 0.5 <= (est := measured_mb("ocp", body) or 0.0) / peak <= 2.0}
    assert not off, off


@pytest.mark.slow
@pytest.mark.parametrize("params", [single(20, 8, 100), phased(3, 4, 2, 300)], ids=["wide", "three-phase"])
def test_the_estimate_is_within_2x_of_the_measured_peak(params):
    peak = measure(params, timeout_s=900)
    assert peak["status"] == "succeeded"
    estimate = measured_mb("ocp", params)
    assert estimate is not None
    assert 0.5 <= estimate / peak["peak_mb"] <= 2.0, (estimate, peak)
