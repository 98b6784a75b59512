"""robust_reentry through HTTP, a real worker, Redis and PostgreSQL (reduced Monte Carlo)."""
import pytest

pytestmark = [pytest.mark.integration, pytest.mark.slow]


def test_robust_max_crossrange_preset(service):
    r = service.submit("robust_reentry", preset="robust-max-crossrange",
                       params={"monte_carlo": {"samples": 400, "chunk_size": 100, "seed": 7}})
    assert r.status_code == 202, r.text
    job = service.wait(r.json()["id"], timeout=300)
    assert job["status"] == "succeeded", job
    assert job["params"]["monte_carlo"]["samples"] == 400
    assert job["params"]["uncertainty"]["cd"]["mean"] == pytest.approx(0.01)
    res = service.client.get(f"/v1/jobs/{job['id']}/result", params={"include": "samples"}).json()
    assert res["solver"]["status"] == "Solve_Succeeded"
    thin = service.result(job["id"])["monte_carlo"]["robust"]["sample_traces"]  # the default body: 20 traces
    assert len(thin["speed_mps"]) == 20
    assert res["deterministic"]["tf_s"] == pytest.approx(2199.26, abs=0.5)
    assert res["tf_s"] > res["deterministic"]["tf_s"] + 10.0
    assert res["final"]["altitude_m"] == pytest.approx(24384.0, abs=0.01)
    n = len(res["trajectory"]["t_s"])
    assert all(len(v) == n for v in res["trajectory"].values())
    mc = res["monte_carlo"]
    assert mc["samples"] == 400 and mc["seed"] == 7
    # 400 samples: the RO keeps the limit in (almost) all of them, the DO in almost none
    assert mc["robust"]["heat_rate_kept_fraction"] >= 0.97
    assert mc["deterministic"]["heat_rate_kept_fraction"] <= 0.03
    assert mc["robust"]["heat_rate_kept_fraction_nodes"] >= mc["robust"]["heat_rate_kept_fraction"]
    lat_do, lat_ro = mc["deterministic"]["objective"], mc["robust"]["objective"]
    assert lat_ro["std"] < 0.65 * lat_do["std"]
    assert lat_do["mean"] > lat_ro["mean"]
    assert any("node" in n for n in res["notes"])
    # plot data: envelope on the nodes, the first 200 sample traces, terminal samples of all 400
    env, traces = mc["robust"]["envelope"], mc["robust"]["sample_traces"]
    assert env["t_s"] == pytest.approx(res["trajectory"]["t_s"], rel=1e-12)
    assert env["altitude_m"]["mean"][-1] == pytest.approx(mc["robust"]["terminal"]["altitude_m"]["mean"], rel=1e-9)
    assert env["heat_rate_w_m2"]["std"][0] < 1e-6 < max(env["heat_rate_w_m2"]["std"])  # exact entry state
    assert len(traces["speed_mps"]) == 200 and {len(row) for row in traces["speed_mps"]} == {n}
    ts = mc["robust"]["terminal_samples"]
    assert len(ts["flight_path_deg"]) == 400   # all samples kept: their mean is the reported mean
    assert sum(ts["flight_path_deg"]) / 400 == pytest.approx(mc["robust"]["terminal"]["flight_path_deg"]["mean"],
                                                             rel=1e-9)
    assert res["verification"]["trajectory"]["t_s"][-1] == pytest.approx(res["tf_s"], rel=1e-12)


def test_robust_bad_params_are_422(service):
    r = service.submit("robust_reentry", params={"monte_carlo": {"samples": -5}})
    assert r.status_code == 422
    assert "samples" in r.text
    r = service.submit("robust_reentry", params={"path": {"max_heat_rate_w_m2": None}})
    assert r.status_code == 422
    assert "max_heat_rate_w_m2" in r.text
