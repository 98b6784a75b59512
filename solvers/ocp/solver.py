"""``solve(problem)``: an ``ocp`` problem transcribed, solved by IPOPT, re-flown, held to its limits, refined.

:class:`OcpSolve` owns the loop, the same for one phase and several (a problem posed as one phase is
the one-phase case): on one grid (:meth:`OcpSolve.on_grid`) it builds the NLP
(:class:`solvers.ocp.trajectory.TrajectoryNLP`, cached per structure), places every phase's numbers
(:mod:`solvers.ocp.scaling`: scales, bounds, parameters) and guess (:mod:`solvers.ocp.guess`:
straight lines, a stored result or the previous round, interpolated onto the grid), runs IPOPT,
checks every phase on its own (:mod:`solvers.ocp.check`: the dense re-flight, limits, terminal
values), and when a path constraint is exceeded between the nodes runs the tighten-and-re-solve
rounds (:meth:`OcpSolve.hold_limits`, :mod:`solvers.ocp.limits`); around that, the grid is refined
(:mod:`solvers.ocp.refine`): to ``accuracy`` when asked, else only on a missed final value.
Failures are values: the solution's ``status.outcome`` says ``infeasible``, ``not_converged``,
``limit_not_held``, ``terminal_not_held``, ``accuracy_not_reached`` or ``cancelled`` with the
solver's words kept; an optimal answer whose necessary conditions of optimality fail
(:mod:`solvers.ocp.optimality`) is ``optimality_not_verified``, still a usable answer.
"""
from __future__ import annotations

import time

import numpy as np

from solvers.common import Outcome, ProgressFn, StopFn
from solvers.ocp.check import AGREEMENT_TOLERANCE, check_phase
from solvers.ocp.costates import multipliers_of
from solvers.ocp.flown import flown_guess, rk4_stiffness
from solvers.ocp.guess import guess_of, stored_phases
from solvers.ocp.limits import MAX_ROUNDS, Margins, worst_excess
from solvers.ocp.problem import OcpProblem
from solvers.ocp.refine import Refinement
from solvers.ocp.scaling import numbers_of
from solvers.ocp.stages import PLAN, REFINED_PLAN
from solvers.ocp.solution import OcpSolution, solution_of
from solvers.ocp.terminal import TERMINAL_ROUNDS, grid_words
from solvers.ocp.trajectory import TrajectoryNLP
from solvers.ocp.violations import INVALID_NUMBER, name_them
from solvers.progress import Progress

__all__ = ["AGREEMENT_TOLERANCE", "TERMINAL_ROUNDS", "WARM_IPOPT", "OcpSolution", "OcpSolve", "solve"]

# A warm start (a stored result, a limit round) begins near the optimum: a small barrier and
# small pushes off the bounds keep IPOPT there (Betts shuttle 100 -> 150 intervals: 4 iterations
# instead of 19; brachistochrone 50 -> 80: 4 instead of 11 with IPOPT's defaults).
WARM_IPOPT = {"mu_init": 1e-4, "bound_push": 1e-6, "bound_frac": 1e-6}
# An overflow this early is the guess's doing (the straight lines, not where IPOPT went): fly one instead.
EARLY_ITERATIONS = 3


class Placed:
    """An NLP with every phase's numbers placed in its vectors: the start, bounds and parameters."""

    def __init__(self, problem: OcpProblem, nlp: TrajectoryNLP, initial_guess: dict | None):
        stored = stored_phases(problem, initial_guess)
        self.z0, self.lbz, self.ubz = np.zeros(nlp.nz), np.full(nlp.nz, -np.inf), np.full(nlp.nz, np.inf)
        p, lbg, ubg, self.nums = [], [], [], []
        for ph, b in zip(problem.phases, nlp.blocks):
            old = stored.get(ph.name)
            warm = None if old is None else {**old, "parameters": (initial_guess or {}).get("parameters")}
            tf_g, th_g, X_g, U_g = guess_of(b.problem, b.nlp.grid, warm)
            num = numbers_of(b.problem, b.nlp, tf_g)
            lb, ub = num.lbz.copy(), num.ubz.copy()
            if b.t0_col is not None:       # a phase of several: its window bounds its ends
                ts, t = num.t_scale, ph.time
                lo_t0 = t.initial if t.initial is not None else t.initial_lower
                hi_t0 = t.initial if t.initial is not None else t.initial_upper
                lo_tf = t.final if t.final is not None else t.final_lower
                hi_tf = t.final if t.final is not None else t.final_upper
                lb[0] = -np.inf if lo_tf is None else lo_tf / ts
                ub[0] = np.inf if hi_tf is None else hi_tf / ts
                self.lbz[b.t0_col] = -np.inf if lo_t0 is None else lo_t0 / ts
                self.ubz[b.t0_col] = np.inf if hi_t0 is None else hi_t0 / ts
                t0_g = float(old["t0"]) if old is not None else b.problem.time.initial
                self.z0[b.t0_col] = t0_g / ts
            self.lbz[b.colmap], self.ubz[b.colmap] = lb, ub
            self.z0[b.colmap] = b.nlp.pack(tf_g, th_g, X_g, U_g)     # theta: every phase's guess is the same
            p.append(num.p)
            lbg.append(num.lbg)
            ubg.append(num.ubg)
            self.nums.append(num)
        elo, ehi, lscale = nlp.event_bounds()
        self.p = np.concatenate(p + [lscale])
        self.lbg, self.ubg = np.concatenate(lbg + [elo]), np.concatenate(ubg + [ehi])
        self.z0 = np.clip(self.z0, self.lbz, self.ubz)
        offsets = np.cumsum([0] + [len(n.lbg) for n in self.nums])
        # each phase's path rows in g, for the limit rounds
        self.path_rows = [(None if n.path_slices is None else slice(o + n.path_slices.start, o + n.path_slices.stop),
                           len(b.problem.path), b.nlp.grid) for n, b, o in zip(self.nums, nlp.blocks, offsets)]


class OcpSolve:
    """One solve of an :class:`OcpProblem` (module docstring): ``OcpSolve(problem, ...).run()``."""

    def __init__(self, problem: OcpProblem, *, initial_guess: dict | None = None,
                 on_progress: ProgressFn | None = None, should_stop: StopFn | None = None,
                 ipopt: dict | None = None):
        self.problem, self.initial_guess = problem, initial_guess
        self.should_stop, self.ipopt = should_stop, ipopt
        self.progress = Progress(on_progress, PLAN if problem.accuracy is None else REFINED_PLAN)

    def run(self) -> OcpSolution:
        """Refined to ``accuracy`` when the problem asks, else only on a final value missed."""
        refinement = Refinement(self)
        if self.problem.accuracy is not None:
            sol = refinement.to_accuracy()
        else:
            sol = refinement.terminal(TERMINAL_ROUNDS)
        self.progress.stage("answer")
        _judge_optimality(sol)
        self.progress.done(sol.status.outcome.value)
        return sol

    # -- one grid ---------------------------------------------------------------------------------
    def on_grid(self, problem: OcpProblem, initial_guess: dict | None,
                progress: Progress | None = None, ipopt: dict | None = None) -> OcpSolution:
        """Build, solve, check every phase and hold the path limits, on the grid ``problem`` has; each
        announced as a stage of ``progress`` (a refinement round's nested stages; None: the job's own);
        ``ipopt``: IPOPT's options on this grid where the solve has none of its own (None: the warm
        start's for a warm guess, else IPOPT's defaults)."""
        progress = progress or self.progress
        t_start = time.perf_counter()
        n = len(problem.phases)
        progress.stage("build", message="building the NLP" if problem.single else f"building the NLP of {n} phases")
        ipopt = own = self.ipopt if self.ipopt is not None else ipopt
        if ipopt is None and initial_guess and "start" not in initial_guess:   # a varied start is not near an optimum
            ipopt = WARM_IPOPT
        nlp = TrajectoryNLP(problem, ipopt=ipopt)
        placed = Placed(problem, nlp, initial_guess)
        build_time = time.perf_counter() - t_start
        assert nlp.solver is not None  # a TrajectoryNLP is built with its solver
        res = nlp.solver.solve(x0=placed.z0, lbx=placed.lbz, ubx=placed.ubz, lbg=placed.lbg, ubg=placed.ubg,
                               p=placed.p, on_progress=progress.stage("solve"), should_stop=self.should_stop)
        if res.status.solver_status == INVALID_NUMBER and res.status.iterations <= EARLY_ITERATIONS:
            nlp, placed, res = self.fly_first(problem, nlp, initial_guess, res, progress, own)
        status = res.status
        first = (status.iterations, status.solve_time_s)
        progress.stage("verification", message="re-flying the controls")
        checks = self.check(problem, nlp, placed, res)
        rounds: list[dict] = []
        if status.ok and all(c.ok for c in checks) and not all(c.limits_held for c in checks):
            warm = TrajectoryNLP(problem, ipopt={**(ipopt or {}), **WARM_IPOPT})
            res, checks, rounds = self.hold_limits(problem, nlp, warm, placed, res, checks, progress)
            status = res.status
        status.iterations = first[0] + sum(r["iterations"] for r in rounds)
        status.solve_time_s = first[1] + sum(r["solve_time_s"] for r in rounds)
        status.build_time_s = build_time if not nlp.was_cached else 0.0
        status.details = {**status.details, "limit_rounds": rounds, "solver_cached": nlp.was_cached}
        name_them(status, problem, nlp, checks, placed.nums)     # IPOPT's own failure, by the user's names
        _judge(status, checks, rounds, problem)
        return solution_of(problem, nlp=nlp, res=res, status=status, checks=checks, rounds=rounds)

    def fly_first(self, problem: OcpProblem, nlp: TrajectoryNLP, initial_guess: dict | None, res, progress,
                  ipopt: dict | None):
        """An overflow at the guess or in the first iterates: once more from the dynamics flown from the
        guess (:mod:`solvers.ocp.flown`), with IPOPT's cold start; ``(nlp, placed, res)`` of that solve,
        whether or not it overflows too (its ``guess_recovery`` details then carry what the flight showed:
        the RK4 stiffness along it)."""
        first = res
        progress.stage("solve", message="the guess overflowed: flying the dynamics for a better one")
        cold = TrajectoryNLP(problem, ipopt=ipopt)
        flown, notes = flown_guess(problem, cold, initial_guess)
        placed = Placed(problem, cold, flown)
        assert cold.solver is not None  # a TrajectoryNLP is built with its solver
        again = cold.solver.solve(x0=placed.z0, lbx=placed.lbz, ubx=placed.ubz, lbg=placed.lbg, ubg=placed.ubg,
                                  p=placed.p, should_stop=self.should_stop, label="from the flown guess")
        stopped = [n for n in notes if n["stopped_at_t"] is not None]
        recovery = {"guess": "flown", "first_iterations": first.status.iterations,
                    "flight_stopped": stopped, "status": again.status.solver_status}
        if again.status.solver_status == INVALID_NUMBER:
            stiff = rk4_stiffness(problem, cold, flown)
            if stiff is not None:
                recovery["rk4_stiffness"] = stiff
        again.status.iterations += first.status.iterations
        again.status.details = {**again.status.details, "guess_recovery": recovery}
        return cold, placed, again

    def check(self, problem: OcpProblem, nlp: TrajectoryNLP, placed: Placed, res) -> list:
        """Every phase of the answer ``res`` checked on its own (:func:`solvers.ocp.check.check_phase`)."""
        agreement = problem.accuracy or AGREEMENT_TOLERANCE     # with accuracy, the states must agree to it
        out = []
        mults = multipliers_of(nlp, res, placed.p, placed.lbz, placed.ubz)
        for b, num, mult in zip(nlp.blocks, placed.nums, mults):
            t0 = b.problem.phase.time.initial if b.t0_col is None else float(res.x[b.t0_col] * num.t_scale)
            out.append(check_phase(b, num, res.x[b.colmap], t0=t0, agreement=agreement, single=problem.single,
                                   mult=mult))
        return out

    def hold_limits(self, problem, nlp, warm, placed: Placed, res, checks, progress: Progress):
        """The tighten-and-re-solve rounds (:mod:`solvers.ocp.limits`): ``(res, checks, rounds)`` of the
        best answer."""
        margins = Margins(placed.path_rows)
        best = (worst_excess(checks), res, checks)
        rounds: list[dict] = []
        for k in range(1, MAX_ROUNDS + 1):
            if all(c.limits_held for c in checks) or (self.should_stop is not None and self.should_stop()):
                break
            lbg, ubg = margins.tighten(checks, placed.lbg, placed.ubg)
            r = warm.solver.solve(x0=res.x, lbx=placed.lbz, ubx=placed.ubz, lbg=lbg, ubg=ubg, p=placed.p,
                                  lam_x0=res.lam_x, lam_g0=res.lam_g, should_stop=self.should_stop,
                                  expected_iterations=15, label=f"limit round {k}",
                                  on_progress=progress.stage("limit", round=k))
            rounds.append({"round": k, "status": r.status.solver_status, "iterations": r.status.iterations,
                           "solve_time_s": r.status.solve_time_s, **margins.words()})
            if not r.status.ok:
                break
            res, checks = r, self.check(problem, nlp, placed, r)
            worst = worst_excess(checks)
            rounds[-1]["worst_excess_scaled"] = worst
            held = all(c.limits_held for c in checks)
            if held or worst < best[0]:
                best = (worst, res, checks)
            if held:
                break
        _, res, checks = best
        return res, checks, rounds


def _judge(status, checks, rounds: list[dict], problem: OcpProblem) -> None:
    """A converged solve whose re-flight fails, exceeds a limit or misses a final value says so."""
    if not status.ok:
        return
    if not all(c.ok for c in checks):
        status.outcome = Outcome.FAILED
        status.message += "; " + "; ".join(c.label + c.verification.message for c in checks if not c.ok)
    elif not all(c.limits_held for c in checks):
        status.outcome = Outcome.LIMIT_NOT_HELD
        worst = {f"{c.label}{k}": v["excess_scaled"] for c in checks for k, v in c.verification.path.items()
                 if not v["held"]}
        status.message = (f"converged, but path limits are exceeded between the nodes after {len(rounds)} "
                          f"tightening rounds: worst scaled excess {worst}")
    elif not all(c.terminal_held for c in checks):
        status.outcome = Outcome.TERMINAL_NOT_HELD
        missed = {f"{c.label}{k}": f"{v['miss']:.3g} (tolerance {v['tolerance']:.3g})" for c in checks
                  for k, v in c.terminal.items() if not v["held"]}
        grids = ", ".join(f"{c.label}{grid_words(ph.problem)}" for c, ph in zip(checks, problem.phases))
        status.message = f"converged on {grids}, but the re-flight misses terminal conditions: {missed}"


def _judge_optimality(sol: OcpSolution) -> None:
    """An optimal answer whose necessary conditions of optimality fail is served, its outcome saying so."""
    if sol.status.outcome is not Outcome.OPTIMAL:
        return
    failed = []
    for p in sol.phases:
        opt = p["verification"].get("optimality") or {}
        if opt.get("held") is False:
            label = "" if sol.single else f"phase {p['name']}: "
            failed.append(label + ", ".join(k for k, v in opt["checks"].items() if not v["held"]))
    if failed:
        sol.status.outcome = Outcome.OPTIMALITY_NOT_VERIFIED
        sol.status.message += "; optimality not verified: " + "; ".join(failed) + " (verification.optimality)"


def solve(problem: OcpProblem, *, initial_guess: dict | None = None, on_progress: ProgressFn | None = None,
          should_stop: StopFn | None = None, seed: int | None = None, ipopt: dict | None = None) -> OcpSolution:
    """Solve (module docstring), the common protocol.  ``initial_guess``: a stored ``ocp`` result of the
    same form (one phase: its ``trajectory``, ``tf`` and ``parameters``; several: its ``phases`` by
    name) interpolated onto this grid.  ``seed`` is accepted for the protocol; nothing here is random."""
    del seed
    return OcpSolve(problem, initial_guess=initial_guess, on_progress=on_progress, should_stop=should_stop,
                    ipopt=ipopt).run()
