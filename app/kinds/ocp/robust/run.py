"""The run of a robust ``ocp`` job (``shared/specs/ocp.md``, "Robust design"): the design
(:func:`solvers.ocp.robust.solver.design_and_confirm`) with its Monte Carlo run by the service
(``ctx.run_monte_carlo``: in process, or fanned across the workers for large counts, the same chunks
either way), and ``not_robust`` when the Monte Carlo does not keep what the design promised (the design
and the Monte Carlo stored, as the ``robust_reentry`` kind does)."""
from __future__ import annotations

import time

from app.kinds.base import JobContext, RunOutcome, json_value, outcome_from_status
from app.kinds.ocp.params import OcpParams, parser_data
from app.kinds.ocp.robust.samples import monte_carlo_block
from app.kinds.ocp.result import build_result

CHUNK_SIZE = 2500        # samples per chunk: the unit of the fan-out across workers
SEED = 20260101          # the Monte Carlo's seed: the same job gives the same draws


def run_robust(params: OcpParams, ctx: JobContext, *, guess: dict | None, t_start: float) -> RunOutcome:
    """The robust job (module docstring)."""
    from solvers.ocp.robust.solver import design_and_confirm

    problem = params.problem

    def monte_carlo(spec, samples, seed):       # its stage announced by design_and_confirm
        return ctx.run_monte_carlo(spec, samples, seed, CHUNK_SIZE)

    rs, block, summary = design_and_confirm(problem, params=parser_data(params), run_monte_carlo=monte_carlo, seed=SEED,
                                      initial_guess=guess, on_progress=ctx.progress, should_stop=ctx.should_stop)
    from_job = params.initial_guess.from_job if guess is not None else None   # warm-starts the deterministic twin
    result = build_result(rs.solution, params, wall_time_s=time.perf_counter() - t_start, warm_start=from_job)
    if block is None:
        return outcome_from_status(rs.solution.status, result)
    if summary is not None and "distribution" in summary:    # which workers computed which chunks
        block["distribution"] = summary["distribution"]
    if summary is not None:
        block["monte_carlo"] = monte_carlo_block(summary)
    result["robust"] = json_value(block)
    outcome = outcome_from_status(rs.solution.status, result)
    if outcome.status != "succeeded" or block["confirmed"]:
        return outcome
    short = {n: f"{100 * c['kept_fraction']:.2f}% kept, {100 * c['required_fraction']:.3f}% required"
             for n, c in block["constraints"].items() if not c["kept"]}
    msg = (f"the Monte Carlo ({block['samples']} draws) does not confirm the robust design after "
           f"{len(block['rounds'])} round(s): {short}; the design and its Monte Carlo are stored as the result")
    return RunOutcome("failed", result=result, error={"code": "not_robust", "message": msg,
                                                      "details": {"rounds": result["robust"]["rounds"]}})
