"""Long-range interception (paper 003; the ``intercept`` job kind): the impulsive Lambert method and
the finite-thrust method (:mod:`.thrust`), one entry point.

The public face: :class:`InterceptProblem`, :class:`ScanSettings`, :class:`ImpulsiveSolution`,
:class:`InterceptSolution` (:mod:`.problem`); :func:`solve`, :func:`solve_impulsive`,
:func:`solve_finite` (:mod:`.solver`); the scenario held once (:mod:`.scenario`), the Lambert
branches (:mod:`.branches`), the porkchop map (:mod:`.porkchop`), paper 003's case (:mod:`.cases`).
Names are imported on first use (:mod:`solvers.lazy`).
"""
from __future__ import annotations

from typing import TYPE_CHECKING

from solvers.lazy import lazy_exports

_EXPORTS = {
    **dict.fromkeys(("ScanSettings", "InterceptProblem", "ImpulsiveSolution", "InterceptSolution"), "problem"),
    **dict.fromkeys(("solve", "solve_impulsive", "solve_finite", "by_impulsive_bound"), "solver"),
    **dict.fromkeys(("Porkchop", "PorkchopSettings", "porkchop_map"), "porkchop"),
    "InterceptScenario": "scenario",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)

if TYPE_CHECKING:  # the same names, for readers, type checkers and import-graph tools
    from solvers.intercept.porkchop import Porkchop, PorkchopSettings, porkchop_map
    from solvers.intercept.problem import ImpulsiveSolution, InterceptProblem, InterceptSolution, ScanSettings
    from solvers.intercept.scenario import InterceptScenario
    from solvers.intercept.solver import by_impulsive_bound, solve, solve_finite, solve_impulsive
