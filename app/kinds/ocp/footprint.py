"""What an ``ocp`` job takes and shows beyond its plots: its memory (:mod:`app.service.job_memory`; its
cost is :func:`app.kinds.ocp.kind.cost`), its trajectory as one CSV table over its phases, and its curve on
the console's compare plot."""
from __future__ import annotations

from app.kinds.base import CompareSeries, MemoryModel
from app.kinds.ocp.size import PhaseSize, phase_sizes
from app.results.tables import columns, columns_at


# Calibration: peak resident MB (VmHWM) of the job in a fresh process (benchmarks/ocp_memory.py's child) on a
# 2-core x86_64, 45 runs: every ocp preset (benchmarks/ocp_preset_memory.py: 128-385 MB), the cases of
# benchmarks/ocp_memory.py (narrow-long 524, wide 1170, wider 2641, wide-lgl 572, three-phase 390,
# three-phase-wide 547, piecewise-long 326, two-phase-lgl 301, robust-shuttle 345, robust-two-phase 223),
# 4x2 on 300 intervals 312 and the same with 1700 more parse-tree nodes in its dynamics (25 sin*cos terms per
# state) 339, 10x8 on 200 761, the robust shuttle on 300 intervals 388.  Least squares of estimate/peak - 1
# with every coefficient >= 0: estimate/peak 0.78 (betts-shuttle-heat-limit-ocp) to 1.16 over all 45.
# (Those peaks were the check's before its blocks; re-measured since where its candidates counted, see
# CANDIDATE_COPIES below: estimate/peak 0.76-1.21 over latest.json's 41.)
# What it says:
# - a small problem's peak is the dense checks', not its NLP's: the minimum-principle check evaluates H at
#   candidate controls x re-flight samples, BLOCK numbers at a time, about 61 bytes a number (CasADi's
#   inputs, map and outputs, freed after).  betts-shuttle-ocp peaks at 336-341 MB there (not the 215 of
#   an older measurement), and its robust twin at 345-349: the robust design's own
#   growth (CADET's sensitivity states, 28,800 step-states) is the ~25 MB its coefficient gives, no more.
# - Monte Carlo draws add nothing measurable, so they are not counted: they run in chunks (10,000 against 2000
#   draws, 349 and 349 on the shuttle, 233 and 232 on the two-phase case; 20,000 against 2000 there, 225 and 223).
# - Piecewise-constant controls cost nothing more since the check averages H over each interval by index
#   (it used a samples x intervals matrix, quadratic in the intervals: tumor-antiangiogenesis on 800
#   intervals peaked at 720 MB with it, 326 without).
FLOOR_MB = 120.4             # the process, CasADi, IPOPT and a tiny problem (the smallest presets: 128-140)
PER_GRID_WIDTH_MB = 1.85e-3  # per step of the check's NLP x (states + controls): variables, Jacobian, factors
PER_GRID_NODE_MB = 12.2e-6   # per step x parse-tree node: the SX graph evaluated at every step (27 MB / 3.06M)
PER_GRID_SENSITIVITY_MB = 1.05e-3  # per step x sensitivity state (robust: states x (states + uncertain quantities))
PER_CHECK_NUMBER_MB = 61e-6  # per number of the minimum-principle check's largest block (see above)
# The minimum-principle check takes its candidate controls a block of whole intervals at a time
# (solvers.ocp.minimum_principle): at most BLOCK candidate numbers and BLOCK evaluated numbers per block,
# whatever the width and length.  Until then it held every candidate at every sample of a phase, about twice
# over: wider (20 controls) peaked at 2641 MB, 319 since; wide 1170, 298 since; narrow-long 524, 293 since;
# three-phase-wide 547, 307 since (benchmarks/ocp_memory.py, each case in its own child).  A block's
# candidates are held once.
CANDIDATE_COPIES = 1.0
# solvers.ocp.minimum_principle's GRID, ZOOM, BLOCK and CORNERS and solvers.ocp.verify's SAMPLES_PER_INTERVAL,
# here so that the API sizes a job without importing CasADi (tests/unit/test_ocp_memory.py checks they agree)
GRID, ZOOM, BLOCK, CORNERS, SAMPLES_PER_INTERVAL = 41, 21, 2_000_000, 6, 20


def _samples(ph: PhaseSize) -> int:
    """The dense re-flight's samples on the check's mesh, where the minimum principle is checked."""
    return ph.intervals * ph.parts * SAMPLES_PER_INTERVAL + 1


def _candidates(ph: PhaseSize) -> int:
    return GRID * ph.controls + (2 ** ph.controls if ph.controls <= CORNERS else 0)


def _rows(ph: PhaseSize) -> int:
    """Numbers per column of an evaluation of H: time, states, costates, controls, path multipliers, bounds."""
    return 2 * ph.states + ph.controls + 2 * ph.paths + 1


def _block_samples(ph: PhaseSize) -> int:
    """Samples in the check's largest block: as many as BLOCK allows (solvers.ocp.minimum_principle's
    ``samples_at_once``), in whole intervals (one at least) where the controls are piecewise-constant."""
    most = max(1, BLOCK // max(ph.controls * _candidates(ph), _rows(ph) * ZOOM, 1))
    piecewise = ph.shooting and ph.parts == 2   # parts 2 in multiple shooting: constant controls (check_parts)
    group = ph.parts * SAMPLES_PER_INTERVAL if piecewise else 1
    return min(_samples(ph), max(group, most // group * group))


def candidates_mb(ph: PhaseSize) -> float:
    """MB of one block's minimum-principle candidates (see CANDIDATE_COPIES): bounded by BLOCK."""
    return CANDIDATE_COPIES * ph.controls * _candidates(ph) * _block_samples(ph) * 8 / 1e6


def check_block_numbers(ph: PhaseSize) -> float:
    """Numbers in the minimum-principle check's largest evaluation of H (``h_of`` on one block of samples:
    as many candidates as fit in BLOCK numbers, at least one), ``_rows`` per column."""
    samples, rows = _block_samples(ph), _rows(ph)
    at_once = min(_candidates(ph), max(1, BLOCK // (samples * rows)))
    return float(at_once * samples * rows)


def _check_mb(ph: PhaseSize) -> float:
    """MB of one phase's minimum-principle check: its largest block's candidates and evaluation."""
    return candidates_mb(ph) + PER_CHECK_NUMBER_MB * check_block_numbers(ph)


def _growth_mb(params: dict) -> float:
    """MB past the floor: the NLPs of every phase (they are one NLP: width, expression graph, robust
    sensitivities), and the largest phase's minimum-principle check (the checks run a phase at a time)."""
    phases = phase_sizes(params)
    if not phases:
        return 0.0
    nlp = sum(ph.grid * (PER_GRID_WIDTH_MB * ph.width + PER_GRID_NODE_MB * ph.nodes
                         + PER_GRID_SENSITIVITY_MB * ph.sensitivities) for ph in phases)
    return nlp + max(_check_mb(ph) for ph in phases)


MEMORY = MemoryModel(floor_mb=FLOOR_MB, size=_growth_mb, floor_size=0.0, per_unit_mb=1.0,
                     grows_with="the steps of the check's mesh (intervals x substeps or LGL nodes x its 2 or 3 "
                                "parts) x (states + controls, the expressions' parse-tree nodes and a robust "
                                "design's sensitivity states), and the minimum-principle check's block of "
                                "candidate controls x samples (bounded)")


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
