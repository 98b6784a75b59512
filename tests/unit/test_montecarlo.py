"""Vectorized Monte Carlo: statistics against closed forms and CADET, chunk merging, step size, solve_ivp."""
from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from solvers.uncertainty.cadet import CadetSystem
from solvers.uncertainty.montecarlo import (
    MCModel, PathConstraint, merge_chunks, register_model, run_monte_carlo, simulate_chunk,
    standard_normals,
)

K0, C0 = 4.0, 0.3


def _oscillator_rhs(x, u, s):
    # stiffness K0 (1 + s0), forcing u: nonlinear in the augmented state (s * x)
    return np.stack([x[1], -K0 * (1.0 + s[0]) * x[0] - C0 * x[1] + u[0]])


def _oscillator(params):
    return MCModel(
        nx=2, nu=1, ns=1, rhs=_oscillator_rhs,
        terminal=lambda x, **_: {"pos": x[0], "vel": x[1]},
        path={"pos": PathConstraint(fn=lambda x, u, s: x[0], limit=float(params.get("pos_limit", 1.05)))},
    )


def _decay(params):
    return MCModel(nx=1, nu=1, ns=1, rhs=lambda x, u, s: -s[0] * x, terminal=lambda x, **_: {"x": x[0]})


def _traced_oscillator(params):
    return MCModel(
        nx=2, nu=1, ns=1, rhs=_oscillator_rhs, terminal=lambda x, **_: {"pos": x[0], "vel": x[1]},
        trace=lambda x, u, s: {"pos": x[0], "energy": 0.5 * x[1] ** 2 + 0.5 * K0 * (1.0 + s[0]) * x[0] ** 2},
        sampled_terminal=("pos",))


register_model("test_oscillator", _oscillator)
register_model("test_traced_oscillator", _traced_oscillator)
register_model("test_decay", _decay)


def _osc_spec(substeps=10):
    t = np.linspace(0.0, 4.0, 41)
    return {
        "model": "test_oscillator", "model_params": {"pos_limit": 1.0},
        "t_nodes": t.tolist(), "controls": [np.cos(t).tolist()],
        "x0_mean": [1.0, 0.0], "x0_cov": [[1e-4, 0.0], [0.0, 1e-4]],
        "s_mean": [0.02], "s_cov": [[0.01 ** 2]],
        "substeps": substeps,
        "required": {"pos": 0.0}, "bands": {"pos": {"wide": 10.0, "narrow": 0.01}},
    }


def test_streams_do_not_depend_on_chunking():
    whole = standard_normals(7, 0, 1000, 3)
    parts = np.hstack([standard_normals(7, a, b - a, 3) for a, b in [(0, 1), (1, 300), (300, 513), (513, 1000)]])
    np.testing.assert_array_equal(whole, parts)
    assert not np.array_equal(whole, standard_normals(8, 0, 1000, 3))


def test_split_equals_unsplit():
    spec = _osc_spec()
    one = merge_chunks([simulate_chunk(spec, 123, 0, 2000)])
    four = merge_chunks([simulate_chunk(spec, 123, a, n) for a, n in [(0, 300), (300, 700), (1000, 256), (1256, 744)]])
    assert one["samples"] == four["samples"] == 2000
    assert one["path"] == four["path"]
    assert one["within"] == four["within"]
    for q in one["terminal"]:
        for k in ("mean", "std"):
            assert four["terminal"][q][k] == pytest.approx(one["terminal"][q][k], rel=1e-12, abs=1e-15)
    # the constraint is active for part of the population: a test that can fail
    assert 0.05 < one["path"]["pos"]["kept_fraction"] < 0.95
    assert one["within"]["pos"]["wide"] == 1.0


def test_decay_matches_lognormal_and_cadet():
    mu, sig, x0, tf, n = 1.0, 0.15, 2.0, 2.0, 20000
    spec = {"model": "test_decay", "t_nodes": np.linspace(0, tf, 21).tolist(), "controls": [[0.0] * 21],
            "x0_mean": [x0], "x0_cov": None, "s_mean": [mu], "s_cov": [[sig ** 2]], "substeps": 10}
    mc = run_monte_carlo(spec, n, 5, chunk_size=5000)["terminal"]["x"]
    mean_exact = x0 * np.exp(-mu * tf + 0.5 * sig ** 2 * tf ** 2)
    std_exact = np.sqrt(x0 ** 2 * (np.exp(-2 * mu * tf + 2 * sig ** 2 * tf ** 2) - np.exp(-2 * mu * tf + sig ** 2 * tf ** 2)))
    # 4 standard errors of the mean; the std's standard error for a lognormal this skewed is ~1%
    assert abs(mc["mean"] - mean_exact) < 4 * std_exact / np.sqrt(n)
    assert mc["std"] == pytest.approx(std_exact, rel=0.04)


def test_oscillator_cadet_vs_monte_carlo():
    spec = _osc_spec()
    mc = run_monte_carlo(spec, 10000, 11, chunk_size=2500)
    x = ca.SX.sym("x", 2)
    u = ca.SX.sym("u", 1)
    s = ca.SX.sym("s", 1)
    f = ca.Function("f", [x, u, s], [ca.vertcat(x[1], -K0 * (1 + s[0]) * x[0] - C0 * x[1] + u[0])])
    sysm = CadetSystem(f, nx=2, nu=1, ns=1, second_order=True)
    z0 = sysm.layout.pack(spec["x0_mean"], spec["x0_cov"], [[0.0], [0.0]])
    Z, _ = sysm.propagate(z0=z0, controls=np.array(spec["controls"]), t_nodes=np.array(spec["t_nodes"]),
                          theta=CadetSystem.theta(spec["s_mean"], spec["s_cov"]), substeps=10)
    m, Pxx, _ = sysm.layout.unpack(Z[:, -1])
    sd = np.sqrt(np.diag(Pxx))
    for i, q in enumerate(["pos", "vel"]):
        assert abs(mc["terminal"][q]["mean"] - m[i]) < 0.05 * sd[i]
        assert mc["terminal"][q]["std"] == pytest.approx(sd[i], rel=0.05)


def test_step_doubling_changes_nothing_reported():
    a = run_monte_carlo(_osc_spec(10), 2000, 3)
    b = run_monte_carlo(_osc_spec(20), 2000, 3)
    for q in a["terminal"]:
        assert b["terminal"][q]["mean"] == pytest.approx(a["terminal"][q]["mean"], abs=1e-6)
        assert b["terminal"][q]["std"] == pytest.approx(a["terminal"][q]["std"], rel=1e-5)
    # the finer grid can only see more of each excursion
    assert b["path"]["pos"]["kept_fraction"] <= a["path"]["pos"]["kept_fraction"]
    assert abs(b["path"]["pos"]["kept_fraction"] - a["path"]["pos"]["kept_fraction"]) < 0.002


def test_samples_against_solve_ivp():
    from solvers.uncertainty.montecarlo import draw_samples, propagate, resolve_model

    spec = _osc_spec()
    model = resolve_model("test_oscillator", spec["model_params"])
    x0, s = draw_samples(spec, 9, 40, 5, nx=2, ns=1)
    t = np.array(spec["t_nodes"])
    U = np.array(spec["controls"])
    xf = propagate(model, x0=x0, s=s, t_nodes=t, controls=U, substeps=10)
    for i in range(5):
        sol = solve_ivp(lambda tt, y, i=i: _oscillator_rhs(y[:, None], [[np.interp(tt, t, U[0])]], s[:, i:i + 1])[:, 0],
                        (t[0], t[-1]), x0[:, i], method="DOP853", rtol=1e-11, atol=1e-12, max_step=0.1)
        np.testing.assert_allclose(xf[:, i], sol.y[:, -1], rtol=0, atol=1e-6)


def test_envelope_and_samples_merge_across_chunks():
    """The plots' envelope is the mean/std over all samples at each node, whatever the split; the
    kept sample traces and terminal samples are the first ones, in sample order."""
    from solvers.uncertainty import montecarlo as mc

    spec = {**_osc_spec(4), "model": "test_traced_oscillator"}
    one = merge_chunks([simulate_chunk(spec, 9, 0, 2500)])
    parts = merge_chunks([simulate_chunk(spec, 9, a, n) for a, n in [(0, 150), (150, 1000), (1150, 1350)]])
    env = one["envelope"]
    assert len(env["t_s"]) == 41 and env["t_s"] == parts["envelope"]["t_s"]
    for q in ("pos", "energy"):
        for k in ("mean", "std"):
            np.testing.assert_allclose(parts["envelope"][q][k], env[q][k], rtol=1e-10, atol=1e-14)
    assert parts["sample_traces"] == one["sample_traces"]
    assert len(one["sample_traces"]["pos"]) == mc.MAX_TRACE_SAMPLES and len(one["sample_traces"]["pos"][0]) == 41
    assert parts["terminal_samples"] == one["terminal_samples"]
    assert len(one["terminal_samples"]["pos"]) == mc.MAX_TERMINAL_SAMPLES
    # The envelope at the last node is the terminal statistic; the traces start at the initial state.
    assert env["pos"]["mean"][-1] == pytest.approx(one["terminal"]["pos"]["mean"], rel=1e-12)
    assert env["pos"]["std"][-1] == pytest.approx(one["terminal"]["pos"]["std"], rel=1e-12)
    traces = np.array(one["sample_traces"]["pos"])
    x0, _ = mc.draw_samples(spec, 9, 0, mc.MAX_TRACE_SAMPLES, nx=2, ns=1)
    np.testing.assert_allclose(traces[:, 0], x0[0], rtol=1e-15)
    np.testing.assert_allclose(one["terminal_samples"]["pos"][:mc.MAX_TRACE_SAMPLES], traces[:, -1], rtol=1e-15)
    # The spread starts at the initial dispersion (sigma 0.01) and changes along the flight.
    assert env["pos"]["std"][0] == pytest.approx(0.01, rel=0.05) and max(env["pos"]["std"]) > 0.015


def test_envelope_keeps_at_most_max_trace_times_nodes():
    from solvers.uncertainty import montecarlo as mc

    nodes = mc.trace_nodes(1001)
    assert nodes.size <= mc.MAX_TRACE_TIMES and nodes[0] == 0 and nodes[-1] == 1000
    assert np.array_equal(mc.trace_nodes(41), np.arange(41))
