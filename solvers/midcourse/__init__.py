"""Timing of midcourse corrections on an upper-stage transfer orbit (paper 002; the ``midcourse`` job kind).

The public face: :class:`MidcourseProblem`, :class:`Dispersion`, :class:`GASettings`,
:class:`ScheduleResult`, :class:`MidcourseSolution`, :func:`paper_problem` (:mod:`.problem`);
:func:`solve` and :class:`CorrectionEvaluator` (:mod:`.solver`); the search's pieces (:mod:`.search`
on :mod:`.nsga2`). Paper 002's numbers are in :mod:`.cases` (numpy-free: the API edge reads them),
the transfer trajectories of a front point in :mod:`.trajectory`. Names are imported on first use
(:mod:`solvers.lazy`), so ``import solvers.midcourse.cases`` loads neither heyoka nor numpy.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

from solvers.lazy import lazy_exports

_EXPORTS = {
    **dict.fromkeys(("OBJECTIVE_NAMES", "Dispersion", "GASettings", "MidcourseProblem", "ScheduleResult",
                     "MidcourseSolution", "paper_problem"), "problem"),
    **dict.fromkeys(("CorrectionEvaluator", "PENALTY", "solve"), "solver"),
    **dict.fromkeys(("hypervolume", "nondominated", "repair_schedule", "run_nsga2"), "search"),
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)

if TYPE_CHECKING:  # the same names, for readers, type checkers and import-graph tools
    from solvers.midcourse.problem import (OBJECTIVE_NAMES, Dispersion, GASettings, MidcourseProblem,
                                           MidcourseSolution, ScheduleResult, paper_problem)
    from solvers.midcourse.search import hypervolume, nondominated, repair_schedule, run_nsga2
    from solvers.midcourse.solver import PENALTY, CorrectionEvaluator, solve
