"""Plots, report and CSV over HTTP for a job run by a real worker: 409 before success, 404 for unknown
names, ETag and 304, gzip."""
from __future__ import annotations

import csv
import io

import pytest

pytestmark = pytest.mark.integration

IMPULSIVE = {"methods": ["impulsive"], "porkchop": {"enabled": True}}


def test_plots_report_and_csv_of_a_finished_job(service):
    job = service.submit("intercept", preset="long-range-intercept", params=IMPULSIVE).json()
    early = service.client.get(f"/v1/jobs/{job['id']}/plots")
    assert early.status_code in (409, 200)
    assert service.wait(job["id"])["status"] == "succeeded"
    index = service.client.get(f"/v1/jobs/{job['id']}/plots").json()
    assert {p["name"] for p in index["plots"]} == {"delta_v_scan", "porkchop"}
    assert {t["name"] for t in index["tables"]} == {"scan", "porkchop"}
    png = service.client.get(index["plots"][0]["png"])
    assert png.status_code == 200 and png.headers["content-type"] == "image/png"
    assert png.content[:8] == b"\x89PNG\r\n\x1a\n"
    etag = png.headers["etag"]
    again = service.client.get(index["plots"][0]["png"], headers={"If-None-Match": etag})
    assert again.status_code == 304 and again.content == b""
    svg = service.client.get(index["plots"][1]["svg"], headers={"Accept-Encoding": "gzip"})
    assert svg.status_code == 200 and svg.headers.get("content-encoding") == "gzip" and b"<svg" in svg.content
    assert service.client.get(f"/v1/jobs/{job['id']}/plots/nope.png").status_code == 404
    report = service.client.get(index["report"])
    assert report.status_code == 200 and report.text.count("<svg ") == 2 and "<script" not in report.text
    table = service.client.get(f"/v1/jobs/{job['id']}/result.csv", params={"table": "scan"})
    rows = list(csv.reader(io.StringIO(table.text)))
    scan = service.client.get(f"/v1/jobs/{job['id']}/result", params={"include": "scan"}).json()["impulsive"]["scan"]
    assert rows[0] == ["t_man_s", "delta_v_mps"] and len(rows) - 1 == len(scan["t_man_s"])
    assert float(rows[10][1]) == pytest.approx(scan["delta_v_mps"][9], rel=1e-12)
    assert service.client.get(f"/v1/jobs/{job['id']}/result.csv", params={"table": "nope"}).status_code == 404


def test_plots_of_a_job_that_did_not_succeed_are_409(service):
    job = service.submit("reentry", preset="shuttle-min-heat-load-terminal").json()  # infeasible
    assert service.wait(job["id"])["status"] == "failed"
    assert service.client.get(f"/v1/jobs/{job['id']}/plots").status_code == 409
    assert service.client.get(f"/v1/jobs/{job['id']}/report.html").status_code == 409


def test_the_default_intercept_result_is_compact_and_keeps_every_minimum(service):
    job = service.submit("intercept", preset="long-range-intercept", params={"methods": ["impulsive"]}).json()
    assert service.wait(job["id"])["status"] == "succeeded"
    default = service.client.get(f"/v1/jobs/{job['id']}/result")
    full = service.client.get(f"/v1/jobs/{job['id']}/result", params={"include": "scan"})
    assert len(default.content) < 50_000 < len(full.content)
    thin, scan = default.json()["impulsive"]["scan"], full.json()["impulsive"]["scan"]
    assert thin["points_stored"] == len(scan["t_man_s"]) == 16161
    dv = scan["delta_v_mps"]
    minima = {scan["t_man_s"][i] for i in range(1, len(dv) - 1)
              if None not in (dv[i - 1], dv[i], dv[i + 1]) and dv[i] <= dv[i - 1] and dv[i] <= dv[i + 1]}
    assert minima and minima <= set(thin["t_man_s"])
    etag = default.headers["etag"]
    assert service.client.get(f"/v1/jobs/{job['id']}/result", headers={"If-None-Match": etag}).status_code == 304
    gz = service.client.get(f"/v1/jobs/{job['id']}/result", params={"include": "scan"},
                            headers={"Accept-Encoding": "gzip"})
    assert gz.headers.get("content-encoding") == "gzip"


def test_the_resubmit_body_posts_back_to_an_identical_job(service):
    job = service.submit("intercept", preset="long-range-intercept", params={"methods": ["impulsive"]}).json()
    body = service.client.get(f"/v1/jobs/{job['id']}/params")
    assert body.status_code == 200 and set(body.json()) == {"kind", "params", "label"}
    again = service.client.post("/v1/jobs", json=body.json())
    assert again.status_code == 202
    first = service.client.get(f"/v1/jobs/{job['id']}").json()
    second = service.client.get(f"/v1/jobs/{again.json()['id']}").json()
    assert second["kind"] == first["kind"] and second["params"] == first["params"]
    assert service.client.get("/v1/jobs/00000000-0000-0000-0000-000000000000/params").status_code == 404


def test_the_oem_of_a_finite_thrust_intercept_over_http(service, tmp_path):
    from oem import OrbitEphemerisMessage

    job = service.submit("intercept", preset="long-range-intercept", params={"methods": ["finite_thrust"]}).json()
    assert service.wait(job["id"])["status"] == "succeeded"
    index = service.client.get(f"/v1/jobs/{job['id']}/plots").json()
    assert index["oem"] == f"/v1/jobs/{job['id']}/result.oem"
    got = service.client.get(index["oem"])
    assert got.status_code == 200 and got.headers["content-type"].startswith("application/ccsds-oem")
    (tmp_path / "r.oem").write_bytes(got.content)
    states = list(OrbitEphemerisMessage.open(tmp_path / "r.oem").states)
    traj = service.client.get(f"/v1/jobs/{job['id']}/result").json()["finite_thrust"]["trajectory"]
    assert 20 < len(states) <= len(traj["t_s"]) and states[0].center == "EARTH"
    assert service.client.get(index["oem"], headers={"If-None-Match": got.headers["etag"]}).status_code == 304
