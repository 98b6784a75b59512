"""The figures the docs quote, written from a run (issue 38 item 2): no headline number is typed by hand.

A page quotes a job's headline numbers as a ```text block of ``= ...`` lines after the ```sh block that
runs the job (the tutorials' "Read the result").  This script runs each such page's blocks in order, in one
shell session as a reader would (the same rule as ``tests/integration/test_readme_blocks.py``, which runs
every block and holds the quotes to the run within their tolerance), against the service at
``$TRAJLAB_URL``, and replaces each headline block by the ``= ...`` lines the command printed.  Blocks
marked ``<!-- no-run: ... -->`` are not run; a block after the last quote is not run either (nothing of it
is quoted).  Other quotes (an error's explanation, elided with ``...``) are left as written and checked by
the test.

Usage (a service running, e.g. ``make run PORT=8317`` and its export line)::

    .venv/bin/python scripts/docs_numbers.py                       # every page with a headline quote
    .venv/bin/python scripts/docs_numbers.py docs/tutorials/intercept.md

It prints each quote it changed (old and new lines).  The check that the pages agree with a run, within
each quote's tolerance, is the docs test's (it runs the same blocks on every test run).

``--tables`` (no service needed) rewrites instead every table of benchmark figures between
``<!-- bench: NAME -->`` and ``<!-- /bench -->`` from ``benchmarks/results/latest.json``
(:mod:`benchmarks.results.tables`; ``tests/unit/test_docs_tables.py`` holds the pages to it)::

    .venv/bin/python scripts/docs_numbers.py --tables              # after a benchmark run
"""
from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FENCE = re.compile(r"^```(\S*)\s*$")
NO_RUN = re.compile(r"^<!--\s*no-run\b.*-->\s*$")
ASSIGNED = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_]*)=", re.M)
HEADLINE = re.compile(r"^= ")


def _name(path: Path) -> str:
    return str(path.relative_to(ROOT)) if path.is_relative_to(ROOT) else str(path)


def fences(lines: list[str]) -> list[tuple[int, int, str]]:
    """``[(opening line, closing line, language)]`` of a page's fenced blocks (0-based)."""
    out, i = [], 0
    while i < len(lines):
        m = FENCE.match(lines[i])
        if not m:
            i += 1
            continue
        j = i + 1
        while j < len(lines) and not lines[j].startswith("```"):
            j += 1
        out.append((i, j, m.group(1)))
        i = j + 1
    return out


def headline_quotes(lines: list[str]) -> list[tuple[int, int, int]]:
    """``[(index of the sh block in the page's fences, text block's opening, closing)]``: the quotes whose
    every line is a headline (``= ...``), each with the sh block that prints it."""
    out, last_sh = [], None
    for k, (i, j, lang) in enumerate(fences(lines)):
        if lang == "sh":
            last_sh = k
        elif lang == "text" and last_sh is not None:
            body = [x for x in lines[i + 1:j] if x.strip()]
            if body and all(HEADLINE.match(x) for x in body):
                out.append((last_sh, i, j))
            last_sh = None
        else:
            last_sh = None
    return out


def run_page(path: Path, *, env: dict, cwd: Path) -> dict[int, str]:
    """Run the page's sh blocks in order up to its last headline quote; ``{sh block index: its output}``."""
    lines = path.read_text().splitlines()
    blocks = fences(lines)
    quoted = headline_quotes(lines)
    if not quoted:
        return {}
    last = max(k for k, _, _ in quoted)
    state = cwd / "state.sh"
    state.write_text("")
    out = {}
    for k, (i, j, lang) in enumerate(blocks[:last + 1]):
        prev = next((lines[n] for n in range(i - 1, -1, -1) if lines[n].strip()), "")
        if lang != "sh" or NO_RUN.match(prev):
            continue
        code = "\n".join(lines[i + 1:j])
        names = " ".join(dict.fromkeys(ASSIGNED.findall(code)))
        keep = f'\nfor _v in {names}; do declare -p "$_v"; done >> {state}' if names else ""
        print(f"{_name(path)}:{i + 1}: running", file=sys.stderr, flush=True)
        p = subprocess.run(["bash", "-euo", "pipefail", "-c", f"source {state}\n{code}{keep}"], cwd=cwd, env=env,
                           capture_output=True, text=True)
        if p.returncode not in (0, 1):
            raise SystemExit(f"{_name(path)}:{i + 1}: exit {p.returncode}\n{p.stderr[-2000:]}")
        out[k] = p.stdout + p.stderr
    return out


def rewrite(path: Path, outputs: dict[int, str]) -> tuple[str, list[str]]:
    """The page with each headline quote replaced by the lines its command printed; the changes."""
    lines = path.read_text().splitlines()
    changes = []
    for k, i, j in sorted(headline_quotes(lines), key=lambda q: -q[1]):
        printed = [x.rstrip() for x in outputs.get(k, "").splitlines() if HEADLINE.match(x)]
        if not printed:
            raise SystemExit(f"{_name(path)}:{i + 1}: the command printed no headline numbers")
        if printed != lines[i + 1:j]:
            changes.append(f"{_name(path)}:{i + 1}:\n  - " + "\n  - ".join(lines[i + 1:j])
                           + "\n  + " + "\n  + ".join(printed))
        lines[i + 1:j] = printed
    return "\n".join(lines) + "\n", changes


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("pages", nargs="*", type=Path, help="pages to refresh (default: every page with a headline quote)")
    ap.add_argument("--tables", action="store_true",
                    help="rewrite the tables between <!-- bench: NAME --> markers from benchmarks/results/latest.json")
    args = ap.parse_args(argv)
    if args.tables:
        sys.path.insert(0, str(ROOT))       # run as a script: benchmarks/ is beside it, not installed
        from benchmarks.results.tables import write_tables
        for name in write_tables([p.resolve() for p in args.pages] or None):
            print(f"{name}: tables rewritten from benchmarks/results/latest.json")
        return 0
    if not os.environ.get("TRAJLAB_URL"):
        ap.error("TRAJLAB_URL is not set: start the service (make run) and paste its export line")
    pages = [p.resolve() for p in args.pages] or sorted(
        p for p in [ROOT / "README.md", *(ROOT / "docs").rglob("*.md")] if headline_quotes(p.read_text().splitlines()))
    env = {**os.environ, "TRAJLAB_PROGRESS": "plain"}
    with tempfile.TemporaryDirectory() as tmp:
        cwd = Path(tmp)
        for name in (".venv", "examples"):
            (cwd / name).symlink_to(ROOT / name)
        for page in pages:
            outputs = run_page(page, env=env, cwd=cwd)
            new, changes = rewrite(page, outputs)
            for c in changes:
                print(c)
            page.write_text(new)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
