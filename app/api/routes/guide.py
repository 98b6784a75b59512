"""``/guide``: the user guide (MkDocs, Material theme, built from ``docs/`` by ``make guide``) as static files.

The built site lives in the package (``app/static/guide``, not in git: ``make install``, ``make guide`` or
the docs test writes it), so the service and the guide it serves come from one checkout.  The pages load nothing from
the internet (``font: false`` in mkdocs.yml; tests/unit/test_docs_site.py checks every built page).
Material's pages carry small inline scripts (its palette and search set-up), so ``/guide`` pages get the
console's policy with those scripts allowed by a per-response nonce (app.api.security_headers), as
/docs does.  Until the site is built, ``/guide`` answers 404 with the command that builds it.
"""
from __future__ import annotations

from pathlib import Path

from fastapi import FastAPI
from fastapi.responses import HTMLResponse, RedirectResponse
from starlette.staticfiles import StaticFiles

from app.api.security_headers import html_with_nonce

SITE = Path(__file__).resolve().parents[2] / "static" / "guide"
NOT_BUILT = ("<!doctype html><title>trajlab guide</title><h1>The guide is not built</h1>"
             "<p>Run <code>make install</code> (or <code>make guide</code>: mkdocs build --strict) and reload.</p>")


class GuideFiles(StaticFiles):
    """StaticFiles whose HTML pages get their inline scripts and styles a nonce (and the policy naming it);
    the site is looked for on every request, so a guide built after the service started is served."""

    async def __call__(self, scope, receive, send):
        if not (SITE / "index.html").is_file():
            await HTMLResponse(NOT_BUILT, status_code=404)(scope, receive, send)
            return
        await super().__call__(scope, receive, send)

    async def get_response(self, path, scope):
        response = await super().get_response(path, scope)
        if response.status_code == 200 and response.media_type == "text/html" and hasattr(response, "path"):
            html = Path(response.path).read_text(encoding="utf-8")
            html, headers = html_with_nonce(html, inline_styles=True)
            return HTMLResponse(html, headers=headers)
        return response


def mount(app: FastAPI) -> None:
    app.add_api_route("/guide", lambda: RedirectResponse("/guide/"), include_in_schema=False)
    app.mount("/guide", GuideFiles(directory=str(SITE), html=True, check_dir=False), name="guide")
