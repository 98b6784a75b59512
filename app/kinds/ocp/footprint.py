"""What an ``ocp`` job takes and shows beyond its plots: its memory (:mod:`app.service.job_memory`; its
cost is :func:`app.kinds.ocp.kind.cost`), its trajectory as one CSV table over its phases, and its curve on
the console's compare plot."""
from __future__ import annotations

from app.kinds.base import CompareSeries, MemoryModel
from app.results.tables import columns, columns_at


def _size(params: dict) -> float:
    """RK4 steps (or LGL nodes) x (states + controls) of the largest NLP the job builds, summed over its
    phases: the answer's check on its mesh with every interval cut in s parts (:func:`check_parts`)."""
    phases = [p for p in params.get("phases") or [] if isinstance(p, dict)] or [params]
    return sum(_phase_size(p) for p in phases)


def _phase_size(params: dict) -> float:
    tr = params.get("transcription") or {}
    if tr.get("method", "multiple_shooting") == "multiple_shooting":
        steps = float(tr.get("substeps", 2))
    else:
        steps = float(tr.get("nodes", 4))
    width = float(len(params.get("states") or []) + len(params.get("controls") or []))
    intervals = len(tr["boundaries"]) - 1 if tr.get("boundaries") else tr.get("intervals", 50)
    return float(intervals) * steps * width * check_parts(tr)


def check_parts(transcription: dict) -> int:
    """The parts each interval is cut into for an answer's check solve (``solvers.ocp.estimate.parts_of``,
    read from the request so the quota needs no solver import): 3 for multiple shooting's linear controls,
    2 otherwise.  The check's NLP is that many times the answer's, and warm-started it takes about as many
    iterations (the golden accuracy cases: 7-16 against 8-16), so it costs about s answers."""
    shooting = transcription.get("method", "multiple_shooting") == "multiple_shooting"
    return 3 if shooting and transcription.get("control", "linear") == "linear" else 2

# Measured (README "Limits and data"; benchmarks/ocp_memory.py): 215 MB resident in a fresh pool process at
# the betts-shuttle-ocp preset's size (100 intervals x 2 steps x 8 states and controls x 3 check parts);
# past it 0.015 MB per step x (states + controls) x check part, fitted to LQ problems of 4x2 states and
# controls on 300 and 1000 intervals (320, 539 MB) and 20x8 on 100 (498 MB): the answer, its check on the
# finer mesh, the re-flight and the optimality checks at its samples.
MEMORY = MemoryModel(floor_mb=215.0, size=_size, floor_size=100.0 * 2 * 8 * 3, per_unit_mb=0.015,
                     grows_with="transcription.intervals x steps per interval x (states + controls) x the check's "
                                "parts (3 for multiple shooting's linear controls, 2 otherwise), summed over the phases")


def trajectory_table(result: dict) -> dict[str, list] | None:
    """Several phases: their trajectories one after the other, a ``phase`` column first (a quantity a phase
    does not have is empty there); one phase: its trajectory."""
    phases = [p for p in result.get("phases") or [] if isinstance(p, dict) and columns(p.get("trajectory"))]
    if not phases:
        return columns_at("trajectory")(result)
    names: list[str] = []
    for p in phases:
        names += [n for n in columns(p["trajectory"]) or {} if n not in names]
    cols: dict[str, list] = {"phase": [], **{n: [] for n in names}}
    for p in phases:
        tr = columns(p["trajectory"]) or {"t": []}
        n = len(tr["t"])
        cols["phase"] += [p["name"]] * n
        for k in names:
            cols[k] += tr.get(k) or [None] * n
    return cols


def compare_series(result: dict) -> CompareSeries:
    """The first pair the problem asked for in ``plots``, else its first quantity against time."""
    tr = result.get("trajectory")
    if tr is None:  # several phases, one after the other: the quantities every phase has
        phases = [p["trajectory"] for p in result.get("phases") or []]
        tr = {n: [v for p in phases for v in p[n]] for n in (phases[0] if phases else {})
              if all(n in p for p in phases)}
    x, y = (result.get("plots") or [["t", next((n for n in tr if n != "t"), "t")]])[0]
    if not (isinstance(tr.get(x), list) and isinstance(tr.get(y), list)):
        raise ValueError(f"compare needs ocp jobs that all have {x} and {y}")
    return CompareSeries(tr[x], tr[y], x, y)
