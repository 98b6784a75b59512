"""An ``ocp`` problem's phases as one NLP: each phase's block from :class:`solvers.ocp.phase.PhaseNLP`,
linked by events.

A problem posed as one phase (``OcpProblem.single``) is the one-phase case with nothing to link: its
initial time is fixed, its boundary conditions and its objective's Mayer term are the phase's own,
so its NLP is the phase's own NLP, cached per structure, and its block covers every column.

With several phases, every phase is transcribed by :class:`solvers.ocp.phase.PhaseNLP` (``build=False``: its
elements and layout on its own decision vector ``[tf, theta, X, U]``); this module places the
phases side by side in one decision vector ``[theta, (t0, tf, X, U) of phase 1, of phase 2, ...]``
(the parameters ``theta`` shared), gives each phase its own initial time as a decision variable
(the phase's elements read ``t0`` from their parameter vector: a wrapper substitutes the
variable), and adds one element of events over all phases: the default continuity of time and
of shared states between consecutive phases, each phase's positive duration, the ``links`` and
the objective's Mayer term.  The Jacobian and Hessian are assembled from the elements' SX blocks
as for one phase (:class:`solvers.ocp.phase.ElementBlocks`), so the NLP is sparse with exact
derivatives, and its solver is cached per structure.

Parameter vector: the phases' own parameter vectors one after the other (each as
:class:`PhaseNLP` lays it out, its ``t0`` entry unused), then the links' scales.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np

from solvers.ocp.phase import Element, PhaseNLP, positive_scale, solver_of_elements
from solvers.ocp.problem import OcpProblem, PhaseProblem
from solvers.ocp.symbolic import PhaseFunctions, functions_of, to_sx
from solvers.transcription.nlp import cached_solver

TF_MIN_FRACTION = 1e-6      # a phase lasts at least this fraction of its time scale


@dataclass
class Block:
    """One phase inside the problem's NLP: its phase NLP block and where it sits."""

    name: str
    problem: PhaseProblem
    nlp: PhaseNLP
    colmap: np.ndarray        # local column of the phase's z -> global column
    t0_col: int | None        # None: t0 is fixed (the one-phase case)
    p_slice: slice

    @property
    def ts_index(self) -> int:
        f = self.nlp.fns
        return self.p_slice.start + f.nc + 1 + f.nx + f.nu

    def global_cols(self, local) -> np.ndarray:
        return self.colmap[np.asarray(local, int)]


class TrajectoryNLP:
    """The assembled NLP of an :class:`OcpProblem` (module docstring)."""

    def __init__(self, mp: OcpProblem, *, ipopt: dict | None = None, functions: list[PhaseFunctions] | None = None,
                 structure: tuple | None = None, build: bool = True):
        """``functions``: each phase's SX functions when they are not the problem's own (the robust phases of
        :mod:`solvers.ocp.robust`, their events element then the subclass's), with ``structure`` the cache
        key's structure; ``build=False``: the blocks and layout only, no solver (an answer to check)."""
        self.mp = mp
        self.sign = -1.0 if mp.objective.sense == "maximize" else 1.0
        fns = functions or [functions_of(ph.problem) for ph in mp.phases]
        if mp.single:
            ph = mp.phases[0]
            nlp = PhaseNLP(ph.problem, fns[0], ipopt=ipopt, build=build, structure=structure)
            self.blocks: list[Block] = [Block(ph.name, ph.problem, nlp, np.arange(nlp.nz), None, slice(0, nlp.np_))]
            self.nz, self.np_, self.links_p = nlp.nz, nlp.np_, slice(nlp.np_, nlp.np_)
            self.solver, self.was_cached, self.layout = nlp.solver, nlp.was_cached, nlp.layout
            return
        nth = len(mp.parameters)
        self.blocks = []
        col, pos = nth, 0
        for ph, f in zip(mp.phases, fns):
            nlp = PhaseNLP(ph.problem, f, build=False)
            rest = nlp.nz - 1 - nth
            colmap = np.concatenate([[col + 1], np.arange(nth), col + 2 + np.arange(rest)]).astype(int)
            self.blocks.append(Block(ph.name, ph.problem, nlp, colmap, col, slice(pos, pos + nlp.np_)))
            col += 2 + rest
            pos += nlp.np_
        self.nz = col
        self.links_p = slice(pos, pos + len(mp.links))
        self.np_ = pos + len(mp.links)
        if not build:
            self.solver, self.was_cached = None, False
            self.layout = [(el.name, el.ny * el.count) for el in self._elements() if el.ny]
            return
        key = ("ocp-multiphase", structure or mp.structure(), tuple(sorted((ipopt or {}).items())))
        self.solver, self.was_cached = cached_solver(
            key, lambda: solver_of_elements(self._elements(), nz=self.nz, np_=self.np_, name="ocp_multiphase",
                                            ipopt=ipopt or {}))
        self.layout = self.solver.layout

    # -- the elements ------------------------------------------------------------------------------
    def elements(self) -> list[Element]:
        """The NLP's elements in the order of its constraint rows (one phase: the phase's own)."""
        return self.blocks[0].nlp.elements() if self.mp.single else self._elements()

    def _elements(self) -> list[Element]:
        out = []
        for i, b in enumerate(self.blocks):
            for el in b.nlp.elements():
                out.append(self._wrapped(i, b, el))
        out.append(self._events())
        return out

    def _wrapped(self, i: int, b: Block, el: Element) -> Element:
        """The phase's element on the global vector: ``w = [t0z, w_phase]``, its ``t0`` the variable."""
        nw = el.cols.shape[1]
        w, P = ca.SX.sym("w", nw + 1), ca.SX.sym("p", self.np_)
        k = ca.SX.sym("k", el.fn.size_in(2))
        pk = P[b.p_slice.start:b.p_slice.stop]
        nc = b.nlp.fns.nc
        t0 = w[0] * P[b.ts_index]
        pk = ca.vertcat(pk[:nc], t0, pk[nc + 1:])
        y, f = el.fn(w[1:], pk, k)
        fn = ca.Function(f"ph{i}_{el.fn.name()}", [w, P, k], [y, f])
        cols = np.column_stack([np.full(el.count, b.t0_col), b.global_cols(el.cols)])
        return Element(f"{b.name}:{el.name}", fn, cols, el.kvals, el.has_f)

    def event_columns(self) -> tuple[np.ndarray, list[dict]]:
        """The events element's columns: theta, then per phase t0, tf, x(first), x(last), u(first), u(last)."""
        nth = len(self.mp.parameters)
        cols, where = [np.arange(nth)], []
        for b in self.blocks:
            n, g = b.nlp, b.nlp.grid
            loc = [b.t0_col], b.global_cols([0]), b.global_cols(n._x_cols(0)), \
                b.global_cols(n._x_cols(g.n_nodes - 1)), b.global_cols(n._u_cols(0)), \
                b.global_cols(n._u_cols(g.n_nodes - 1))
            cols += [np.asarray(c, int) for c in loc]
            where.append({"nx": n.fns.nx, "nu": n.fns.nu})
        return np.concatenate(cols), where

    def _events(self) -> Element:
        mp, nth = self.mp, len(self.mp.parameters)
        cols, _ = self.event_columns()
        w, P = ca.SX.sym("w", cols.size), ca.SX.sym("p", self.np_)
        b0 = self.blocks[0]
        f0 = b0.nlp.fns
        split0 = b0.nlp.split_p(P[b0.p_slice.start:b0.p_slice.stop])
        c, theta = split0["c"], w[:nth] * split0["thetas"]
        env = {n: c[i] for i, (n, _) in enumerate(mp.constants)}
        env.update({q.name: theta[i] for i, q in enumerate(mp.parameters)})
        ev: dict[tuple, Any] = {}
        per = []
        i = nth
        for b in self.blocks:
            f = b.nlp.fns
            sp = b.nlp.split_p(P[b.p_slice.start:b.p_slice.stop])
            ts = sp["ts"]
            t0, tf = w[i] * ts, w[i + 1] * ts
            i += 2
            x0, xf = w[i:i + f.nx] * sp["xs"], w[i + f.nx:i + 2 * f.nx] * sp["xs"]
            i += 2 * f.nx
            u0, uf = w[i:i + f.nu] * sp["us"], w[i + f.nu:i + 2 * f.nu] * sp["us"]
            i += 2 * f.nu
            ev[("t0", b.name)], ev[("tf", b.name)] = t0, tf
            for j, s in enumerate(b.problem.state_names):
                ev[("initial", s, b.name)], ev[("final", s, b.name)] = x0[j], xf[j]
            for j, u in enumerate(b.problem.control_names):
                ev[("initial", u, b.name)], ev[("final", u, b.name)] = u0[j], uf[j]
            per.append((t0, tf, ts, sp["xs"]))
        del f0
        rows = []
        for k in range(len(self.blocks) - 1):            # order (= 0 where time is continuous)
            rows.append((per[k + 1][0] - per[k][1]) / per[k][2])
        for t0, tf, ts, _ in per:                         # positive durations
            rows.append((tf - t0) / ts)
        for k, x in mp.state_links:
            a, b = self.blocks[k], self.blocks[k + 1]
            j = a.problem.state_names.index(x)
            rows.append((ev[("initial", x, b.name)] - ev[("final", x, a.name)]) / per[k][3][j])
        lscale = P[self.links_p]
        for j, lk in enumerate(mp.links):
            rows.append(to_sx(lk.expr, env, {t.name: t for t in mp.tables}, ev) / lscale[j])
        mayer = to_sx(mp.objective.expr, env, {t.name: t for t in mp.tables}, ev) \
            if mp.objective.expr is not None else ca.SX(0)
        fn = ca.Function("ocp_multiphase_events", [w, P, ca.SX.sym("k")], [ca.vertcat(*rows), self.sign * mayer])
        return Element("events", fn, cols[None, :], np.zeros(1), mp.objective.expr is not None)

    def event_bounds(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Bounds of the events element's rows, and the links' scales (the tail of p); none for one phase."""
        mp, n = self.mp, len(self.blocks)
        if mp.single:
            return np.zeros(0), np.zeros(0), np.zeros(0)
        lo, hi = [], []
        for k in range(n - 1):
            lo.append(0.0)
            hi.append(0.0 if k in mp.time_links else np.inf)
        lo += [TF_MIN_FRACTION] * n
        hi += [np.inf] * n
        lo += [0.0] * len(mp.state_links)
        hi += [0.0] * len(mp.state_links)
        scales = np.array([positive_scale(lk.lower, lk.upper) for lk in mp.links])
        for lk, s in zip(mp.links, scales):
            lo.append(-np.inf if lk.lower is None else lk.lower / s)
            hi.append(np.inf if lk.upper is None else lk.upper / s)
        return np.array(lo), np.array(hi), scales
