"""What an ``ocp`` job takes and shows beyond its plots: its memory (:mod:`app.service.job_memory`; its
cost is :func:`app.kinds.ocp.kind.cost`), its trajectory as one CSV table over its phases, and its curve on
the console's compare plot."""
from __future__ import annotations

from app.kinds.base import CompareSeries, MemoryModel
from app.kinds.ocp.size import PhaseSize, draws, phase_sizes
from app.results.tables import columns, columns_at


# Calibration (benchmarks/ocp_memory.py and one-off runs of the same child, peak resident MB on a quiet
# 2-core x86_64; linear-quadratic problems of n states, m controls, multiple shooting with 2 RK4 substeps
# unless said): narrow-long 4x2 on 1000 intervals 506, wide 30x10 on 200 1096, wider 50x20 on 150 2640,
# wide-lgl 20x8 on 150 LGL intervals of 5 nodes 571, three-phase 3 x (6x2 on 400) 390, three-phase-wide
# 3 x (20x8 on 100) 547, betts-shuttle-ocp 215, 4x2 on 300 313 and the same with 1700 more parse-tree nodes
# in its dynamics (25 sin*cos terms per state) 335; robust: betts-shuttle-robust-ocp 349 (10,000 or 2000 Monte
# Carlo draws alike), a two-phase 3x1 robust problem of 4 draws on 100 + 100 intervals 232 (2000 draws) and
# 233 (10,000 draws).  Fitted (max |log(estimate/peak)| 0.10 over the deterministic nine); not fitted, the
# presets free-flying-robot (6 controls: 412 MB measured, 347 estimated) and rayleigh-mixed-constraint (253, 237):
FLOOR_MB = 205.0            # the pool process, CasADi, IPOPT and a tiny problem
PER_GRID_WIDTH_MB = 2.35e-3  # per step of the check's NLP x (states + controls): variables, Jacobian, factors
PER_GRID_NODE_MB = 7.2e-6   # per step x parse-tree node: the SX graph evaluated at every step (22 MB / 3.06M)
# The minimum-principle check's candidate controls at the dense re-flight's samples (solvers.ocp.
# minimum_principle: controls x (41 per control + 2^controls corners up to 6 controls) x 20 samples per
# interval of the check's mesh, doubles), held a phase at a time and about twice over (the candidate sets
# and their concatenation): what made `wider` (20 controls) 2.6 GB, not its 70-term integrand (7 MB).
CANDIDATE_COPIES = 2.15
SAMPLES_PER_INTERVAL = 20   # solvers.ocp.verify.SAMPLES_PER_INTERVAL
# A robust design adds CADET's sensitivity states: their rows (states x (states + draws) per step) and their
# graph, the phase's expressions differentiated in (states + draws) directions at every step.  Two
# robust cases fit both exactly (shuttle 130 MB over its twin, the two-phase problem 15 MB); the Monte
# Carlo runs in chunks and its draws added nothing measurable (10,000 against 2000 on both).
PER_GRID_SENSITIVITY_MB = 2.5e-4
PER_GRID_NODE_DIRECTION_MB = 7.0e-5


def candidates_mb(ph: PhaseSize) -> float:
    """MB of one phase's minimum-principle candidates (see CANDIDATE_COPIES)."""
    corners = 2 ** ph.controls if ph.controls <= 6 else 0
    samples = ph.intervals * ph.parts * SAMPLES_PER_INTERVAL
    return CANDIDATE_COPIES * ph.controls * (41 * ph.controls + corners) * samples * 8 / 1e6


def _growth_mb(params: dict) -> float:
    """MB past the floor: the NLPs of every phase (they are one NLP), their expression graphs, the robust
    sensitivities, and the largest phase's minimum-principle candidates (the checks run a phase at a time)."""
    phases = phase_sizes(params)
    if not phases:
        return 0.0
    w = draws(params)
    nlp = sum(ph.grid * (PER_GRID_WIDTH_MB * ph.width + PER_GRID_NODE_MB * ph.nodes
                         + PER_GRID_SENSITIVITY_MB * ph.sensitivities
                         + (PER_GRID_NODE_DIRECTION_MB * ph.nodes * (ph.states + w) if w else 0.0))
              for ph in phases)
    return nlp + max(candidates_mb(ph) for ph in phases)


MEMORY = MemoryModel(floor_mb=FLOOR_MB, size=_growth_mb, floor_size=0.0, per_unit_mb=1.0,
                     grows_with="the steps of the check's mesh (intervals x substeps or LGL nodes x its 2 or 3 "
                                "parts) x (states + controls and the expressions' parse-tree nodes), a robust "
                                "design's sensitivities, and controls^2 x intervals (the minimum-principle check)")


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
