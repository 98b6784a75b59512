"""``/docs`` (Swagger UI 5) and ``/redoc`` served from assets in the package: they work offline.

FastAPI's default pages load Swagger UI, ReDoc, Google Fonts and a favicon from the internet, and
render blank on an air-gapped network.  The assets live in ``app/static/docs`` (with their licences).
"""
from __future__ import annotations

from pathlib import Path

from fastapi import APIRouter, FastAPI
from fastapi.openapi.docs import get_redoc_html, get_swagger_ui_html, get_swagger_ui_oauth2_redirect_html
from fastapi.responses import HTMLResponse

from app.api.security_headers import html_with_nonce

STATIC = Path(__file__).resolve().parents[2] / "static" / "docs"
router = APIRouter(include_in_schema=False)
NO_FAVICON = "data:,"  # the default favicon is fetched from fastapi.tiangolo.com


def _with_nonce(page: HTMLResponse, **csp_options) -> HTMLResponse:
    """The page with its inline start-up script allowed by a fresh nonce (app.api.security_headers)."""
    html, headers = html_with_nonce(bytes(page.body).decode(), **csp_options)
    return HTMLResponse(html, headers=headers)


@router.get("/docs", response_class=HTMLResponse)
def swagger_ui():
    return _with_nonce(get_swagger_ui_html(
        openapi_url="/openapi.json", title="trajlab API", oauth2_redirect_url="/docs/oauth2-redirect",
        swagger_js_url="/static/docs/swagger-ui-bundle.js", swagger_css_url="/static/docs/swagger-ui.css",
        swagger_favicon_url=NO_FAVICON,
        # no spec validator badge: it would send the document to validator.swagger.io
        swagger_ui_parameters={"validatorUrl": None}))


@router.get("/docs/oauth2-redirect", response_class=HTMLResponse)
def swagger_ui_redirect():
    return _with_nonce(get_swagger_ui_oauth2_redirect_html())


REDOC_LOGO = "https://cdn.redoc.ly/redoc/logo-mini.svg"


@router.get("/static/docs/redoc.standalone.js")
def redoc_js():
    """ReDoc as shipped, less the one image it loads from its vendor's CDN (an empty src: it hides itself)."""
    from fastapi.responses import Response

    body = (STATIC / "redoc.standalone.js").read_text(encoding="utf-8").replace(REDOC_LOGO, "")
    return Response(body, media_type="text/javascript", headers={"Cache-Control": "public, max-age=86400"})


@router.get("/redoc", response_class=HTMLResponse)
def redoc():
    # ReDoc's styled-components write <style> elements at run time (no nonce reaches them): styles inline
    # on this page only; scripts stay by path or nonce
    return _with_nonce(get_redoc_html(openapi_url="/openapi.json", title="trajlab API",
                                      redoc_js_url="/static/docs/redoc.standalone.js", redoc_favicon_url=NO_FAVICON,
                                      with_google_fonts=False), inline_styles=True)


def mount(app: FastAPI) -> None:
    from fastapi.staticfiles import StaticFiles

    app.include_router(router)  # before the mount: its redoc.standalone.js wins
    app.mount("/static/docs", StaticFiles(directory=str(STATIC)), name="docs-static")
