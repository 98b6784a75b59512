"""Robust design on the LGL transcription (issue 37 item 2, "on both transcriptions"): the sensitivities collocated
with the mean against the covariance known in closed form, ``bryson-denham-robust`` on LGL against its closed-form
robust optimum and against multiple shooting, several phases on LGL (and mixed with shooting), each design
confirmed by its Monte Carlo flying the LGL interpolant of the controls.

LGL with ``n`` nodes per segment integrates a right-hand side that is a polynomial of degree <= n - 1 in time
exactly; the variational equations of the double integrator have such right-hand sides (S_v' = f_w, S_x' = S_v),
so its covariance is the closed form to round-off, and the filter y' = -y + b, whose sensitivity is 1 - e^-t, is
within the Lobatto rule's error: degree 2n - 3 = 7 exact, about h^9 / 9! (f^(8) = e^-t) ~ 1e-9 on a segment of
h = 0.2, 2e-13 measured.
"""
from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from solvers.ocp import PRESETS
from tests.support import robust_confirmed
from tests.unit.test_ocp_robust_phases import ONE, SB, SV, SW, SX, TWO

LGL = {"method": "lgl", "intervals": 5, "nodes": 5}


def _closed_form(design, *, y_atol: float) -> None:
    """S = dx/dw, w = [xi_x, xi_v, dw, db] (test_ocp_robust_phases.py); P = S Sigma S^T at every node."""
    for d in design.phases:
        t, n = d.t_nodes, 4                       # x, v, y and the integral of u^2
        S = d.Z[n:].reshape(n, 4, -1, order="F")
        w = np.array([1.0, 1.0, SW ** 2, SB ** 2])[:, None]
        np.testing.assert_allclose((S[1] ** 2 * w).sum(axis=0), SV ** 2 + (SW * t) ** 2, rtol=1e-12)
        np.testing.assert_allclose((S[0] ** 2 * w).sum(axis=0), SX ** 2 + (SV * t) ** 2 + (SW * t ** 2 / 2) ** 2,
                                   rtol=1e-12)
        np.testing.assert_allclose(np.abs(S[2, 3]) * SB, SB * (1.0 - np.exp(-t)), atol=y_atol)


def test_the_collocated_covariance_is_the_closed_form_and_the_monte_carlo_confirms_it():
    body = copy.deepcopy(ONE)
    body["transcription"] = LGL
    rs, block, _ = robust_confirmed(body)
    assert rs.solution.status.ok, rs.solution.status.message
    assert rs.solution.solver["method"] == "lgl" and rs.solution.solver["nodes_per_interval"] == 5
    assert rs.design.phases[0].t_nodes.size == 21             # 5 segments of 5 nodes, the ends shared
    _closed_form(rs.design, y_atol=1e-9)
    # the objective's sigma: final(y) carries b's 1 - e^-1, the integral of u^2 is certain (open loop)
    assert block["objective"]["cadet_std"] == pytest.approx(SB * (1.0 - math.exp(-1.0)), abs=1e-9)
    assert block["confirmed"] is True and block["k_constraints"] == 2.0
    # the limit v <= 1.6 held at mean + 2 sigma at the nodes and, by CADET between them, on the interpolant
    assert rs.prediction["constraints"]["v_max"]["excess_scaled_dense"] <= 1e-3
    # the Monte Carlo's mean objective is CADET's within its sampling error (2000 draws, 4 standard errors)
    o = block["objective"]
    assert abs(o["mean"] - o["cadet_mean"]) <= 4 * o["cadet_std"] / math.sqrt(block["samples"]) + 1e-6


def test_several_lgl_phases_and_a_mixed_pair_carry_the_covariance_across_the_link():
    for second in (LGL, {"method": "multiple_shooting", "intervals": 10, "control": "constant", "substeps": 2}):
        body = copy.deepcopy(TWO)
        body["phases"][0]["transcription"], body["phases"][1]["transcription"] = LGL, second
        rs, block, _ = robust_confirmed(body)
        assert rs.solution.status.ok, rs.solution.status.message
        # RK4 on the shooting phase: its exp(-t) within (h/2)^4 / 120 ~ 3e-9 (test_ocp_robust_phases.py)
        _closed_form(rs.design, y_atol=1e-8)
        a, b = rs.design.phases
        np.testing.assert_allclose(b.Z[4:, 0].reshape(4, 4, order="F")[:3], a.Z[4:, -1].reshape(4, 4, order="F")[:3],
                                   atol=1e-12)
        assert block["objective"]["cadet_std"] == pytest.approx(SB * (1.0 - math.exp(-1.0)), abs=1e-8)
        assert block["confirmed"] is True


# --- bryson-denham-robust on LGL ------------------------------------------------------------------------------------
def _bryson_denham_robust_optimum(sigma: float = 0.01, k: float = 3.0, limit: float = 1.0 / 9.0) -> float:
    """The robust design keeps x + k sigma t <= l (sigma_x = sigma t exactly, test_ocp_robust_presets.py).  With
    y = x + k sigma t: y'' = u, y(0) = 0, y'(0) = a = 1 + k sigma, y(1) = k sigma, y'(1) = -b, b = 1 - k sigma,
    y <= l: Bryson & Ho sec. 3.11's problem with unequal ends.  Its optimum rides the limit between two cubic arcs
    that meet it with u = 0 (second-order constraint): the entry arc costs (2/9) a^3 / l over t1 = 3 l / a, the exit
    (2/9) b^3 / d with d = l - k sigma over 3 d / b (t1 + 3 d / b = 0.57 < 1, so the arc exists); sigma = 0 gives
    the classical 4 / (9 l) = 4."""
    a, b, d = 1.0 + k * sigma, 1.0 - k * sigma, limit - k * sigma
    assert 3 * limit / a + 3 * d / b < 1.0
    return 2.0 / 9.0 * (a ** 3 / limit + b ** 3 / d)


def _objectives(method: str, intervals: tuple[int, ...]) -> dict[int, float]:
    found = {}
    for m in intervals:
        body = copy.deepcopy(PRESETS["bryson-denham-robust"]["params"])
        body["transcription"] = ({"method": "lgl", "intervals": m, "nodes": 4} if method == "lgl"
                                 else {**body["transcription"], "intervals": m})
        rs, block, _ = robust_confirmed(body, seed=0)
        assert rs.solution.status.ok and block["confirmed"] is True, rs.solution.status.message
        found[m] = rs.solution.objective
    return found


def _within_its_estimate(found: dict[int, float], coarse: int, fine: int, best: float) -> float:
    """The corners of u at the arc's junctions (u' jumps) keep either transcription at low order there, so a
    grid's error is measured by the same transcription on the nested grid (twice the intervals): the coarse
    answer must be within 1.5 times that estimate of the truth (4/3 for a second-order error), the fine one
    closer."""
    estimate = abs(found[coarse] - found[fine])
    assert abs(found[coarse] - best) <= 1.5 * estimate, (found, best)
    assert abs(found[fine] - best) < abs(found[coarse] - best)
    return estimate


def test_bryson_denham_robust_on_lgl_reaches_the_closed_form_optimum():
    best = _bryson_denham_robust_optimum()
    assert best == pytest.approx(4.6859280, abs=1e-7)
    lgl = _objectives("lgl", (30, 60))                   # measured 4.685861 and 4.685926
    _within_its_estimate(lgl, 30, 60, best)


@pytest.mark.slow
def test_bryson_denham_robust_on_lgl_and_on_shooting_agree_within_their_estimates():
    """Both on about the same 91 nodes (the preset's 90 shooting intervals; 30 LGL segments of 4 nodes)."""
    best = _bryson_denham_robust_optimum()
    lgl, ms = _objectives("lgl", (30, 60)), _objectives("multiple_shooting", (90, 180))
    e_lgl, e_ms = _within_its_estimate(lgl, 30, 60, best), _within_its_estimate(ms, 90, 180, best)
    assert abs(lgl[30] - ms[90]) <= 1.5 * (e_lgl + e_ms), (lgl, ms)      # measured 4.685861 and 4.685897
