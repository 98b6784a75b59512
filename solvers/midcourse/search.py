"""NSGA-II over midcourse correction times (paper 002): the search of :mod:`solvers.midcourse`.

NSGA-II (Deb et al. 2002) on plain arrays (:mod:`solvers.midcourse.nsga2`; pymoo's per-individual
bookkeeping was two thirds of the paper run), driven by our loop so that it owns termination and
cancellation; the repair that keeps a schedule sorted, spaced and in bounds; the non-dominated
filter and the normalized hypervolume of a front (pymoo's HV).
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Callable

import numpy as np

from solvers.common import ProgressFn, StopFn

if TYPE_CHECKING:
    from solvers.midcourse.problem import MidcourseProblem


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

    ``ev(times (N, k)) -> objectives (N, 3)`` is any vectorized evaluator.  The loop
    (:func:`solvers.midcourse.nsga2.nsga2`) owns termination: it stops after the generation in
    which ``should_stop()`` turns true, with that population as the partial result.  The same
    seed gives the same front.
    """
    from solvers.midcourse.nsga2 import Operators, nsga2

    lo, hi = map(float, problem.time_bounds)
    ga = problem.ga
    state = {"cancelled": False, "copies": 0}

    def after_generation(gen: int) -> bool:
        on_progress(min(gen / ga.generations, 1.0), f"generation {gen}/{ga.generations}")
        state["cancelled"] = bool(should_stop())
        return bool(state["cancelled"])

    # With the paper's rates a third of the offspring are exact copies of a parent (no crossover,
    # or crossover on no variable, and no mutation): their objectives are known, so only new
    # schedules reach the evaluator (the same numbers; the evaluator is deterministic).
    known: dict[bytes, np.ndarray] = {}

    def evaluate(x: np.ndarray) -> np.ndarray:
        keys = [row.tobytes() for row in x]
        new = {}
        for i, key in enumerate(keys):
            if key not in known and key not in new:
                new[key] = i
        if new:
            f_new = np.asarray(ev(x[list(new.values())]), float)
            known.update(zip(new, f_new))
        state["copies"] += len(keys) - len(new)
        return np.array([known[key] for key in keys])

    x, f, generation = nsga2(
        evaluate, variables=problem.corrections, bounds=(lo, hi), population=ga.population, generations=ga.generations,
        ops=Operators(crossover_prob=ga.crossover_prob, mutation_prob=ga.mutation_prob,
                      crossover_eta=ga.crossover_eta, mutation_eta=ga.mutation_eta),
        repair=lambda t: repair_schedule(t, lower=lo, upper=hi, spacing=problem.min_spacing),
        seed=seed, after_generation=after_generation, unique=ga.eliminate_duplicates)
    if hasattr(ev, "evaluations"):
        ev.evaluations += state["copies"]     # the count stays that of the schedules the search asked for
    idx = nondominated(f)
    return x[idx], f[idx], generation, state["cancelled"]
