"""A Monte Carlo above the chunk threshold is split across real worker processes and merged."""
from __future__ import annotations

import pytest

pytestmark = pytest.mark.integration


def test_robust_monte_carlo_split_over_two_workers(service):
    # The fixture sets TRAJLAB_MONTE_CARLO_CHUNK_SAMPLES=2000: 6000 samples make 3 chunks per design.
    service.start_second_worker()
    try:
        job = service.submit("robust_reentry", preset="robust-max-crossrange",
                             params={"monte_carlo": {"samples": 6000, "chunk_size": 2000, "seed": 11}}).json()
        done = service.wait(job["id"], timeout=300)
        assert done["status"] == "succeeded", done
        mc = service.client.get(f"/v1/jobs/{job['id']}/result", params={"include": "samples"}).json()["monte_carlo"]
    finally:
        service.stop_second_worker()
    for design in ("deterministic", "robust"):
        block = mc[design]
        dist = block["distribution"]
        assert block["samples"] == 6000 and dist["chunks"] == 3
        assert sum(dist["computed_by"].values()) == 3
        # at least one chunk was computed by a worker other than the job's own process
        assert any(not who.startswith("job@") for who in dist["computed_by"]), dist
        # the plots' envelope merged from the chunks agrees with the terminal statistics
        env = block["envelope"]
        assert env["speed_mps"]["mean"][-1] == pytest.approx(block["terminal"]["speed_mps"]["mean"], rel=1e-9)
        assert env["speed_mps"]["std"][-1] == pytest.approx(block["terminal"]["speed_mps"]["std"], rel=1e-9)
        assert len(block["sample_traces"]["altitude_m"]) == 200
        assert len(block["terminal_samples"]["altitude_m"]) == 2000
    assert mc["robust"]["heat_rate_kept_fraction"] >= 0.99
    assert mc["deterministic"]["heat_rate_kept_fraction"] <= 0.01
