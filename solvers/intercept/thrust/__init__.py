"""Finite-thrust, fuel-optimal interception by LGL pseudospectral collocation
(paper 003, method I): switching structure, mesh refinement, independent
verification and optimality diagnostics.

Model: :mod:`solvers.models.relative_motion` (nonlinear relative motion in the
target's Hill frame, nondimensionalised by the target radius and 1/n).
Objective: maximise final mass; terminal condition: relative position zero at
``tf`` (fixed, or free within user bounds).

Transcription (:mod:`solvers.transcription.lgl`): multi-segment LGL on a
sequence of *arcs*.  An arc is a coast (no thrust, no control variables), a
burn (full thrust, direction ``d`` with ``|d| <= 1`` at every node) or, for the
paper's formulation, a free arc (throttle ``u`` in [0, 1] and direction).  The
arc durations are NLP variables summing to ``tf``, so the switch times are
solved for exactly: the bang-bang thrust never has to be represented by a
polynomial across a jump, the NLP is smooth, and IPOPT converges in tens of
iterations instead of stalling for thousands (what the paper's single 60-node
segment with a free throttle does here; see ``benchmarks/intercept.py``).

Structure: the warm start names the burns (from the impulsive answer: a burn
of ``m0 (1 - exp(-dv/c)) c / Tmax`` around the impulse time, plus a burn at
t=0 that may shrink to nothing; from a stored job: its burns).  After the
solve the switching function on the coasts tells whether a burn is missing
(Pontryagin: the engine must be off wherever ``S < 0``); a coast where it is
positive gets a new burn and the problem is solved again.

Refinement (Betts sec. 4.7): each segment is re-propagated from its first node
under the interpolated control; arcs whose segments' end-state defects are
large get twice the segments, until the inertial re-propagation of the whole
thrust history misses the target by less than ``miss_tolerance_m``.

Verification re-propagates the optimal controls, interpolated exactly as the
collocation polynomials (per-segment Lagrange), with DOP853 (rtol 1e-10) in
inertial coordinates, two-body for both spacecraft.

Optimality evidence (Fahroo & Ross 2001, covector mapping): costates
``lambda_i = -nu_i / w_i`` from the defect multipliers; the Hamiltonian
``H = lambda' f`` must be constant (the dynamics are autonomous in the Hill
frame) and equal to ``-dJ/dtf`` (zero for free tf inside its bounds); the
switching function ``S = |lambda_v|/m + lambda_m/c`` must be positive exactly
where the engine is on, and the thrust must point along ``-lambda_v``.

The package: ``problem`` (what is asked and answered), ``layout`` (arcs and
segments), ``collocation`` (the NLP), ``planning`` (warm starts), ``diagnostics``
(verification and optimality), ``solve`` (the loop).  This face re-exports (lazily,
:mod:`solvers.lazy`) what a caller needs, including the warm-start, verification and diagnostic functions
that ``benchmarks/intercept.py`` uses to treat other transcriptions the same way.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

from solvers.lazy import lazy_exports

_EXPORTS = {
    **dict.fromkeys(("optimality_evidence", "segment_defects", "verify_controls"), "diagnostics"),
    **dict.fromkeys(("plan_impulsive", "plan_trajectory", "propagate_hill"), "planning"),
    **dict.fromkeys(("FiniteThrustProblem", "FiniteThrustSolution", "ImpulsiveGuess", "MeshOptions", "Plan", "Scaled",
                     "TrajectoryGuess", "nondimensionalise"), "problem"),
    "solve_finite_thrust": "solve",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)

if TYPE_CHECKING:  # the same names, for readers, type checkers and import-graph tools
    from solvers.intercept.thrust.diagnostics import optimality_evidence, segment_defects, verify_controls
    from solvers.intercept.thrust.planning import plan_impulsive, plan_trajectory, propagate_hill
    from solvers.intercept.thrust.problem import (
        FiniteThrustProblem, FiniteThrustSolution, ImpulsiveGuess, MeshOptions, Plan, Scaled, TrajectoryGuess,
        nondimensionalise,
    )
    from solvers.intercept.thrust.solve import solve_finite_thrust
