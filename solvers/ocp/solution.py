"""What a solve of an ``ocp`` problem returns: :class:`OcpSolution`, one shape for one phase and several.

Every phase reports the same block (:mod:`solvers.ocp.check`: times, ends, trajectory, its own
verification and transcription).  A problem posed as one phase reads that block at the top
(``trajectory``, ``initial``, ``final``; its ``verification`` and ``solver`` are the phase's, as the
contract's single-phase result has them); several phases keep their blocks in ``phases`` with the
links checked at the solution and an account over all phases.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from solvers.common import SolveStatus
from solvers.ocp.problem import OcpProblem
from solvers.ocp.violations import INVALID_NUMBER


@dataclass
class OcpSolution:
    status: SolveStatus
    objective: float                      # in the user's sense (a maximum is reported as it is)
    sense: str
    t0: float
    tf: float
    parameters: dict[str, float]
    phases: list[dict]                    # per phase: {name, t0, tf, initial, final, trajectory, verification, solver}
    verification: dict
    solver: dict
    notes: list[str] = field(default_factory=list)
    single: bool = False                  # posed as one phase: its block is the answer
    # per phase, for refinement (solvers.ocp.refine): "path" the worst scaled path excess per interval,
    # "state" a function giving the scaled local errors per interval (a second re-flight, run when asked)
    interval_errors: list[dict] = field(default_factory=list)

    @property
    def initial(self) -> dict[str, float]:
        return self.phases[0]["initial"]

    @property
    def final(self) -> dict[str, float]:
        return self.phases[-1]["final"]

    @property
    def trajectory(self) -> dict | None:
        """The nodes of a problem posed as one phase (several phases: each phase's own)."""
        return self.phases[0]["trajectory"] if self.single else None

    def warm(self) -> dict:
        """This answer as the next round's initial guess (:func:`solvers.ocp.guess.stored_phases`)."""
        return {"phases": self.phases, "parameters": self.parameters}


def solution_of(problem: OcpProblem, *, nlp, res, status: SolveStatus, checks: list, rounds: list[dict]) -> OcpSolution:
    """The solution of one grid: every phase's block, the notes, the verification and the account."""
    agreement = checks[0].report["verification"]["agreement_tolerance"]
    notes = [f"{c.label}the re-flown controls depart from the transcription's states by {c.worst:.3g} (scaled), "
             f"more than {agreement:g}: the grid is too coarse for this problem (or the optimizer exploits the "
             "discretization, as free controls at every collocation node can); refine the grid or use multiple "
             "shooting" for c in checks if c.ok and not c.agrees]
    for c in checks:       # an LGL control's polynomial overshooting its bounds between the nodes
        for name, e in c.verification.controls.items():
            if not e["held"]:
                notes.append(f"{c.label}control {name} leaves its bounds [{e['lower']}, {e['upper']}] between the "
                             f"nodes (worst {e['worst_value']:.4g} at t = {e['worst_t']:.4g}): LGL holds a bound at "
                             "the nodes only; refine, or use multiple shooting for a control that saturates")
    recovery = status.details.get("guess_recovery")
    if recovery and recovery["status"] != INVALID_NUMBER:
        notes.append(f"the first guess overflowed (IPOPT {INVALID_NUMBER} at iteration "
                     f"{recovery['first_iterations']}); solved from a guess flown from the dynamics with the "
                     "guessed controls clipped to their bounds (solvers.ocp.flown)")
    if rounds:
        held = all(c.limits_held for c in checks)
        notes.append(f"path limits tightened on the intervals where the dense re-propagation exceeded "
                     f"them: {len(rounds)} round(s), limits {'held' if held else 'NOT held'}")
    phases = [c.report for c in checks]
    account = {"iterations": status.iterations, "status": status.solver_status, "outcome": status.outcome.value,
               "message": status.message, "build_time_s": status.build_time_s, "solve_time_s": status.solve_time_s,
               "cached_build": nlp.was_cached, "max_constraint_violation": status.max_constraint_violation,
               "limit_rounds": rounds}
    theta = checks[0].attempt.theta
    if problem.single:
        verification, solver = phases[0]["verification"], {**phases[0]["solver"], **account}
    else:
        notes.insert(0, f"{len(phases)} phases solved as one NLP ({', '.join(p['name'] for p in phases)}); "
                        f"links: {len(problem.links)} stated, {len(problem.time_links)} time and "
                        f"{len(problem.state_links)} state continuities by default")
        worst = 0.0
        for c in checks:
            worst = max(worst, c.worst) if c.ok else float("nan")
        verification = {"ok": all(c.ok for c in checks), "limits_held": all(c.limits_held for c in checks),
                        "terminal_held": all(c.terminal_held for c in checks),
                        "controls_held": all(c.report["verification"]["controls_held"] for c in checks),
                        "agrees": all(c.agrees for c in checks), "agreement_tolerance": agreement,
                        # each phase's own mode is in its block; here the one that needed interval by interval
                        "mode": next((c.verification.mode for c in checks if c.verification.restart),
                                     checks[0].verification.mode),
                        "max_state_difference_scaled_overall": worst,
                        "links": link_values(problem, phases, theta)}
        solver = {"method": "multiphase", "intervals": sum(p["solver"]["intervals"] for p in phases), **account}
    return OcpSolution(status=status, objective=float(nlp.sign * res.f), sense=problem.objective.sense,
                       t0=phases[0]["t0"], tf=phases[-1]["tf"],
                       parameters={q.name: float(theta[i]) for i, q in enumerate(problem.parameters)},
                       phases=phases, verification=verification, solver=solver, notes=notes,
                       single=problem.single, interval_errors=[c.errors for c in checks])


def link_values(problem: OcpProblem, phases: list[dict], theta) -> dict[str, dict]:
    """Each stated link's value at the solution's nodes, against its bounds (how exactly a jump holds)."""
    import casadi as ca

    from solvers.ocp.symbolic import to_sx

    ev: dict[tuple, ca.SX] = {}
    for p in phases:
        ev[("t0", p["name"])], ev[("tf", p["name"])] = ca.SX(p["t0"]), ca.SX(p["tf"])
        for k, tr in p["trajectory"].items():
            if k != "t":
                ev[("initial", k, p["name"])], ev[("final", k, p["name"])] = ca.SX(float(tr[0])), ca.SX(float(tr[-1]))
    env = {n: ca.SX(v) for n, v in problem.constants}
    env.update({q.name: ca.SX(float(theta[i])) for i, q in enumerate(problem.parameters)})
    out = {}
    for lk in problem.links:
        v = float(ca.evalf(to_sx(lk.expr, env, {t.name: t for t in problem.tables}, ev)))
        out[lk.name] = {"expr": lk.text, "value": v, "lower": lk.lower, "upper": lk.upper, "phases": list(lk.phases)}
    return out
