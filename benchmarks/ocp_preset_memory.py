"""Peak memory of every ``ocp`` preset against its estimate (issue 36 item 1: "within 2x of the measured
peak on every preset"), each preset run in a fresh process the way a worker's pool child runs it.

Run: ``python -m benchmarks.ocp_preset_memory`` (``--presets a,b`` for a subset; ``--readme-only`` rewrites
the README table from latest.json without measuring; ``--estimates-only`` recomputes the estimates of the
recorded peaks after a change of the model alone).

The peak is the child's own high-water mark (``VmHWM``, :func:`benchmarks.ocp_memory.measure`); the
estimate is :func:`app.service.job_memory.measured_mb` (without the margin).  Figures go to
``benchmarks/results/latest.json`` under ``ocp_preset_memory``, their table to README.md between
``<!-- bench: ocp_preset_memory -->`` and ``<!-- /bench -->`` (:func:`benchmarks.results.tables.ocp_preset_memory`).
"""
from __future__ import annotations

import argparse
import sys

from benchmarks.ocp_memory import README, measure_all, reestimate


def ocp_presets() -> dict[str, dict]:
    """Every ``ocp`` preset's body, by name, in the registry's order."""
    from app.kinds import PRESETS

    return {name: p.params for name, p in PRESETS.items() if p.kind == "ocp"}


def write_readme() -> None:
    from benchmarks.results.tables import write_tables
    write_tables([README])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--presets", default="", help="comma-separated names (default: every ocp preset)")
    ap.add_argument("--readme-only", action="store_true", help="rewrite README's table from latest.json only")
    ap.add_argument("--estimates-only", action="store_true",
                    help="recompute the estimates of latest.json's peaks with the model as it is now, no measuring")
    args = ap.parse_args()
    from benchmarks.results import write_results
    if args.readme_only or args.estimates_only:
        if args.estimates_only:
            reestimate("ocp_preset_memory", ocp_presets())
        write_readme()
        return 0
    bodies = ocp_presets()
    names = args.presets.split(",") if args.presets else list(bodies)
    figures = measure_all({name: bodies[name] for name in names}, "preset", 40)
    write_results("ocp_preset_memory", figures)
    write_readme()
    return 0


if __name__ == "__main__":
    sys.exit(main())
