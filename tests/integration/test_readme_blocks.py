"""The README's and the guide's commands work as written (issue 28 item 3, issue 38 item 2): every ```sh block
runs, in order, against one live service on a free port (not 8000), with only ``TRAJLAB_URL`` (and, for
``trajlab keys``, the database URL) set, as a reader who pasted ``make run``'s ``export TRAJLAB_URL=...``
line would have.

Which blocks run: every fenced block whose language is ``sh``, unless the line before its fence is an HTML
comment ``<!-- no-run: why -->`` (``make run`` itself, docker compose, a restore that replaces the database,
a study of many long solves); blocks in any other language (```text, ```json, a bare fence) are never run.
A page's blocks run one after the other in one session, as a reader pastes them into one terminal: a
variable a block sets (``ID=$(... submit ...)``) is there for the page's later blocks.  Each block runs in
``bash -euo pipefail`` from a scratch directory holding the repository's ``.venv`` and ``examples`` (files
the examples write land there), within ``BLOCK_TIMEOUT_S``.

Where a page quotes a command's output (a ```text block after the ```sh block, prose between them allowed)
the output must say what the page says: each quoted piece between ``...`` elisions, whitespace and line
wrapping aside, and every number in it within the quote's tolerance of the number the run printed
(:func:`says`): a figure in e-notation is a residual (a miss, a violation) and must be within a factor
``RESIDUAL_FACTOR``; any other within ``QUOTE_RTOL`` relative, or the tolerance a ``<!-- quoted: rtol=X
why -->`` comment right before the ```text fence states (a method whose answer moves more with the
machine: NSGA-II's front, a Monte Carlo share).  The figures themselves are written by
``scripts/docs_numbers.py`` from a run, not typed.
"""
from __future__ import annotations

import os
import re
import subprocess
import time
from pathlib import Path

import pytest

from tests.integration.live import live_server

pytestmark = [pytest.mark.integration, pytest.mark.slow]

ROOT = Path(__file__).resolve().parents[2]
BLOCK_TIMEOUT_S = 400
FENCE = re.compile(r"^```(\S*)\s*$")
NO_RUN = re.compile(r"^<!--\s*no-run\b.*-->\s*$")
QUOTED = re.compile(r"^<!--\s*quoted:\s*rtol=([0-9.eE+-]+)\b.*-->\s*$")
QUOTE_RTOL = 2e-3          # a headline's printed digits (4-5 significant) moved by a solve's last bits
RESIDUAL_FACTOR = 10.0     # a residual's size, not its digits, is what a page says
# a number as the CLI prints it: thousands separators, a decimal part, an exponent
NUMBER = r"-?(?:\d{1,3}(?:,\d{3})+|\d+)(?:\.\d+)?(?:[eE][-+]?\d+)?"
ASSIGNED = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_]*)=", re.M)


def quoted_output(text: str) -> dict[int, str]:
    """``{line of an sh block: the text block right after it}``: the output the page quotes for that command."""
    return {line: quote for line, (quote, _) in quotes(text).items()}


def quotes(text: str) -> dict[int, tuple[str, float]]:
    """``{line of an sh block: (the text block after it, its numbers' relative tolerance)}``."""
    lines, out = text.splitlines(), {}
    last_sh: int | None = None
    i = 0
    while i < len(lines):
        m = FENCE.match(lines[i])
        if not m:  # prose between a command and its quoted output keeps them paired
            i += 1
            continue
        j = i + 1
        while j < len(lines) and not lines[j].startswith("```"):
            j += 1
        if m.group(1) == "sh":
            last_sh = i + 1
        elif m.group(1) == "text" and last_sh is not None:
            prev = next((lines[k] for k in range(i - 1, -1, -1) if lines[k].strip()), "")
            tol = QUOTED.match(prev)
            out[last_sh] = ("\n".join(lines[i + 1:j]), float(tol.group(1)) if tol else QUOTE_RTOL)
            last_sh = None
        else:
            last_sh = None
        i = j + 1
    return out


def _close(printed: str, quoted: str, rtol: float) -> bool:
    a, b = float(printed.replace(",", "")), float(quoted.replace(",", ""))
    if "e" in quoted.lower():                     # a residual: its size
        return a == b or (a * b > 0 and max(abs(a / b), abs(b / a)) <= RESIDUAL_FACTOR)
    return abs(a - b) <= rtol * max(abs(a), abs(b))


def _piece_said(norm: str, piece: str, rtol: float) -> bool:
    words = re.split(f"({NUMBER})", piece)
    pattern = "".join(f"({NUMBER})" if k % 2 else re.escape(w) for k, w in enumerate(words))
    numbers = words[1::2]
    return any(all(_close(got, want, rtol) for got, want in zip(m.groups(), numbers))
               for m in re.finditer(pattern, norm))


def says(output: str, quoted: str, rtol: float = 0.0) -> list[str]:
    """The quoted pieces (between ``...``) the output does not say, whitespace normalized, each number
    within ``rtol`` relative (a residual in e-notation within ``RESIDUAL_FACTOR``) of the one printed."""
    norm = " ".join(output.split())
    pieces = [" ".join(p.split()) for p in quoted.split("...")]
    return [p for p in pieces if p and not _piece_said(norm, p, rtol)]


def run_page(blocks: list[tuple[int, str]], *, name: str, cwd: Path, env: dict, quoted: dict | None = None) -> int:
    """Run a page's blocks in order in one session (module docstring); returns how many ran."""
    state = cwd / f".state-{name.replace('/', '_')}.sh"
    state.write_text("")
    quoted = quoted or {}
    for line, code in blocks:
        t0 = time.monotonic()
        names = " ".join(dict.fromkeys(ASSIGNED.findall(code)))
        keep = f'\nfor _v in {names}; do declare -p "$_v"; done >> {state}' if names else ""
        script = f"source {state}\n{code}{keep}"
        p = subprocess.run(["bash", "-euo", "pipefail", "-c", script], cwd=cwd, env=env, capture_output=True,
                           text=True, timeout=BLOCK_TIMEOUT_S)
        where = f"{name}:{line}"
        # a command quoted with its failure's explanation may exit 1 (failed job): the page says so
        ok = p.returncode == 0 or (line in quoted and p.returncode == 1)
        assert ok, f"{where} block failed ({p.returncode}):\n{code}\n--- stdout\n{p.stdout[-2000:]}\n" \
                   f"--- stderr\n{p.stderr[-3000:]}"
        if line in quoted:
            text, rtol = quoted[line]
            missing = says(p.stdout + p.stderr, text, rtol)
            assert not missing, f"{where}: the output does not say {missing}:\n{p.stdout[-2000:]}{p.stderr[-3000:]}"
        print(f"{where}: {time.monotonic() - t0:.1f} s", flush=True)
    return len(blocks)


def shell_blocks(text: str) -> tuple[list[tuple[int, str]], list[int]]:
    """``([(line, code)] to run, [lines of sh blocks marked no-run])``, line numbers 1-based at the fence."""
    lines = text.splitlines()
    run, skipped, i = [], [], 0
    while i < len(lines):
        m = FENCE.match(lines[i])
        if not m:
            i += 1
            continue
        start, lang = i, m.group(1)
        j = i + 1
        while j < len(lines) and not lines[j].startswith("```"):
            j += 1
        prev = next((lines[k] for k in range(start - 1, -1, -1) if lines[k].strip()), "")
        if lang == "sh":
            (skipped.append(start + 1) if NO_RUN.match(prev) else run.append((start + 1, "\n".join(lines[start + 1:j]))))
        i = j + 1
    return run, skipped


def test_the_block_finder_reads_fences_and_markers():
    text = "a\n```sh\necho 1\n```\n<!-- no-run: server -->\n```sh\nmake run\n```\n```json\n{}\n```\n```\nx\n```\n"
    assert shell_blocks(text) == ([(2, "echo 1")], [6])


def test_readme_and_guide_blocks_run_against_one_live_service(service, tmp_path):
    """The README's blocks, then every page of docs/ (module docstring), against one service and one server."""
    readme_text = (ROOT / "README.md").read_text()
    run, skipped = shell_blocks(readme_text)
    assert len(run) >= 5 and len(skipped) >= 4  # quick start, results, studies, vehicles, keys; make run, celery, long solves
    pages = sorted(p for p in (ROOT / "docs").rglob("*.md"))
    for name in (".venv", "examples"):
        (tmp_path / name).symlink_to(ROOT / name)
    counts = {"README.md": (len(run), len(skipped))}
    with live_server(service.client.app) as url:
        assert not url.endswith(":8000")
        base = {k: v for k, v in os.environ.items() if not k.startswith("TRAJLAB_")}
        base.update(TRAJLAB_URL=url, TRAJLAB_PROGRESS="plain")
        run_page(run, name="README.md", cwd=tmp_path, quoted=quotes(readme_text),
                 env={**base, "TRAJLAB_DATABASE_URL": service.client.app.state.settings.database_url})
        assert (tmp_path / "heating.png").read_bytes()[:4] == b"\x89PNG"
        assert "META_START" in (tmp_path / "intercept.oem").read_text()
        assert (tmp_path / "trade.csv").read_text().startswith("index,path.max_heat_rate_w_m2,status")
        for page in pages:
            rel = f"docs/{page.relative_to(ROOT / 'docs').as_posix()}"
            text = page.read_text()
            blocks, marked = shell_blocks(text)
            counts[rel] = (run_page(blocks, name=rel, cwd=tmp_path, env=base, quoted=quotes(text)), len(marked))
    print("blocks run / marked no-run:", counts, flush=True)
    assert sum(r for r, _ in counts.values()) >= 30
    for tutorial in ("reentry", "robust_reentry", "midcourse", "intercept", "ocp"):
        assert counts[f"docs/tutorials/{tutorial}.md"][0] >= 2     # every tutorial's jobs run, not only marked


def test_quoted_output_pairs_a_command_with_the_text_after_it():
    text = "```sh\nrun a\n```\n\nsays:\n\n```text\nline one ...\n  wrapped\n```\n```sh\nb\n```\n"
    assert quoted_output(text) == {1: "line one ...\n  wrapped"}
    assert says("x line one y wrapped z", quoted_output(text)[1]) == []
    assert says("line two", "line one") == ["line one"]
    # numbers within the quote's tolerance; a residual (e-notation) within a factor 10
    assert says("= crossrange 30.6255 deg", "crossrange 30.62 deg", 2e-3) == []
    assert says("= crossrange 30.9 deg", "crossrange 30.62 deg", 2e-3) == ["crossrange 30.62 deg"]
    assert says("flight time 2,198.9 s", "flight time 2,198.8 s", 2e-3) == []
    assert says("miss 0.0085 m; missed by 3.1e-05", "missed by 7.61e-05", 2e-3) == []
    assert says("missed by 3.1e-07", "missed by 7.61e-05", 2e-3) == ["missed by 7.61e-05"]
    tolerant = "```sh\nb\n```\n<!-- quoted: rtol=0.05 NSGA-II -->\n```text\nhypervolume 0.7293\n```\n"
    assert quotes(tolerant) == {1: ("hypervolume 0.7293", 0.05)}
    assert says("hypervolume 0.766 (0-1)", *quotes(tolerant)[1]) == []


def test_docs_numbers_writes_the_headlines_a_command_printed(tmp_path):
    """scripts/docs_numbers.py replaces a headline quote (every line ``= ...``) by the lines its command
    printed, and leaves other quotes (an error's explanation with ``...``) as written."""
    from scripts.docs_numbers import headline_quotes, rewrite

    page = tmp_path / "page.md"
    page.write_text("```sh\nID=$(x)\nwait $ID\n```\n\n## Read\n\n```text\n= old 1.0 deg\n```\n"
                    "```sh\nfail\n```\n```text\n  infeasible: ...\n```\n")
    assert headline_quotes(page.read_text().splitlines()) == [(0, 7, 9)]
    new, changes = rewrite(page, {0: "abc123\n[progress]\n= new 1.02 deg\n= flight time 2 s\n  key 1\n"})
    assert "= new 1.02 deg\n= flight time 2 s\n```" in new and "  infeasible: ..." in new
    assert len(changes) == 1 and "= old 1.0 deg" in changes[0]
