"""Screenshots of the console for the guide and the README: the New job form, a job page per kind and a
failed job, saved as docs/img/console-*.png.

Runs against a service that is already up (``make run``; ``--url`` or ``TRAJLAB_URL``): submits one preset
per kind (the robust one with 2,000 Monte Carlo samples, to be quick), waits for each, and photographs its
page with Debian's Chromium (Playwright, from the test extra).  Nothing is written before every job has
finished.  ``python scripts/console_screenshots.py --help`` says the options.
"""
from __future__ import annotations

import argparse
import os
import shutil
import sys
import time
from pathlib import Path

import httpx

CASES = [  # (file name, kind, preset, params)
    ("console-job-reentry.png", "reentry", "betts-max-crossrange-heat-limited", None),
    ("console-job-robust_reentry.png", "robust_reentry", "robust-max-crossrange", {"monte_carlo": {"samples": 2000}}),
    ("console-job-midcourse.png", "midcourse", "upper-stage-two-corrections", None),
    ("console-job-intercept.png", "intercept", "long-range-intercept", None),
    ("console-job-ocp.png", "ocp", "brachistochrone", None),
    ("console-failed-job.png", "reentry", "betts-max-crossrange-heat-limited", {"path": {"max_heat_rate_w_m2": 200000.0}}),
]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--url", default=os.environ.get("TRAJLAB_URL", "http://127.0.0.1:8000"),
                        help="the running service (TRAJLAB_URL; default http://127.0.0.1:8000)")
    parser.add_argument("--out", type=Path, default=Path("docs/img"), help="where the PNGs go (default docs/img)")
    parser.add_argument("--timeout", type=float, default=900.0, help="seconds to wait for each job")
    args = parser.parse_args(argv)
    headers = {"Authorization": f"Bearer {os.environ['TRAJLAB_API_KEY']}"} if os.environ.get("TRAJLAB_API_KEY") else {}
    client = httpx.Client(base_url=args.url, headers=headers, timeout=30)
    jobs = []
    for name, kind, preset, params in CASES:
        body = {"kind": kind, "preset": preset, "label": preset} | ({"params": params} if params else {})
        r = client.post("/v1/jobs", json=body)
        r.raise_for_status()
        jobs.append((name, r.json()["id"]))
    for name, job_id in jobs:
        deadline = time.monotonic() + args.timeout
        while client.get(f"/v1/jobs/{job_id}").json()["status"] not in ("succeeded", "failed", "cancelled"):
            if time.monotonic() > deadline:
                print(f"{name}: job {job_id} did not finish in {args.timeout} s", file=sys.stderr)
                return 1
            time.sleep(2)
    from playwright.sync_api import sync_playwright

    args.out.mkdir(parents=True, exist_ok=True)
    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=shutil.which("chromium") or "/usr/bin/chromium",
                                     args=["--headless", "--no-sandbox", "--disable-gpu"])
        page = browser.new_page(viewport={"width": 1280, "height": 900}, bypass_csp=True)
        page.goto(f"{args.url}/new?kind=reentry")
        page.wait_for_selector('[data-path="grid.intervals"]')
        page.screenshot(path=str(args.out / "console-new-job-form.png"), full_page=True)
        for name, job_id in jobs:
            page.goto(f"{args.url}/jobs/{job_id}")
            page.wait_for_function("document.body.dataset.summary === 'shown'", timeout=60_000)
            # every plot drawn (an <img> without its src yet counts as complete: wait for its pixels)
            page.wait_for_function("(() => { const imgs = [...document.querySelectorAll('img.plot')]; "
                                   "return imgs.length > 0 && imgs.every(i => i.naturalWidth > 0); })()",
                                   timeout=120_000)
            page.screenshot(path=str(args.out / name), full_page=True)
            print(args.out / name)
        page.goto(f"{args.url}/")
        page.wait_for_function("[...document.querySelectorAll('#jobs td.headline')].some(td => td.textContent)")
        page.wait_for_timeout(1000)
        page.screenshot(path=str(args.out / "console-job-list.png"), full_page=False)
        browser.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
