"""The web console in a real headless Chromium (Debian's package, driven by Playwright) against the real stack.

Every request the browser makes is recorded: none may leave 127.0.0.1.
"""
from __future__ import annotations

import shutil
import time
import uuid
from urllib.parse import urlparse

import pytest

from tests.integration.live import live_server

pytestmark = [pytest.mark.integration, pytest.mark.browser]

CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
        "--disable-component-update", "--disable-sync", "--no-first-run", "--disable-quic"]
LONG_MIDCOURSE = {"mode": "optimize", "corrections": 2, "population": 100, "generations": 2500, "seed": 7}
IMPULSIVE = {"methods": ["impulsive"]}


@pytest.fixture(scope="module")
def browser_page(service):
    from playwright import sync_api  # a test dependency: missing is an error, never a skip
    if not shutil.which("chromium"):
        pytest.fail("Debian's chromium is not installed (make test installs it: scripts/test-prerequisites.sh)")
    with live_server(service.client.app) as url, sync_api.sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=CHROMIUM, args=ARGS)
        # Playwright's wait_for_function evaluates its predicate as a string, which the console's CSP refuses
        # ('unsafe-eval'); these tests drive the pages with the policy bypassed, and
        # test_the_pages_work_under_their_content_security_policy_with_no_violation holds it
        page = browser.new_page(bypass_csp=True)
        seen: list[str] = []
        page.on("request", lambda req: seen.append(req.url))
        page.set_default_timeout(30_000)
        yield url, page, seen
        browser.close()
    hosts = {urlparse(u).hostname for u in seen if urlparse(u).scheme in ("http", "https", "ws", "wss")}
    assert hosts <= {"127.0.0.1"}, f"requests left 127.0.0.1: {sorted(hosts)}"
    assert seen, "the browser made no request at all"


def test_submit_a_preset_from_the_form_and_watch_it_finish(browser_page):
    url, page, _ = browser_page
    page.goto(f"{url}/")
    page.wait_for_function("document.querySelector('#page-info').textContent.includes(' of ')")
    page.goto(f"{url}/new?kind=intercept")
    page.wait_for_selector('input[data-path="methods"]')
    assert "1501.73" in page.inner_text("#preset-description")  # the preset's description is shown
    page.fill('input[data-path="methods"]', '["impulsive"]')
    page.fill("#label", "from-the-browser")
    page.click("#submit")
    page.wait_for_url(f"{url}/jobs/*")
    page.evaluate("window.__noReload = 1")
    page.wait_for_function("document.querySelector('#status').textContent === 'succeeded'", timeout=120_000)
    assert page.evaluate("window.__noReload") == 1  # progress came live, the page was never reloaded
    assert page.inner_text("#progress-text") == "100.0%"
    assert page.eval_on_selector("#bar", "el => el.style.width") == "100%"
    page.wait_for_selector("#numbers tbody tr")
    numbers = page.inner_text("#numbers")
    assert "delta_v_mps" in numbers and "2302.4" in numbers, numbers


def test_invalid_parameters_show_the_422_next_to_the_field(browser_page):
    url, page, _ = browser_page
    page.goto(f"{url}/new?kind=reentry")
    page.wait_for_selector('input[data-path="grid.intervals"]')
    page.fill('input[data-path="grid.intervals"]', "-5")
    page.click("#submit")
    slot = '[data-error-for="grid.intervals"]'
    page.wait_for_function(f"document.querySelector('{slot}').textContent.length > 0")
    assert "greater than" in page.inner_text(slot)
    assert page.url.startswith(f"{url}/new")  # nothing was submitted


def test_an_ocp_problem_is_edited_as_json_and_each_422_is_listed_with_its_line(browser_page):
    url, page, _ = browser_page
    page.goto(f"{url}/new?kind=ocp")
    page.wait_for_function("document.querySelector('#params-json').value.includes('dynamics')")
    assert page.is_visible("#params-json") and page.is_hidden("#params")
    text = page.input_value("#params-json")   # the brachistochrone preset, the first of the kind
    assert '"x": "v*sin(theta)"' in text
    page.fill("#params-json", text.replace('"x": "v*sin(theta)"', '"x": "v*sin(teta)"'))
    page.click("#submit")
    page.wait_for_selector("#json-errors li")
    error = page.inner_text("#json-errors")
    assert "params.dynamics.x (line " in error and "unknown name 'teta'; did you mean 'theta'?" in error
    selected = page.evaluate("(() => { const a = document.querySelector('#params-json');"
                             " return a.value.slice(a.selectionStart, a.selectionEnd); })()")
    assert '"x": "v*sin(teta)"' in selected   # the line of the field named is selected
    assert page.url.startswith(f"{url}/new")  # nothing was submitted
    page.fill("#params-json", "{not json")
    page.click("#submit")
    assert "not valid JSON" in page.inner_text("#form-error")
    page.fill("#params-json", text)
    page.click("#submit")
    page.wait_for_url(f"{url}/jobs/*")
    page.wait_for_function("document.querySelector('#status').textContent === 'succeeded'", timeout=120_000)
    page.wait_for_selector("#plots img")
    assert page.locator("#plots img").count() >= 4   # every state and control against time
    assert "objective" in page.inner_text("#numbers")


def test_cancel_a_running_job_from_its_page(browser_page, service):
    url, page, _ = browser_page
    job = service.submit("midcourse", preset="upper-stage-two-corrections", params=LONG_MIDCOURSE).json()
    page.goto(f"{url}/jobs/{job['id']}")
    page.wait_for_function("document.querySelector('#status').textContent === 'running'", timeout=60_000)
    page.click("#cancel")
    page.wait_for_function("document.querySelector('#status').textContent === 'cancelled'", timeout=60_000)
    assert service.client.get(f"/v1/jobs/{job['id']}").json()["status"] == "cancelled"


def test_delete_a_job_from_its_page(browser_page, service):
    url, page, _ = browser_page
    job = service.submit("midcourse", preset="upper-stage-two-corrections", params=LONG_MIDCOURSE).json()
    page.goto(f"{url}/jobs/{job['id']}")
    page.wait_for_selector("#kind:not(:empty)")
    page.once("dialog", lambda dialog: dialog.accept())  # the confirm() before deleting
    page.click("#delete")
    page.wait_for_url(f"{url}/")
    assert service.client.get(f"/v1/jobs/{job['id']}").status_code == 404


def test_compare_two_jobs_on_one_plot(browser_page, service):
    url, page, _ = browser_page
    ids = []
    for tof in (8080.5, 9000.0):
        job = service.submit("intercept", preset="long-range-intercept",
                             params={**IMPULSIVE, "intercept_time_s": tof}, label=f"tf {tof}").json()
        ids.append(job["id"])
    for job_id in ids:
        assert service.wait(job_id)["status"] == "succeeded"
    page.goto(f"{url}/compare?ids={','.join(ids)}")
    page.wait_for_function("document.querySelector('#compare-img').naturalWidth > 0")
    assert page.eval_on_selector("#compare-img", "img => img.naturalWidth") == 800


def test_with_keys_the_console_asks_once_and_shows_only_that_owners_jobs(browser_page, service):
    from fastapi.testclient import TestClient

    from app.api.auth import create_key
    from app.api.main import create_app

    _, page, _ = browser_page
    settings = service.settings.model_copy(update={"auth": "required"})
    app = create_app(settings)
    suffix = uuid.uuid4().hex[:6]
    _, key_a = create_key(app.state.db, name=f"console-a-{suffix}")
    _, key_b = create_key(app.state.db, name=f"console-b-{suffix}")
    with TestClient(app) as client:
        ids = {}
        for who, key in (("a", key_a), ("b", key_b)):
            r = client.post("/v1/jobs", json={"kind": "intercept", "preset": "long-range-intercept",
                                              "params": IMPULSIVE, "label": f"owner-{who}-{suffix}"},
                            headers={"Authorization": f"Bearer {key}"})
            assert r.status_code == 202, r.text
            ids[who] = r.json()["id"]
    with live_server(app) as url:
        page.goto(f"{url}/")
        page.wait_for_selector("#key-box:not([hidden])")  # a 401 from /v1/jobs: the console asks for a key
        page.fill("#key-input", key_a)
        page.click("#key-form button")
        page.wait_for_selector(f'tr[data-id="{ids["a"]}"]')
        assert page.locator(f'tr[data-id="{ids["b"]}"]').count() == 0
        assert "API key set" in page.inner_text("#key-status")
        page.goto(f"{url}/jobs/{ids['b']}")  # another owner's job is not found, even by its id
        page.wait_for_function("document.querySelector('#error').textContent.includes('not found')")
        page.evaluate("localStorage.removeItem('trajlab.apiKey')")


def test_docs_and_a_report_render_offline(browser_page, service):
    url, page, seen = browser_page
    page.goto(f"{url}/docs")
    page.wait_for_selector(".opblock-summary-path", timeout=60_000)  # Swagger UI 5 drew the operation list
    paths = page.eval_on_selector_all(".opblock-summary-path", "els => els.map(e => e.textContent)")
    assert any("/v1/jobs" in p for p in paths)
    page.goto(f"{url}/redoc")
    page.wait_for_selector("h1", timeout=60_000)
    job = service.submit("intercept", preset="long-range-intercept", params=IMPULSIVE).json()
    assert service.wait(job["id"])["status"] == "succeeded"
    page.goto(f"{url}/v1/jobs/{job['id']}/report.html")
    assert page.locator("figure svg").count() == 1 and page.locator("figure svg").first.bounding_box()["width"] > 100
    page.goto(f"{url}/jobs/{job['id']}")  # the console's job page shows the plots as images
    page.wait_for_function("[...document.querySelectorAll('#plots img')].some(i => i.naturalWidth > 0)")
    assert all(urlparse(u).hostname in (None, "127.0.0.1") for u in seen if u.startswith("http"))


def _csp_violations(page) -> list[str]:
    """Chromium reports a blocked script, style, eval or frame as a console error naming the policy."""
    found: list[str] = []
    page.on("console", lambda msg: found.append(msg.text) if "Content Security Policy" in msg.text
            or "X-Frame-Options" in msg.text else None)
    return found


def _until(tab, js: str, timeout: float = 60.0) -> None:
    """Poll ``js`` from here (CDP evaluation, which a page's CSP does not govern, unlike wait_for_function)."""
    deadline = time.monotonic() + timeout
    while not tab.evaluate(js):
        assert time.monotonic() < deadline, f"not within {timeout} s: {js}"
        time.sleep(0.2)


def test_the_pages_work_under_their_content_security_policy_with_no_violation(browser_page, service):
    url, page, _ = browser_page
    job = service.submit("intercept", preset="long-range-intercept", params=IMPULSIVE).json()
    assert service.wait(job["id"])["status"] == "succeeded"
    context = page.context.browser.new_context()  # the policy enforced (the fixture's page bypasses it)
    tab = context.new_page()
    violations = _csp_violations(tab)
    try:
        r = tab.goto(f"{url}/")
        assert "frame-ancestors 'none'" in r.headers["content-security-policy"]
        assert r.headers["x-frame-options"] == "DENY" and r.headers["x-content-type-options"] == "nosniff"
        _until(tab, "document.querySelector('#page-info').textContent.includes(' of ')")
        _until(tab, "[...document.querySelectorAll('#jobs .bar')].some(b => b.style.width === '100%')")
        tab.goto(f"{url}/new?kind=intercept")
        tab.wait_for_selector('input[data-path="methods"]')
        assert "1501.73" in tab.inner_text("#preset-description")  # the presets came through the JSON block
        tab.goto(f"{url}/jobs/{job['id']}")
        _until(tab, "document.querySelector('#status').textContent === 'succeeded'")
        _until(tab, "[...document.querySelectorAll('#plots img')].some(i => i.naturalWidth > 0)")
        tab.goto(f"{url}/compare?ids={job['id']}")
        tab.wait_for_selector("#compare-form")
        tab.goto(f"{url}/docs")
        tab.wait_for_selector(".opblock-summary-path", timeout=60_000)  # Swagger UI ran from its nonce'd script
        tab.goto(f"{url}/redoc")
        tab.wait_for_selector("h1", timeout=60_000)
        tab.goto(f"{url}/v1/jobs/{job['id']}/report.html")
        assert tab.locator("figure svg").count() == 1
        tab.wait_for_timeout(300)  # a late report has time to arrive
        assert violations == [], violations
    finally:
        context.close()


def test_a_framing_page_is_refused(browser_page):
    url, page, _ = browser_page
    context = page.context.browser.new_context()
    tab = context.new_page()
    violations = _csp_violations(tab)
    try:
        tab.set_content(f'<iframe id="f" src="{url}/" width="600" height="400"></iframe>')
        tab.wait_for_timeout(1500)
        assert tab.frame_locator("#f").locator("#jobs").count() == 0  # the console never rendered in the frame
        assert any("frame-ancestors" in v or "X-Frame-Options" in v for v in violations), violations
    finally:
        context.close()
