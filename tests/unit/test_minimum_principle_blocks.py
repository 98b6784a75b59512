"""The minimum-principle check (:mod:`solvers.ocp.minimum_principle`) taken a block at a time: its answer does
not depend on the block (the same candidates, minima and worst gap to the bit), and the memory it allocates
follows the block, not candidates x samples (which took 2.6 GB on 20 controls over 150 intervals)."""
from __future__ import annotations

import tracemalloc

import numpy as np
import pytest

import solvers.ocp.optimality as optimality
from benchmarks.ocp_memory import single
from solvers.ocp import minimum_principle as mp
from solvers.ocp import parse_problem, solve


def _check_inputs(body: dict) -> dict:
    """The arguments the solve handed the check (its first call: the phase as solved)."""
    seen: list[dict] = []
    real = optimality.minimum_principle

    def keep(**kw):
        seen.append(kw)
        return real(**kw)

    optimality.minimum_principle = keep
    try:
        sol = solve(parse_problem(body))
    finally:
        optimality.minimum_principle = real
    assert sol.status.ok and seen
    return seen[0]


@pytest.fixture(scope="module", params=["linear", "constant"])
def inputs(request):
    """4 states and 4 controls (corners and grids) on 20 intervals, a mixed path constraint that binds; linear
    or piecewise-constant controls."""
    body = single(4, 4, 20)
    body["transcription"]["control"] = request.param
    body["path"] = [{"name": "mix", "expr": "u0 + u1 + x2", "upper": 0.2}]
    return _check_inputs(body)


def _peak_bytes(kw: dict, block: int) -> tuple[tuple, int]:
    tracemalloc.start()
    try:
        out = mp.minimum_principle(**kw, block=block)
        return out, tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def test_the_blocks_change_nothing_but_the_memory(inputs):
    nu, S = inputs["fns"].nu, inputs["dense"][0].size
    whole = nu * mp.candidate_count(nu) * S                  # every candidate at every sample at once
    big, big_peak = _peak_bytes(inputs, whole * 4)          # one block: the check unblocked
    small_block = 5_000
    small, small_peak = _peak_bytes(inputs, small_block)
    assert small == big                                      # same worst gap, time and samples, to the bit
    assert big[0] >= 0.0 and big[2] == S
    # the blocked check holds a few arrays of the block's size (candidates, tiled states and costates, H)
    # beside the re-flight's own (costates at the samples, the gaps), never candidates x samples
    per_sample = 8 * (2 * inputs["fns"].nx + 2 * nu + 8)
    bound = 16 * 8 * small_block + 4 * per_sample * S
    assert small_peak <= bound < 8 * whole, (small_peak, bound, big_peak)
    assert big_peak > 8 * whole                              # the unblocked one does hold them all


def test_sample_blocks_hold_whole_intervals():
    group = np.repeat(np.arange(5), [3, 1, 4, 2, 6])
    cuts = mp.sample_blocks(group, most=5)
    assert [(c.start, c.stop) for c in cuts] == [(0, 4), (4, 8), (8, 10), (10, 16)]   # the last one alone > 5
    assert mp.sample_blocks(np.arange(7), most=3) == [slice(0, 3), slice(3, 6), slice(6, 7)]
