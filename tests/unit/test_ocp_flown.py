"""A poor first guess is replaced by the dynamics flown from it before the job gives up, and an overflow that
remains says what happened (issue 35 item 4): real solves through the kind's ``run``, as a worker runs it.

The case is Rao and Mease's hyper-sensitive problem over a long horizon (OCAM 21(1), 2000, sec. 3.1; in
GPOPS-II's example set with tf = 10000): x' = -x^3 + u, x(0) = 1, x(tf) = 1.5, minimize 1/2 int (x^2 + u^2).
For so long a horizon the answer is two boundary layers joined by x = 0, whose costs the Hamilton-Jacobi
equation gives in closed form (the infinite-horizon value functions; the linearised closed loop decays at
rate 1, so tf = 10000 changes them by ~e^-5000): leaving x0, V(x0) = int_0^x0 (-s^3 + s sqrt(s^4 + 1)) ds,
and arriving at xf, W(xf) = int_0^xf (s^3 + s sqrt(s^4 + 1)) ds: J = V(1) + W(1.5) = 3.3620569 (GPOPS-II's
and Betts' tables report 3.3620559, 3e-7 below: their discretisation).
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import quad

from app.kinds.ocp import OcpParams, run
from tests.support import RecordingContext

TF = 10000.0
HYPERSENSITIVE = {
    "states": [{"name": "x", "initial": 1.0, "final": 1.5}], "controls": [{"name": "u"}],
    "time": {"initial": 0.0, "final": TF}, "dynamics": {"x": "-x**3 + u"},
    "objective": {"sense": "minimize", "integrand": "0.5*(x**2 + u**2)"},
}


def analytic_optimum() -> float:
    def layer(sign: float, end: float) -> float:
        return quad(lambda s: sign * s**3 + s * np.sqrt(s**4 + 1.0), 0.0, end, epsabs=1e-14, epsrel=1e-14)[0]
    return layer(-1.0, 1.0) + layer(1.0, 1.5)


def graded_boundaries(first_step_s: float, growth: float) -> list[float]:
    """Interval boundaries in [0, 1]: short in the boundary layers at both ends, growing geometrically
    towards the middle, where x = 0 and a long RK4 step is stable."""
    half, h = [0.0], first_step_s
    while half[-1] < TF / 2:
        half.append(min(half[-1] + h, TF / 2))
        h *= growth
    t = np.concatenate([half, TF - np.array(half[::-1][1:])])
    return (t / TF).tolist()


def outcome(body: dict):
    return run(OcpParams.model_validate(body), RecordingContext())


def test_the_closed_form_optimum():
    assert analytic_optimum() == pytest.approx(3.3620569049, abs=1e-9)


def test_a_graded_multiple_shooting_grid_is_recovered_by_the_flown_guess():
    # the straight line from 1 to 1.5 meets RK4 steps of up to ~300 s in the middle (h |lambda| = 3 x^2 h
    # ~ 1000): IPOPT overflows at the first guess.  Flown from x(0) = 1 with u = 0 the state decays to 0 and
    # every step is stable: the same grid then solves.
    b = graded_boundaries(0.025, 1.075)
    body = {**HYPERSENSITIVE, "transcription": {"method": "multiple_shooting", "intervals": len(b) - 1,
                                                "boundaries": b, "substeps": 4}}
    out = outcome(body)
    assert out.status == "succeeded", out.error
    assert any("the first guess overflowed (IPOPT Invalid_Number_Detected at iteration 0); solved from a guess "
               "flown from the dynamics" in n for n in out.result["notes"]), out.result["notes"]
    # RK4's h^4 on this grid: 138 intervals (first step 0.05 s, growth 1.15) miss the closed form by 7.4e-5,
    # these 266 by 5.3e-6 (a ratio of 14)
    assert out.result["objective"]["value"] == pytest.approx(analytic_optimum(), rel=1e-5)


def test_a_uniform_grid_overflows_whatever_the_guess_and_says_why():
    # 50 intervals x 2 RK4 steps of 100 s; at the fixed final value x(tf) = 1.5 (an NLP bound, so the flown
    # guess keeps it) the dynamics' rate is 3 x^2 = 6.75 1/s: h |lambda| = 675, past RK4's stability limit
    # 2.785 whatever the guess (at x(0) = 1 it is 300), so the flown guess overflows too
    out = outcome(HYPERSENSITIVE)
    assert out.status == "failed" and out.error["code"] == "numerical_overflow", out.error
    recovery = out.error["details"]["guess_recovery"]
    assert recovery["guess"] == "flown" and recovery["status"] == "Invalid_Number_Detected"
    stiff = recovery["rk4_stiffness"]
    assert stiff["t"] == TF and stiff["step"] == pytest.approx(100.0, rel=1e-12)
    assert stiff["rate"] == pytest.approx(6.75, rel=1e-12) and stiff["h_lambda"] == pytest.approx(675.0, rel=1e-12)
    message = out.error["message"]
    assert "RK4 steps of 100 s meet a rate |lambda| = 6.75 1/s of the dynamics at t = 10000 (h |lambda| = 675" \
        in message, message
    assert "steps at least 243 times shorter there" in message, message
    advice = " ".join(out.error["details"]["advice"])
    assert 'transcription.method "lgl"' in advice and "substeps" in advice


def test_a_guess_through_where_an_expression_is_undefined_is_recovered():
    # the user's straight line for x goes from 1 to -1: sqrt(x) is NaN on half the nodes.  Flown with the
    # middle of u's bounds (u = 1) the state stays at the equilibrium x = 1, where every expression is defined.
    body = {"states": [{"name": "x", "initial": 1.0}], "controls": [{"name": "u", "lower": 0.0, "upper": 2.0}],
            "time": {"initial": 0.0, "final": 2.0}, "dynamics": {"x": "u - sqrt(x)"},
            "objective": {"sense": "minimize", "integrand": "(x - 0.25)**2 + 0.1*u**2"},
            "transcription": {"intervals": 20}, "initial_guess": {"states": {"x": [1.0, -1.0]}}}
    out = outcome(body)
    assert out.status == "succeeded", out.error
    assert any("the first guess overflowed" in n for n in out.result["notes"])
    # the same problem from a harmless guess reaches the same optimum
    body["initial_guess"] = {}
    plain = outcome(body)
    assert plain.status == "succeeded"
    assert not any("the first guess overflowed" in n for n in plain.result["notes"])
    assert out.result["objective"]["value"] == pytest.approx(plain.result["objective"]["value"], rel=1e-6)
