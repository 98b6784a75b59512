"""``solve_phases(problem)``: a multi-phase ``ocp`` problem solved as one NLP, each phase re-flown.

The NLP is :class:`solvers.ocp.multiphase.MultiPhaseNLP`; the numbers of each phase (scales,
bounds, parameter vector, the straight-line guess or a stored phase interpolated onto its grid)
are the single phase's (:mod:`solvers.ocp.solver`), placed in the global vector.  After IPOPT
each phase is re-flown and checked on its own, as a single phase is (:mod:`solvers.ocp.verify`,
:mod:`solvers.ocp.terminal`): the phase's controls from its own solved initial state.  A
terminal condition missed on the re-flight refines every phase's grid (as a single phase does),
warm-started.  Path limits exceeded between the nodes are tightened where they were exceeded and the
NLP solved again (:mod:`solvers.ocp.phase_limits`), as for a single phase; still exceeded, the solve
ends ``limit_not_held``.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from types import SimpleNamespace

import numpy as np

from solvers.common import Outcome, ProgressFn, SolveStatus, StopFn
from solvers.ocp.multiphase import MultiPhaseNLP
from solvers.ocp.phase_limits import hold_phase_limits
from solvers.ocp.phases_spec import MultiPhaseProblem

# The single phase's packing, re-flight and result of one phase, reused per phase (same package).
from solvers.ocp.solver import (
    AGREEMENT_TOLERANCE,
    WARM_IPOPT,
    Attempt,
    functions_of,
    guess_of,
    numbers_of,
    solution_of,
    verify_attempt,
)
from solvers.ocp.terminal import (
    TERMINAL_ROUNDS,
    TERMINAL_TOLERANCE,
    finer,
    grid_words,
    terminal_checks,
)
from solvers.ocp.verify import local_errors


@dataclass
class MultiPhaseSolution:
    status: SolveStatus
    objective: float
    sense: str
    t0: float
    tf: float
    parameters: dict[str, float]
    phases: list[dict]                 # {name, t0, tf, initial, final, trajectory, verification, solver}
    verification: dict
    solver: dict
    notes: list[str] = field(default_factory=list)
    # per phase, for mesh refinement (solvers.ocp.phase_refine): "path" the worst scaled path excess
    # per interval, "state" a function giving the scaled local errors per interval
    interval_errors: list[dict] = field(default_factory=list)


def stored_phases(initial_guess: dict | None) -> dict[str, dict]:
    """A stored multi-phase result's phases by name (empty without one)."""
    if not initial_guess:
        return {}
    return {p["name"]: p for p in initial_guess.get("phases") or [] if isinstance(p, dict) and "name" in p}


def solve_phases(problem: MultiPhaseProblem, *, initial_guess: dict | None = None,
                 on_progress: ProgressFn | None = None, should_stop: StopFn | None = None,
                 seed: int | None = None, ipopt: dict | None = None) -> MultiPhaseSolution:
    """Solve (module docstring).  ``initial_guess``: a stored multi-phase ``ocp`` result with the
    same phase names (each phase's trajectory interpolated onto its grid)."""
    del seed
    if problem.accuracy is not None:
        from solvers.ocp.phase_refine import solve_phases_refined
        return solve_phases_refined(
            problem, initial_guess=initial_guess, should_stop=should_stop,
            solve_once=lambda mp, warm, should_stop: _solve_once(mp, warm, on_progress, should_stop, ipopt))
    sol = _solve_once(problem, initial_guess, on_progress, should_stop, ipopt)
    refinements = []
    while sol.status.outcome is Outcome.TERMINAL_NOT_HELD and len(refinements) < TERMINAL_ROUNDS:
        phases = [replace(ph, problem=finer(ph.problem)) if finer(ph.problem) else ph for ph in problem.phases]
        if all(a is b for a, b in zip(phases, problem.phases)):
            break
        refinements.append("; ".join(f"{a.name}: {grid_words(a.problem)} -> {grid_words(b.problem)}"
                                     for a, b in zip(problem.phases, phases)))
        warm = {"phases": sol.phases, "parameters": sol.parameters}
        problem = replace(problem, phases=tuple(phases))
        sol = _solve_once(problem, warm, on_progress, should_stop, ipopt)
    if refinements:
        sol.notes.insert(0, "terminal conditions missed on the re-flight, every phase's grid refined "
                         f"(warm-started): {' | '.join(refinements)}; now "
                         f"{'held' if sol.verification['terminal_held'] else 'NOT held'}")
        sol.solver["terminal_refinements"] = refinements
    return sol


def _solve_once(mp: MultiPhaseProblem, initial_guess, on_progress, should_stop, ipopt) -> MultiPhaseSolution:
    progress = on_progress or (lambda f, m: None)
    t_start = time.perf_counter()
    progress(0.0, f"building the NLP of {len(mp.phases)} phases")
    stored = stored_phases(initial_guess)
    if ipopt is None and stored:
        ipopt = WARM_IPOPT
    nlp = MultiPhaseNLP(mp, functions_of, ipopt=ipopt)
    z0, lbz, ubz = np.zeros(nlp.nz), np.full(nlp.nz, -np.inf), np.full(nlp.nz, np.inf)
    p, lbg, ubg, nums = [], [], [], []
    for ph, b in zip(mp.phases, nlp.blocks):
        old = stored.get(ph.name)
        warm = None if old is None else {"trajectory": old["trajectory"], "tf": old["tf"],
                                         "parameters": initial_guess.get("parameters")}
        tf_g, th_g, X_g, U_g = guess_of(b.problem, b.nlp.grid, warm)
        t0_g = float(old["t0"]) if old is not None else b.problem.time.initial
        num = numbers_of(b.problem, b.nlp, tf_g)
        ts, t = num.t_scale, ph.time
        lo_t0 = t.initial if t.initial is not None else t.initial_lower
        hi_t0 = t.initial if t.initial is not None else t.initial_upper
        lo_tf = t.final if t.final is not None else t.final_lower
        hi_tf = t.final if t.final is not None else t.final_upper
        lb, ub = num.lbz.copy(), num.ubz.copy()
        lb[0] = -np.inf if lo_tf is None else lo_tf / ts
        ub[0] = np.inf if hi_tf is None else hi_tf / ts
        lbz[b.colmap], ubz[b.colmap] = lb, ub
        lbz[b.t0_col] = -np.inf if lo_t0 is None else lo_t0 / ts
        ubz[b.t0_col] = np.inf if hi_t0 is None else hi_t0 / ts
        z0[b.colmap] = b.nlp.pack(tf_g, th_g, X_g, U_g)     # theta: every phase's guess is the same
        z0[b.t0_col] = t0_g / ts
        p.append(num.p)
        lbg.append(num.lbg)
        ubg.append(num.ubg)
        nums.append(num)
    elo, ehi, lscale = nlp.event_bounds()
    p = np.concatenate(p + [lscale])
    lbg, ubg = np.concatenate(lbg + [elo]), np.concatenate(ubg + [ehi])
    build_time = time.perf_counter() - t_start
    z0 = np.clip(z0, lbz, ubz)
    res = nlp.solver.solve(x0=z0, lbx=lbz, ubx=ubz, lbg=lbg, ubg=ubg, p=p, on_progress=on_progress,
                           should_stop=should_stop, progress_span=(0.02, 0.9))
    status = res.status
    status.build_time_s = build_time if not nlp.was_cached else 0.0
    progress(0.92, "re-flying each phase")

    def evaluate(r):
        return _evaluate(mp, nlp, nums, r)

    ev, rounds = evaluate(res), []
    if status.ok and ev.all_ok and not ev.limits_held:
        progress(0.94, "tightening path limits violated between the nodes")
        offsets = np.cumsum([0] + [len(n.lbg) for n in nums])
        rows = [(None if n.path_slices is None else slice(o + n.path_slices.start, o + n.path_slices.stop),
                 len(b.problem.path), b.nlp.grid) for n, b, o in zip(nums, nlp.blocks, offsets)]
        warm = MultiPhaseNLP(mp, functions_of, ipopt={**(ipopt or {}), **WARM_IPOPT})
        first = (status.iterations, status.solve_time_s)
        res, ev, rounds = hold_phase_limits(solver=warm.solver, rows=rows, bounds=(lbz, ubz, lbg, ubg), p=p,
                                            res=res, ev=ev, evaluate=evaluate, should_stop=should_stop)
        status = res.status
        status.iterations = first[0] + sum(r["iterations"] for r in rounds)
        status.solve_time_s = first[1] + sum(r["solve_time_s"] for r in rounds)
        status.build_time_s = build_time if not nlp.was_cached else 0.0
        status.details = {**status.details, "limit_rounds": rounds}
    theta, phases, notes, errors = ev.theta, ev.phases, ev.notes, ev.errors
    all_ok, limits_held, terminal_held, agrees, worst_all = ev.all_ok, ev.limits_held, ev.terminal_held, \
        ev.agrees, ev.worst
    if rounds:
        notes.append(f"path limits tightened on the intervals where the dense re-propagation exceeded them: "
                     f"{len(rounds)} round(s), limits {'held' if limits_held else 'NOT held'}")
    if status.ok and not all_ok:
        status.outcome = Outcome.FAILED
        status.message += "; the re-flight of a phase failed"
    elif status.ok and not limits_held:
        status.outcome = Outcome.LIMIT_NOT_HELD
        status.message = "converged, but path limits are exceeded between the nodes (see each phase's verification)"
    elif status.ok and not terminal_held:
        status.outcome = Outcome.TERMINAL_NOT_HELD
        missed = {f"{p['name']}: {k}": v["miss"] for p in phases for k, v in p["verification"]["terminal"].items()
                  if not v["held"]}
        status.message = f"converged, but the re-flight misses terminal conditions: {missed}"
    notes.insert(0, f"{len(phases)} phases solved as one NLP ({', '.join(p['name'] for p in phases)}); "
                    f"links: {len(mp.links)} stated, {len(mp.time_links)} time and {len(mp.state_links)} state "
                    "continuities by default")
    verification = {"ok": all_ok, "limits_held": limits_held, "terminal_held": terminal_held, "agrees": agrees,
                    "agreement_tolerance": mp.accuracy or AGREEMENT_TOLERANCE,
                    "max_state_difference_scaled_overall": worst_all,
                    "links": _link_values(mp, phases, theta)}
    solver = {"method": "multiphase", "intervals": sum(p["solver"]["intervals"] for p in phases),
              "iterations": status.iterations, "status": status.solver_status, "outcome": status.outcome.value,
              "message": status.message, "build_time_s": status.build_time_s, "solve_time_s": status.solve_time_s,
              "cached_build": nlp.was_cached, "max_constraint_violation": status.max_constraint_violation,
              "limit_rounds": rounds}
    progress(1.0, status.outcome.value)
    return MultiPhaseSolution(status=status, objective=float(nlp.sign * res.f), sense=mp.objective.sense,
                              t0=phases[0]["t0"], tf=phases[-1]["tf"],
                              parameters={q.name: float(theta[i]) for i, q in enumerate(mp.parameters)},
                              phases=phases, verification=verification, solver=solver, notes=notes,
                              interval_errors=errors)


def _evaluate(mp: MultiPhaseProblem, nlp: MultiPhaseNLP, nums: list, res) -> SimpleNamespace:
    """Every phase of the answer ``res`` re-flown and checked (its verification, terminal values, trajectory)."""
    status = res.status
    nth = len(mp.parameters)
    agreement = mp.accuracy or AGREEMENT_TOLERANCE     # with accuracy, the states must agree to it
    theta = res.x[:nth] * (nums[0].theta_scale if nth else 1.0)
    phases, notes, errors = [], [], []
    all_ok, limits_held, terminal_held, agrees, worst_all = True, True, True, True, 0.0
    excess = []
    for ph, b, num in zip(mp.phases, nlp.blocks, nums):
        t0 = float(res.x[b.t0_col] * num.t_scale)
        prob = replace(b.problem, phase=replace(b.problem.phase, time=replace(b.problem.phase.time, initial=t0)))
        att = Attempt(b.nlp, num, SimpleNamespace(x=res.x[b.colmap], status=status, f=float("nan")))
        ver = verify_attempt(prob, b.nlp, num, att)
        excess.append(ver.interval_excess)
        errors.append({"path": np.max(ver.interval_excess, axis=0) if ver.interval_excess else None,
                       "state": _local(b, num, att, t0)})
        fns = b.nlp.fns
        terminal = terminal_checks(problem=prob, fns=fns, x_scale=num.x_scale, c=num.p[:fns.nc], theta=att.theta,
                                   tf=att.tf, x=ver.x, u=ver.u) if ver.ok else {}
        one = solution_of(prob, b.nlp, num, att, ver, status, [])
        worst = max(ver.max_scaled_difference.values(), default=0.0)
        ph_agrees = bool(ver.ok and worst <= agreement)
        held = all(c["held"] for c in terminal.values())
        one.verification.update(agrees=ph_agrees, agreement_tolerance=agreement, terminal=terminal,
                                terminal_held=held, terminal_tolerance=TERMINAL_TOLERANCE)
        all_ok &= ver.ok
        limits_held &= ver.limits_held
        terminal_held &= held
        agrees &= ph_agrees
        worst_all = max(worst_all, worst) if ver.ok else float("nan")
        psolver = {k: one.solver[k] for k in ("method", "intervals", "control", "substeps", "nodes_per_interval")}
        phases.append({"name": ph.name, "t0": t0, "tf": att.tf, "initial": one.initial, "final": one.final,
                       "trajectory": one.trajectory, "verification": one.verification, "solver": psolver})
        if not ph_agrees and ver.ok:
            notes.append(f"phase {ph.name}: the re-flown controls depart from the transcription's states by "
                         f"{worst:.3g} (scaled), more than {agreement:g}: refine this phase's grid")
    return SimpleNamespace(theta=theta, phases=phases, notes=notes, errors=errors, excess=excess, all_ok=all_ok,
                           limits_held=limits_held, terminal_held=terminal_held, agrees=agrees, worst=worst_all)


def _local(b, num, att, t0: float):
    """The phase's scaled local error per interval, computed when asked (a second re-flight)."""
    def run():
        return local_errors(fns=b.nlp.fns, grid=b.nlp.grid, t_nodes=t0 + (att.tf - t0) * b.nlp.grid.tau(), X=att.X,
                            U=b.nlp.node_controls(att.U), theta=att.theta, c=num.p[:b.nlp.fns.nc], t0=t0,
                            tf=att.tf, x_scale=num.x_scale)
    return run


def _link_values(mp: MultiPhaseProblem, phases: list[dict], theta) -> dict[str, dict]:
    """Each stated link's value at the solution's nodes, against its bounds (how exactly a jump holds)."""
    import casadi as ca

    from solvers.ocp.symbolic import to_sx

    ev = {}
    for p in phases:
        ev[("t0", p["name"])], ev[("tf", p["name"])] = ca.SX(p["t0"]), ca.SX(p["tf"])
        for k, tr in p["trajectory"].items():
            if k != "t":
                ev[("initial", k, p["name"])], ev[("final", k, p["name"])] = ca.SX(float(tr[0])), ca.SX(float(tr[-1]))
    env = {n: ca.SX(v) for n, v in mp.constants}
    env.update({q.name: ca.SX(float(theta[i])) for i, q in enumerate(mp.parameters)})
    out = {}
    for lk in mp.links:
        v = float(ca.evalf(to_sx(lk.expr, env, {t.name: t for t in mp.tables}, ev)))
        out[lk.name] = {"expr": lk.text, "value": v, "lower": lk.lower, "upper": lk.upper, "phases": list(lk.phases)}
    return out
