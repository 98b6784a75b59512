"""The ``ocp`` kind: an optimal-control problem the user writes down as data, solved and verified.

Public face.  The problem side (:func:`parse_problem`, the dataclasses, :data:`PRESETS`) is
standard-library only, so the API process validates a problem and lists the presets without
loading numpy or CasADi; :func:`solve` and :class:`OcpSolution` are loaded on first use
(PEP 562), together with CasADi.

Modules: ``expressions`` (the safe grammar), ``problem`` (the typed dataclasses), ``spec``
(params -> :class:`OcpProblem`, with ``fields``: the readers of single fields and sections), ``cases`` (presets with published optima), ``phases_spec`` (several phases: params ->
:class:`MultiPhaseProblem`), ``phase_cases`` (their presets); with CasADi:
``multiphase`` (the phases' blocks in one NLP), ``multisolve`` (:func:`solve` of several phases), ``symbolic`` (tree -> SX), ``phase`` (one phase -> a cached NLP, multiple shooting or LGL, with
block derivatives), ``verify`` (DOP853 re-flight), ``limits`` (limits that hold between the
nodes), ``terminal`` (final values that hold on the re-flight), ``grid`` (where the nodes sit: equal
intervals or a refined mesh), ``refine`` (the grid refined to ``accuracy``, or on a terminal miss,
through :mod:`solvers.transcription.refine`), ``solver`` (:func:`solve`).
"""
from __future__ import annotations

from solvers.ocp.cases import PRESETS
from solvers.ocp.expressions import OcpInputError
from solvers.ocp.phases_spec import MultiPhaseProblem
from solvers.ocp.spec import OcpLimits, OcpProblem, parse_problem

__all__ = ["PRESETS", "MultiPhaseProblem", "MultiPhaseSolution", "OcpInputError", "OcpLimits", "OcpProblem",
           "OcpSolution", "parse_problem", "solve"]

_LAZY = {"OcpSolution": "solvers.ocp.solver", "MultiPhaseSolution": "solvers.ocp.multisolve"}


def solve(problem, **kwargs):
    """One phase (:func:`solvers.ocp.solver.solve`) or several (:func:`solvers.ocp.multisolve.solve_phases`),
    as :func:`parse_problem` returned it; same keywords, the common protocol."""
    if isinstance(problem, MultiPhaseProblem):
        from solvers.ocp.multisolve import solve_phases
        return solve_phases(problem, **kwargs)
    from solvers.ocp.solver import solve as solve_one
    return solve_one(problem, **kwargs)


def __getattr__(name: str):
    if name in _LAZY:
        import importlib
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
