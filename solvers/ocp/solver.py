"""``solve(problem)``: one ``ocp`` phase transcribed, solved by IPOPT, re-flown and held to its limits.

Steps: the phase's SX functions (:mod:`solvers.ocp.symbolic`, cached per structure), the cached
NLP (:mod:`solvers.ocp.phase`), the numbers of this job (scales, bounds, parameters, the
guess: straight lines or a stored result interpolated onto the grid), IPOPT, the dense
re-propagation (:mod:`solvers.ocp.verify`), and, when a path constraint is exceeded between the
nodes, the tighten-and-re-solve rounds of :mod:`solvers.ocp.limits`.  Failures are values: the
solution's ``status.outcome`` says ``infeasible``, ``not_converged``, ``limit_not_held`` or
``cancelled`` with the solver's words kept.
"""
from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field

import numpy as np

from solvers.common import Outcome, ProgressFn, SolveStatus, StopFn
from solvers.ocp.limits import hold_path_limits
from solvers.ocp.phase import PhaseNLP, positive_scale
from solvers.ocp.spec import OcpProblem
from solvers.ocp.symbolic import PhaseFunctions, phase_functions
from solvers.ocp.terminal import (
    TERMINAL_ROUNDS,
    TERMINAL_TOLERANCE,
    grid_words,
    terminal_checks,
)
from solvers.ocp.verify import Verification, local_errors, verify

_FUNCTIONS: dict[tuple, PhaseFunctions] = {}
_FUNCTIONS_LOCK = threading.Lock()
TF_MIN_FRACTION = 1e-6
# Without ``accuracy``, re-flown states within 1% of their scale count as agreeing with the answer.
AGREEMENT_TOLERANCE = 1e-2      # a free phase lasts at least this fraction of its time scale


@dataclass
class OcpSolution:
    status: SolveStatus
    objective: float                      # in the user's sense (a maximum is reported as it is)
    sense: str
    t0: float
    tf: float
    initial: dict[str, float]
    final: dict[str, float]
    parameters: dict[str, float]
    trajectory: dict[str, np.ndarray]     # "t", every state, control and named expression at the nodes
    verification: dict
    solver: dict
    notes: list[str] = field(default_factory=list)
    # per interval, for refinement: "path" the worst scaled path excess, "state" a function giving the
    # scaled local errors (solvers.ocp.verify.local_errors: a second re-flight, run when asked)
    interval_errors: dict = field(default_factory=dict)


# A warm start (a stored result, a limit round) begins near the optimum: a small barrier and
# small pushes off the bounds keep IPOPT there (Betts shuttle 100 -> 150 intervals: 4 iterations
# instead of 19; brachistochrone 50 -> 80: 4 instead of 11 with IPOPT's defaults).
WARM_IPOPT = {"mu_init": 1e-4, "bound_push": 1e-6, "bound_frac": 1e-6}


def reset_caches() -> None:
    """Forget the symbolic functions (benchmarks time a cold build with this and
    :func:`solvers.transcription.nlp.clear_cache`)."""
    from solvers.ocp.symbolic import table_function
    with _FUNCTIONS_LOCK:
        _FUNCTIONS.clear()
    table_function.cache_clear()


def functions_of(problem: OcpProblem) -> PhaseFunctions:
    """The phase's SX functions, built once per structure (grid aside) in this process."""
    key = problem.structure()[:-1]          # the functions do not depend on the grid
    with _FUNCTIONS_LOCK:
        fns = _FUNCTIONS.get(key)
    if fns is None:
        fns = phase_functions(problem)
        with _FUNCTIONS_LOCK:
            if len(_FUNCTIONS) > 32:
                _FUNCTIONS.clear()
            _FUNCTIONS[key] = fns
    return fns


@dataclass
class Numbers:
    """The numbers of one job on a built structure: parameter vector, bounds, scales."""

    p: np.ndarray
    lbz: np.ndarray
    ubz: np.ndarray
    lbg: np.ndarray
    ubg: np.ndarray
    x_scale: np.ndarray
    u_scale: np.ndarray
    t_scale: float
    theta_scale: np.ndarray
    path_scale: np.ndarray
    path_slices: slice | None


def _scales(problem: OcpProblem, tf_guess: float):
    ph = problem.phase
    xs = np.array([s.scale or positive_scale(s.lower, s.upper, s.initial, s.final) for s in ph.states])
    us = np.array([k.scale or positive_scale(k.lower, k.upper) for k in ph.controls])
    ts = positive_scale(ph.time.initial, tf_guess, ph.time.final_upper)
    ths = np.array([positive_scale(q.lower, q.upper, q.guess) for q in problem.parameters])
    return xs, us, ts, ths


def numbers_of(problem: OcpProblem, nlp: PhaseNLP, tf_guess: float) -> Numbers:
    ph, g = problem.phase, nlp.grid
    N, Nu = g.n_nodes, g.n_controls
    xs, us, ts, ths = _scales(problem, tf_guess)
    t0 = ph.time.initial
    inf = np.inf

    def lo(v):
        return -inf if v is None else v

    def hi(v):
        return inf if v is None else v

    if ph.time.final is not None:
        tf_lb = tf_ub = ph.time.final
    else:
        tf_lb = max(lo(ph.time.final_lower), t0 + TF_MIN_FRACTION * ts)
        tf_ub = hi(ph.time.final_upper)
    x_lb = np.tile(np.array([lo(s.lower) for s in ph.states])[:, None], (1, N))
    x_ub = np.tile(np.array([hi(s.upper) for s in ph.states])[:, None], (1, N))
    for i, s in enumerate(ph.states):
        if s.initial is not None:
            x_lb[i, 0] = x_ub[i, 0] = s.initial
        if s.final is not None:
            x_lb[i, -1] = x_ub[i, -1] = s.final
    u_lb = np.tile(np.array([lo(k.lower) for k in ph.controls]).reshape(-1, 1), (1, Nu))
    u_ub = np.tile(np.array([hi(k.upper) for k in ph.controls]).reshape(-1, 1), (1, Nu))
    th_lb = np.array([lo(q.lower) for q in problem.parameters])
    th_ub = np.array([hi(q.upper) for q in problem.parameters])

    def pack(tf, th, x, u):
        return np.concatenate([[tf / ts], np.asarray(th, float) / ths,
                               (x / xs[:, None]).ravel(order="F"), (u / us[:, None]).ravel(order="F")])

    path_scale = np.array([positive_scale(c.lower, c.upper) for c in ph.path])
    bnd_scale = np.array([positive_scale(c.lower, c.upper) for c in ph.boundary])
    c = np.array([v for _, v in problem.constants])
    p = np.concatenate([c, [t0], xs, us, [ts], ths, path_scale, bnd_scale, [1.0]])
    lbg, ubg, path_slice, i = [], [], None, 0
    for name, n in nlp.layout:
        if name == "defects":
            lbg.append(np.zeros(n))
            ubg.append(np.zeros(n))
        elif name == "path":
            path_slice = slice(i, i + n)
            lbg.append(np.tile([lo(k.lower) / s for k, s in zip(ph.path, path_scale)], N))
            ubg.append(np.tile([hi(k.upper) / s for k, s in zip(ph.path, path_scale)], N))
        else:
            lbg.append(np.array([lo(k.lower) / s for k, s in zip(ph.boundary, bnd_scale)]))
            ubg.append(np.array([hi(k.upper) / s for k, s in zip(ph.boundary, bnd_scale)]))
        i += n
    nlp.pack = pack
    return Numbers(p=p, lbz=pack(tf_lb, th_lb, x_lb, u_lb), ubz=pack(tf_ub, th_ub, x_ub, u_ub),
                   lbg=np.concatenate(lbg), ubg=np.concatenate(ubg), x_scale=xs, u_scale=us,
                   t_scale=ts, theta_scale=ths, path_scale=path_scale, path_slices=path_slice)


def _interp_rows(tau_new, tau_old, rows) -> np.ndarray:
    return np.vstack([np.interp(tau_new, tau_old, r) for r in rows]) if len(rows) else np.zeros((0, tau_new.size))


def guess_of(problem: OcpProblem, grid, initial_guess: dict | None = None):
    """``(tf, theta, X (nx, N), U (nu, Nu))`` physical: a stored result interpolated onto the grid,
    else straight lines between the ends the problem fixes (or its guess, or the bounds' middle)."""
    ph = problem.phase
    tau = grid.tau()
    tau_u = tau if grid.n_controls == grid.n_nodes else tau[:-1]
    t0 = ph.time.initial
    if initial_guess:
        traj = initial_guess["trajectory"]
        t_old = np.asarray(traj["t"], float)
        tf = float(initial_guess.get("tf", t_old[-1])) if ph.time.final is None else ph.time.final
        s_old = (t_old - t_old[0]) / max(t_old[-1] - t_old[0], 1e-300)
        X = _interp_rows(tau, s_old, [np.asarray(traj[s.name], float) for s in ph.states])
        U = _interp_rows(tau_u, s_old, [np.asarray(traj[k.name], float) for k in ph.controls])
        stored = initial_guess.get("parameters") or {}
        theta = np.array([float(stored.get(q.name, _mid(q.lower, q.upper, q.guess))) for q in problem.parameters])
        return tf, theta, X, U
    gs = ph.guess
    if ph.time.final is not None:
        tf = ph.time.final
    elif gs.tf is not None:
        tf = gs.tf
    elif ph.time.final_guess is not None:
        tf = ph.time.final_guess
    else:
        lo, hi = ph.time.final_lower, ph.time.final_upper
        tf = 0.5 * (lo + hi) if lo is not None and hi is not None else (hi if hi is not None else t0 + 1.0)
    rows = []
    for s in ph.states:
        if s.name in gs.states:
            a, b = gs.states[s.name]
        else:
            mid = _mid(s.lower, s.upper, None)
            a = s.initial if s.initial is not None else (s.final if s.final is not None else mid)
            b = s.final if s.final is not None else a
        rows.append(a + (b - a) * tau)
    X = np.vstack(rows)
    urows = []
    for k in ph.controls:
        a, b = gs.controls.get(k.name, (_mid(k.lower, k.upper, None),) * 2)
        urows.append(a + (b - a) * tau_u)
    U = np.vstack(urows) if urows else np.zeros((0, tau_u.size))
    theta = np.array([_mid(q.lower, q.upper, q.guess) for q in problem.parameters])
    return tf, theta, X, U


def _mid(lo, hi, guess) -> float:
    if guess is not None:
        return guess
    if lo is not None and hi is not None:
        return 0.5 * (lo + hi)
    if lo is not None:
        return max(lo, 0.0) if lo <= 0 else lo
    if hi is not None:
        return min(hi, 0.0)
    return 0.0


class Attempt:
    """One IPOPT solve on the phase NLP, unpacked into physical arrays."""

    def __init__(self, nlp: PhaseNLP, num: Numbers, res):
        self.res = res
        self.status = res.status
        z = res.x
        fns, g = nlp.fns, nlp.grid
        i = 1 + fns.ntheta
        j = i + fns.nx * g.n_nodes
        self.tf = float(z[0]) * num.t_scale
        self.theta = z[1:i] * num.theta_scale
        self.X = z[i:j].reshape((fns.nx, g.n_nodes), order="F") * num.x_scale[:, None]
        self.U = z[j:].reshape((fns.nu, g.n_controls), order="F") * num.u_scale[:, None]


def solve(problem: OcpProblem, *, initial_guess: dict | None = None, on_progress: ProgressFn | None = None,
          should_stop: StopFn | None = None, seed: int | None = None, ipopt: dict | None = None) -> OcpSolution:
    """Solve one phase (module docstring).  ``initial_guess``: a stored ``ocp`` result (its
    ``trajectory``, ``tf`` and ``parameters``) interpolated onto this grid.  ``seed`` is accepted
    for the common protocol; nothing here is random.  A final value missed on the re-flight is
    solved again on a finer grid (:mod:`solvers.ocp.terminal`), warm-started from the answer; with
    ``accuracy`` the grid is refined until the answer holds to it (:mod:`solvers.ocp.refine`)."""
    del seed
    from solvers.ocp import refine

    kw = {"on_progress": on_progress, "ipopt": ipopt}
    if problem.accuracy is not None:
        return refine.solve_refined(problem, solve_on_grid=_solve_on_grid, initial_guess=initial_guess,
                                    should_stop=should_stop, **kw)
    return refine.solve_terminal(problem, solve_on_grid=_solve_on_grid, initial_guess=initial_guess,
                                 should_stop=should_stop, rounds=TERMINAL_ROUNDS, **kw)


def _solve_on_grid(problem: OcpProblem, *, initial_guess, on_progress, should_stop, ipopt) -> OcpSolution:
    progress = on_progress or (lambda f, m: None)
    t_start = time.perf_counter()
    progress(0.0, "building the NLP")
    fns = functions_of(problem)
    if ipopt is None and initial_guess:
        ipopt = WARM_IPOPT
    nlp = PhaseNLP(problem, fns, ipopt=ipopt)
    grid = nlp.grid
    tf_g, th_g, X_g, U_g = guess_of(problem, grid, initial_guess)
    num = numbers_of(problem, nlp, tf_g)
    build_time = time.perf_counter() - t_start
    z0 = np.clip(nlp.pack(tf_g, th_g, X_g, U_g), num.lbz, num.ubz)
    res = nlp.solver.solve(x0=z0, lbx=num.lbz, ubx=num.ubz, lbg=num.lbg, ubg=num.ubg, p=num.p,
                           on_progress=on_progress, should_stop=should_stop, progress_span=(0.02, 0.9))
    att = Attempt(nlp, num, res)
    notes: list[str] = []
    ver = verify_attempt(problem, nlp, num, att)
    rounds = []
    if att.status.ok and fns.npath and not ver.limits_held and ver.ok:
        progress(0.92, "tightening path limits violated between the nodes")
        warm = PhaseNLP(problem, fns, ipopt={**(ipopt or {}), **WARM_IPOPT})
        att, ver, rounds = hold_path_limits(problem=problem, nlp=warm, num=num, attempt=att, verification=ver,
                                            verify=lambda a: verify_attempt(problem, nlp, num, a),
                                            make_attempt=lambda r: Attempt(nlp, num, r),
                                            should_stop=should_stop)
    status = att.status
    total_iters = res.status.iterations + sum(r["iterations"] for r in rounds)
    status.iterations = total_iters
    status.build_time_s = build_time if not nlp.was_cached else 0.0
    status.solve_time_s = res.status.solve_time_s + sum(r["solve_time_s"] for r in rounds)
    if status.ok and not ver.ok:
        status.outcome = Outcome.FAILED
        status.message += f"; {ver.message}"
    elif status.ok and not ver.limits_held:
        status.outcome = Outcome.LIMIT_NOT_HELD
        worst = {k: v["excess_scaled"] for k, v in ver.path.items() if not v["held"]}
        status.message = (f"converged, but path limits are exceeded between the nodes after {len(rounds)} "
                          f"tightening rounds: worst scaled excess {worst}")
    terminal = terminal_checks(problem=problem, fns=fns, x_scale=num.x_scale, c=num.p[:fns.nc], theta=att.theta,
                               tf=att.tf, x=ver.x, u=ver.u) if ver.ok else {}
    terminal_held = all(c["held"] for c in terminal.values())
    if status.ok and not terminal_held:
        status.outcome = Outcome.TERMINAL_NOT_HELD
        missed = {k: f"{v['miss']:.3g} (tolerance {v['tolerance']:.3g})" for k, v in terminal.items() if not v["held"]}
        status.message = (f"converged on {grid_words(problem)}, but the re-flight misses terminal conditions: "
                          f"{missed}")
    status.details = {**status.details, "limit_rounds": rounds, "solver_cached": nlp.was_cached}
    agreement = problem.accuracy or AGREEMENT_TOLERANCE
    worst = max(ver.max_scaled_difference.values(), default=0.0)
    agrees = bool(ver.ok and worst <= agreement)
    if ver.ok and not agrees:
        notes.append(f"the re-flown controls depart from the transcription's states by {worst:.3g} (scaled), "
                     f"more than {agreement:g}: the grid is too coarse for this problem (or the optimizer "
                     "exploits the discretization, as free controls at every collocation node can); "
                     "refine the grid or use multiple shooting")
    if rounds:
        notes.append(f"path limits tightened on the intervals where the dense re-propagation exceeded "
                     f"them: {len(rounds)} round(s), limits {'held' if ver.limits_held else 'NOT held'}")
    progress(1.0, status.outcome.value)
    sol = solution_of(problem, nlp, num, att, ver, status, notes)
    sol.verification.update(agrees=agrees, agreement_tolerance=agreement, terminal=terminal,
                            terminal_held=terminal_held, terminal_tolerance=TERMINAL_TOLERANCE)
    sol.interval_errors = {"path": np.max(ver.interval_excess, axis=0) if ver.interval_excess else None,
                           "state": lambda: _local_errors(problem, nlp, num, att)}    # on demand
    return sol


def verify_attempt(problem: OcpProblem, nlp: PhaseNLP, num: Numbers, att: Attempt) -> Verification:
    ph = problem.phase
    t0 = ph.time.initial
    t_nodes = t0 + (att.tf - t0) * nlp.grid.tau()
    return verify(fns=nlp.fns, grid=nlp.grid, t_nodes=t_nodes, X=att.X, U=nlp.node_controls(att.U),
                  theta=att.theta, c=num.p[:nlp.fns.nc], t0=t0, tf=att.tf,
                  state_names=ph.state_names, x_scale=num.x_scale,
                  path_bounds=[(c.lower, c.upper) for c in ph.path],
                  path_names=[c.name for c in ph.path], path_scale=num.path_scale)


def _local_errors(problem: OcpProblem, nlp: PhaseNLP, num: Numbers, att: Attempt) -> np.ndarray:
    t0 = problem.phase.time.initial
    return local_errors(fns=nlp.fns, grid=nlp.grid, t_nodes=t0 + (att.tf - t0) * nlp.grid.tau(), X=att.X,
                        U=nlp.node_controls(att.U), theta=att.theta, c=num.p[:nlp.fns.nc], t0=t0, tf=att.tf,
                        x_scale=num.x_scale)


def solution_of(problem, nlp, num, att, ver, status, notes) -> OcpSolution:
    ph, fns, g = problem.phase, nlp.fns, nlp.grid
    t0 = ph.time.initial
    t = t0 + (att.tf - t0) * g.tau()
    Un = nlp.node_controls(att.U)
    c = num.p[:fns.nc]
    traj = {"t": t}
    traj.update({s.name: att.X[i] for i, s in enumerate(ph.states)})
    traj.update({k.name: Un[i] for i, k in enumerate(ph.controls)})
    if ph.expressions:
        E = np.asarray(fns.named.map(t.size)(t[None, :], att.X, Un, att.theta, c, t0, att.tf))
        traj.update({n: E[i] for i, (n, _) in enumerate(ph.expressions)})
    # The NLP minimizes sign * (mayer + integral) with objective scale 1: undo the sign only.
    objective = float(nlp.sign * att.res.f)
    solver = {"method": g.method, "intervals": g.intervals,
              "control": g.control if g.method == "multiple_shooting" else "polynomial",
              "substeps": g.substeps if g.method == "multiple_shooting" else None,
              "nodes_per_interval": g.nodes if g.method == "lgl" and g.segment_nodes is None else None,
              "boundaries": None if g.boundaries is None else list(g.boundaries),
              "segment_nodes": None if g.segment_nodes is None else list(g.segment_nodes),
              "iterations": status.iterations, "status": status.solver_status,
              "outcome": status.outcome.value, "message": status.message,
              "build_time_s": status.build_time_s, "solve_time_s": status.solve_time_s,
              "cached_build": nlp.was_cached,
              "max_constraint_violation": status.max_constraint_violation,
              "limit_rounds": status.details.get("limit_rounds", [])}
    return OcpSolution(status=status, objective=objective, sense=problem.objective.sense, t0=t0, tf=att.tf,
                       initial={s.name: float(att.X[i, 0]) for i, s in enumerate(ph.states)},
                       final={s.name: float(att.X[i, -1]) for i, s in enumerate(ph.states)},
                       parameters={q.name: float(att.theta[i]) for i, q in enumerate(problem.parameters)},
                       trajectory=traj, verification=ver.as_dict(), solver=solver, notes=notes)
