"""Issue 30: the console's pages and /docs carry a strict CSP and refuse framing; failed API keys are
rate-limited per client address (SQLite, TestClient, TRAJLAB_AUTH=required; Redis unreachable, so each
process counts alone: the shared count across real API processes is tests/integration/test_key_limiter.py).  The same pages in a real
browser, with no CSP violation and a framing page refused: tests/integration/test_console_browser.py."""
from __future__ import annotations

import re

import pytest
from fastapi.testclient import TestClient

from app.api import auth
from app.api.key_attempts import FailedKeyAttempts
from app.api.main import create_app
from app.runtime.migrate import upgrade
from app.runtime.settings import Settings


@pytest.fixture(scope="module")
def client(tmp_path_factory):
    url = f"sqlite:///{tmp_path_factory.mktemp('hard') / 'hard.db'}"
    upgrade(url)
    settings = Settings(database_url=url, broker_url="redis://127.0.0.1:1/0", auth="required", auth_max_failures=3,
                        auth_failure_window_s=600)
    app = create_app(settings)
    with TestClient(app) as c:
        _, key = auth.create_key(app.state.db, name="carol")
        c.key = key
        yield c


@pytest.mark.parametrize("path", ["/", "/new", "/compare", "/jobs/" + "0" * 32, "/docs", "/redoc"])
def test_every_html_page_has_a_strict_policy_and_refuses_framing(client, path):
    r = client.get(path)
    assert r.status_code == 200 and r.headers["content-type"].startswith("text/html")
    csp = r.headers["content-security-policy"]
    directives = dict(d.strip().split(" ", 1) for d in csp.split(";"))
    assert directives["frame-ancestors"] == "'none'" and directives["object-src"] == "'none'"
    assert "'unsafe-inline'" not in directives["script-src"] and "'unsafe-eval'" not in directives["script-src"]
    assert r.headers["x-frame-options"] == "DENY"
    assert r.headers["x-content-type-options"] == "nosniff"
    assert r.headers["referrer-policy"] == "no-referrer"
    # an inline script runs only with this response's nonce (the docs' start-up script); the console has none
    nonces = set(re.findall(r"'nonce-([^']+)'", directives["script-src"]))
    for tag in re.findall(r"<script(?![^>]*\bsrc=)(?![^>]*application/json)[^>]*>", r.text):
        assert any(f'nonce="{n}"' in tag for n in nonces), tag
    assert not re.search(r"\son[a-z]+\s*=", r.text), "an inline event handler"
    if not path.endswith(("docs", "redoc")):
        assert not nonces and " style=" not in r.text


def test_each_docs_page_gets_a_fresh_nonce(client):
    first, second = (client.get("/docs").headers["content-security-policy"] for _ in range(2))
    assert first != second


def test_json_responses_say_nosniff_and_no_html_headers(client):
    r = client.get("/healthz")
    assert r.headers["x-content-type-options"] == "nosniff" and "content-security-policy" not in r.headers


def test_failed_keys_are_rate_limited_per_address_with_retry_after(client):
    from app.api.observability import HTTP_REGISTRY

    def counted(outcome):
        return HTTP_REGISTRY.get_sample_value("trajlab_auth_failures_total", {"outcome": outcome}) or 0.0

    before = counted("invalid"), counted("refused")
    bad = {"Authorization": "Bearer tl_not-a-key"}
    assert [client.get("/v1/jobs", headers=bad).status_code for _ in range(3)] == [401] * 3
    r = client.get("/v1/jobs", headers=bad)
    assert r.status_code == 429 and 1 <= int(r.headers["Retry-After"]) <= 600
    # both kinds of failure are counted in the metrics (trajlab_auth_failures_total{outcome})
    assert (counted("invalid") - before[0], counted("refused") - before[1]) == (3.0, 1.0)
    # a valid key from the same address is served: others' failures never lock a user out (issue 36),
    # and it does not clear the count; a missing key is still a 401
    assert client.get("/v1/jobs", headers={"Authorization": f"Bearer {client.key}"}).status_code == 200
    assert client.get("/v1/jobs", headers=bad).status_code == 429
    assert client.get("/v1/jobs").status_code == 401
    # an X-Forwarded-For from a peer not in TRAJLAB_TRUSTED_PROXIES (none here) changes nothing
    forged = {**bad, "X-Forwarded-For": "10.9.9.9"}
    assert client.get("/v1/jobs", headers=forged).status_code == 429
    # another address is not affected (the counter is per address)
    other = TestClient(client.app, client=("10.1.2.3", 5555))
    assert other.get("/v1/jobs", headers={"Authorization": f"Bearer {client.key}"}).status_code == 200


def test_failures_leave_the_window():
    now = [0.0]
    limiter = FailedKeyAttempts(max_failures=2, window_s=10, clock=lambda: now[0])
    limiter.failed("a")
    now[0] = 4.0
    limiter.failed("a")
    assert limiter.retry_after_s("a") == 6 and limiter.retry_after_s("b") is None
    now[0] = 10.5
    assert limiter.retry_after_s("a") is None  # the first failure left the window
