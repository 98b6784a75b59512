"""Mesh refinement to a stated accuracy: the error model, the splitting rules and the loop.

Generic over the transcription and the kind: a *mesh* is interval boundaries on normalized time
``[0, 1]`` and, for LGL collocation, the nodes of each interval (:class:`Mesh`); a *trial* is one
solve on one mesh with its independent re-propagation.  The ``ocp`` kind (:mod:`solvers.ocp.refine`)
and the ``reentry`` kind (:mod:`solvers.reentry.refine`) drive :func:`refine` with their own
``solve`` and ``plan``; a multi-phase problem drives it with a tuple of meshes (one per phase) and a
``plan`` that refines each phase's mesh from its own interval errors.

The error model (what a ``solve`` reports per interval)
    ``interval_error[k]``: the worst, over the states, of ``|x_reflown - x_nlp| / scale`` on interval
    ``k`` when the re-propagation is *restarted* at the interval's first node (its local error: what
    that interval's discretization adds); ``max_error``: the same with the re-propagation
    continuous from the initial state (the global error, which the result's verification reports
    and the accuracy is judged on).  Intervals share the accuracy by their length (an error
    density, Hairer-Norsett-Wanner's per-unit-step control): interval ``k`` of fraction ``w_k`` of
    the horizon meets its share when ``e_k <= target * w_k``; then the local errors sum to at most
    ``target``.  Where the global error exceeds the sum of the local ones (the dynamics amplify
    them) the target is lowered by that factor (:func:`round_target`).

The splitting rules
    * multiple shooting (:func:`split_shooting`): the local error of an interval integrated by a
      method of order ``p`` (RK4: 4) falls as ``h^(p+1)``, its density as ``h^p``; an interval that
      misses is split into ``n = ceil((e / (target w))^(1/p))`` equal parts, at least 2 and at most
      ``max_split``;
    * LGL collocation (:func:`refine_lgl`, the ph method of Patterson, Hager & Rao, "A ph mesh
      refinement method for optimal control", OCAM 36(4), 2015, as GPOPS-II): an interval of degree
      ``N`` that misses by ``r = e / (target w)`` needs ``P = ceil(log(r) / log(N))`` more degrees
      where its error decays exponentially with the degree (a smooth solution); when ``N + P`` stays
      within ``n_max - 1`` the degree is raised (p), else the interval is split (h) into
      ``max(2, ceil((N + P) / N_min))`` intervals of the minimum degree.  An interval whose degree
      was raised in the previous round without its error falling by the predicted factor decays
      slowly (a kink or a switch inside): it is split instead.

The loop (:func:`refine`)
    ``solve(mesh, previous) -> trial`` builds, solves (warm from ``previous``, a trial or None) and
    verifies on ``mesh``; ``accept(trial) -> bool`` says the accuracy (and whatever else: limits that
    hold, terminal values) is reached; ``plan(mesh, trial, history) -> mesh | None`` proposes the next
    mesh (None: nothing left to refine).  A trial exposes ``converged`` (bool), ``max_error``,
    ``objective``, ``iterations`` and ``intervals`` (and optionally ``error``, the one the best round is
    chosen by, and ``record()``, more fields of its round's record).  The loop stops when a trial is accepted, when
    ``max_rounds`` refinements are spent, when a solve does not converge, when ``plan`` gives up
    or ``should_stop()``; it returns every round's record and the best trial (the accepted one, else
    the converged one with the smallest error).
"""
from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

SAFETY = 0.8          # aim under the accuracy, so one round usually suffices
RK4_ORDER = 4


@dataclass(frozen=True)
class Mesh:
    """Interval boundaries on ``[0, 1]`` (first 0, last 1, increasing) and, for LGL, the nodes of
    each interval (``None`` for multiple shooting)."""

    boundaries: tuple[float, ...]
    nodes: tuple[int, ...] | None = None

    def __post_init__(self):
        b = np.asarray(self.boundaries, float)
        if b.size < 2 or b[0] != 0.0 or b[-1] != 1.0 or np.any(np.diff(b) <= 0.0):
            raise ValueError("mesh boundaries must increase strictly from 0 to 1")
        if self.nodes is not None and len(self.nodes) != b.size - 1:
            raise ValueError("one node count per interval")

    @classmethod
    def uniform(cls, intervals: int, nodes: int | None = None) -> Mesh:
        b = np.linspace(0.0, 1.0, intervals + 1)
        b[0], b[-1] = 0.0, 1.0
        return cls(tuple(b.tolist()), None if nodes is None else (nodes,) * intervals)

    @property
    def intervals(self) -> int:
        return len(self.boundaries) - 1

    @property
    def node_counts(self) -> tuple[int, ...]:
        """The LGL nodes of each interval (a multiple-shooting mesh has none)."""
        if self.nodes is None:
            raise ValueError("a multiple-shooting mesh has no LGL nodes")
        return self.nodes

    @property
    def widths(self) -> np.ndarray:
        return np.diff(np.asarray(self.boundaries, float))

    def is_uniform(self) -> bool:
        w = self.widths
        same_nodes = self.nodes is None or len(set(self.nodes)) == 1
        return bool(same_nodes and np.allclose(w, w[0], rtol=1e-12, atol=0.0))


def misses(errors: ArrayLike, widths: ArrayLike, target: float) -> np.ndarray:
    """Per interval, how many times its share ``target * width`` its error is (> 1: it misses)."""
    e = np.asarray(errors, float)
    share = target * np.asarray(widths, float)
    return np.where(np.isfinite(e), e / share, np.inf)


def round_target(accuracy: float, max_error: float, interval_errors: Sequence[float]) -> float:
    """The target of the next round's summed local errors: ``SAFETY * accuracy`` divided by the
    ratio of the global error to the sum of the local ones (above 1: the dynamics amplify them;
    below 1: they partly cancel, counted down to a half)."""
    total = float(np.sum(np.asarray(interval_errors, float)))
    amplification = max_error / total if total > 0.0 and math.isfinite(max_error) else 1.0
    return SAFETY * accuracy / max(0.5, amplification)


def equidistributed_error(errors, target: float, *, order: int = RK4_ORDER) -> float:
    """The local error ``delta`` every interval of the refined mesh should have so that they sum to
    ``target`` with the fewest intervals: splitting interval ``k`` into ``n_k`` parts leaves each part
    ``e_k / n_k^(order+1)``; the fewest parts for a given sum make the parts' errors equal
    (``n_k ~ e_k^(1/(order+1))``), hence ``delta = (target / sum e_k^(1/(order+1)))^((order+1)/order)``."""
    e = np.asarray(errors, float)
    q = order + 1.0
    s = float(np.sum(np.power(e[np.isfinite(e)], 1.0 / q)))
    return (target / s) ** (q / order) if s > 0.0 else target


def split_counts(errors, widths, target: float, *, order: int = RK4_ORDER, max_split: int = 8) -> np.ndarray:
    """Parts each interval is split into so that the local errors sum to at most ``target`` with the
    fewest intervals (multiple shooting, a method of ``order``: an interval cut in ``n`` keeps
    ``e / n^order``): one part at a time goes to the interval whose error it lowers most (greedy,
    optimal for this convex separable allocation, and it lands on :func:`equidistributed_error`'s
    ``n ~ e^(1/(order+1))``), at most ``max_split`` parts; an unknown error gets ``max_split``.
    ``widths`` is unused (the local error already carries the interval's length)."""
    import heapq

    del widths
    e = np.asarray(errors, float)
    n = np.ones(e.size, int)
    n[~np.isfinite(e)] = max_split
    finite = np.where(np.isfinite(e), e, 0.0)
    total = float(np.sum(finite))
    delta = equidistributed_error(e, target, order=order)      # an interval below it is fine as it is
    gain = [(-(v - v / 2.0 ** order), k) for k, v in enumerate(finite) if v > delta and n[k] < max_split]
    heapq.heapify(gain)
    while total > target and gain:
        g, k = heapq.heappop(gain)
        total += g
        n[k] += 1
        if n[k] < max_split:
            nxt = finite[k] / n[k] ** order - finite[k] / (n[k] + 1.0) ** order
            heapq.heappush(gain, (-nxt, k))
    return n


def subdivide(boundaries: ArrayLike, counts: Sequence[int] | np.ndarray) -> tuple[float, ...]:
    """The boundaries with interval ``k`` cut into ``counts[k]`` equal parts."""
    b = np.asarray(boundaries, float)
    out = [0.0]
    for k, n in enumerate(counts):
        out += list(b[k] + (b[k + 1] - b[k]) * np.arange(1, n + 1) / n)
    out[-1] = 1.0
    return tuple(float(v) for v in out)


def split_shooting(mesh: Mesh, errors, target: float, *, order: int = RK4_ORDER, max_split: int = 8,
                   force: Sequence[int] = ()) -> Mesh | None:
    """Multiple shooting: split the intervals that miss (module docstring); ``force``: intervals split in
    two whatever their error (a path limit exceeded there).  None when nothing misses."""
    n = split_counts(errors, mesh.widths, target, order=order, max_split=max_split)
    for k in force:
        n[k] = max(n[k], 2)
    if np.all(n == 1):
        return None
    return Mesh(subdivide(mesh.boundaries, n))


def refine_lgl(mesh: Mesh, errors, target: float, *, n_min: int = 4, n_max: int = 12,
               previous: dict | None = None, force: Sequence[int] = ()) -> Mesh | None:
    """LGL: raise the degree (p) or split (h) each interval that misses (module docstring).

    ``previous``: ``{(a, b): (nodes, error)}`` of the last round's intervals by their boundaries,
    so an interval whose degree was raised without the predicted gain is split instead.
    None when nothing misses."""
    r = misses(errors, mesh.widths, target)
    b = np.asarray(mesh.boundaries, float)
    new_b, new_n, changed = [0.0], [], False
    for k, nk in enumerate(mesh.node_counts):
        degree = nk - 1
        if r[k] <= 1.0 and k not in force:
            new_b.append(float(b[k + 1]))
            new_n.append(nk)
            continue
        changed = True
        ratio = r[k] if math.isfinite(r[k]) and r[k] > 1.0 else float(n_max) ** 2
        extra = max(1, math.ceil(math.log(ratio) / math.log(max(degree, 2))))
        slow = False
        prev = (previous or {}).get((round(b[k], 12), round(b[k + 1], 12)))
        if prev is not None and prev[0] < nk:
            # the degree went prev[0] -> nk; exponential decay predicted a gain of degree^(added)
            gained = prev[1] / max(float(errors[k]), 1e-300)
            slow = gained < float(max(prev[0] - 1, 2)) ** (nk - prev[0]) / 10.0
        if k not in force and not slow and degree + extra <= n_max - 1:
            new_b.append(float(b[k + 1]))
            new_n.append(nk + extra)
        else:
            parts = max(2, math.ceil((degree + extra) / max(n_min - 1, 1)))
            parts = min(parts, 8)
            cut = b[k] + (b[k + 1] - b[k]) * np.arange(1, parts + 1) / parts
            new_b += [float(v) for v in cut]
            new_n += [n_min] * parts
    if not changed:
        return None
    new_b[-1] = 1.0
    return Mesh(tuple(new_b), tuple(new_n))


def lgl_history(mesh: Mesh, errors) -> dict:
    """What :func:`refine_lgl` wants as ``previous`` from this round."""
    b = mesh.boundaries
    return {(round(b[k], 12), round(b[k + 1], 12)): (mesh.node_counts[k], float(errors[k]))
            for k in range(mesh.intervals)}


def uniform_count(intervals: int, errors, target: float, *, order: int = RK4_ORDER,
                  max_factor: int = 8, max_intervals: int | None = None) -> int | None:
    """For a transcription that keeps equal intervals: the interval count whose local errors sum to
    ``target`` (``errors`` on ``intervals`` equal intervals; refining all by ``F`` leaves
    ``sum(e) / F^order``), at most ``max_factor`` times more; None when they already do or the
    cap is reached."""
    e = np.asarray(errors, float)
    total = float(np.sum(e)) if np.all(np.isfinite(e)) else math.inf
    if total <= target:
        return None
    factor = (total / target) ** (1.0 / order) if math.isfinite(total) else max_factor
    n = int(min(intervals * max_factor, max(intervals + 1, math.ceil(intervals * factor))))
    if max_intervals is not None:
        n = min(n, max_intervals)
    return n if n > intervals else None


@dataclass
class RefineResult:
    best: Any                          # the accepted trial, else the converged one with the least error
    last: Any
    rounds: list[dict] = field(default_factory=list)
    reached: bool = False
    stopped: str = ""                  # why the loop ended without reaching the accuracy


def record(k: int, trial, seconds: float) -> dict:
    """One round of ``solver.refinement``."""
    err = float(trial.max_error)
    out = {"round": k, "intervals": int(trial.intervals), "max_error": err if math.isfinite(err) else None,
           "objective": float(trial.objective) if trial.objective is not None else None,
           "iterations": int(trial.iterations), "time_s": round(seconds, 4)}
    extra = getattr(trial, "record", None)      # a kind's own estimates of the round (the ocp kind's)
    if callable(extra):
        out.update(extra())
    return out


def refine(*, mesh, solve: Callable, accept: Callable, plan: Callable, max_rounds: int,
           should_stop: Callable | None = None, previous=None) -> RefineResult:
    """Solve, verify and refine until ``accept`` (module docstring).  ``previous``: the warm start of
    the first solve (passed to ``solve`` as is)."""
    rounds: list[dict] = []
    history: list = []
    best, trial, reached, stopped = None, None, False, ""
    for k in range(max_rounds + 1):
        t0 = time.perf_counter()
        trial = solve(mesh, previous if k == 0 else trial)
        rounds.append(record(k, trial, time.perf_counter() - t0))
        history.append((mesh, trial))
        if trial.converged and (best is None or _better(trial, best)):
            best = trial
        if not trial.converged:
            stopped = "the solve on the refined mesh did not converge" if k else "the first solve did not converge"
            break
        if accept(trial):
            best, reached = trial, True
            break
        if should_stop is not None and should_stop():
            stopped = "cancelled"
            break
        if k == max_rounds:
            stopped = f"max_refinements ({max_rounds}) spent"
            break
        nxt = plan(mesh, trial, history)
        if nxt is None:
            stopped = "no interval left to refine within the limits"
            break
        mesh = nxt
    return RefineResult(best=best if best is not None else trial, last=trial, rounds=rounds,
                        reached=reached, stopped=stopped)


def _better(a, b) -> bool:
    """``a`` has the smaller error: its ``error`` when the trial has one (all its estimates), else its
    re-flight's ``max_error``."""
    ea, eb = float(getattr(a, "error", a.max_error)), float(getattr(b, "error", b.max_error))
    if not math.isfinite(eb):
        return True
    return math.isfinite(ea) and ea < eb
