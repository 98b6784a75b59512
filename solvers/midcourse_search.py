"""NSGA-II over midcourse correction times (paper 002): the search of :mod:`solvers.midcourse`.

pymoo's NSGA-II (Deb et al. 2002) with a vectorized binary tournament, a hash-based
duplicate elimination and no history, which keeps its own bookkeeping small, driven
by pymoo's ``ask``/``tell`` so that our loop owns termination and cancellation; the
repair that keeps a schedule sorted, spaced and in bounds; the non-dominated filter
and the normalized hypervolume of a front.
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Callable

import numpy as np

from solvers.common import ProgressFn, StopFn

if TYPE_CHECKING:
    from solvers.midcourse import MidcourseProblem


def repair_schedule(times: np.ndarray, *, lower: float, upper: float, spacing: float) -> np.ndarray:
    """Sort each row and push times apart to ``spacing`` while keeping them in bounds.

    A forward pass enforces ``t_i >= max(lower, t_{i-1} + spacing)``, then a backward
    pass ``t_i <= min(upper, t_{i+1} - spacing)``; together they keep the order and
    the spacing whenever ``(k - 1) * spacing <= upper - lower`` (checked by the caller).
    """
    x = np.sort(np.clip(np.asarray(times, dtype=float), lower, upper), axis=1)
    k = x.shape[1]
    for i in range(1, k):
        x[:, i] = np.maximum(x[:, i], x[:, i - 1] + spacing)
    x[:, -1] = np.minimum(x[:, -1], upper)
    for i in range(k - 2, -1, -1):
        x[:, i] = np.minimum(x[:, i], x[:, i + 1] - spacing)
    return x


def hypervolume(objectives: np.ndarray, reference: tuple[float, float, float]) -> float:
    """Fraction of the box ``[0, reference]`` dominated by the points (0 to 1).

    Objectives are divided by the reference first so that m/s and m weigh alike;
    points outside the box contribute only their part inside it.
    """
    from pymoo.indicators.hv import HV

    f = np.asarray(objectives, float) / np.asarray(reference, float)
    f = f[np.all(f < 1.0, axis=1)]
    if f.size == 0:
        return 0.0
    return float(HV(ref_point=np.ones(3))(f))


def nondominated(f: np.ndarray) -> np.ndarray:
    """Indices of the non-dominated rows of f (minimization), O(n^2) vectorized."""
    le = np.all(f[:, None, :] <= f[None, :, :], axis=2)
    lt = np.any(f[:, None, :] < f[None, :, :], axis=2)
    dominated = np.any(le & lt, axis=0)
    return np.flatnonzero(~dominated)


def run_nsga2(problem: MidcourseProblem, ev: Callable[[np.ndarray], np.ndarray], *, seed: int,
              on_progress: ProgressFn, should_stop: StopFn):
    """NSGA-II over the correction times: ``(times, objectives)`` of the final non-dominated
    set, the generations run, and whether it was cancelled.

    ``ev(times (N, k)) -> objectives (N, 3)`` is any vectorized evaluator.  pymoo's
    ``ask``/``tell`` loop runs here, so this loop owns termination: it stops after the
    generation in which ``should_stop()`` turns true, with that population as the
    partial result.  The same seed gives the same front.
    """
    from pymoo.algorithms.moo.nsga2 import NSGA2
    from pymoo.core.duplicate import DuplicateElimination
    from pymoo.core.problem import Problem
    from pymoo.core.repair import Repair
    from pymoo.operators.crossover.sbx import SBX
    from pymoo.operators.mutation.pm import PM
    from pymoo.operators.survival.rank_and_crowding import RankAndCrowding
    from pymoo.operators.survival.rank_and_crowding.metrics import (
        FunctionalDiversity,
        calc_crowding_distance,
    )
    from pymoo.operators.selection.tournament import TournamentSelection

    lo, hi = map(float, problem.time_bounds)
    k = problem.corrections
    ga = problem.ga

    class TimesProblem(Problem):
        def __init__(self):
            super().__init__(n_var=k, n_obj=3, xl=lo, xu=hi, elementwise=False)

        def _evaluate(self, x, out, *args, **kwargs):
            out["F"] = ev(x)

    class SortAndSpace(Repair):
        def _do(self, prob, x, **kwargs):
            return repair_schedule(x, lower=lo, upper=hi, spacing=problem.min_spacing)

    class HashDuplicates(DuplicateElimination):
        """Duplicates are equal schedules to 1 microsecond: a set lookup, not pymoo's cdist."""

        @staticmethod
        def _keys(pop):
            return [tuple(r) for r in np.round(pop.get("X") * 1e6).astype(np.int64)]

        def _do(self, pop, other, is_duplicate):
            keys = self._keys(pop)
            seen = set() if other is None else set(self._keys(other))
            for i, key in enumerate(keys):
                if key in seen:
                    is_duplicate[i] = True
                elif other is None:
                    seen.add(key)
            return is_duplicate

    def tournament(pop, P, algorithm, **kwargs):
        # NSGA-II's binary tournament on rank then crowding (no constraints here),
        # vectorized: pymoo's default loops in Python over every pair.
        rank = pop.get("rank").astype(float)
        crowd = pop.get("crowding").astype(float)
        a, b = P[:, 0], P[:, 1]
        rs = algorithm.random_state
        pick_a = (rank[a] < rank[b]) | ((rank[a] == rank[b]) & (crowd[a] > crowd[b]))
        tie = (rank[a] == rank[b]) & (crowd[a] == crowd[b])
        pick_a = np.where(tie, rs.random(len(a)) < 0.5, pick_a)
        return np.where(pick_a, a, b)[:, None].astype(int)

    class LightNSGA2(NSGA2):
        def _set_optimum(self, **kwargs):
            # No constraints, so pymoo's per-individual feasibility scan is wasted work.
            self.opt = self.pop[self.pop.get("rank") == 0]

    algorithm = LightNSGA2(
        pop_size=ga.population,
        selection=TournamentSelection(func_comp=tournament),
        crossover=SBX(prob=ga.crossover_prob, eta=ga.crossover_eta),
        mutation=PM(prob=1.0, prob_var=ga.mutation_prob, eta=ga.mutation_eta),
        repair=SortAndSpace(),
        # Copies of a point get zero crowding distance, so they are dropped first.
        survival=RankAndCrowding(crowding_func=FunctionalDiversity(calc_crowding_distance,
                                                                   filter_out_duplicates=True)),
        eliminate_duplicates=HashDuplicates() if ga.eliminate_duplicates else False,
    )
    algorithm.setup(TimesProblem(), termination=("n_gen", ga.generations), seed=seed, verbose=False,
                    save_history=False)
    generation, cancelled = 0, False
    while algorithm.has_next():
        offspring = algorithm.ask()
        if offspring is not None:
            algorithm.evaluator.eval(algorithm.problem, offspring, algorithm=algorithm)
        algorithm.tell(infills=offspring)
        generation = int(algorithm.n_gen) - 1   # tell() has moved the counter on to the next generation
        on_progress(min(generation / ga.generations, 1.0), f"generation {generation}/{ga.generations}")
        if should_stop():
            cancelled = True
            break
    x, f = algorithm.pop.get("X"), algorithm.pop.get("F")
    idx = nondominated(f)
    return x[idx], f[idx], generation, cancelled
