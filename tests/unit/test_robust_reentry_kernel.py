"""The compiled Monte Carlo propagation (solvers.robust_reentry.kernel) against the numpy RK4.

Same steps, same checks: the summaries must agree to rounding (1e-9 relative) and count the same
samples, on controls that cross the heating limit in some samples and not in others, with all
three path limits, and on the rotating Earth.  No solve needed: a hand-made control history.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from solvers import robust_reentry as rr
from solvers.robust_reentry import kernel as rk
from solvers.models import shuttle as sh
from solvers.uncertainty import montecarlo as mc

DEG = np.pi / 180


def _spec(problem, *, heat_limit=None):
    t = np.linspace(0.0, 1800.0, 61)
    u = np.vstack([np.full(t.size, 20.0 * DEG) + 5 * DEG * np.sin(t / 600.0),
                   np.linspace(-30.0, -75.0, t.size) * DEG])
    spec = rr.monte_carlo_spec(problem, t=t, u=u, substeps=5)
    mp = spec["model_params"]
    mp["max_heat_rate_w_m2"] = heat_limit or mp["max_heat_rate_w_m2"]
    mp["max_dynamic_pressure_pa"] = 9000.0
    mp["max_load_factor"] = 1.5
    return spec


@pytest.mark.parametrize("rotating", [False, True])
def test_compiled_equals_numpy(rotating):
    problem = rr.RobustReentryProblem(uncertainty=rr.Uncertainty(s_std=(0.05, 0.05)))
    problem.base.vehicle = dataclasses.replace(problem.base.vehicle, rotating_earth=rotating)
    assert rk.supports(problem.base.vehicle)
    spec = _spec(problem)
    # a limit that some samples keep and some do not
    probe = mc.run_monte_carlo({**spec, "propagator": "numpy"}, 300, 11, 100)
    spec = _spec(problem, heat_limit=0.98 * probe["path"]["heat_rate"]["worst"])
    a = mc.run_monte_carlo(spec, 300, 11, 100)
    b = mc.run_monte_carlo({**spec, "propagator": "numpy"}, 300, 11, 100)
    assert a["failed_samples"] == b["failed_samples"] == 0
    for q in b["terminal"]:
        for s in ("mean", "std"):
            assert a["terminal"][q][s] == pytest.approx(b["terminal"][q][s], rel=1e-9, abs=1e-12), q
    assert a["within"] == b["within"]
    for name, pb in b["path"].items():
        pa = a["path"][name]
        assert (pa["kept_fraction"], pa["kept_fraction_nodes"]) == (pb["kept_fraction"], pb["kept_fraction_nodes"])
        assert pa["worst"] == pytest.approx(pb["worst"], rel=1e-9)
    assert 0.0 < a["path"]["heat_rate"]["kept_fraction"] < 1.0
    for q in b["envelope"]:
        if q != "t_s":
            np.testing.assert_allclose(a["envelope"][q]["mean"], b["envelope"][q]["mean"], rtol=1e-9)
    np.testing.assert_allclose(a["terminal_samples"]["altitude_m"], b["terminal_samples"]["altitude_m"], rtol=1e-9)


def test_chunking_does_not_change_bits_and_unsupported_vehicles_fall_back():
    problem = rr.RobustReentryProblem()
    spec = _spec(problem)
    one = mc.simulate_chunk(spec, 5, 0, 64)
    two = [mc.simulate_chunk(spec, 5, 0, 17), mc.simulate_chunk(spec, 5, 17, 47)]
    assert one["terminal_samples"]["altitude_m"] == (two[0]["terminal_samples"]["altitude_m"]
                                                     + two[1]["terminal_samples"]["altitude_m"])
    us76 = dataclasses.replace(sh.SHUTTLE, atmosphere=dataclasses.replace(sh.SHUTTLE.atmosphere, kind="us1976"))
    assert not rk.supports(us76)
    model = mc.resolve_model("shuttle_reentry", {**spec["model_params"],
                                                 "vehicle": {**spec["model_params"]["vehicle"],
                                                             "atmosphere": dataclasses.asdict(us76.atmosphere)}})
    assert model.kernel is None


def test_a_sample_does_not_depend_on_its_lane_or_block():
    # the kernel runs blocks of rk.LANES samples, the last padded: every sample must come out with
    # the same bits wherever it sits in a block and whatever fills the rest of its block
    problem = rr.RobustReentryProblem(uncertainty=rr.Uncertainty(s_std=(0.05, 0.05)))
    spec = _spec(problem)
    v = problem.base.vehicle
    n = rk.LANES + 23
    x0, s = mc.draw_samples(spec, 3, 0, n, nx=6, ns=2)
    kw = {"t_nodes": spec["t_nodes"], "controls": np.asarray(spec["controls"]), "substeps": 5,
          "kept_nodes": mc.trace_nodes(len(spec["t_nodes"])), "path": rk.PATH_ORDER}
    whole = rk.run_chunk(v, x0=x0, s=s, **kw)
    for a, b in ((0, 1), (1, 6), (6, n)):                 # lane offsets 0, 1 and 6; padded blocks
        part = rk.run_chunk(v, x0=x0[:, a:b], s=s[:, a:b], **kw)
        np.testing.assert_array_equal(part[0], whole[0][:, a:b])
        for w in (1, 2):
            for name in rk.PATH_ORDER:
                np.testing.assert_array_equal(part[w][name], whole[w][name][a:b])
        for q in whole[3]:
            np.testing.assert_array_equal(part[3][q], whole[3][q][:, a:b])
    rev = rk.run_chunk(v, x0=x0[:, ::-1], s=s[:, ::-1], **kw)     # every sample in another lane
    np.testing.assert_array_equal(rev[0][:, ::-1], whole[0])
