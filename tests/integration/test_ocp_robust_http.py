"""A robust ``ocp`` job through the whole service (issue 37): HTTP submit, a real worker, the Monte Carlo of
60,000 draws fanned across the workers in chunks (past TRAJLAB_MONTE_CARLO_CHUNK_SAMPLES), the contract's
``robust`` block stored; a design its Monte Carlo does not confirm fails ``not_robust`` with the result stored."""
import copy

import pytest

from tests.unit.test_ocp_robust import PUSHED

pytestmark = pytest.mark.integration


def _stored(service, done) -> dict:
    """The stored result: served as it is, or (a failed job) as the partial result of the 409."""
    r = service.client.get(f"/v1/jobs/{done['id']}/result")
    assert r.status_code == (200 if done["status"] == "succeeded" else 409), r.text
    return r.json() if r.status_code == 200 else r.json()["partial_result"]


def _submit(service, body, label):
    resp = service.submit("ocp", params=body, label=label)
    assert resp.status_code == 202, resp.text
    return service.wait(resp.json()["id"], timeout=600)


@pytest.mark.slow
def test_a_robust_job_fans_its_monte_carlo_across_workers_and_stores_the_robust_block(service):
    body = copy.deepcopy(PUSHED)
    body["robust"]["monte_carlo"] = {"samples": 60_000, "rounds": 0}
    body["robust"]["k"] = 3.0
    done = _submit(service, body, "ocp robust fan-out")
    assert done["status"] in ("succeeded", "failed"), done
    rob = _stored(service, done)["robust"]
    assert rob["samples"] == 60_000 and rob["distribution"]["chunks"] == 24
    c = rob["constraints"]["v_max"]
    assert c["required_fraction"] == pytest.approx(0.99865, abs=1e-5)
    assert rob["confirmed"] is (done["status"] == "succeeded")
    if not rob["confirmed"]:
        assert done["error"]["code"] == "not_robust"


def test_doubled_sigmas_fail_not_robust_with_the_design_stored(service):
    body = copy.deepcopy(PUSHED)
    body["robust"]["monte_carlo"].update(sigma_factor=2.0, rounds=0)
    done = _submit(service, body, "ocp robust doubled sigmas")
    assert done["status"] == "failed" and done["error"]["code"] == "not_robust", done
    result = _stored(service, done)
    assert result["robust"]["confirmed"] is False and result["trajectory"]["v"]
