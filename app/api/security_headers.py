"""Browser-side hardening of every HTML page (the console, /docs, /redoc) and ``nosniff`` on every response.

With keys on, the console is a page that holds an API key (localStorage), so a script injected into it
could read the key, and a page that framed it could click "cancel" (issue 30).  Every HTML response
therefore carries:

* ``Content-Security-Policy``: scripts and styles only from this origin, by path (the console's
  ``console.js`` and ``console.css``: its pages have no inline script, handler or style attribute), no
  plugins, no ``<base>`` rewriting, forms and fetches to this origin only, and ``frame-ancestors 'none'``;
  a page with an inline script of its own (Swagger UI's start-up script on /docs) sets its own policy
  with a per-response nonce (:func:`html_with_nonce`), which this middleware leaves as it is;
* ``X-Frame-Options: DENY`` (what older browsers read instead of ``frame-ancestors``);
* ``Referrer-Policy: no-referrer`` (a job id in the URL never leaves in a Referer).

Every response, HTML or not, says ``X-Content-Type-Options: nosniff`` (a result body is never run as a
script).  A pure ASGI middleware that only touches the response's start message: the event stream
passes through untouched and the JSON routes pay a header append.
"""
from __future__ import annotations

import secrets

from starlette.types import ASGIApp, Message, Receive, Scope, Send

CSP = ("default-src 'self'; script-src 'self'; style-src 'self'; img-src 'self' data: blob:; "
       "connect-src 'self'; font-src 'self'; object-src 'none'; base-uri 'none'; form-action 'self'; "
       "frame-ancestors 'none'")
# A job's report (a self-contained file: its own <style>, matplotlib's SVGs with style attributes) runs no
# script at all and loads nothing.
REPORT_CSP = ("default-src 'none'; style-src 'unsafe-inline'; img-src data:; base-uri 'none'; form-action 'none'; "
              "frame-ancestors 'none'")
NOSNIFF = (b"x-content-type-options", b"nosniff")
HTML_HEADERS = ((b"x-frame-options", b"DENY"), (b"referrer-policy", b"no-referrer"))


def csp_with_nonce(nonce: str, *, inline_styles: bool = False) -> str:
    """The console's policy with a page's inline scripts and styles allowed by their nonce; ``inline_styles``
    allows every inline style instead (a nonce would make browsers ignore ``'unsafe-inline'``) and blob:
    workers (ReDoc)."""
    styles = "style-src 'self' 'unsafe-inline'; worker-src 'self' blob:" if inline_styles \
        else f"style-src 'self' 'nonce-{nonce}'"
    return CSP.replace("script-src 'self'", f"script-src 'self' 'nonce-{nonce}'").replace("style-src 'self'", styles)


def html_with_nonce(html: str, *, inline_styles: bool = False) -> tuple[str, dict[str, str]]:
    """``html`` with every inline ``<script>``/``<style>`` given a fresh nonce, and the policy header that
    allows exactly those (for pages written by a library: FastAPI's Swagger UI and ReDoc pages)."""
    nonce = secrets.token_urlsafe(16)
    html = html.replace("<script>", f'<script nonce="{nonce}">').replace("<style>", f'<style nonce="{nonce}">')
    return html, {"Content-Security-Policy": csp_with_nonce(nonce, inline_styles=inline_styles)}


class SecurityHeaders:
    def __init__(self, app: ASGIApp):
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return

        async def send_with_headers(message: Message) -> None:
            if message["type"] == "http.response.start":
                headers = list(message.get("headers", ()))
                headers.append(NOSNIFF)
                names = {k.lower() for k, _ in headers}
                content_type = next((v for k, v in headers if k.lower() == b"content-type"), b"")
                if content_type.startswith(b"text/html"):
                    headers.extend(HTML_HEADERS)
                    if b"content-security-policy" not in names:
                        headers.append((b"content-security-policy", CSP.encode()))
                message["headers"] = headers
            await send(message)

        await self.app(scope, receive, send_with_headers)
