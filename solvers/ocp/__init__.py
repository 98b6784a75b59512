"""The ``ocp`` kind: an optimal-control problem the user writes down as data, solved and verified.

Public face.  The problem side (:func:`parse_problem`, the dataclasses, :data:`PRESETS`) is
standard-library only, so the API process validates a problem and lists the presets without
loading numpy or CasADi; :func:`solve` and :class:`OcpSolution` are loaded on first use
(PEP 562), together with CasADi.

One model for one phase and several: a problem posed with the single-phase fields is the
one-phase case of :class:`OcpProblem`, parsed, built, solved, refined, verified and reported by the
same code (as dymos' ``Trajectory`` of ``Phase`` objects, rockit's ``Ocp(Stage)``).

Modules, standard library only: ``expressions`` (the safe grammar), ``problem`` (the typed
dataclasses: :class:`OcpProblem` of named phases, each a ``PhaseProblem`` to the transcription),
``readers`` (single values, the namespace of names, the size limits), ``spec`` (params ->
:class:`OcpProblem`: what the phases share, the one-phase case, several phases), ``phase_spec`` (one
phase's params -> its ``PhaseProblem``, the same for both forms), ``phases_spec`` (what only several
phases have: names, windows in time, links), ``shape`` (the fields of each section of the params,
declared once), ``cases`` (presets with published optima).  With CasADi: ``symbolic`` (tree -> SX, the phase's functions cached per structure),
``grid`` (where a phase's nodes sit), ``phase`` (one phase -> its NLP elements, multiple shooting or
LGL, block derivatives), ``trajectory`` (the phases' blocks and their events in one cached NLP; one
phase is its own NLP), ``scaling`` (a phase's scales, bounds and parameter vector; its answer
unpacked), ``guess`` (a phase's initial guess: straight lines or a stored answer), ``verify`` (the
DOP853 re-flight), ``terminal`` (final values that hold on the re-flight), ``check`` (one phase of an
answer checked and reported), ``optimality`` (its costates, Hamiltonian and necessary conditions), ``limits`` (path limits tightened where the re-flight exceeds them),
``refine`` (every phase's grid refined to ``accuracy``, or on a terminal miss), ``solution`` (the
solution and its report), ``solver`` (:class:`solvers.ocp.solver.OcpSolve`, the loop, and
:func:`solve`).
"""
from __future__ import annotations

from solvers.ocp.cases import PRESETS
from solvers.ocp.expressions import OcpInputError
from solvers.ocp.problem import OcpProblem
from solvers.ocp.spec import OcpLimits, parse_problem

__all__ = ["PRESETS", "OcpInputError", "OcpLimits", "OcpProblem", "OcpSolution", "parse_problem", "solve"]

_LAZY = {"OcpSolution": "solvers.ocp.solution"}


def solve(problem: OcpProblem, **kwargs):
    """:func:`solvers.ocp.solver.solve` (one phase or several, as :func:`parse_problem` returned it;
    the common protocol), loaded with CasADi on first use."""
    from solvers.ocp.solver import solve as solve_problem
    return solve_problem(problem, **kwargs)


def __getattr__(name: str):
    if name in _LAZY:
        import importlib
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
