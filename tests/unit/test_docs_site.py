"""The user guide (mkdocs.yml, docs/): ``mkdocs build --strict`` passes, no built page loads anything from
the internet, the API reference holds every route of the OpenAPI document, "When a job fails" has a
section per error code, and the service serves the build at /guide under its Content-Security-Policy.

Run here, in pytest, rather than as a line of the Makefile's test target: the build then runs wherever
the suite runs (CI, a developer's ``pytest tests/unit``), it shares the imported app with the other tests
(the reference page is generated from ``create_app().openapi()``), and the checks on the built HTML sit
beside the build.  It builds into ``app/static/guide``, the directory ``make guide`` writes and /guide
serves (not in git), so the browser test finds the guide built.
"""
from __future__ import annotations

import re
from html.parser import HTMLParser
from pathlib import Path

import pytest

from app.api.routes.guide import SITE

ROOT = Path(__file__).resolve().parents[2]
ASSET_TAGS = {"link": "href", "script": "src", "img": "src", "iframe": "src", "source": "src", "embed": "src",
              "object": "data", "audio": "src", "video": "src"}


class _Assets(HTMLParser):
    """Every URL a page loads by itself (stylesheets, scripts, images, frames), not the links one follows."""

    def __init__(self):
        super().__init__()
        self.urls: list[str] = []
        self.styles: list[str] = []
        self._in_style = False

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag in ASSET_TAGS and a.get(ASSET_TAGS[tag]):
            if tag != "link" or (a.get("rel") or "") not in ("canonical", "alternate"):
                self.urls.append(a[ASSET_TAGS[tag]])
        self._in_style = tag == "style"
        if a.get("style"):
            self.styles.append(a["style"])

    def handle_data(self, data):
        if self._in_style:
            self.styles.append(data)


@pytest.fixture(scope="module")
def site():
    from mkdocs.commands.build import build
    from mkdocs.config import load_config

    config = load_config(str(ROOT / "mkdocs.yml"), site_dir=str(SITE), strict=True)
    build(config)  # strict: any warning (a broken link, a missing nav file, a bad snippet) raises
    return SITE


@pytest.mark.slow
def test_the_guide_builds_strict_with_every_page_of_the_nav(site):
    for page in ("tutorials/reentry", "tutorials/robust_reentry", "tutorials/midcourse", "tutorials/intercept",
                 "tutorials/ocp", "vehicle", "failures", "production", "reference/api"):
        assert (site / page / "index.html").is_file(), page


@pytest.mark.slow
def test_no_built_page_loads_anything_from_the_internet(site):
    pages = list(site.rglob("*.html"))
    assert len(pages) >= 10
    for page in pages:
        parser = _Assets()
        parser.feed(page.read_text(encoding="utf-8"))
        external = [u for u in parser.urls if re.match(r"(https?:)?//", u)]
        assert external == [], (page, external)
        assert not any("url(http" in s or "@import" in s for s in parser.styles), page
    for css in site.rglob("*.css"):
        text = css.read_text(encoding="utf-8")
        assert not re.search(r"url\([\"']?(https?:)?//|@import\s+url\([\"']?https?:", text), css


def test_the_api_reference_holds_every_route_of_the_openapi_document(site):
    from app.api.main import create_app
    from app.runtime.settings import Settings

    doc = create_app(Settings(database_url="sqlite:///:memory:", broker_url="redis://127.0.0.1:1/0")).openapi()
    page = (site / "reference/api/index.html").read_text(encoding="utf-8")
    for path, ops in doc["paths"].items():
        for method in ops:
            if method in ("get", "post", "put", "patch", "delete"):
                assert f"{method.upper()} {path}".replace("{", "&#123;") in page or \
                    f"{method.upper()} {path}" in page, (method, path)
    assert all(f">{name}<" in page or f"{name}<a" in page for name in doc["components"]["schemas"]), "schemas"


def test_when_a_job_fails_has_a_section_per_error_code():
    from app.kinds.failures import ADVICE, WHAT

    text = (ROOT / "docs/failures.md").read_text(encoding="utf-8")
    for code in WHAT:
        assert f"### `{code}`" in text, code
        assert all(a in text for a in ADVICE[code]), code


def test_the_service_serves_the_guide_at_slash_guide_with_nonced_scripts(site, tmp_path):
    from fastapi.testclient import TestClient

    from app.api.main import create_app
    from app.runtime.migrate import upgrade
    from app.runtime.settings import Settings

    url = f"sqlite:///{tmp_path / 'g.db'}"
    upgrade(url)
    with TestClient(create_app(Settings(database_url=url, broker_url="redis://127.0.0.1:1/0"))) as client:
        r = client.get("/guide/failures/")
        assert r.status_code == 200 and "When a job fails" in r.text
        csp = r.headers["content-security-policy"]
        nonce = re.search(r"'nonce-([^']+)'", csp).group(1)
        scripts = re.findall(r"<script(?![^>]*\bsrc=)(?![^>]*application/json)([^>]*)>", r.text)
        assert scripts and all(f'nonce="{nonce}"' in attrs for attrs in scripts)
        assert client.get("/guide").status_code in (200, 307)
        css = next(p for p in (site / "assets/stylesheets").glob("main.*.min.css"))
        assert client.get(f"/guide/assets/stylesheets/{css.name}").status_code == 200
