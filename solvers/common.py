"""The one protocol every solve follows: callbacks in, a typed outcome out.

Every job-kind entry point is ``solve(problem, *, initial_guess=None,
on_progress=None, should_stop=None, seed=None) -> <Kind>Solution``; each
solution dataclass carries a :class:`SolveStatus` so that a failed or
unconverged solve is a value, never a silent success or only an exception.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum
from typing import Callable

ProgressFn = Callable[[float, str], None]
"""``on_progress(fraction, message)``: fraction in [0, 1], e.g. (0.3, "IPOPT iteration 31")."""

StopFn = Callable[[], bool]
"""``should_stop()``: True once the job was cancelled; solvers poll it each iteration."""


class Outcome(str, Enum):
    """What became of a solve. Maps one-to-one onto the API's job status/error codes."""

    OPTIMAL = "optimal"              # converged to a (local) optimum that meets the constraints
    # converged, feasible and verified, but a necessary condition of optimality checked on the costates fails
    # (ocp: verification.optimality): the answer is served as a success, its outcome saying so
    OPTIMALITY_NOT_VERIFIED = "optimality_not_verified"
    INFEASIBLE = "infeasible"        # the NLP solver proved or reported local infeasibility
    NOT_CONVERGED = "not_converged"  # iteration/time budget exhausted, or diverged
    CANCELLED = "cancelled"          # should_stop() answered True
    LIMIT_NOT_HELD = "limit_not_held"  # converged, but a path limit is exceeded between the nodes
    TERMINAL_NOT_HELD = "terminal_not_held"  # converged, but the re-propagation misses a final value
    ACCURACY_NOT_REACHED = "accuracy_not_reached"  # mesh refinement ran out of rounds short of the accuracy
    NUMERICAL_OVERFLOW = "numerical_overflow"  # the problem's own numbers overflowed or gave NaN (ocp)
    FAILED = "failed"                # anything else (bad problem data detected late, numerical error)


@dataclass
class SolveStatus:
    """The solver's verdict, with the solver's own words kept verbatim."""

    outcome: Outcome
    solver_status: str = ""          # e.g. IPOPT's return_status "Solve_Succeeded"
    message: str = ""
    iterations: int = 0
    build_time_s: float = 0.0
    solve_time_s: float = 0.0
    max_constraint_violation: float = 0.0
    details: dict = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        """A converged answer that meets the constraints (optimal, or one whose optimality is not verified)."""
        return self.outcome in (Outcome.OPTIMAL, Outcome.OPTIMALITY_NOT_VERIFIED)


def noop_progress(fraction: float, message: str) -> None:
    """Default progress sink."""


def never_stop() -> bool:
    """Default stop predicate."""
    return False
