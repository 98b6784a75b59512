"""The docs' tables of benchmark figures, rendered from ``benchmarks/results/latest.json`` (issue 38 item 2):
no measured figure in a table is typed by hand.

A page holds a generated table between ``<!-- bench: NAME -->`` and ``<!-- /bench -->``; ``NAME`` is the
renderer below (one small function per table, reading latest.json's entry of that name).  After a
benchmark run, ``python scripts/docs_numbers.py --tables`` (or the benchmark itself, as
``benchmarks.ocp_memory`` does) rewrites every such table; ``tests/unit/test_docs_tables.py`` fails when a
table between markers differs from its rendering, so a typed edit or a stale table is caught.

Tables whose figures no benchmark records (measured once, by hand or by a test) stay typed, each with a
line under it saying what measured it.
"""
from __future__ import annotations

import json
import re
from collections.abc import Callable
from pathlib import Path

from benchmarks.results import LATEST

ROOT = Path(__file__).resolve().parents[2]
BLOCK = re.compile(r"(<!-- bench: (?P<name>[A-Za-z0-9_]+) -->\n)(?P<body>.*?)(<!-- /bench -->)", re.S)


def _caption(module: str, entry: dict, extra: str = "") -> str:
    """The line under a table: what ran it, when and where (and ``extra``; a re-estimate's date)."""
    if "estimated" in entry:
        extra += f"; estimates of the model as of {entry['estimated']} (`--estimates-only`)"
    return f"(`python -m benchmarks.{module}`, {entry['when']}, {entry['machine']}{extra})"


def _row(cells: list[str]) -> str:
    return "|" + "|".join(f" {c} " if c else " " for c in cells) + "|"


def _errors(run: dict) -> int:
    """Every failure ``wrk`` counts: socket errors (connect, read, write, timeout) and non-2xx answers."""
    return sum(int(run.get(k, 0)) for k in ("connect", "read", "write", "timeout", "status", "errors"))


# (label, issue 16 target, measured group, load, what the PostgreSQL cell shows, the ratio's, SQLite's):
# "p99" adds the 99th percentile, "errors" says how many failed, "rows" the rows a listing counted.
API_ROWS = [
    ("`POST /v1/jobs`, 16 connections", ">= 600/s, p99 < 100 ms", "trajlab", "post_c16", "p99", "p99", "p99"),
    ("`GET /v1/jobs/{id}`, 16", ">= 1,500/s", "trajlab", "get_c16", "p99", "", ""),
    ("`GET /v1/jobs?limit=20`, 16", ">= 500/s", "trajlab", "list_c16", "rows", "", ""),
    ("`POST /v1/jobs`, 100", "p99 < 400 ms, no errors", "trajlab", "post_c100", "p99 errors", "p99", "p99"),
    ("`POST /v1/jobs`, 16, a worker consuming", "", "trajlab_with_worker", "post_c16", "p99", "", ""),
]


def _load_cell(run: dict, show: str) -> str:
    out = [f"{run['rps']:,.0f}/s"]
    if "p99" in show:
        out.append(f"p99 {run['p99_ms']:.0f} ms")
    if "errors" in show:
        n = _errors(run)
        out.append("no errors" if n == 0 else f"{n:,} errors")
    text = ", ".join(out)
    return f"{text} ({run['rows_at_list']:,} rows)" if "rows" in show and "rows_at_list" in run else text


def api_load(entry: dict) -> str:
    """``api_load`` (2 API processes, the default): each load on PostgreSQL, as a ratio to the bare app of
    the same run (the same load on it, without a worker), and on the embedded SQLite."""
    f = entry["figures"]
    pg, lite = f["postgresql"], f["sqlite"]
    rows = ["| `wrk` load | issue 16 target | PostgreSQL | vs bare app | SQLite (embedded) |", "|---|---|---|---|---|"]
    for label, target, group, load, pg_show, ratio_show, lite_show in API_ROWS:
        run, bare = pg[group][load], pg["baseline"][load]
        ratio = f"{run['rps'] / bare['rps']:.2f}x"
        if "p99" in ratio_show:
            ratio += f", p99 {run['p99_ms'] / bare['p99_ms']:.2f}x"
        rows.append(_row([label, target, _load_cell(run, pg_show), ratio, _load_cell(lite[group][load], lite_show)]))
    met = [t["met"] for t in f["targets"].values()]
    start = f["loadavg_start"][0]
    return "\n".join(rows) + "\n\n" + _caption(
        "api_load", entry, f", {f['cpus']} cores, {f['api_processes']} API processes, best of {f['repeat']} runs of "
        f"{f['seconds_per_load']} s, load average {start:.1f} at the start; issue 16 targets met: {sum(met)} of "
        f"{len(met)}")


def ocp_memory(entry: dict) -> str:
    """``ocp_memory``: each case's size, the memory model's estimate and the peak measured in a child."""
    from benchmarks.ocp_memory import SIZES       # what each case is, declared beside the cases
    rows = ["| case | problem | estimate MB | measured peak MB | estimate / peak |", "|---|---|---|---|---|"]
    for name, f in entry["figures"].items():
        rows.append(f"| `{name}` | {SIZES.get(name, '')} | {f['estimate_mb']:.0f} | {f['peak_mb']:.0f} | "
                    f"{f['ratio']:.2f} |")
    return "\n".join(rows) + "\n\n" + _caption("ocp_memory", entry)


def ocp_preset_memory(entry: dict) -> str:
    """``ocp_preset_memory``: every ocp preset's estimate against the peak measured in a child, and their range."""
    rows = ["| preset | estimate MB | measured peak MB | estimate / peak |", "|---|---|---|---|"]
    figs = entry["figures"]
    for name, f in figs.items():
        rows.append(f"| `{name}` | {f['estimate_mb']:.0f} | {f['peak_mb']:.0f} | {f['ratio']:.2f} |")
    ratios = [f["ratio"] for f in figs.values()]
    return "\n".join(rows) + "\n\n" + _caption(
        "ocp_preset_memory", entry, f"; {len(ratios)} presets, estimate / peak {min(ratios):.2f} to {max(ratios):.2f}")


# the robust presets' deterministic twins and units, as docs/tutorials/ocp.md names them (declared, not measured)
# (twin, unit, format of the twin's objective, of the robust one, of the cost)
ROBUST_TWINS = {"rocket-ascent-q-limit-robust": ("rocket-ascent-q-limit", " m", "{:.1f}", "{:.0f}", "{:.0f}"),
                "orbit-raising-uncertain-thrust-robust": ("orbit-raising-band", "", "{:.4f}", "{:.4f}", "{:.3f}"),
                "bryson-denham-robust": ("bryson-denham", "", "{:.4f}", "{:.4f}", "{:.3f}"),
                "betts-shuttle-robust-ocp": ("betts-shuttle-heat-limit-ocp", " deg", "{:.4f}", "{:.4f}", "{:.3f}")}
STATISTIC = {"mean": "mean", "mean_minus_k_sigma": "mean - {k:g} sigma", "mean_plus_k_sigma": "mean + {k:g} sigma"}


def ocp_robust(entry: dict) -> str:
    """``ocp_robust``: each robust preset's job answer (its last Monte Carlo round) against its deterministic
    twin on the same grid; the cost of robustness is their difference."""
    from solvers.ocp import PRESETS
    rows = ["| robust preset | twin | twin objective | robust objective | cost |", "|---|---|---|---|---|"]
    for name, (twin, unit, twin_fmt, fmt, cost_fmt) in ROBUST_TWINS.items():
        f, body = entry["figures"][name], PRESETS[name]["params"]
        rob, sense = body["robust"], body["objective"]["sense"]
        k = float(rob.get("k", 3.0))
        default = "mean_minus_k_sigma" if sense == "maximize" else "mean_plus_k_sigma"
        how = STATISTIC[rob.get("objective", default)].format(k=k)
        k_c = f["job_k_constraints"]
        if k_c is not None and k_c > k:
            how += f"; limit k raised to {k_c:.3f}"
        cost = (f["det_objective"] - f["job_objective"]) * (1 if sense == "maximize" else -1)   # what robustness gives up
        rows.append(f"| `{name}` | `{twin}` | {twin_fmt.format(f['det_objective'])}{unit} | "
                    f"{fmt.format(f['job_objective'])}{unit} ({how}) | {cost_fmt.format(cost)}{unit} |")
    return "\n".join(rows) + "\n\n" + _caption(
        "ocp_robust", entry, ", each robust job as the service runs it, its Monte Carlo rounds included")


def compiles(entry: dict) -> str:
    """``compiles``: each run of the tutorials on a fresh service (in the order run), its compiles and their
    CPU, and the time to the answers against ``TRAJLAB_JIT=off``."""
    f = entry["figures"]
    rows = ["| `TRAJLAB_JIT` | run | answers s | compiles | most at once | compile CPU s | compile cores |",
            "|---|---|---|---|---|---|---|"]
    for mode in ("off", "background"):
        for i, r in enumerate(f.get(mode, {}).get("runs", []), 1):
            pending = " (more waiting when stopped)" if r["compiling_when_stopped"] else ""
            rows.append(_row([f"`{mode}`", str(i), f"{r['answers_s']:.1f}", f"{r['compiles']}{pending}",
                              str(r["most_at_once"]), f"{r['cpu_s']:.1f}", f"{r['compile_cores']:.2f}"]))
    how = ", each mode twice (off, background, background, off)" if f.get("abba") else ""
    how += ", the robust tutorial at 2000 samples (--quick)" if f.get("quick") else ""
    ratio = f"; answers background / off: {f['answers_ratio']:.2f}" if "answers_ratio" in f else ""
    return "\n".join(rows) + "\n\n" + _caption("compiles", entry, how + ratio)


RENDERERS: dict[str, Callable[[dict], str]] = {"api_load": api_load, "compiles": compiles, "ocp_memory": ocp_memory,
                                                 "ocp_preset_memory": ocp_preset_memory, "ocp_robust": ocp_robust}


def latest() -> dict:
    return json.loads(LATEST.read_text())


def render(name: str, results: dict) -> str:
    """The body between ``name``'s markers: its table from ``results`` (latest.json's content)."""
    if name not in RENDERERS:
        raise KeyError(f"<!-- bench: {name} -->: no renderer of that name in benchmarks/results/tables.py")
    if name not in results:
        raise KeyError(f"<!-- bench: {name} -->: latest.json has no entry {name!r} (run python -m benchmarks.{name})")
    return RENDERERS[name](results[name]) + "\n"


def tables(text: str) -> list[tuple[str, str]]:
    """``[(name, body)]`` of a page's generated tables, in page order."""
    return [(m.group("name"), m.group("body")) for m in BLOCK.finditer(text)]


def rewrite(text: str, results: dict) -> str:
    """``text`` with every table between markers rendered from ``results``."""
    return BLOCK.sub(lambda m: m.group(1) + render(m.group("name"), results) + m.group(4), text)


def pages() -> list[Path]:
    """README.md and every page under docs/ that holds a generated table."""
    candidates = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
    return [p for p in candidates if p.exists() and tables(p.read_text())]


def write_tables(paths: list[Path] | None = None) -> list[str]:
    """Rewrite the tables of ``paths`` (default: every page with one) from latest.json; the pages changed."""
    results, changed = latest(), []
    for path in paths or pages():
        old = path.read_text()
        new = rewrite(old, results)
        if new != old:
            path.write_text(new)
            changed.append(str(path.relative_to(ROOT)) if path.is_relative_to(ROOT) else str(path))
    return changed
