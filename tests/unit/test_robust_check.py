"""The robust design's confirmation rules (solvers.robust_reentry.check): targets, tolerance, correction.

The numbers of a round come from a Monte Carlo summary; here the summaries are written by hand
so that each rule is checked at its edge (the loop itself runs on real solves in
tests/unit/test_robust_confirmation.py).
"""
from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from solvers.robust_reentry import check as rc

N = 10000


def _summary(kept: float, sd_h: float = 3800.0) -> dict:
    terminal = {"altitude_m": {"mean": 24384.0, "std": sd_h}, "speed_mps": {"mean": 762.0, "std": 200.0},
                "flight_path_rad": {"mean": -0.087, "std": 0.04}, "latitude_rad": {"mean": 0.5, "std": 0.0045}}
    return {"samples": N, "terminal": terminal,
            "path": {"heat_rate": {"kept_fraction": kept, "kept_fraction_nodes": kept, "limit": 794955.0}}}


def _prediction(sd_h: float = 3800.0):
    sigma = np.zeros((6, 3))
    sigma[:, -1] = [sd_h, 0.0, 0.0045, 200.0, 0.04, 0.0]
    # heating 3.2 sigma below the limit at its closest point
    return SimpleNamespace(sigma=sigma, heat_mean=np.array([5e5, 794955.0 - 3.2 * 1e4, 6e5]),
                           heat_sigma=np.array([1e4, 1e4, 1e4]))


LIMITS = {"altitude_m": 4500.0, "speed_mps": 250.0, "flight_path_rad": math.radians(3.0)}


def _assess(kept, sd_h=3800.0, k=3.0, correction=None, **kw):
    corr = correction or rc.Correction(k_constraint=k, sigma_limits=dict(LIMITS))
    return rc.assess(summary=_summary(kept, sd_h), prediction=_prediction(3800.0), objective_promised=0.49,
                     k_objective=3.0, k_constraint_user=k, correction=corr, sigma_limits_user=LIMITS,
                     settings=rc.LoopSettings(**kw))


def test_default_target_is_the_one_sided_normal_share_and_tolerance_binomial():
    rec = _assess(0.9990)
    h = rec["constraints"]["heat_rate"]
    assert h["target"] == pytest.approx(0.998650, abs=1e-6)
    # z(99%) = 2.326, sqrt(p (1 - p) / n) = 3.67e-4 at n = 10,000
    assert h["tolerance"] == pytest.approx(2.3263 * math.sqrt(0.99865 * 0.00135 / N), rel=1e-3)
    assert h["acceptance"] == pytest.approx(0.99780, abs=1e-5)
    assert h["promised"] == pytest.approx(rc.normal_share(3.2), rel=1e-12)
    assert rec["agrees"] is True
    assert rec["objective"]["monte_carlo"] == pytest.approx(0.5 - 3 * 0.0045, rel=1e-12)


def test_share_below_acceptance_disagrees_and_raises_kc_by_the_quantile_gap():
    rec = _assess(0.9954)          # the preset's first design
    assert rec["agrees"] is False
    assert rec["constraints"]["heat_rate"]["agrees"] is False
    nxt = rc.correct(rec, rc.Correction(k_constraint=3.0, sigma_limits=dict(LIMITS)), samples=N)
    gap = 3.0 - rc.quantile(0.9954)     # Phi^-1(Phi(3)) = 3
    assert gap == pytest.approx(0.3955, abs=1e-3)
    assert nxt.k_constraint == pytest.approx(3.0 + gap + rc.K_OVERSHOOT, rel=1e-12)
    assert nxt.sigma_limits == LIMITS   # the sigma limits agreed: untouched
    assert "99.54%" in rc.failure_message(rec) and "99.865%" in rc.failure_message(rec)
    assert rc.shortfall(rec) > 0


def test_share_just_inside_the_tolerance_agrees():
    assert _assess(0.99781)["agrees"] is True
    assert _assess(0.99779)["agrees"] is False
    # an explicit target replaces Phi(kC)
    assert _assess(0.9954, heat_target=0.995)["agrees"] is True


def test_sigma_above_its_limit_tightens_the_nlp_limit_by_mc_over_cadet():
    rec = _assess(1.0, sd_h=4600.0)
    c = rec["constraints"]["sigma_altitude_m"]
    assert c["agrees"] is False and rec["agrees"] is False
    assert c["monte_carlo_relative_standard_error"] == pytest.approx(1 / math.sqrt(2 * (N - 1)), rel=1e-12)
    nxt = rc.correct(rec, rc.Correction(k_constraint=3.0, sigma_limits=dict(LIMITS)), samples=N)
    assert nxt.k_constraint == 3.0
    assert nxt.sigma_limits["altitude_m"] == pytest.approx(4500.0 * 3800.0 / 4600.0 * rc.SIGMA_SAFETY, rel=1e-12)
    assert "sigma of the final altitude_m: Monte Carlo 4600 above the limit 4500" in rc.failure_message(rec)
    assert rc.shortfall(rec) == pytest.approx(4600 / 4500 - 1, rel=1e-12)


def test_no_correction_where_the_linearization_fails():
    rec = _assess(1.0, sd_h=3.5 * 3800.0)
    assert rc.correct(rec, rc.Correction(k_constraint=3.0, sigma_limits=dict(LIMITS)), samples=N) is None
