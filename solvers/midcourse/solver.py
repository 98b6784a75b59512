"""Timing of midcourse corrections on an upper-stage transfer orbit (paper 002).

What this module is for: the ``midcourse`` job kind.  Zhang, Shi & Cui (2011,
"Research on optimization of midcourse correction time points of upper stage
transfer orbit via NSGA-II") fly an upper stage for ``T = 12900 s`` from an
erroneous initial state; at each correction time ``t_k`` it solves the
two-body Lambert problem (their eqs. (6)-(8)) from its current state to the
*nominal* target position at ``T`` and applies the impulse.  Coasts follow the
J2 dynamics of their eqs. (1)-(5) (:mod:`solvers.astro.j2`).  Three objectives
are minimized (eq. (9)): total delta-v, final position error and final velocity
error; NSGA-II (Deb et al. 2002) searches the correction times.

Speed: the uncorrected erroneous trajectory is propagated once with Taylor dense
output, so the state at the first correction of every candidate is an
interpolation; each later coast is a SIMD-batched heyoka propagation of the
whole population, and the Lambert problems are solved vectorized over it.
The search itself (NSGA-II, repair, hypervolume) is :mod:`solvers.midcourse.search`.

The Monte Carlo option draws the initial error from a zero-mean Gaussian with
the given 3-sigma per axis; each candidate is then evaluated on the same
samples (common random numbers) and the GA minimizes the mean or a percentile
over samples.
"""
from __future__ import annotations

import time

import numpy as np

from solvers.astro.j2 import J2Propagator
from solvers.common import Outcome, ProgressFn, SolveStatus, StopFn, never_stop, noop_progress
from solvers.midcourse.problem import MidcourseProblem, MidcourseSolution, ScheduleResult
from solvers.midcourse.search import hypervolume, nondominated, run_nsga2

# A candidate whose Lambert problem does not converge gets these objective
# values: finite (pymoo and JSON dislike inf) and dominated by every real point.
PENALTY = np.array([1.0e6, 1.0e12, 1.0e6])
_MIRROR = np.array([-1.0, 1.0, 1.0])


def _triple(v) -> tuple[float, float, float]:
    a, b, c = v
    return (float(a), float(b), float(c))


class CorrectionEvaluator:
    """Objectives of correction schedules, vectorized over schedules and error samples."""

    def __init__(self, problem: MidcourseProblem):
        from solvers.astro.lambert import lambert

        self._lambert = lambert
        self.p = problem
        self.frame = problem.frame
        self.mu = problem.constants.mu
        self.tf = float(problem.tf_s)
        self.prop = J2Propagator(problem.frame.spin_axis, problem.constants, problem.tol)
        r0 = np.asarray(problem.r0, float) + self.frame.r0
        v0 = np.asarray(problem.v0, float)
        self.r_target = np.asarray(problem.r_target, float) + self.frame.r0
        self.v_target = np.asarray(problem.v_target, float)
        dr = np.asarray(problem.position_error, float)
        dv = np.asarray(problem.velocity_error, float)
        if problem.dispersion is None:
            offsets = np.concatenate([dr, dv])[None, :]
        else:
            rng = np.random.default_rng(problem.dispersion.seed)
            sigma = np.abs(np.concatenate([dr, dv])) / 3.0
            offsets = rng.standard_normal((problem.dispersion.samples, 6)) * sigma
        self.initial = np.concatenate([r0, v0])[None, :] + offsets        # (S, 6) geocentric
        self.samples = self.initial.shape[0]
        self.prop.warm_up()
        nominal_end = self.prop.propagate(np.concatenate([r0, v0])[None, :], t0=0.0, t1=self.tf)[0]
        self.nominal_miss = (float(np.linalg.norm(nominal_end[:3] - self.r_target)),
                             float(np.linalg.norm(nominal_end[3:] - self.v_target)))
        # Dense output of each sample's uncorrected coast: the state at the first
        # correction is then an evaluation, not a propagation.
        self._dense = [self.prop.dense(s, t0=0.0, t1=self.tf) for s in self.initial]
        self.evaluations = 0
        self.lambert_failures = 0
        self.time_s = 0.0

    def _impulse(self, r: np.ndarray, v: np.ndarray, tof: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Lambert impulse to the nominal target, on the branch closest to the current velocity.

        Both zero-revolution branches are solved in one vectorized call: mirroring
        x -> -x reverses the z part of r1 x r2, so the retrograde arc of (r1, r2) is
        the mirror image of the prograde arc of the mirrored pair.  One call of 2N
        rows instead of two of N halves the per-call overhead, which dominates at
        population sizes of ~100.
        """
        n = r.shape[0]
        target = np.broadcast_to(self.r_target, r.shape)
        sol = self._lambert(self.mu, np.concatenate([r, r * _MIRROR]),
                            np.concatenate([target, target * _MIRROR]), np.concatenate([tof, tof]),
                            revolutions=0, prograde=True)
        v1 = np.asarray(sol.v1, float).reshape(2 * n, 3)
        v1[n:] *= _MIRROR
        conv = np.asarray(sol.converged, bool).reshape(-1) & np.all(np.isfinite(v1), axis=1)
        dv = v1 - np.concatenate([v, v])
        cost = np.where(conv, np.linalg.norm(np.where(conv[:, None], dv, 0.0), axis=1), np.inf)
        retro = cost[n:] < cost[:n]
        best = np.where(retro[:, None], dv[n:], dv[:n])
        ok = conv[:n] | conv[n:]
        return np.where(ok[:, None], best, 0.0), ok

    def evaluate_samples(self, times: np.ndarray, *, keep_impulses: bool = False):
        """Objectives per schedule and sample: (N, S, 3), and impulses (N, S, k, 3) if asked."""
        t_start = time.perf_counter()
        times = np.atleast_2d(np.asarray(times, dtype=float))
        n, k = times.shape
        s_count = self.samples
        # Row m = schedule m // S, sample m % S.
        if k == 0:
            states = np.repeat(np.stack([d(np.array([self.tf]))[0] for d in self._dense])[None],
                               n, axis=0).reshape(n * s_count, 6)
        else:
            states = np.stack([d(times[:, 0]) for d in self._dense], axis=1).reshape(n * s_count, 6)
        t_rows = np.repeat(times, s_count, axis=0)
        total_dv = np.zeros(n * s_count)
        ok = np.ones(n * s_count, dtype=bool)
        impulses = np.zeros((n * s_count, k, 3))
        for j in range(k):
            tj = t_rows[:, j]
            dv, conv = self._impulse(states[:, :3], states[:, 3:], self.tf - tj)
            ok &= conv
            states[:, 3:] += dv
            total_dv += np.linalg.norm(dv, axis=1)
            impulses[:, j] = dv
            t_next = t_rows[:, j + 1] if j + 1 < k else np.full(n * s_count, self.tf)
            states = self.prop.propagate(states, t0=tj, t1=t_next)
        f = np.stack([total_dv,
                      np.linalg.norm(states[:, :3] - self.r_target, axis=1),
                      np.linalg.norm(states[:, 3:] - self.v_target, axis=1)], axis=1)
        bad = ~ok | ~np.all(np.isfinite(f), axis=1)
        f[bad] = PENALTY
        self.lambert_failures += int(np.count_nonzero(bad))
        self.evaluations += n
        self.time_s += time.perf_counter() - t_start
        f = f.reshape(n, s_count, 3)
        if keep_impulses:
            return f, impulses.reshape(n, s_count, k, 3)
        return f

    def statistics(self, f: np.ndarray) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
        """(objectives minimized, mean, percentile), each (N, 3), from per-sample values (N, S, 3)."""
        d = self.p.dispersion
        if d is None:
            return f[:, 0], None, None
        mean = f.mean(axis=1)
        pct = np.percentile(f, d.percentile, axis=1)
        return (mean if d.statistic == "mean" else pct), mean, pct

    def __call__(self, times: np.ndarray) -> np.ndarray:
        return self.statistics(self.evaluate_samples(times))[0]


def solve(problem: MidcourseProblem, *, initial_guess=None, on_progress: ProgressFn | None = None,
          should_stop: StopFn | None = None, seed: int | None = None) -> MidcourseSolution:
    """Evaluate the given schedules or optimize the correction times with NSGA-II.

    ``initial_guess`` is unused (the GA samples its own population); ``seed``
    drives the GA and defaults to 1.
    """
    del initial_guess
    on_progress = on_progress or noop_progress
    should_stop = should_stop or never_stop
    t_start = time.perf_counter()
    ev = CorrectionEvaluator(problem)
    build_s = time.perf_counter() - t_start
    sol = MidcourseSolution(status=SolveStatus(Outcome.OPTIMAL), nominal_miss=ev.nominal_miss,
                            hypervolume_reference=_triple(problem.hypervolume_reference))
    f0 = ev.evaluate_samples(np.zeros((1, 0)))
    sol.uncorrected = ev.statistics(f0)[0][0]
    ev.evaluations = 0          # count only the schedules asked for or searched

    cancelled = False
    if problem.mode == "evaluate":
        for i, sched in enumerate(problem.schedules):
            if should_stop():
                cancelled = True
                break
            t = np.asarray(sched, float)[None, :]
            failures_before = ev.lambert_failures
            f, imp = ev.evaluate_samples(t, keep_impulses=True)
            obj, mean, pct = ev.statistics(f)
            sol.schedules.append(ScheduleResult(
                times=t[0], objectives=obj[0],
                mean=None if mean is None else mean[0],
                percentile=None if pct is None else pct[0],
                impulses=imp[0, 0] if ev.samples == 1 else None,
                lambert_failures=ev.lambert_failures - failures_before))
            on_progress((i + 1) / len(problem.schedules), f"schedule {i + 1}/{len(problem.schedules)}")
        if sol.schedules:
            objs = np.array([s.objectives for s in sol.schedules])
            sol.hypervolume = hypervolume(objs[nondominated(objs)], problem.hypervolume_reference)
        sol.evaluations = ev.evaluations
    else:
        sol.seed = 1 if seed is None else int(seed)
        x, f, gens, cancelled = run_nsga2(problem, ev, seed=sol.seed, on_progress=on_progress,
                                          should_stop=should_stop)
        order = np.lexsort(f.T[::-1])           # by delta-v, then position error
        x, f = x[order], f[order]
        sol.pareto_times, sol.pareto_objectives = x, f
        sol.evaluations = ev.evaluations
        if problem.dispersion is not None and len(x):
            # Re-evaluate the front to report both statistics (same samples, so exact).
            _, sol.pareto_mean, sol.pareto_percentile = ev.statistics(ev.evaluate_samples(x))
        sol.hypervolume = hypervolume(f, problem.hypervolume_reference)
        sol.generations = int(gens)

    sol.seed = sol.seed if problem.mode == "optimize" else seed
    sol.lambert_failures = ev.lambert_failures
    sol.evaluation_time_s = ev.time_s
    total = time.perf_counter() - t_start
    if cancelled:
        outcome, msg = Outcome.CANCELLED, "cancelled by request; partial result"
    else:
        outcome, msg = Outcome.OPTIMAL, "NSGA-II finished" if problem.mode == "optimize" else "schedules evaluated"
    sol.status = SolveStatus(outcome, solver_status="cancelled" if cancelled else "finished", message=msg,
                             iterations=sol.generations, build_time_s=build_s,
                             solve_time_s=total - build_s,
                             details={"lambert_failures": ev.lambert_failures})
    return sol
