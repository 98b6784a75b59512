"""The size of what an ``ocp`` job will build, read from its request without building anything: per phase
its grid (intervals, integration steps, the check solve's parts), its width (states, controls and, for a
robust design, the sensitivity states) and the size of its expressions as parse-tree nodes.  Both the
job's cost (:func:`app.kinds.ocp.kind.cost`: quota and heavy queue) and its memory
(:mod:`app.kinds.ocp.footprint`) are computed from these same figures.

The node count is the one the parser limits (``solvers.ocp.expressions.parse_expression`` counts
``ast.walk`` of the same text against ``max_expression_nodes``): every CasADi SX node of a phase's
functions comes from one of them, and each RK4 stage or collocation node evaluates them again.
Standard library only: the API process sizes a job without importing CasADi.
"""
from __future__ import annotations

import ast
from dataclasses import dataclass


def expression_nodes(text) -> int:
    """Parse-tree nodes of one expression (a bare number is one; text that does not parse counts its
    characters / 4, about a node each: the parser refuses it before anything is built anyway)."""
    if text is None:
        return 0
    if isinstance(text, (bool, int, float)):
        return 1
    try:
        return sum(1 for _ in ast.walk(ast.parse(str(text).strip(), mode="eval")))
    except (SyntaxError, ValueError, RecursionError, MemoryError):
        return len(str(text)) // 4 + 1


def check_parts(transcription: dict) -> int:
    """The parts each interval is cut into for an answer's check solve (``solvers.ocp.estimate.parts_of``,
    read from the request so the quota needs no solver import): 3 for multiple shooting's linear controls,
    2 otherwise.  The check's NLP is that many times the answer's, and warm-started it takes about as many
    iterations (the golden accuracy cases: 7-16 against 8-16), so it costs about s answers."""
    shooting = transcription.get("method", "multiple_shooting") == "multiple_shooting"
    return 3 if shooting and transcription.get("control", "linear") == "linear" else 2


@dataclass(frozen=True)
class PhaseSize:
    """One phase as the job will build it."""

    shooting: bool        # multiple shooting (else LGL collocation)
    intervals: int
    steps: float          # RK4 substeps per shooting interval, or LGL nodes per interval
    parts: int            # the check solve's cut of each interval (:func:`check_parts`)
    states: int
    controls: int
    nodes: int            # parse-tree nodes of its dynamics, named expressions, path constraints, integrand
    paths: int            # path constraints
    sensitivities: int    # robust design: states x (states + draws) per node (CADET's S and its rates), else 0

    @property
    def width(self) -> int:
        return self.states + self.controls

    @property
    def grid(self) -> float:
        """Integration steps (or collocation nodes) of the check's NLP, the largest the job builds."""
        return float(self.intervals) * self.steps * self.parts


def phase_bodies(params: dict) -> list[dict]:
    """Each phase as a single-phase body (its share of the integrand, the problem's accuracy); a problem
    posed as one phase is its own."""
    if not params.get("phases"):
        return [params]
    integrand = (params.get("objective") or {}).get("integrand")
    return [{**ph, "objective": {"integrand": integrand.get(ph.get("name")) if isinstance(integrand, dict)
                                 else integrand}, "accuracy": params.get("accuracy")}
            for ph in params["phases"] if isinstance(ph, dict)]


def draws(params: dict) -> int:
    """Uncertain quantities of a robust design (constants and initial states), 0 without one."""
    if not params.get("robust"):
        return 0
    unc = params.get("uncertainty") or {}
    return len(unc.get("parameters") or {}) + len(unc.get("initial") or {})


def monte_carlo_samples(params: dict) -> int:
    """The robust design's Monte Carlo draws (its default 2000, ``solvers.ocp.robust.model``), 0 without one."""
    if not params.get("robust"):
        return 0
    return int(((params["robust"].get("monte_carlo") or {}).get("samples")) or 2000)


def phase_sizes(params: dict) -> list[PhaseSize]:
    """The phases of the job as it will build them."""
    w = draws(params)
    out = []
    for body in phase_bodies(params):
        tr = body.get("transcription") or {}
        shooting = tr.get("method", "multiple_shooting") == "multiple_shooting"
        steps = float(tr.get("substeps", 2)) if shooting else float(tr.get("nodes", 4))
        intervals = len(tr["boundaries"]) - 1 if tr.get("boundaries") else int(tr.get("intervals", 50))
        nodes = sum(expression_nodes(v) for group in ("expressions", "dynamics")
                    for v in (body.get(group) or {}).values())
        nodes += sum(expression_nodes(c.get("expr")) for c in (body.get("path") or []) if isinstance(c, dict))
        nodes += expression_nodes((body.get("objective") or {}).get("integrand"))
        nx, nu = len(body.get("states") or []), len(body.get("controls") or [])
        paths = sum(1 for c in body.get("path") or [] if isinstance(c, dict))
        out.append(PhaseSize(shooting=shooting, intervals=intervals, steps=steps, parts=check_parts(tr), states=nx,
                             controls=nu, nodes=nodes, paths=paths, sensitivities=nx * (nx + w) if w else 0))
    return out
