"""The result of an ``ocp`` job (``shared/specs/ocp.md``, "Result"): its typed model and its builder.

The names of the user's states, controls and expressions are the keys of ``initial``, ``final``,
``parameters`` and ``trajectory``, so those blocks are maps (``dict[str, number]``,
``dict[str, series]``) rather than fixed fields.  Every number goes through
:func:`app.kinds.base.json_value`: a non-finite value is ``null``.
"""
from __future__ import annotations

from typing import Any, Literal

from pydantic import Field

from app.kinds.base import json_float, json_value
from app.kinds.result_models import Num, ResultModel, Series
from app.kinds.ocp.robust.result import OcpRobustResult


class OcpResultObjective(ResultModel):
    """The optimized objective, in the user's sense (a maximum is reported as the positive maximum)."""

    value: Num = Field(description="Optimal value of expr + integral of integrand (the user's units)")
    sense: Literal["minimize", "maximize"] = Field(description="minimize or maximize, as posed")


class OcpRefinementRound(ResultModel):
    """One solve of the mesh refinement (round 0: the grid as given)."""

    round: int = Field(description="0 for the grid as given, then 1, 2, ...")
    intervals: int = Field(description="Mesh intervals of this round")
    max_error: Num = Field(None, description="Worst scaled state difference of its re-flight (null: not re-flown)")
    state_error: Num = Field(None, description="Estimated error of the states against the continuous optimum, "
                             "each scaled by its scale: the re-flight's difference or twice the change against the "
                             "check on the halved mesh, the larger (null: not estimated)")
    objective: Num = Field(None, description="Objective of this round's answer")
    objective_error_estimate: Num = Field(None, description="Estimated relative error of the objective against "
                                          "the continuous optimum: twice its relative change against the check "
                                          "solve on the halved mesh (null: the check did not converge)")
    check_intervals: int | None = Field(None, description="Intervals of the check solve (every interval halved)")
    check_objective: Num = Field(None, description="Objective of the check solve")
    check_iterations: int | None = Field(None, description="NLP iterations of the check solve (not in `iterations`)")
    iterations: int = Field(description="NLP iterations of this round (its limit rounds included)")
    time_s: Num = Field(None, description="Wall time of the round: build, solve, re-flight and check (s)")


class OcpResultAccuracy(ResultModel):
    """The answer's accuracy against the continuous problem's optimum, estimated (with or without `accuracy`)."""

    requested: Num = Field(None, description="The `accuracy` asked for (null: none; the grid as given)")
    state_error: Num = Field(None, description="Estimated error of the states, each scaled by its scale: the "
                             "larger of the re-flight's difference and twice the change against the check")
    objective_error_estimate: Num = Field(None, description="Estimated relative error of the objective: twice "
                                          "its relative change against the check solve on the halved mesh "
                                          "(exact when halving halves the error, up to 2x high when it falls "
                                          "faster); null when the check did not converge")
    reached: bool | None = Field(None, description="Both estimates within `requested` (null: none requested)")
    estimated_by: str | None = Field(None, description="How the estimates were made")
    reflight_state_error: Num = Field(None, description="The re-flight's own worst scaled state difference "
                                      "(the controls as returned, integrated independently)")
    check_intervals: int | None = Field(None, description="Intervals of the check solve")
    check_objective: Num = Field(None, description="Objective of the check solve")
    check_iterations: int | None = Field(None, description="NLP iterations of the check solve")
    check_time_s: Num = Field(None, description="Wall time of the check solve (s)")
    check_failure: str | None = Field(None, description="Why there is no estimate (the check did not converge)")


class OcpResultSolver(ResultModel):
    """How the problem was solved: transcription, NLP solver status, iterations and times."""

    method: str | None = Field(None, description="Transcription: multiple_shooting or lgl")
    intervals: int | None = Field(None, description="Mesh intervals")
    control: str | None = Field(None, description="Control within an interval: linear, constant (multiple "
                                "shooting) or polynomial (LGL)")
    substeps: int | None = Field(None, description="multiple_shooting: RK4 steps per interval")
    nodes_per_interval: int | None = Field(None, description="lgl: collocation nodes per interval")
    cached_build: bool | None = Field(None, description="The NLP of this structure came from the per-process "
                                      "cache (build time ~0)")
    limit_rounds: list[dict[str, Any]] | None = Field(
        None, description="Rounds of tightening path limits that the dense re-flight found exceeded between "
        "the nodes, each re-solved warm (empty: none needed)")
    terminal_refinements: list[str] | None = Field(
        None, description="Finer grids solved, warm-started, because the re-flight missed a terminal "
        "condition (e.g. '100 intervals x 2 RK4 steps -> 100 intervals x 4 RK4 steps'); absent: none needed")
    refinement: list[OcpRefinementRound] | None = Field(
        None, description="Mesh refinement: each round's intervals, worst error, objective, iterations and "
        "time (with `accuracy`, or when a missed terminal value refined the grid); absent: none")
    accuracy: OcpResultAccuracy | None = Field(
        None, description="The answer's estimated errors against the continuous optimum (states and objective), "
        "the accuracy requested and whether both estimates reached it")
    boundaries: list[float] | None = Field(None, description="A non-uniform (refined) mesh: the interval boundaries "
                                           "as fractions of the horizon, to pose again as transcription.boundaries; "
                                           "null: equal intervals")
    segment_nodes: list[int] | None = Field(None, description="lgl on a refined mesh: nodes of each interval")
    status: str = Field(description="The NLP solver's own status word, e.g. IPOPT's Solve_Succeeded")
    outcome: str | None = Field(None, description="What became of the solve: optimal, infeasible, "
                                "not_converged, limit_not_held, terminal_not_held, accuracy_not_reached, cancelled, failed; "
                                "optimality_not_verified: a feasible answer served as a success whose "
                                "verification.optimality names a necessary condition that failed")
    message: str | None = Field(None, description="The solver's message")
    iterations: int = Field(description="NLP iterations, all solves")
    build_time_s: Num = Field(description="Time to build the NLP (s); ~0 when the structure was cached")
    solve_time_s: Num = Field(description="Time in the NLP solver (s)")
    max_constraint_violation: Num = Field(description="Worst constraint violation at the solution (NLP units)")


class OcpResultPathCheck(ResultModel):
    """One path constraint on the dense re-flight: its worst values against its bounds."""

    lower: Num = Field(None, description="Lower bound (null: none)")
    upper: Num = Field(None, description="Upper bound (null: none)")
    min: Num = Field(None, description="Smallest value on the dense grid")
    max: Num = Field(None, description="Largest value on the dense grid")
    worst_t: Num = Field(None, description="Time of the worst value (s)")
    excess_scaled: Num = Field(None, description="Worst excess over a bound divided by `scale` (<= 0: within)")
    scale: Num = Field(None, description="The constraint's typical magnitude used to scale the excess")
    held: bool | None = Field(None, description="Within the bounds to the tolerance on the whole dense grid")


class OcpResultControlCheck(ResultModel):
    """One bounded LGL control on the dense re-flight: its interpolating polynomial against its bounds,
    which the NLP holds at the nodes only."""

    lower: Num = Field(None, description="Lower bound (null: none)")
    upper: Num = Field(None, description="Upper bound (null: none)")
    min: Num = Field(None, description="Smallest value of the interpolant on the dense grid")
    max: Num = Field(None, description="Largest value of the interpolant on the dense grid")
    worst_value: Num = Field(None, description="The value farthest outside the bounds (or nearest them)")
    worst_t: Num = Field(None, description="Time of the worst value (s)")
    excursion: Num = Field(None, description="Distance of the worst value beyond its bound (0: within)")
    held: bool | None = Field(None, description="Excursion within limit_tolerance of the bounds' width")


class OcpResultTerminalCheck(ResultModel):
    """One terminal condition on the re-flight: a fixed final value or a boundary constraint."""

    requested: Num = Field(None, description="The fixed final value asked for (final(state) checks)")
    lower: Num = Field(None, description="The boundary constraint's lower bound (null: none)")
    upper: Num = Field(None, description="The boundary constraint's upper bound (null: none)")
    reflown: Num = Field(None, description="The value on the re-flown trajectory")
    miss: Num = Field(None, description="How far the re-flown value is from the request or the bounds")
    tolerance: Num = Field(None, description="The miss still counted as held: terminal_tolerance times the "
                           "state's scale, or what that miss in every state moves the constraint")
    held: bool | None = Field(None, description="miss <= tolerance")


class OcpResultLinkCheck(ResultModel):
    """A stated link between phases, evaluated at the solution."""

    expr: str | None = Field(None, description="The link as written")
    value: Num = Field(None, description="Its value at the solution")
    lower: Num = Field(None, description="Lower bound (null: none)")
    upper: Num = Field(None, description="Upper bound (null: none)")
    phases: list[str] | None = Field(None, description="The phases it names")


class OcpResultOptimalityCheck(ResultModel):
    """One necessary condition of optimality, measured against the size of the Hamiltonian's terms."""

    value: Num = Field(None, description="The condition's residual, relative to the size of H's terms")
    tolerance: Num = Field(None, description="The largest residual counted as held (the answer's agreement "
                           "tolerance: its accuracy, or 1%)")
    held: bool | None = Field(None, description="value <= tolerance")
    expected: Num = Field(None, description="hamiltonian_final: the value H(tf) must take; transversality: the "
                          "costate the ends' multipliers give")
    allowance: Num = Field(None, description="piecewise-constant controls: the part of the tolerance the mesh "
                           "allows where a control jumps (the costates are not unique there), relative")
    intervals: int | None = Field(None, description="stationarity of piecewise-constant controls: the intervals "
                                  "checked (their integral of dH/du)")
    end: str | None = Field(None, description="transversality: initial or final, where the worst gap is")
    state: str | None = Field(None, description="transversality: the state whose costate it is")
    costate: Num = Field(None, description="transversality: the costate estimated there")
    nodes: int | None = Field(None, description="stationarity: the nodes checked (every control strictly inside "
                              "its bounds; the path constraints' multipliers are in H)")
    t: Num = Field(None, description="minimum_principle: the time of the worst gap H(u used) - min H over the "
                   "controls' bounds")
    samples: int | None = Field(None, description="minimum_principle: the re-flight's samples checked (the "
                                "nodes and between them; the admissible set held to the mixed path constraints)")


class OcpResultOptimality(ResultModel):
    """Evidence that the answer is an optimum: each necessary condition that applies."""

    held: bool | None = Field(None, description="Every condition checked held")
    checks: dict[str, OcpResultOptimalityCheck] | None = Field(
        None, description="hamiltonian_constant, hamiltonian_final, stationarity, minimum_principle, "
        "transversality: those that apply")
    message: str | None = Field(None, description="Which conditions were checked and which failed")


class OcpResultGrowth(ResultModel):
    """How much the dynamics amplify an error along the answer (solvers/ocp/growth.py)."""

    exponent: Num = Field(None, description="G = integral of the largest positive real part of the linearised "
                          "dynamics' eigenvalues over the phase: errors grow by about e^G")
    amplification: Num = Field(None, description="e^G (null past the largest double)")
    max_real_eigenvalue: Num = Field(None, description="Largest real part of df/dx's eigenvalues at any node (1/s)")
    duration_s: Num = Field(None, description="The phase's duration")
    threshold_exponent: Num = Field(None, description="ln(agreement_tolerance / 1e-8): past it even an exact "
                                    "answer's re-flight from t0 departs by more than the agreement")


class OcpResultVerification(ResultModel):
    """The controls re-flown by an independent integrator on a dense grid, against the solution."""

    method: str | None = Field(None, description="Integrator and tolerances of the re-flight")
    mode: Literal["from_t0", "interval_by_interval"] | None = Field(
        None, description="from_t0: one flight from the initial state, the states' difference at every node; "
        "interval_by_interval: dynamics that amplify errors past what that flight can follow (growth), so each "
        "interval is re-flown from its own first node and its defect held to agreement_tolerance")
    mode_reason: str | None = Field(None, description="Why this mode, with the growth figure")
    growth: OcpResultGrowth | None = Field(None, description="How much the dynamics amplify errors along the answer")
    samples_per_interval: int | None = Field(None, description="Dense points per mesh interval")
    max_state_difference: dict[str, Num] | None = Field(
        None, description="state name -> largest |re-flown - solution| over the nodes (the state's unit)")
    max_state_difference_scaled: dict[str, Num] | None = Field(
        None, description="state name -> the same divided by the state's scale")
    max_state_difference_scaled_overall: Num = Field(None, description="Largest scaled difference of any state")
    agrees: bool | None = Field(None, description="The re-flown states agree with the solution within "
                                "agreement_tolerance (scaled); false: the grid is too coarse for this problem")
    agreement_tolerance: Num = Field(None, description="Largest scaled difference counted as agreement "
                                     "(the problem's `accuracy`, or the service's default)")
    path: dict[str, OcpResultPathCheck] | None = Field(None, description="path constraint name -> its check "
                                                       "on the dense grid")
    limits_held: bool | None = Field(None, description="Every path constraint held on the dense grid")
    controls: dict[str, OcpResultControlCheck] | None = Field(
        None, description="LGL: bounded control name -> its interpolant on the dense grid against its bounds")
    controls_held: bool | None = Field(None, description="Every control within its bounds on the dense grid "
                                       "(multiple shooting: by construction)")
    limit_tolerance: Num = Field(None, description="Scaled excess still counted as held")
    terminal: dict[str, OcpResultTerminalCheck] | None = Field(
        None, description="'final(state)' or a boundary constraint's name -> its check on the re-flight")
    terminal_held: bool | None = Field(None, description="Every terminal condition held on the re-flight")
    terminal_tolerance: Num = Field(None, description="Miss still counted as held, as a fraction of each "
                                    "state's scale")
    ok: bool | None = Field(None, description="The integrator reached the final time")
    message: str | None = Field(None, description="The integrator's message (empty when ok)")
    links: dict[str, OcpResultLinkCheck] | None = Field(
        None, description="Several phases: each stated link's value at the solution against its bounds")
    optimality: OcpResultOptimality | None = Field(
        None, description="Necessary conditions of optimality from the costates (both transcriptions)")


class OcpResultPhaseSolver(ResultModel):
    """One phase's transcription."""

    method: str | None = Field(None, description="multiple_shooting or lgl")
    intervals: int | None = Field(None, description="Mesh intervals of the phase")
    control: str | None = Field(None, description="linear, constant or polynomial")
    substeps: int | None = Field(None, description="multiple_shooting: RK4 steps per interval")
    nodes_per_interval: int | None = Field(None, description="lgl: collocation nodes per interval")
    boundaries: list[float] | None = Field(None, description="A non-uniform mesh: its interval boundaries in "
                                           "normalized time (null: equal intervals)")
    segment_nodes: list[int] | None = Field(None, description="lgl on a non-uniform mesh: the nodes of each "
                                            "interval")


class OcpResultPhase(ResultModel):
    """One phase of a multi-phase answer: its times, ends, trajectory and its own re-flight."""

    name: str = Field(description="The phase's name, as posed")
    t0: Num = Field(description="The phase's initial time (s)")
    tf: Num = Field(description="The phase's final time (s)")
    initial: dict[str, Num] = Field(description="state name -> value at the phase's t0")
    final: dict[str, Num] = Field(description="state name -> value at the phase's tf")
    trajectory: dict[str, Series] = Field(description="`t` and the phase's states, controls and expressions "
                                          "at its nodes")
    costates: dict[str, Series] | None = Field(
        None, description="state name -> its costate at the nodes (of the objective as minimised), from the "
        "NLP's multipliers (multiple shooting)")
    hamiltonian: Series | None = Field(None, description="The Hamiltonian at the nodes")
    verification: OcpResultVerification | None = Field(None, description="The phase's controls re-flown from "
                                                       "its own initial state on a dense grid")
    solver: OcpResultPhaseSolver | None = Field(None, description="The phase's transcription")


class OcpResultOptimum(ResultModel):
    """One local optimum the starts met."""

    objective: Num = Field(description="Its objective, in the user's sense (the best of its group)")
    count: int = Field(description="How many starts ended there")


class OcpResultStart(ResultModel):
    """What became of one start."""

    start: int = Field(description="The start's index (0: the guess given)")
    status: str = Field(description="succeeded, failed or cancelled")
    objective: Num = Field(None, description="Its objective, in the user's sense")
    iterations: int | None = Field(None, description="Its IPOPT iterations")
    code: str | None = Field(None, description="Its error code, when it failed")
    message: str | None = Field(None, description="Its error message, when it failed (shortened)")
    by: str | None = Field(None, description="The worker that computed it")


class OcpResultSearch(ResultModel):
    """Several starts (params.search): how many, how many succeeded, the local optima they met."""

    starts: int = Field(description="Initial guesses solved from")
    succeeded: int = Field(description="Starts that succeeded")
    distinct_optima: list[OcpResultOptimum] = Field(description="The succeeded starts' objectives grouped "
                                                    "within `tolerance` (relative), best first")
    best_start: int | None = Field(description="The start whose answer is the result (all failed: the one "
                                   "that came closest)")
    rule: str = Field(description="How the varied starts are made")
    seed: int = Field(description="The seed of the varied starts' random numbers")
    tolerance: float = Field(description="Relative difference under which two objectives are one optimum: "
                             "the accuracy asked, else what the NLP's tolerance leaves (1e-5)")
    each: list[OcpResultStart] = Field(description="Every start, in order")


class OcpResult(ResultModel):
    """Result of an ``ocp`` job: the optimal trajectory of your problem, its solve and its independent
    verification (the controls re-flown by another integrator on a dense grid)."""

    title: str | None = Field(None, description="The problem's title, as posed")
    objective: OcpResultObjective = Field(description="The optimized objective")
    t0: Num = Field(description="Initial time (s)")
    tf: Num = Field(description="Final time (s)")
    initial: dict[str, Num] = Field(description="state name -> value at t0 (several phases: the first's)")
    final: dict[str, Num] = Field(description="state name -> value at tf (several phases: the last's)")
    parameters: dict[str, Num] = Field(description="parameter name -> optimal value")
    trajectory: dict[str, Series] | None = Field(
        None, description="`t` and every state, control and expression at the nodes, equal-length arrays; "
        "null where not finite (several phases: in each phase)")
    costates: dict[str, Series] | None = Field(
        None, description="state name -> its costate at the nodes (of the objective as minimised), from the "
        "NLP's multipliers (multiple shooting)")
    hamiltonian: Series | None = Field(None, description="The Hamiltonian at the nodes")
    phases: list[OcpResultPhase] | None = Field(None, description="Several phases: one block per phase, in "
                                                "time order; absent for a single phase")
    units: dict[str, str] = Field(default_factory=dict, description="name -> unit, for the names declared "
                                  "with one")
    verification: OcpResultVerification | None = Field(
        description="The controls re-flown by an independent integrator on a dense grid: the largest state "
        "difference per state (scaled and absolute), the worst value of each path constraint on that grid "
        "against its bounds, and whether every limit held; null when not run")
    solver: OcpResultSolver = Field(description="Transcription and NLP solver account")
    plots: list[list[str]] = Field(default_factory=list, description="The extra plot pairs [x, y] asked for")
    warm_start: str | None = Field(None, description="The job this solve was warm-started from")
    wall_time_s: Num = Field(None, description="Wall time of the job's run (s)")
    notes: list[str] = Field(description="How the answer was obtained and what to keep in mind")
    search: OcpResultSearch | None = Field(None, description="Several starts (params.search.starts > 1): the "
                                           "result is the best start's")
    robust: OcpRobustResult | None = Field(None, description="Robust design (with uncertainty): the design's "
                                           "Monte Carlo beside CADET, the kept shares, confirmed")


def _map(d) -> dict:
    return {str(k): json_float(v) if v is not None else None for k, v in (d or {}).items()}


def _optimality(p: dict) -> dict:
    """The phase's costates and Hamiltonian at the nodes."""
    if p.get("costates") is None:
        return {}
    return {"costates": {str(k): json_value(v) for k, v in p["costates"].items()},
            "hamiltonian": json_value(p["hamiltonian"])}


def _phase(p: dict) -> dict:
    return {"name": p["name"], "t0": json_float(p["t0"]), "tf": json_float(p["tf"]),
            "initial": _map(p["initial"]), "final": _map(p["final"]),
            "trajectory": {str(k): json_value(v) for k, v in p["trajectory"].items()}, **_optimality(p),
            "verification": json_value(p["verification"]), "solver": json_value(p["solver"])}


def build_result(sol, params, *, wall_time_s: float, warm_start: str | None = None) -> dict:
    """The JSON result of an :class:`solvers.ocp.OcpSolution` (plain floats and lists): one phase at the
    top level (``trajectory``), several in ``phases`` (``initial`` of the first, ``final`` of the last)."""
    s = sol.status
    solver = dict(json_value(sol.solver))
    solver.update({"status": s.solver_status, "outcome": s.outcome.value, "message": s.message or None,
                   "iterations": int(s.iterations), "build_time_s": json_float(s.build_time_s),
                   "solve_time_s": json_float(s.solve_time_s),
                   "max_constraint_violation": json_float(s.max_constraint_violation)})
    phases = [_phase(p) for p in sol.phases]
    declared = (*params.states, *params.controls) if sol.single else \
        [d for ph in params.phases for d in (*ph.states, *ph.controls)]
    out = {
        "title": params.title,
        "objective": {"value": json_float(sol.objective), "sense": sol.sense},
        "t0": json_float(sol.t0), "tf": json_float(sol.tf),
        "initial": phases[0]["initial"], "final": phases[-1]["final"],
        "parameters": _map(sol.parameters),
        **({"trajectory": phases[0]["trajectory"], **_optimality(sol.phases[0])} if sol.single
           else {"phases": phases}),
        "units": {d.name: d.unit for d in declared if d.unit},
        "verification": json_value(sol.verification),
        "solver": solver,
        "plots": [list(p) for p in params.plots],
        "warm_start": warm_start,
        "wall_time_s": json_float(wall_time_s),
        "notes": [str(n) for n in sol.notes],
    }
    return out
