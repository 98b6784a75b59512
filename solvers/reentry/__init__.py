"""Lifting reentry trajectory optimization by direct multiple shooting (the ``reentry`` job kind).

The public face: :class:`ReentryProblem`, :class:`Terminal`, :class:`ReentrySolution`
(:mod:`.problem`), :func:`solve` the NLP's pieces (:mod:`.shooting`), the
initial guesses (:mod:`.guess`); the limits that hold between nodes are in :mod:`.limits`; the grid
refined to an accuracy in :mod:`.refine` (whose ``solve`` is the package's).
Names are imported on first use (:mod:`solvers.lazy`), so importing the package loads no CasADi.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

from solvers.lazy import lazy_exports

_EXPORTS = {
    **dict.fromkeys(("OBJECTIVES", "T_SCALE", "HEAT_LOAD_SCALE", "Terminal", "ReentryProblem",
                     "ReentrySolution"), "problem"),
    "TerminalTolerance": "terminal",
    **dict.fromkeys(("param_vector", "shooting_problem", "state_bounds"), "shooting"),
    **dict.fromkeys(("objective_value", "path_quantities"), "solver"),
    "solve": "refine",          # solver.solve, refined to ``accuracy`` when it is set
    **dict.fromkeys(("InitialGuess", "linear_guess", "on_grid", "rhs_numpy", "simulate_constant_controls"),
                    "guess"),
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)

if TYPE_CHECKING:  # the same names, for readers, type checkers and import-graph tools
    from solvers.reentry.guess import InitialGuess, linear_guess, on_grid, rhs_numpy, simulate_constant_controls
    from solvers.reentry.problem import (HEAT_LOAD_SCALE, OBJECTIVES, T_SCALE, ReentryProblem, ReentrySolution,
                                         Terminal)
    from solvers.reentry.terminal import TerminalTolerance
    from solvers.reentry.refine import solve
    from solvers.reentry.shooting import param_vector, shooting_problem, state_bounds
    from solvers.reentry.solver import objective_value, path_quantities
