"""The ``ocp`` kind's terminal conditions held on the re-flight (issue 25), as path limits are.

The NLP meets a fixed final value or a boundary constraint at its own final node; what the user
flies is the re-flight of the controls (:mod:`solvers.ocp.verify`), whose final state differs by
the transcription's error.  Each fixed final value must hold there within ``TERMINAL_TOLERANCE``
of the state's scale, and each boundary constraint that depends on the final state within what
that much miss in every state moves it (to first order, by finite differences on the events
function).  A miss is refined, warm-started, on a finer grid (multiple shooting: twice the RK4
substeps, up to ``MAX_SUBSTEPS``; LGL: twice the segments), at most ``TERMINAL_ROUNDS`` times;
then the solve ends ``terminal_not_held`` with its best answer, never a silent success.  These
rounds run through the same loop as mesh refinement (:mod:`solvers.ocp.refine`); with ``accuracy``
set, that refinement handles a terminal miss instead (its target lowered to this tolerance).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

TERMINAL_TOLERANCE = 1e-5      # of each state's scale (Betts shuttle: 2.6 ft of altitude, 0.26 ft/s)
TERMINAL_ROUNDS = 3
MAX_SUBSTEPS = 32
MAX_LGL_SEGMENTS = 1000


def terminal_checks(*, problem, fns, x_scale, c, theta, tf: float, x: np.ndarray, u: np.ndarray,
                    tolerance: float = TERMINAL_TOLERANCE) -> dict[str, dict]:
    """Every fixed final value and final-state boundary constraint on the re-flown trajectory
    (``x``, ``u``: its dense states and controls), each with its miss, tolerance and ``held``."""
    ph = problem.phase
    x0, xf = x[:, 0], x[:, -1]
    scale = np.asarray(x_scale, float)
    out: dict[str, dict] = {}
    for i, s in enumerate(ph.states):
        if s.final is not None:
            miss, tol = abs(float(xf[i]) - s.final), tolerance * float(scale[i])
            out[f"final({s.name})"] = {"requested": s.final, "reflown": float(xf[i]), "miss": miss,
                                       "tolerance": tol, "held": bool(miss <= tol)}
    if not fns.nboundary:
        return out
    u0, uf, t0 = u[:, 0], u[:, -1], ph.time.initial

    def events(xe):
        return np.asarray(fns.events(t0, tf, x0, xe, u0, uf, theta, c)[0], float).ravel()

    g = events(xf)
    moved = np.zeros_like(g)
    for i in range(len(xf)):
        step = np.zeros_like(xf)
        step[i] = tolerance * scale[i]
        moved += np.abs(events(xf + step) - g)
    for k, con in enumerate(ph.boundary):
        if moved[k] == 0.0:
            continue            # not a condition on the final state: the NLP holds it exactly
        v = float(g[k])
        miss = max(0.0, (con.lower - v) if con.lower is not None else 0.0, (v - con.upper) if con.upper is not None else 0.0)
        out[con.name or f"boundary.{k}"] = {"lower": con.lower, "upper": con.upper, "reflown": v, "miss": miss,
                                            "tolerance": float(moved[k]), "held": bool(miss <= moved[k])}
    return out


def finer(problem):
    """The same problem on the next finer grid, or None at the cap."""
    tr = problem.phase.transcription
    if tr.method == "multiple_shooting":
        if tr.substeps >= MAX_SUBSTEPS:
            return None
        tr = replace(tr, substeps=min(2 * tr.substeps, MAX_SUBSTEPS))
    else:
        if tr.intervals >= MAX_LGL_SEGMENTS or (tr.boundaries is not None and 2 * tr.intervals > MAX_LGL_SEGMENTS):
            return None
        if tr.boundaries is not None:         # a mesh given by boundaries: every interval halved
            from solvers.transcription.refine import subdivide

            nodes = None if tr.segment_nodes is None else tuple(n for n in tr.segment_nodes for _ in (0, 1))
            tr = replace(tr, intervals=2 * tr.intervals, boundaries=subdivide(tr.boundaries, [2] * tr.intervals),
                         segment_nodes=nodes)
        else:
            tr = replace(tr, intervals=min(2 * tr.intervals, MAX_LGL_SEGMENTS))
    return replace(problem, phase=replace(problem.phase, transcription=tr))


def grid_words(problem) -> str:
    tr = problem.phase.transcription
    if tr.method == "multiple_shooting":
        return f"{tr.intervals} intervals x {tr.substeps} RK4 steps"
    return f"{tr.intervals} LGL segments of {tr.nodes} nodes"
