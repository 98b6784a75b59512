"""Every command of the CLI against a real ``trajlab serve`` on another port whose data directory is not where
the CLI runs (issue 38 item 1): the operator's commands through the API with an admin key, or through the
database found as ``serve`` finds it; a missing database in one line; the client path importing no part of
the service."""
from __future__ import annotations

import os
import re
import subprocess
import sys
import time
from pathlib import Path

import httpx
import pytest

from tests.integration.live import free_port
from tests.support import wait_serving

pytestmark = pytest.mark.integration
ROOT = Path(__file__).resolve().parents[2]
# What the client path must never load: the service's frameworks, its numerics, its own layers
FORBIDDEN = ("fastapi", "starlette", "pydantic", "sqlalchemy", "alembic", "celery", "redis", "casadi", "numpy",
             "scipy", "matplotlib", "app.api", "app.service", "app.kinds", "app.results", "solvers")


def _base_env() -> dict:
    drop = ("TRAJLAB_BROKER_URL", "TRAJLAB_DATABASE_URL", "TRAJLAB_DATA_DIR", "TRAJLAB_URL", "TRAJLAB_API_KEY",
            "TRAJLAB_PORT", "TRAJLAB_AUTH")
    return {**{k: v for k, v in os.environ.items() if k not in drop}, "PYTHONPATH": str(ROOT)}


@pytest.fixture(scope="module")
def served(tmp_path_factory):
    """``trajlab serve`` with keys required, its data directory in a directory of its own, on a free port."""
    home = tmp_path_factory.mktemp("service")
    data, port = home / "moved-data", free_port()
    env = {**_base_env(), "TRAJLAB_DATA_DIR": str(data), "TRAJLAB_AUTH": "required", "TRAJLAB_JIT": "off"}
    with open(home / "serve.log", "ab") as log:
        proc = subprocess.Popen([sys.executable, "-m", "app.cli.commands", "serve", "--port", str(port)], cwd=home,
                                env=env, stdout=log, stderr=subprocess.STDOUT)
    url = f"http://127.0.0.1:{port}"
    try:
        wait_serving(url + "/healthz", proc=proc, what="trajlab serve", log=home / "serve.log", status=200)
        yield {"url": url, "data": data, "home": home}
    finally:
        proc.terminate()
        proc.wait(timeout=60)


def _cli(*args: str, cwd: Path, env: dict, importtime: bool = False) -> subprocess.CompletedProcess:
    flags = ["-X", "importtime"] if importtime else []
    return subprocess.run([sys.executable, *flags, "-m", "app.cli.commands", *args], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=300, check=False)


@pytest.fixture(scope="module")
def admin(served):
    """An admin key made as an operator on the service's machine makes the first one: ``trajlab keys create``
    with the service's TRAJLAB_DATA_DIR (the database as ``serve`` finds it, while it runs)."""
    p = _cli("keys", "create", "--name", "root", "--admin", cwd=served["home"],
             env={**_base_env(), "TRAJLAB_DATA_DIR": str(served["data"])})
    assert p.returncode == 0, p.stderr
    return p.stdout.strip()


@pytest.fixture
def elsewhere(served, admin, tmp_path):
    """The CLI in another directory (no var/ there), told only the URL and the key."""
    return {"cwd": tmp_path, "env": {**_base_env(), "TRAJLAB_URL": served["url"], "TRAJLAB_API_KEY": admin}}


def test_keys_purge_usage_backup_through_the_api(served, elsewhere):
    p = _cli("keys", "create", "--name", "ci", "--owner", "team", **elsewhere)
    assert p.returncode == 0, p.stderr
    key = p.stdout.strip()
    assert key.startswith("tl_") or len(key) > 20
    assert httpx.get(served["url"] + "/v1/jobs", headers={"Authorization": f"Bearer {key}"}).status_code == 200
    listed = _cli("keys", "list", **elsewhere)
    assert listed.returncode == 0 and re.search(r"^ci\s+team\s", listed.stdout, re.MULTILINE), listed.stdout
    # a non-admin key is refused in one line (403: exit 2)
    refused = _cli("keys", "list", cwd=elsewhere["cwd"], env={**elsewhere["env"], "TRAJLAB_API_KEY": key})
    assert refused.returncode == 2 and "admin key" in refused.stderr and "Traceback" not in refused.stderr
    assert _cli("keys", "revoke", "ci", **elsewhere).returncode == 0
    assert httpx.get(served["url"] + "/v1/jobs", headers={"Authorization": f"Bearer {key}"}).status_code == 401
    again = _cli("keys", "revoke", "no-such-key", **elsewhere)
    assert again.returncode == 2 and "no key named 'no-such-key'" in again.stderr
    purge = _cli("purge", "--older-than", "30", "--dry-run", **elsewhere)
    assert purge.returncode == 0 and purge.stdout.startswith("would delete 0 job(s)"), purge.stderr
    usage = _cli("usage", **elsewhere)
    assert usage.returncode == 0 and "jobs (" in usage.stdout, usage.stderr
    dest = elsewhere["cwd"] / "copy.sqlite"
    backup = _cli("backup", str(dest), **elsewhere)
    assert backup.returncode == 0, backup.stderr
    assert dest.read_bytes()[:16] == b"SQLite format 3\x00" and "SQLite backup" in backup.stderr
    import sqlite3

    with sqlite3.connect(dest) as conn:  # the service's database as it was: the keys made above are in it
        assert {r[0] for r in conn.execute("select name from api_keys")} >= {"root", "ci"}


def test_a_missing_database_is_one_line_naming_it(served, tmp_path):
    """Without a URL, the operator's commands open the database as ``serve`` would from here: none in this
    directory's var/, so one line naming the path and what to set, never a traceback (nor a new empty file)."""
    for args in (("keys", "list"), ("purge", "--older-than", "1"), ("backup", "out.db")):
        p = _cli(*args, cwd=tmp_path, env=_base_env())
        assert p.returncode == 1, (args, p.stderr)
        lines = p.stderr.strip().splitlines()
        assert len(lines) == 1 and str(tmp_path / "var" / "trajlab.db") in lines[0], p.stderr
        assert "TRAJLAB_DATA_DIR" in lines[0] and "TRAJLAB_URL" in lines[0]
    assert not (tmp_path / "var" / "trajlab.db").exists()


def test_presets_vehicles_and_a_mistyped_preset(elsewhere):
    p = _cli("presets", "reentry", **elsewhere)
    assert p.returncode == 0 and "betts-max-crossrange" in p.stdout and "upper-stage" not in p.stdout
    every = _cli("presets", **elsewhere)
    assert every.returncode == 0 and {"reentry", "midcourse", "intercept", "ocp"} <= set(every.stdout.split())
    assert _cli("presets", "nokind", **elsewhere).returncode == 2
    v = _cli("vehicles", **elsewhere)
    assert v.returncode == 0 and "shuttle" in v.stdout.lower(), v.stderr
    typo = _cli("submit", "reentry", "--preset", "betts-max-crosrange", **elsewhere)
    assert typo.returncode == 2
    assert "'mars-msl-minimum-heat'" in typo.stderr or typo.stderr.count("'") >= 14, typo.stderr
    assert "..." not in typo.stderr and "Traceback" not in typo.stderr


def test_help_is_plain_text(elsewhere):
    p = _cli("--help", **elsewhere)
    assert p.returncode == 0 and "``" not in p.stdout and ":mod:" not in p.stdout
    assert "presets" in p.stdout and "TRAJLAB_URL" in p.stdout


def test_submit_sends_the_job_without_loading_the_service(served, elsewhere):
    """The real submit path (`-X importtime`): the job arrives, and not one module of the service's frameworks,
    numerics or layers was imported to send it."""
    t0 = time.monotonic()
    p = _cli("submit", "reentry", "--preset", "betts-max-crossrange", "--set", "grid.intervals=20", "--label", "fast",
             importtime=True, **elsewhere)
    took = time.monotonic() - t0
    assert p.returncode == 0, p.stderr[-2000:]
    imported = {line.split("|")[-1].strip() for line in p.stderr.splitlines() if line.startswith("import time:")}
    assert "httpx" in imported                        # the reading works: the client's own library is there
    loaded = sorted(m for m in imported if m.split(".")[0] in FORBIDDEN or m.startswith(FORBIDDEN))
    assert loaded == [], loaded
    job_id = p.stdout.strip().splitlines()[-1]
    job = httpx.get(f"{served['url']}/v1/jobs/{job_id}",
                    headers={"Authorization": f"Bearer {elsewhere['env']['TRAJLAB_API_KEY']}"}).json()
    assert job["label"] == "fast" and job["params"]["grid"]["intervals"] == 20
    print(f"submit in a subprocess (interpreter start included, -X importtime on): {took:.2f} s; "
          f"{len(imported)} modules")
