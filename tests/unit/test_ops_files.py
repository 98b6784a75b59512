"""deploy/: the alert rules load in Debian's promtool, the dashboard is Grafana JSON with a query per panel.
That every metric they name is in a scrape is checked against a running service in
tests/integration/test_observability.py (with :func:`metric_names_in_ops_files`)."""
from __future__ import annotations

import json
import re
import shutil
import subprocess
from pathlib import Path

import pytest
import yaml

DEPLOY = Path(__file__).resolve().parents[2] / "deploy"
RULES = DEPLOY / "prometheus" / "alerts.yml"
DASHBOARD = DEPLOY / "grafana" / "trajlab-dashboard.json"
_METRIC = re.compile(r"\b(trajlab_[a-z0-9_]+|up)\b")


def _expressions() -> list[str]:
    rules = [rule["expr"] for group in yaml.safe_load(RULES.read_text())["groups"] for rule in group["rules"]]
    panels = json.loads(DASHBOARD.read_text())["panels"]
    return rules + [target["expr"] for panel in panels for target in panel["targets"]]


def metric_names_in_ops_files() -> set[str]:
    """Every trajlab_* series the alert rules and the dashboard query (``up`` is Prometheus's own)."""
    return {name for expr in _expressions() for name in _METRIC.findall(expr) if name != "up"}


@pytest.mark.integration  # a real part (Debian's promtool, installed by make test's prerequisites)
def test_alert_rules_load_in_promtool():
    promtool = shutil.which("promtool")
    assert promtool, "promtool is missing: scripts/test-prerequisites.sh installs Debian's prometheus"
    out = subprocess.run([promtool, "check", "rules", str(RULES)], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stdout + out.stderr
    assert "SUCCESS" in out.stdout


def test_rules_cover_the_issue_and_dashboard_queries_every_panel():
    alerts = {rule["alert"] for group in yaml.safe_load(RULES.read_text())["groups"] for rule in group["rules"]}
    assert {"TrajlabQueueGrowing", "TrajlabKindFailing", "TrajlabRecoveryLoopStale",
            "TrajlabWorkerRestarting"} <= alerts
    dashboard = json.loads(DASHBOARD.read_text())
    assert dashboard["uid"] and all(panel["targets"] and panel["title"] for panel in dashboard["panels"])
    assert {"trajlab_queue_depth", "trajlab_jobs_finished_total", "trajlab_recovery_heartbeat_timestamp_seconds",
            "trajlab_worker_restarts_total", "trajlab_job_duration_seconds_bucket",
            "trajlab_http_request_duration_seconds_bucket", "trajlab_build_info"} <= metric_names_in_ops_files()


@pytest.mark.integration  # a real part (Debian's promtool, installed by make test's prerequisites)
def test_scrape_config_loads_in_promtool(tmp_path):
    # the compose paths (/etc/prometheus/...) pointed at deploy/'s rules and a stand-in key file
    key = tmp_path / "key"
    key.write_text("tl_stand_in\n")
    text = (DEPLOY / "prometheus" / "prometheus.yml").read_text()
    config = tmp_path / "prometheus.yml"
    config.write_text(text.replace("/etc/prometheus/trajlab-alerts.yml", str(RULES))
                      .replace("/etc/prometheus/trajlab-metrics-key", str(key)))
    promtool = shutil.which("promtool")
    assert promtool, "promtool is missing: scripts/test-prerequisites.sh installs Debian's prometheus"
    out = subprocess.run([promtool, "check", "config", str(config)], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stdout + out.stderr


def test_the_image_builds_the_guide_and_carries_the_compose_servers_postgresql_client():
    # Docker cannot run here: the Dockerfile is read. The guide is built (strictly) before the package is
    # installed, into the directory the service serves; the PostgreSQL client tools are the major version
    # of docker-compose.yml's postgres image (trajlab backup refuses older tools, app/cli/backup.py).
    root = DEPLOY.parent
    dockerfile = (root / "Dockerfile").read_text()
    compose = yaml.safe_load((root / "docker-compose.yml").read_text())
    server_major = re.fullmatch(r"postgres:(\d+)(\.\d+)*", compose["services"]["postgres"]["image"]).group(1)
    assert re.search(rf"\bpostgresql-client-{server_major}\b", dockerfile), server_major
    assert "mkdocs build --strict" in dockerfile
    final = dockerfile.rsplit("\nFROM ", 1)[1]
    served = "./app/static/guide"   # app/api/routes/guide.py: SITE, inside the installed package
    assert re.search(rf"COPY --from=guide /guide {served}\n", final)
    assert final.index(served) < final.index("pip install --no-cache-dir --no-deps .")
