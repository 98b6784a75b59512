"""The arc structure of a finite-thrust solution: coast, burn and free-throttle arcs,
their segments, how a warm start's burn windows become arcs, and how the structure
changes between rounds (a burn added where the switching function asks for one,
segments doubled where the re-propagation defects are large)."""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from solvers.intercept.thrust.problem import MeshOptions, Plan, Scaled
from solvers.transcription.lgl import Mesh

ARC_KINDS = ("coast", "burn", "free")
# ----------------------------------------------------------------------------- layout

@dataclass(frozen=True)
class Arc:
    """A stretch of the trajectory with one thrust law: coast, burn (full thrust) or free (throttle)."""

    kind: str        # "coast", "burn" or "free"
    segments: int


@dataclass(frozen=True)
class Layout:
    """Arcs, their (initial or fixed) durations as fractions of tf, LGL nodes per segment."""

    arcs: tuple[Arc, ...]
    sigma: tuple[float, ...]
    nodes: int
    free_durations: bool
    form: str = "integral"     # collocation form, see solvers.transcription.lgl

    @property
    def defect_nodes(self) -> int:
        """Collocation equations per segment and state."""
        return self.nodes - 1 if self.form == "integral" else self.nodes

    @property
    def arc_of_segment(self) -> list[int]:
        return [a for a, arc in enumerate(self.arcs) for _ in range(arc.segments)]

    @property
    def segments(self) -> int:
        return sum(arc.segments for arc in self.arcs)

    def count(self, *kinds: str) -> int:
        """Nodes on arcs of the given kinds."""
        return self.nodes * sum(arc.segments for arc in self.arcs if arc.kind in kinds)

    def mesh(self, sigma=None) -> Mesh:
        sig = np.maximum(np.asarray(self.sigma if sigma is None else sigma, float), 0.0)
        h = np.concatenate([[sig[a] / arc.segments] * arc.segments for a, arc in enumerate(self.arcs)])
        b = np.concatenate([[0.0], np.cumsum(h)])
        # zero-length arcs give repeated boundaries; keep them strictly increasing
        b = np.maximum.accumulate(b / b[-1] + np.arange(b.size) * 1e-12)
        return Mesh(tuple((b / b[-1]).tolist()), self.nodes)

    def key(self) -> tuple:
        return (self.arcs, self.nodes, self.free_durations, self.form)

    def throttle(self) -> np.ndarray:
        """Per node: 1 on burns, 0 on coasts, nan where the throttle is a variable."""
        val = {"coast": 0.0, "burn": 1.0, "free": np.nan}
        return np.repeat([val[self.arcs[a].kind] for a in self.arc_of_segment], self.nodes)


def layout_for(plan: Plan, opts: MeshOptions, s: Scaled) -> Layout:
    """The arcs of a plan's burn windows (or the paper's free-throttle segments), segment lengths from ``opts``."""
    if opts.structure == "free_throttle":
        return Layout((Arc("free", opts.segments),), (1.0,), opts.nodes, False, "differential")
    arcs, sigma, t = [], [], 0.0
    T = s.sc.time_s

    def add(kind, t0, t1):
        seg_s = opts.burn_segment_s if kind == "burn" else opts.coast_segment_s
        n = np.ceil((t1 - t0) * T / seg_s - 1e-9)
        arcs.append(Arc(kind, int(np.clip(n, 1, max(1, opts.max_segments // 4)))))
        sigma.append((t1 - t0) / plan.tf)

    for a, b in sorted(plan.windows):
        a, b = max(a, t), min(b, plan.tf)
        if b <= a:
            continue
        if a > t:
            add("coast", t, a)
        add("burn", a, b)
        t = b
    if t < plan.tf:
        add("coast", t, plan.tf)
    return Layout(tuple(arcs), tuple(sigma), opts.nodes, True)


def control_times(mesh: Mesh, tf: float) -> np.ndarray:
    """Node times nudged into their segment, so a control sampled at a segment
    edge comes from that segment's side of a switch."""
    b = np.asarray(mesh.boundaries)
    span = np.diff(b)[:, None]
    return np.clip(mesh.node_fractions(), b[:-1, None] + 1e-7 * span, b[1:, None] - 1e-7 * span).ravel() * tf


def missing_burn(layout: Layout, mesh: Mesh, X, U, tf, s: Scaled, lam) -> Layout | None:
    """A coast on which the switching function says the engine should be on
    gets a short burn at the switching function's peak (new layout), else None."""
    N = layout.nodes
    sw = np.linalg.norm(lam[3:6], axis=0) / X[6] + lam[6] / s.c
    interior = np.tile(np.r_[False, np.ones(N - 2, bool), False], layout.segments)
    top = max(float(np.max(np.abs(sw[interior]))), 1e-300)
    seg_arc = np.repeat(layout.arc_of_segment, N)
    t = mesh.node_fractions().ravel()
    best = None
    for a, arc in enumerate(layout.arcs):
        sel = interior & (seg_arc == a)
        if arc.kind != "coast" or not sel.any() or layout.sigma[a] < 1e-9:
            continue
        i = np.flatnonzero(sel)[np.argmax(sw[sel])]
        if sw[i] > 0.02 * top and (best is None or sw[i] > best[1]):
            best = (a, sw[i], t[i])
    if best is None:
        return None
    a, _, tc = best
    start = float(np.sum(np.asarray(layout.sigma)[:a]))
    end = start + layout.sigma[a]
    width = min(1e-3, 0.1 * (end - start))
    t0, t1 = max(start, tc - width / 2), min(end, tc + width / 2)
    arcs = list(layout.arcs)
    sig = list(layout.sigma)
    pieces = [(Arc("coast", max(1, round(layout.arcs[a].segments * (t0 - start) / (end - start)))), t0 - start),
              (Arc("burn", 1), t1 - t0),
              (Arc("coast", max(1, round(layout.arcs[a].segments * (end - t1) / (end - start)))), end - t1)]
    pieces = [p for p in pieces if p[1] > 1e-9]
    arcs[a:a + 1] = [p[0] for p in pieces]
    sig[a:a + 1] = [p[1] for p in pieces]
    return replace(layout, arcs=tuple(arcs), sigma=tuple(sig))


def refined_layout(layout: Layout, defects_m: np.ndarray, opts: MeshOptions) -> Layout | None:
    """Twice the segments on the arcs holding the large segment defects."""
    room = opts.max_segments - layout.segments
    if room <= 0:
        return None
    flag = defects_m >= 0.25 * float(np.max(defects_m))
    seg_arc = np.asarray(layout.arc_of_segment)
    arcs = list(layout.arcs)
    for a in sorted(set(seg_arc[flag].tolist()), key=lambda a: -float(np.max(defects_m[seg_arc == a]))):
        add = min(arcs[a].segments, room)
        if add <= 0:
            break
        arcs[a] = Arc(arcs[a].kind, arcs[a].segments + add)
        room -= add
    return replace(layout, arcs=tuple(arcs))


def without_short_arcs(layout: Layout, min_fraction: float) -> Layout | None:
    """The layout without arcs shorter than ``min_fraction`` of tf (None if there are none).

    The NLP may drive an arc's duration to its bound 0 (the paper case's first coast ended
    8 ns long, holding a whole segment of nodes): such an arc is no part of the answer.  Its
    (tiny) duration goes to a neighbour and neighbours of one kind merge, so the durations
    still sum to tf and the next solve, warm-started from this one, sees one switch fewer.
    """
    sig = np.asarray(layout.sigma, float)
    short = sig < min_fraction
    if not short.any() or short.all():
        return None
    arcs: list[Arc] = []
    sigma: list[float] = []
    carry = 0.0
    for arc, dur, drop in zip(layout.arcs, sig, short):
        if drop:
            if sigma:
                sigma[-1] += dur
            else:
                carry += dur
            continue
        if arcs and arcs[-1].kind == arc.kind:
            arcs[-1] = Arc(arc.kind, arcs[-1].segments + arc.segments)
            sigma[-1] += dur
        else:
            arcs.append(arc)
            sigma.append(dur + carry)
            carry = 0.0
    return replace(layout, arcs=tuple(arcs), sigma=tuple(sigma))
