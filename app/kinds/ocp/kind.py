"""The ``ocp`` kind: the optimal-control problem the user writes down (``shared/specs/ocp.md``).

API edge of :mod:`solvers.ocp`: the presets (from :mod:`solvers.ocp.cases`, each citing its
source and published optimum), ``run`` (warm start, solve with the job's progress and cancel
callbacks, the result of the spec's "Result" section), the key numbers, and the cost estimate
that feeds the quota and the heavy queue.  ``solvers.ocp`` (CasADi) is imported inside ``run``
only: the API process never loads it.
"""
from __future__ import annotations

import time

from app.kinds.base import (
    JobContext,
    JobFailure,
    KindSpec,
    Preset,
    RunOutcome,
)
from app.kinds.ocp.footprint import MEMORY, compare_series, trajectory_table
from app.kinds.ocp.headlines import headlines
from app.kinds.ocp.params import OcpParams
from app.kinds.ocp.plots import plots as ocp_plots
from app.kinds.ocp.result import OcpResult
from app.kinds.ocp.robust.plots import robust_plots
from app.kinds.ocp.robust.trade import ROBUST_TABLES, robust_key_numbers
from app.kinds.ocp.search import run_search, solve_one
from app.kinds.ocp.size import PhaseSize, phase_bodies, phase_sizes
from app.kinds.ocp.trade import swept_label, trade_outputs
from app.kinds.ocp.warm_start import WARM_START_FIELD, load_warm_start, misfit
from app.results.tables import columns_at
from solvers.ocp import cases


def _presets() -> list[Preset]:
    out = []
    for name, case in cases.PRESETS.items():
        description = case["description"]
        optimum = case.get("optimum")
        if optimum is not None and str(optimum) not in description:
            description += f" Published optimum: {optimum}."
        out.append(Preset(name=name, kind="ocp", description=description, params=case["params"]))
    return out


PRESETS = _presets()


def plots(result: dict) -> list:
    """The problem's own plots, then a robust design's Monte Carlo plots (KindSpec.plots)."""
    return ocp_plots(result) + robust_plots(result)


def run(params: OcpParams, ctx: JobContext) -> RunOutcome:
    t_start = time.perf_counter()
    problem = params.problem
    from_job = params.initial_guess.from_job
    guess = load_warm_start(ctx, from_job, problem) if from_job else None
    if problem.robust is not None:
        from app.kinds.ocp.robust.run import run_robust
        return run_robust(params, ctx, guess=guess, t_start=t_start)
    if problem.starts > 1:                  # several starts, fanned out (app/kinds/ocp/search.py)
        return run_search(params, ctx, guess, from_job=from_job)
    try:
        return solve_one(params, problem, guess, on_progress=ctx.progress, should_stop=ctx.should_stop,
                         wall_start=t_start, warm_start=from_job)
    except (KeyError, TypeError, ValueError) as exc:
        if guess is None:
            raise
        # a stored result the solver cannot map onto this problem (other states, say)
        raise JobFailure("invalid_input", f"{WARM_START_FIELD}: job {from_job} does not fit this problem "
                                          f"({type(exc).__name__}: {str(exc)[:200]})") from None


def _limits_held(verification) -> bool | None:
    if not isinstance(verification, dict):
        return None
    for key in ("limits_held", "all_limits_held", "held"):
        if isinstance(verification.get(key), bool):
            return verification[key]
    return None


def key_numbers(result: dict) -> dict:
    """Objective (in the user's sense), final time, each state's final value and each optimized parameter
    (``final.h``, ``parameters.k``), iterations, and what the dense re-flight found: whether every limit
    held and whether the re-flown states agree with the solution; a robust design's numbers by source
    (``mc.``, ``cadet.``, ``deterministic.``: app.kinds.ocp.robust.trade)."""
    out = {"objective": result["objective"]["value"], "sense": result["objective"]["sense"],
           "tf": result["tf"], **{f"final.{k}": v for k, v in (result.get("final") or {}).items()},
           **{f"parameters.{k}": v for k, v in (result.get("parameters") or {}).items()},
           "iterations": (result.get("solver") or {}).get("iterations")}
    held = _limits_held(result.get("verification"))
    if held is not None:
        out["limits_held"] = held
    agrees = (result.get("verification") or {}).get("agrees")
    if isinstance(agrees, bool):
        out["verification_agrees"] = agrees
    return {**out, **robust_key_numbers(result)}


# One work unit is about one RK4 step of one reentry shooting interval (app.service.quota: the Betts
# reentry at 100 intervals x 2 substeps costs 200).  That problem written as an ocp (the betts-shuttle-ocp preset: 6 states,
# 2 controls, 345 parse-tree nodes of expressions) costs the same per solve: the NLP grows with the integration
# steps and the states and controls, each step's cost with the size of the expressions.  An ocp answer is
# two solves, its own and its check on the finer nested mesh (solvers.ocp.estimate), which the reentry
# kind does not make: ``cost`` counts both.  The sizes are the memory model's (app.kinds.ocp.size): the
# same parse-tree nodes, and a robust design's sensitivity states counted in its width.
REFERENCE_WIDTH = 8          # states + controls of the reference problem
REFERENCE_NODES = 345.0      # parse-tree nodes of its dynamics, expressions, path constraints and integrand
MIN_NODES = 86.0             # a tiny problem still costs its NLP's overhead (a quarter of the reference)


def cost(params: dict) -> float:
    """Work units: the sum over the phases of intervals x steps per interval x (states + controls, and a
    robust design's sensitivity states) x expression size (parse-tree nodes), scaled to the reference above;
    times (1 + s) for the check solve every answer gets on its mesh with every interval cut in s parts
    (:func:`app.kinds.ocp.size.check_parts`); times the refinement rounds when ``accuracy`` asks for mesh
    refinement (each round is an answer with its check); times ``search.starts`` (each start a solve)."""
    starts = int(((params.get("search") or {}).get("starts")) or 1)
    bodies = phase_bodies(params)
    return starts * sum(_phase_cost(body, ph) for body, ph in zip(bodies, phase_sizes(params), strict=True))


def _phase_cost(body: dict, ph: PhaseSize) -> float:
    tr = body.get("transcription") or {}
    steps = ph.steps if ph.shooting else ph.steps - 1.0
    width = float(ph.width + ph.sensitivities) / REFERENCE_WIDTH
    size = max(MIN_NODES, float(ph.nodes)) / REFERENCE_NODES
    refine = 1.0 + (float(tr.get("max_refinements", 8)) if body.get("accuracy") else 0.0)
    return float(ph.intervals) * steps * width * size * refine * (1.0 + ph.parts)


SPEC = KindSpec(
    kind="ocp",
    params_model=OcpParams,
    run=run,
    presets=PRESETS,
    summary="Your own optimal-control problem as data: states, controls, dynamics and constraints as "
            "expressions; multiple shooting or LGL, verified by an independent re-flight",
    time_limit_s=900.0,
    key_numbers=key_numbers,
    result_model=OcpResult,
    cost=cost,
    plots=plots,
    headlines=headlines,
    trade_outputs=trade_outputs,
    swept_label=swept_label,
    warm_start_misfit=misfit,
    memory=MEMORY,
    tables={"trajectory": trajectory_table, "verification": columns_at("verification.trajectory"), **ROBUST_TABLES},
    warm_start_field=WARM_START_FIELD,
    compare=compare_series,
    json_editor=True,   # a problem written as data: "New job" edits it as JSON, not as a form of fields
)
