"""One self-contained HTML report per job: parameters, key numbers, solver, verification, notes and
every plot inlined as SVG.  No script, no stylesheet or image from anywhere: it can be mailed."""
from __future__ import annotations

import html
import json
from typing import Any


def _table(d: dict) -> str:
    rows = "".join(f"<tr><th>{html.escape(str(k))}</th><td>{html.escape(_fmt(v))}</td></tr>" for k, v in d.items()
                   if not isinstance(v, (dict, list)) or (isinstance(v, list) and len(v) <= 6))
    return f"<table>{rows}</table>"


def _fmt(v) -> str:
    if isinstance(v, float):
        return f"{v:.8g}"
    return str(v)


def _headlines(lines: list[dict]) -> str:
    """The kind's headline numbers (app.kinds.headlines), one line each, the verdict marked."""
    items = "".join(f"<li class=\"{'good' if h.get('good') else 'bad' if h.get('good') is False else ''}\">"
                    f"{html.escape(h['text'])}</li>" for h in lines)
    return f"<ul class=\"headlines\">{items}</ul>" if items else ""


def render_report(*, job: dict, result: dict, key_numbers: dict, svgs: list[tuple[str, str]],
                  headlines: list[dict] | None = None) -> str:
    blocks = [f"<h2>Key numbers</h2>{_headlines(headlines or [])}{_table(key_numbers)}"]
    for label, block in _blocks(result):
        blocks.append(f"<h2>{html.escape(label)}</h2>{_table(block)}")
    notes = _notes(result)
    if notes:
        blocks.append("<h2>Notes</h2><ul>" + "".join(f"<li>{html.escape(n)}</li>" for n in notes) + "</ul>")
    for title, svg in svgs:
        # the SVG's own XML prolog is dropped so it can sit inline in HTML
        body = svg[svg.find("<svg"):]
        blocks.append(f"<figure><figcaption>{html.escape(title)}</figcaption>{body}</figure>")
    params = html.escape(json.dumps(job["params"], indent=2))
    title = html.escape(f"{job['kind']} job {job.get('label') or job['id']}")
    return f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>trajlab: {title}</title>
<style>
body {{ font: 14px/1.4 system-ui, sans-serif; margin: 2em; color: #1d2330; max-width: 1100px; }}
table {{ border-collapse: collapse; margin: .5em 0; }} th, td {{ border-bottom: 1px solid #e3e6ee;
padding: .2em .8em; text-align: left; }} th {{ font-weight: 500; color: #5b6475; }}
figure {{ margin: 1.5em 0; }} figure svg {{ max-width: 100%; height: auto; }}
pre {{ background: #f4f6fa; padding: .8em; overflow: auto; }}
ul.headlines {{ font-size: 16px; }} li.good {{ color: #1b6e3a; }} li.bad {{ color: #a3261b; }}
</style></head><body>
<h1>{title}</h1>
<p>status <b>{html.escape(job['status'])}</b>, created {html.escape(str(job['created_at']))}, finished
{html.escape(str(job['finished_at']))}, id <code>{html.escape(job['id'])}</code></p>
{''.join(blocks)}
<h2>Parameters (resolved: post them back to POST /v1/jobs to re-run)</h2><pre>{params}</pre>
</body></html>
"""


def _blocks(result: dict):
    """(label, dict) of the solver and verification blocks wherever they sit in the result."""
    for path in ("solver", "verification", "impulsive.solver", "impulsive.verification", "finite_thrust.solver",
                 "finite_thrust.verification", "objective", "final"):
        node: Any = result
        for part in path.split("."):
            node = node.get(part) if isinstance(node, dict) else None
        if isinstance(node, dict):
            yield path.replace(".", " "), node


def _notes(result: dict) -> list[str]:
    notes = list(result.get("notes") or [])
    for key in ("impulsive", "finite_thrust"):
        notes += list((result.get(key) or {}).get("notes") or [])
    return [str(n) for n in notes]
