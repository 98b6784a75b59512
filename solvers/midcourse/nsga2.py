"""NSGA-II on plain arrays (Deb, Pratap, Agarwal & Meyarivan 2002), the search of paper 002's
midcourse kind: binary tournament on rank and crowding, simulated binary crossover (SBX),
polynomial mutation, a repair, elitist survival by non-dominated rank and crowding distance.

Why not pymoo's NSGA2: it keeps every individual as a Python object, and on the paper run
(100 x 500) its per-individual ``get``/``set`` bookkeeping took two thirds of the job (4 of
6 s here, against 2 s for all 50,000 trajectory evaluations).  Here a population is two
arrays, and each generation is a few vectorized operations on them.  The operators are
pymoo's own formulas (SBX with its bound-aware spread factor, each variable crossed with
probability 0.5; polynomial mutation with its bound-aware form), so the settings mean what
they meant; the random streams differ, so a seed gives a different (equally good) front.
Exact copies get zero crowding distance and go first at survival, as with pymoo's
``filter_out_duplicates``.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np


@dataclass(frozen=True)
class Operators:
    """NSGA-II settings: per-pair crossover and per-variable mutation probabilities, SBX and PM indices."""

    crossover_prob: float = 0.8
    mutation_prob: float = 0.1
    crossover_eta: float = 15.0
    mutation_eta: float = 20.0


def nondominated_ranks(f: np.ndarray, enough: int | None = None) -> np.ndarray:
    """Front index of each row of ``f`` (0: non-dominated), by peeling off fronts of the
    dominance matrix; once ``enough`` rows are ranked the rest get ``n`` (survival needs no more)."""
    n = f.shape[0]
    enough = n if enough is None else enough
    # objective by objective: numpy reduces a short last axis (np.all(..., axis=2)) slowly
    le = np.ones((n, n), bool)
    lt = np.zeros((n, n), bool)
    for j in range(f.shape[1]):
        col = f[:, j]
        le &= col[:, None] <= col[None, :]
        lt |= col[:, None] < col[None, :]
    dom = (le & lt).astype(np.int32)           # dom[i, j]: i dominates j
    count = dom.sum(axis=0)                    # how many dominate j
    rank = np.full(n, n)
    front = np.flatnonzero(count == 0)
    r, ranked = 0, 0
    while front.size:
        rank[front] = r
        ranked += front.size
        if ranked >= enough:
            break
        count -= dom[front].sum(axis=0)
        count[front] = -1
        front = np.flatnonzero(count == 0)
        r += 1
    return rank


def crowding(f: np.ndarray, rank: np.ndarray) -> np.ndarray:
    """Crowding distance within each ranked front (inf at a front's extremes, 0 for exact copies:
    copies of a point add nothing to the front's spread, so only the first keeps a distance).

    All fronts at once: per objective, one sort by (front, value); a point's gap is the distance
    between its neighbours in its front over the front's span (a loop over fronts cost as much
    as the rest of a generation, the population holding a dozen fronts or more)."""
    n, m = f.shape
    dist = np.zeros(n)
    order = np.lexsort(f.T[::-1])
    same = np.all(f[order[1:]] == f[order[:-1]], axis=1)
    dup = np.zeros(n, bool)
    dup[order[1:][same]] = True                # equal rows always share a front
    idx = np.flatnonzero((rank < n) & ~dup)
    if idx.size == 0:
        return dist
    r = rank[idx]
    pos = np.arange(idx.size)
    d = np.zeros(idx.size)
    for j in range(m):
        srt = np.lexsort((f[idx, j], r))
        v = f[idx[srt], j]
        fr = r[srt]
        change = fr[1:] != fr[:-1]
        first = np.empty(idx.size, bool)
        last = np.empty(idx.size, bool)
        first[0], first[1:] = True, change
        last[-1], last[:-1] = True, change
        start = np.maximum.accumulate(np.where(first, pos, 0))
        end = np.minimum.accumulate(np.where(last, pos, idx.size - 1)[::-1])[::-1]
        span = v[end] - v[start]
        gap = np.full(idx.size, np.inf)
        inner = np.flatnonzero(~(first | last))
        sp = span[inner]
        gap[inner] = np.where(sp > 0, (v[inner + 1] - v[inner - 1]) / np.where(sp > 0, sp, 1.0), 0.0)
        d[srt] += gap
    dist[idx] = d
    return dist


def survive(f: np.ndarray, size: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Indices of the ``size`` survivors (by rank, then crowding, larger first), and their ranks and crowding."""
    rank = nondominated_ranks(f, size)
    crowd = crowding(f, rank)
    order = np.lexsort((-crowd, rank))[:size]
    return order, rank[order], crowd[order]


def tournament(rank: np.ndarray, crowd: np.ndarray, count: int, rng: np.random.Generator) -> np.ndarray:
    """``count`` parents, each the better of two members (lower rank, then larger crowding; ties at
    random).  The competitors come from random permutations, so every member competes equally
    often, as in pymoo's tournament."""
    n = rank.size
    comp = np.concatenate([rng.permutation(n) for _ in range(-(-2 * count // n))])[:2 * count]
    a, b = comp[0::2], comp[1::2]
    pick_a = (rank[a] < rank[b]) | ((rank[a] == rank[b]) & (crowd[a] > crowd[b]))
    tie = (rank[a] == rank[b]) & (crowd[a] == crowd[b])
    pick_a = np.where(tie, rng.random(count) < 0.5, pick_a)
    return np.where(pick_a, a, b)


def sbx(p1: np.ndarray, p2: np.ndarray, lo: float, hi: float, ops: Operators, rng: np.random.Generator):
    """Simulated binary crossover of parent pairs (rows), bounded (pymoo's ``cross_sbx``)."""
    n, k = p1.shape
    eta = ops.crossover_eta
    do = (rng.random((n, 1)) < ops.crossover_prob) & (rng.random((n, k)) < 0.5)
    do &= np.abs(p1 - p2) > 1e-14
    y1, y2 = np.minimum(p1, p2), np.maximum(p1, p2)
    delta = np.where(do, y2 - y1, 1.0)
    u = rng.random((n, k))

    def child(beta):
        alpha = 2.0 - np.power(beta, -(eta + 1.0))
        small = u <= 1.0 / alpha
        betaq = np.where(small, np.power(np.maximum(u * alpha, 0.0), 1.0 / (eta + 1.0)),
                         np.power(1.0 / np.maximum(2.0 - u * alpha, 1e-300), 1.0 / (eta + 1.0)))
        return betaq

    bq1 = child(1.0 + 2.0 * (y1 - lo) / delta)
    bq2 = child(1.0 + 2.0 * (hi - y2) / delta)
    c1 = 0.5 * ((y1 + y2) - bq1 * delta)
    c2 = 0.5 * ((y1 + y2) + bq2 * delta)
    # which child inherits which side: at random, as in pymoo
    swap = rng.random((n, k)) < 0.5
    c1, c2 = np.where(swap, c2, c1), np.where(swap, c1, c2)
    c1 = np.clip(np.where(do, c1, p1), lo, hi)
    c2 = np.clip(np.where(do, c2, p2), lo, hi)
    return c1, c2


def polynomial_mutation(x: np.ndarray, lo: float, hi: float, ops: Operators, rng: np.random.Generator):
    """Bounded polynomial mutation of each variable with probability ``mutation_prob`` (pymoo's ``mut_pm``)."""
    eta = ops.mutation_eta
    do = rng.random(x.shape) < ops.mutation_prob
    span = hi - lo
    d1 = (x - lo) / span
    d2 = (hi - x) / span
    u = rng.random(x.shape)
    pw = 1.0 / (eta + 1.0)
    low = u <= 0.5
    val_lo = 2.0 * u + (1.0 - 2.0 * u) * np.power(1.0 - d1, eta + 1.0)
    val_hi = 2.0 * (1.0 - u) + 2.0 * (u - 0.5) * np.power(1.0 - d2, eta + 1.0)
    dq = np.where(low, np.power(np.maximum(val_lo, 0.0), pw) - 1.0, 1.0 - np.power(np.maximum(val_hi, 0.0), pw))
    return np.where(do, np.clip(x + dq * span, lo, hi), x)


def _duplicates(off: np.ndarray, pop: np.ndarray) -> np.ndarray:
    """Offspring rows equal (to 1e-6) to a population row or to an earlier offspring row."""
    seen = {tuple(r) for r in np.round(pop * 1e6).astype(np.int64)}
    out = np.zeros(off.shape[0], bool)
    for i, r in enumerate(np.round(off * 1e6).astype(np.int64)):
        key = tuple(r)
        out[i] = key in seen
        seen.add(key)
    return out


def nsga2(evaluate: Callable[[np.ndarray], np.ndarray], *, variables: int, bounds: tuple[float, float],
          population: int, generations: int, ops: Operators, repair: Callable[[np.ndarray], np.ndarray],
          seed: int, after_generation: Callable[[int], bool],
          unique: bool = False) -> tuple[np.ndarray, np.ndarray, int]:
    """Run NSGA-II: ``(X, F)`` of the last population and the generations run.

    Generation 1 is the random initial population (pymoo's count), each later one ``population``
    offspring.  ``after_generation(g)`` is called after each; True stops the search there (the
    caller's cancellation), with that population as the result.  ``unique``: offspring that
    copy a member or each other (to 1e-6) are mated again, up to 20 times.
    """
    lo, hi = map(float, bounds)
    rng = np.random.default_rng(seed)
    x = repair(rng.uniform(lo, hi, (population, variables)))
    f = np.asarray(evaluate(x), float)
    keep, rank, crowd = survive(f, population)
    x, f = x[keep], f[keep]
    gen = 1
    if after_generation(gen):
        return x, f, gen
    pairs = (population + 1) // 2
    while gen < generations:
        mates = tournament(rank, crowd, 2 * pairs, rng)
        c1, c2 = sbx(x[mates[:pairs]], x[mates[pairs:]], lo, hi, ops, rng)
        off = np.concatenate([c1, c2])[:population]
        off = repair(polynomial_mutation(off, lo, hi, ops, rng))
        for _ in range(20 if unique else 0):
            dup = _duplicates(off, x)
            if not dup.any():
                break
            # re-mate the offspring that copy a member or an earlier offspring (pymoo's re-mating)
            m = tournament(rank, crowd, 2 * int(dup.sum()), rng)
            c1, _ = sbx(x[m[::2]], x[m[1::2]], lo, hi, ops, rng)
            off[dup] = repair(polynomial_mutation(c1, lo, hi, ops, rng))
        f_off = np.asarray(evaluate(off), float)
        x_all, f_all = np.concatenate([x, off]), np.concatenate([f, f_off])
        keep, rank, crowd = survive(f_all, population)
        x, f = x_all[keep], f_all[keep]
        gen += 1
        if after_generation(gen):
            break
    return x, f, gen
