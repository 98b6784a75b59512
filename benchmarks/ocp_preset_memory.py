"""Peak memory of every ``ocp`` preset against its estimate (issue 36 item 1: "within 2x of the measured
peak on every preset"), each preset run in a fresh process the way a worker's pool child runs it.

Run: ``python -m benchmarks.ocp_preset_memory`` (``--presets a,b`` for a subset; ``--readme-only`` rewrites
the README table from latest.json without measuring).

The peak is the child's own high-water mark (``VmHWM``, :func:`benchmarks.ocp_memory.measure`); the
estimate is :func:`app.service.job_memory.measured_mb` (without the margin).  Figures go to
``benchmarks/results/latest.json`` under ``ocp_preset_memory``, their table to README.md between
``<!-- ocp_preset_memory table -->`` and ``<!-- /ocp_preset_memory table -->``.
"""
from __future__ import annotations

import argparse
import json
import sys

from benchmarks.ocp_memory import README, measure

BEGIN, END = "<!-- ocp_preset_memory table -->", "<!-- /ocp_preset_memory table -->"


def ocp_presets() -> dict[str, dict]:
    """Every ``ocp`` preset's body, by name, in the registry's order."""
    from app.kinds import PRESETS

    return {name: p.params for name, p in PRESETS.items() if p.kind == "ocp"}


def table(entry: dict) -> str:
    """The README's table of ``entry`` (latest.json's ``ocp_preset_memory``), the ratios' range last."""
    rows = ["| preset | estimate MB | measured peak MB | estimate / peak |", "|---|---|---|---|"]
    figs = entry["figures"]
    for name, f in figs.items():
        rows.append(f"| `{name}` | {f['estimate_mb']:.0f} | {f['peak_mb']:.0f} | {f['ratio']:.2f} |")
    ratios = [f["ratio"] for f in figs.values()]
    return ("\n".join(rows) + f"\n\n{len(ratios)} presets, estimate / peak {min(ratios):.2f}-{max(ratios):.2f} "
            f"(`python -m benchmarks.ocp_preset_memory`, {entry['when']}, {entry['machine']})")


def write_readme(entry: dict) -> None:
    text = README.read_text()
    if BEGIN not in text:
        return
    head, rest = text.split(BEGIN, 1)
    _, tail = rest.split(END, 1)
    README.write_text(f"{head}{BEGIN}\n{table(entry)}\n{END}{tail}")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--presets", default="", help="comma-separated names (default: every ocp preset)")
    ap.add_argument("--readme-only", action="store_true", help="rewrite README's table from latest.json only")
    args = ap.parse_args()
    from benchmarks.results import LATEST, write_results
    if args.readme_only:
        write_readme(json.loads(LATEST.read_text())["ocp_preset_memory"])
        return 0
    from app.service.job_memory import measured_mb

    bodies = ocp_presets()
    names = args.presets.split(",") if args.presets else list(bodies)
    figures = {}
    print(f"{'preset':<40}{'status':<11}{'estimate MB':>13}{'peak MB':>10}{'ratio':>8}")
    for name in names:
        est = measured_mb("ocp", bodies[name]) or 0.0
        r = measure(bodies[name])
        r.update(estimate_mb=est, ratio=est / r["peak_mb"])
        figures[name] = r
        print(f"{name:<40}{r['status']:<11}{est:>13.0f}{r['peak_mb']:>10.0f}{r['ratio']:>8.2f}", flush=True)
    write_results("ocp_preset_memory", figures)
    write_readme(json.loads(LATEST.read_text())["ocp_preset_memory"])
    return 0


if __name__ == "__main__":
    sys.exit(main())
