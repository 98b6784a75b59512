"""The console's Studies pages in Chromium under their Content-Security-Policy (issue 28 item 2): the list with
the study, its page with live progress to the end, the trade curve drawn, the rows linking each point's job."""
from __future__ import annotations

import shutil

import pytest

from tests.integration.live import live_server
from tests.integration.test_console_browser import ARGS, CHROMIUM, _csp_violations, _until

pytestmark = [pytest.mark.integration, pytest.mark.browser]

STUDY = {"kind": "intercept", "preset": "long-range-intercept", "mode": "independent", "label": "browser-study",
         "params": {"methods": ["impulsive"], "scan": {"step_s": 10.0}},
         "sweeps": [{"path": "intercept_time_s", "values": [8080.5, 9000.0]}]}


def test_the_studies_pages_show_progress_plot_and_point_jobs(service):
    from playwright import sync_api

    assert shutil.which("chromium"), "Debian's chromium is not installed (scripts/test-prerequisites.sh)"
    r = service.client.post("/v1/studies", json=STUDY)
    assert r.status_code == 202, r.text
    study_id = r.json()["id"]
    with live_server(service.client.app) as url, sync_api.sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=CHROMIUM, args=ARGS)
        try:
            tab = browser.new_page()  # the policy enforced
            violations = _csp_violations(tab)
            tab.goto(f"{url}/studies")
            _until(tab, f"[...document.querySelectorAll('#studies a')].some(a => a.href.endsWith('{study_id}'))")
            assert "crossrange-vs-heating" in tab.inner_text("#study-preset")
            assert "heating limit" in tab.inner_text("#study-preset-description")
            tab.goto(f"{url}/studies/{study_id}")
            _until(tab, "document.querySelector('#study-plot').dataset.final === '1'", timeout=120)
            assert tab.inner_text("#study-status") == "finished"
            assert tab.inner_text("#study-progress") == "100.0%"
            assert tab.evaluate("document.querySelector('#study-plot').naturalWidth") > 0
            rows = tab.locator("#study-rows tbody tr")
            assert rows.count() == 2
            links = tab.eval_on_selector_all("#study-rows a.point-job", "as => as.map(a => a.getAttribute('href'))")
            jobs = [row["job_id"] for row in service.client.get(f"/v1/studies/{study_id}/result").json()["rows"]]
            assert links == [f"/jobs/{j}" for j in jobs]
            assert "2302.4" in tab.inner_text("#study-rows")  # paper 003's optimum at 8080.5 s
            tab.click("#study-rows a.point-job >> nth=0")
            _until(tab, "document.querySelector('#status').textContent === 'succeeded'")
            # a succeeded job offers a warm start; the page shows the status before it re-reads the job and
            # un-hides the button, so wait for that state rather than read it at once
            _until(tab, "document.querySelector('#warm').hidden === false")
            assert violations == [], violations
        finally:
            browser.close()
