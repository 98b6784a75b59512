"""The command-line client against a live service (uvicorn on 127.0.0.1, a real worker, PostgreSQL, Redis)."""
from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from app.cli.client_commands import parse_set
from tests.integration.live import free_port, live_server

pytestmark = pytest.mark.integration

LONG_MIDCOURSE = {"mode": "optimize", "corrections": 2, "population": 100, "generations": 2500, "seed": 7}


@pytest.fixture(scope="module")
def live_url(service):
    with live_server(service.client.app) as url:
        yield url


def _trajlab(url: str, *args: str, timeout: float = 180) -> subprocess.CompletedProcess:
    env = {**os.environ, "TRAJLAB_URL": url, "TRAJLAB_PROGRESS": "bar"}
    return subprocess.run([sys.executable, "-m", "app.cli.commands", *args], env=env, capture_output=True, text=True,
                          timeout=timeout)


def test_parse_set_nests_paths_and_reads_json_values():
    assert parse_set(["grid.intervals=50", "methods=[\"impulsive\"]", "label=x y", "a.b.c=null"]) == {
        "grid": {"intervals": 50}, "methods": ["impulsive"], "label": "x y", "a": {"b": {"c": None}}}
    with pytest.raises(ValueError):
        parse_set(["grid..intervals=5"])


def test_submit_wait_shows_progress_and_the_numbers(live_url):
    p = _trajlab(live_url, "submit", "intercept", "--preset", "long-range-intercept",
                 "--set", 'methods=["impulsive"]', "--label", "cli", "--wait")
    assert p.returncode == 0, p.stderr
    job_id = p.stdout.splitlines()[0].strip()
    assert len(job_id) == 32
    assert "100.0%" in p.stderr  # the progress bar reached the end
    assert "succeeded" in p.stdout
    numbers = {line.split()[0]: line.split()[1] for line in p.stdout.splitlines()[2:] if line.startswith("  ")}
    dv = [float(v) for k, v in numbers.items() if "delta_v_mps" in k]
    assert dv and dv[0] == pytest.approx(2302.48, abs=0.01), p.stdout
    shown = _trajlab(live_url, "jobs", "--kind", "intercept")
    assert shown.returncode == 0 and job_id in shown.stdout


def test_bad_set_exits_2_with_the_api_message(live_url):
    p = _trajlab(live_url, "submit", "reentry", "--preset", "betts-max-crossrange", "--set", "grid.intervals=-5")
    assert p.returncode == 2
    assert "grid.intervals" in p.stderr and "Traceback" not in p.stderr
    p = _trajlab(live_url, "show", "doesnotexist")
    assert p.returncode == 2 and "not found" in p.stderr


def test_cancel_exits_3(live_url, service):
    job = service.submit("midcourse", preset="upper-stage-two-corrections", params=LONG_MIDCOURSE).json()
    service.wait(job["id"], until=("running",), timeout=60)
    p = _trajlab(live_url, "cancel", job["id"])
    assert p.returncode == 3, (p.stdout, p.stderr)
    assert service.client.get(f"/v1/jobs/{job['id']}").json()["status"] == "cancelled"


def test_unreachable_service_exits_4():
    p = _trajlab(f"http://127.0.0.1:{free_port()}", "jobs")
    assert p.returncode == 4 and "cannot reach" in p.stderr


def test_submit_file_takes_a_whole_job_body(live_url, service):
    """examples/ hold whole ``POST /v1/jobs`` bodies; ``--file`` sends one as it is, and a kind on the command line
    that contradicts the body is refused before anything is sent."""
    body_file = os.path.join(os.path.dirname(__file__), "..", "..", "examples", "mars-entry.json")
    p = _trajlab(live_url, "submit", "--file", body_file, "--label", "from-file")
    assert p.returncode == 0, p.stderr
    job = service.client.get(f"/v1/jobs/{p.stdout.strip()}").json()
    assert job["kind"] == "reentry" and job["label"] == "from-file"
    sent = json.loads(open(body_file).read())["params"]
    assert job["params"]["planet"] == sent["planet"] == "mars"
    assert job["params"]["initial_state"]["speed_mps"] == sent["initial_state"]["speed_mps"]
    p = _trajlab(live_url, "submit", "ocp", "--file", body_file)
    assert p.returncode == 1 and "is a 'reentry' job, not 'ocp'" in p.stderr
