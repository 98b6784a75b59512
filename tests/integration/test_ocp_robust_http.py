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


def test_a_robust_job_on_lgl_is_accepted_and_confirmed(service):
    """Robust design on LGL was once a 422 at submission (issue 37 item 2); now it is designed and confirmed."""
    body = copy.deepcopy(PUSHED)
    body["transcription"] = {"method": "lgl", "intervals": 5, "nodes": 5}
    body["robust"]["monte_carlo"] = {"samples": 400, "rounds": 0}
    done = _submit(service, body, "ocp robust lgl")
    assert done["status"] == "succeeded", done
    result = _stored(service, done)
    assert result["solver"]["method"] == "lgl" and result["robust"]["confirmed"] is True
    c = result["robust"]["constraints"]["v_max"]
    assert c["kept_fraction"] >= c["required_fraction"] - c["sampling_tolerance"]


def test_doubled_sigmas_fail_not_robust_with_the_design_stored(service):
    body = copy.deepcopy(PUSHED)
    body["robust"]["monte_carlo"].update(sigma_factor=2.0, rounds=0)
    done = _submit(service, body, "ocp robust doubled sigmas")
    assert done["status"] == "failed" and done["error"]["code"] == "not_robust", done
    result = _stored(service, done)
    assert result["robust"]["confirmed"] is False and result["trajectory"]["v"]


# --- everything a result has (issue 37 item 4) --------------------------------------------------------------
def _csv_rows(service, job_id: str, table: str) -> list[list[str]]:
    r = service.client.get(f"/v1/jobs/{job_id}/result.csv", params={"table": table})
    assert r.status_code == 200, r.text
    return [line.split(",") for line in r.text.splitlines()]


def test_a_robust_result_serves_its_envelope_plots_histogram_and_csv(service):
    import numpy as np

    done = _submit(service, copy.deepcopy(PUSHED), "ocp robust plots and csv")
    assert done["status"] == "succeeded", done
    result = service.result(done["id"])
    rob = result["robust"]
    env = rob["monte_carlo"]["envelope"]
    # v's Monte Carlo spread is the closed form of the open-loop plan within 4 standard errors of a sample std
    t, std = np.asarray(env["t"]), np.asarray(env["states"]["v"]["std"])
    exact = np.sqrt(0.05 ** 2 + (0.2 * t) ** 2)
    assert np.all(np.abs(std - exact) <= 4 * exact / np.sqrt(2 * rob["samples"]))

    index = service.client.get(f"/v1/jobs/{done['id']}/plots").json()
    names = {p["name"] for p in index["plots"]}
    assert {"mc-state-x", "mc-state-v", "mc-state-y", "mc-constraint-v_max", "mc-objective"} <= names
    plot = next(p for p in index["plots"] if p["name"] == "mc-constraint-v_max")
    svg = service.client.get(plot["svg"])
    assert svg.status_code == 200
    k_c = rob["k_constraints"]
    for words in ("mean", f"mean +- {k_c:g} sigma", "upper limit"):   # the legend's series (text kept as comments)
        assert f"<!-- {words} -->" in svg.text, words
    hist = next(p for p in index["plots"] if p["name"] == "mc-objective")
    assert "<!-- 2000 samples -->" in service.client.get(hist["svg"]).text

    samples = _csv_rows(service, done["id"], "robust_samples")
    assert samples[0] == ["sample", "objective"] and len(samples) == 1 + rob["samples"] == 2001
    objective = np.array([float(r[1]) for r in samples[1:]])
    assert objective.mean() == pytest.approx(rob["objective"]["mean"], rel=1e-12)
    envelope = _csv_rows(service, done["id"], "robust_envelope")
    assert envelope[0][:3] == ["t", "x.mean", "x.std"] and "v_max.mean" in envelope[0]
    assert len(envelope) == 1 + len(env["t"]) == 1 + 21        # 20 intervals: every node kept
    rounds = _csv_rows(service, done["id"], "robust_rounds")
    assert len(rounds) == 1 + len(rob["rounds"])


def test_a_study_over_k_prices_robustness_with_monte_carlo_and_cadet_columns(service):
    import time

    body = copy.deepcopy(PUSHED)
    body["robust"]["monte_carlo"]["rounds"] = 0      # each point at its own k (no round raises it)
    r = service.client.post("/v1/studies", json={"kind": "ocp", "params": body, "mode": "independent",
                                                 "label": "ocp robust price vs k",
                                                 "sweeps": [{"path": "robust.k", "values": [1.0, 2.0, 3.0]}]})
    assert r.status_code == 202, r.text
    sid = r.json()["id"]
    deadline = time.monotonic() + 600
    while service.client.get(f"/v1/studies/{sid}").json()["status"] == "running":
        assert time.monotonic() < deadline, "study still running"
        time.sleep(0.5)
    rows = service.client.get(f"/v1/studies/{sid}/result").json()["rows"]
    assert [row["status"] for row in rows] == ["succeeded"] * 3, rows
    cadet = [row["cadet.objective"] for row in rows]
    mc = [row["mc.objective"] for row in rows]
    # the price of robustness grows with k (12.0037, 12.3496, 13.8104 for k = 1, 2, 3 on this machine)
    assert cadet[0] < cadet[1] < cadet[2] and mc[0] < mc[1] < mc[2]
    assert all(row["deterministic.objective"] == pytest.approx(12.0, rel=1e-6) for row in rows)
    for row in rows:
        assert row["cadet.cost_of_robustness"] == pytest.approx(row["cadet.objective"] - 12.0, abs=1e-5)
        assert row["mc.kept_percent.v_max"] >= 100 * 0.84 and row["mc.samples"] == 2000
        # the design's cost is certain (open loop, the control does not see w): both say so
        assert row["mc.objective"] == pytest.approx(row["cadet.objective"], rel=1e-5)
    svg = service.client.get(f"/v1/studies/{sid}/plot.svg")
    assert svg.status_code == 200 and "k (sigmas of margin)" in svg.text


def test_a_robust_job_warm_starts_from_a_finished_deterministic_job(service):
    deterministic = copy.deepcopy(PUSHED)
    deterministic.pop("uncertainty")
    deterministic.pop("robust")
    det = _submit(service, deterministic, "ocp deterministic twin")
    assert det["status"] == "succeeded", det
    cold = _submit(service, copy.deepcopy(PUSHED), "ocp robust cold")
    warm_body = copy.deepcopy(PUSHED)
    warm_body["initial_guess"] = {"from_job": det["id"]}
    warm = _submit(service, warm_body, "ocp robust warm")
    assert cold["status"] == warm["status"] == "succeeded", (cold, warm)
    c, w = service.result(cold["id"]), service.result(warm["id"])
    assert w["warm_start"] == det["id"] and c["warm_start"] is None
    assert w["objective"]["value"] == pytest.approx(c["objective"]["value"], rel=1e-8)
    assert w["robust"]["deterministic_objective"] == pytest.approx(service.result(det["id"])["objective"]["value"],
                                                                   rel=1e-8)
    # an LQ twin converges in a handful of iterations either way (5 cold, 6 warm measured): no promise of fewer
    assert w["robust"]["timing"]["deterministic_iterations"] <= c["robust"]["timing"]["deterministic_iterations"] + 3
