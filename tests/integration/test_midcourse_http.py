"""The midcourse kind through the whole service: HTTP submit, real worker, stored result."""
import time

import pytest

pytestmark = pytest.mark.integration


def test_paper_preset_reduced_gives_a_front(service):
    resp = service.submit("midcourse", preset="upper-stage-two-corrections",
                          params={"population": 20, "generations": 15, "seed": 3})
    assert resp.status_code == 202, resp.text
    job = resp.json()
    assert job["params"]["population"] == 20 and job["params"]["corrections"] == 2
    assert job["params"]["crossover_prob"] == 0.8 and job["params"]["time_bounds_s"] == [0.0, 12800.0]
    done = service.wait(job["id"], timeout=180)
    assert done["status"] == "succeeded", done
    assert done["progress"] == 1.0
    result = service.result(job["id"])
    assert result["generations"] == 15 and result["seed"] == 3 and result["evaluations"] >= 20 * 15
    front = result["pareto_front"]
    assert len(front) >= 3
    for p in front:
        t = p["times_s"]
        assert len(t) == 2 and 0.0 <= t[0] <= t[1] <= 12800.0
        assert p["delta_v_mps"] > 0 and p["position_error_m"] > 0 and p["velocity_error_mps"] >= 0
    # No point of the front dominates another.
    objs = [(p["delta_v_mps"], p["position_error_m"], p["velocity_error_mps"]) for p in front]
    for a in objs:
        assert not any(all(x <= y for x, y in zip(b, a)) and b != a for b in objs)
    assert 0.0 < result["hypervolume"] <= 1.0
    assert result["hypervolume_reference"] == {"delta_v_mps": 150.0, "position_error_m": 2000.0,
                                               "velocity_error_mps": 70.0}
    assert any("261 m" in n for n in result["notes"])


def test_table3_preset_numbers(service):
    resp = service.submit("midcourse", preset="upper-stage-table3")
    assert resp.status_code == 202, resp.text
    done = service.wait(resp.json()["id"], timeout=120)
    assert done["status"] == "succeeded", done
    rows = service.result(done["id"])["schedules"]
    # Spec Table 3, reimplementation column: dV and velocity error to 0.5 m/s, position to 2 m.
    expect = [(0.0, 708233.0, 103.455), (91.798, 786.7, 32.349), (138.097, 330.1, 68.053),
              (51.518, 337.6, 8.866), (32.004, 337.5, 4.315), (40.160, 337.8, 4.623), (29.072, 337.8, 2.081)]
    assert len(rows) == len(expect)
    for row, (dv, pos, vel) in zip(rows, expect):
        assert row["delta_v_mps"] == pytest.approx(dv, abs=0.5)
        assert row["position_error_m"] == pytest.approx(pos, abs=2.0)
        assert row["velocity_error_mps"] == pytest.approx(vel, abs=0.5)


def test_cancel_keeps_a_partial_front(service):
    resp = service.submit("midcourse", preset="upper-stage-two-corrections",
                          params={"generations": 5000, "seed": 11})
    assert resp.status_code == 202, resp.text
    job_id = resp.json()["id"]
    deadline = time.monotonic() + 60
    while True:
        job = service.client.get(f"/v1/jobs/{job_id}").json()
        if job["status"] == "running" and job["progress"] > 0:
            break
        assert job["status"] in ("queued", "running") and time.monotonic() < deadline, job
        time.sleep(0.1)
    assert service.client.post(f"/v1/jobs/{job_id}/cancel").status_code == 202
    done = service.wait(job_id, timeout=60)
    assert done["status"] == "cancelled", done
    body = service.client.get(f"/v1/jobs/{job_id}/result")
    assert body.status_code == 409
    partial = body.json()["partial_result"]
    assert partial["pareto_front"] and 0 < partial["generations"] < 5000


def test_bad_midcourse_params_are_422(service):
    resp = service.submit("midcourse", params={"mode": "evaluate", "schedules": [[8000.0, 3000.0]]})
    assert resp.status_code == 422
    assert "schedules" in resp.text and "sorted" in resp.text
    resp = service.submit("midcourse", params={"corrections": 7})
    assert resp.status_code == 422 and "corrections" in resp.text
