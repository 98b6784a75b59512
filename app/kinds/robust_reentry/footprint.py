"""What a ``robust_reentry`` job takes and keeps: its cost in :mod:`app.service.quota`'s work units, its
memory (:mod:`app.service.job_memory`) and its default result body (:mod:`app.results.compact`)."""
from __future__ import annotations

import copy

from app.kinds.base import MemoryModel
from app.kinds.reentry.edge import shooting_cost

TRACES = 20   # Monte Carlo sample traces per design in the default body (?include=samples: all of them)


def cost(params: dict) -> float:
    """10 x the reentry cost (18 sensitivity equations per state, three continuation stages) x
    (1 + Monte Carlo samples / 1000)."""
    samples = float((params.get("monte_carlo") or {}).get("samples", 0))
    return 10.0 * shooting_cost(params) * (1.0 + samples / 1000.0)


def _size(params: dict) -> float:
    grid = params.get("grid") or {}
    return float(grid.get("intervals", 100)) * float((params.get("robust") or {}).get("substeps", 2))


# Measured (README "Limits and data"): 397 MB for the preset (100 intervals x 2 substeps) in a fresh pool
# process, 0.06 MB more per interval x substep of the augmented system; the Monte Carlo runs in chunks, so
# its samples do not add to the peak.
MEMORY = MemoryModel(floor_mb=397.0, size=_size, floor_size=200.0, per_unit_mb=0.06,
                     grows_with="grid.intervals x robust.substeps")


def compact(result: dict, include: set[str]) -> dict:
    """The Monte Carlo keeps :data:`TRACES` of its sample traces per design unless ``samples`` is asked for."""
    if "samples" in include or not isinstance(result.get("monte_carlo"), dict):
        return result
    result = copy.copy(result)
    mc = result["monte_carlo"] = dict(result["monte_carlo"])
    for design, block in mc.items():
        if isinstance(block, dict) and isinstance(block.get("sample_traces"), dict):
            block = mc[design] = dict(block)
            block["sample_traces"] = {q: v[:TRACES] for q, v in block["sample_traces"].items()}
    return result
