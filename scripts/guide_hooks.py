"""MkDocs hook of the user guide (mkdocs.yml ``hooks:``): writes the API reference page from the service's
own OpenAPI document at build time, so the guide's reference is the code's.

``docs/reference/api.md`` holds the marker ``<!-- openapi-reference -->``; this hook replaces it with one
section per tag, one entry per operation (method, path, summary, parameters, request body, responses) and
the request and result schemas with their fields' types and descriptions.  No network: the document comes
from ``create_app().openapi()`` on a throwaway SQLite URL (building the document touches no database).
"""
from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path

MARKER = "<!-- openapi-reference -->"
ROOT = Path(__file__).resolve().parents[1]


def openapi_document() -> dict:
    if str(ROOT) not in sys.path:
        sys.path.insert(0, str(ROOT))
    from app.api.main import create_app
    from app.runtime.settings import Settings

    with tempfile.TemporaryDirectory() as tmp:
        app = create_app(Settings(database_url=f"sqlite:///{os.path.join(tmp, 'guide.db')}",
                                  broker_url="redis://127.0.0.1:1/0"))
        return app.openapi()


def _cell(text) -> str:
    return " ".join(str(text or "").split()).replace("|", "\\|")


def _type(schema: dict) -> str:
    if "$ref" in schema:
        name = schema["$ref"].rsplit("/", 1)[-1]
        return f"[{name}](#{name.lower()})"
    for key in ("anyOf", "oneOf"):
        if key in schema:
            return " or ".join(_type(s) for s in schema[key])
    if schema.get("type") == "array":
        return f"list of {_type(schema.get('items') or {})}"
    if "enum" in schema:
        return "one of " + ", ".join(f"`{v}`" for v in schema["enum"])
    if "const" in schema:
        return f"`{schema['const']}`"
    return schema.get("type", "any")


def _operation(method: str, path: str, op: dict) -> list[str]:
    out = [f"### `{method.upper()} {path}`", ""]
    if op.get("summary"):
        out += [f"**{_cell(op['summary'])}**", ""]
    if op.get("description"):
        out += [op["description"].strip(), ""]
    params = op.get("parameters") or []
    if params:
        out += ["| parameter | in | type | description |", "| --- | --- | --- | --- |"]
        out += [f"| `{p['name']}`{' (required)' if p.get('required') else ''} | {p.get('in')} | "
                f"{_cell(_type(p.get('schema') or {}))} | {_cell(p.get('description'))} |" for p in params]
        out.append("")
    body = ((op.get("requestBody") or {}).get("content") or {}).get("application/json")
    if body:
        out += [f"Request body: {_type(body.get('schema') or {})}", ""]
        examples = body.get("examples") or {}
        if examples:
            out += ["Examples: " + ", ".join(f"`{name}`" for name in examples), ""]
    responses = op.get("responses") or {}
    if responses:
        out += ["| status | meaning |", "| --- | --- |"]
        for status, r in responses.items():
            schema = ((r.get("content") or {}).get("application/json") or {}).get("schema")
            shape = f" ({_type(schema)})" if schema else ""
            out.append(f"| {status} | {_cell(r.get('description'))}{_cell(shape)} |")
        out.append("")
    return out


def _schema(name: str, schema: dict) -> list[str]:
    out = [f"### {name}", ""]
    if schema.get("description"):
        out += [_cell(schema["description"]), ""]
    props = schema.get("properties") or {}
    if props:
        required = set(schema.get("required") or [])
        out += ["| field | type | description |", "| --- | --- | --- |"]
        out += [f"| `{field}`{' (required)' if field in required else ''} | {_cell(_type(s))} | "
                f"{_cell(s.get('description') or s.get('title'))} |" for field, s in props.items()]
        out.append("")
    return out


def reference_markdown(doc: dict) -> str:
    by_tag: dict[str, list[str]] = {}
    for path, ops in doc.get("paths", {}).items():
        for method, op in ops.items():
            if method not in ("get", "post", "put", "patch", "delete"):
                continue
            tag = (op.get("tags") or ["other"])[0]
            by_tag.setdefault(tag, []).extend(_operation(method, path, op))
    lines = [f"Document version {doc.get('info', {}).get('version', '')}, "
             f"{sum(len(v) for v in doc.get('paths', {}).values())} operations.", ""]
    for tag in sorted(by_tag):
        lines += [f"## {tag}", ""] + by_tag[tag]
    lines += ["## Schemas", ""]
    for name, schema in sorted(doc.get("components", {}).get("schemas", {}).items()):
        lines += _schema(name, schema)
    return "\n".join(lines)


def on_page_markdown(markdown: str, page, config, files) -> str:  # MkDocs hook
    if MARKER not in markdown:
        return markdown
    return markdown.replace(MARKER, reference_markdown(openapi_document()))
