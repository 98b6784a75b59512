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

import sys

from benchmarks.ocp_memory import command


def ocp_presets() -> dict[str, dict]:
    """Every ``ocp`` preset's body, by name, in the registry's order."""
    from app.kinds import PRESETS

    return {name: p.params for name, p in PRESETS.items() if p.kind == "ocp"}


def main() -> int:
    return command("ocp_preset_memory", ocp_presets(), "preset", 40, __doc__ or "")


if __name__ == "__main__":
    sys.exit(main())
