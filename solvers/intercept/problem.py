"""The intercept kind's problem and solutions: :class:`InterceptProblem` (the scenario, the methods
to run, their settings), :class:`ScanSettings`, :class:`ImpulsiveSolution`, :class:`InterceptSolution`.

Held apart from :mod:`solvers.intercept.solver` so that readers of a problem (the API edge, the
benchmarks) need not load the methods.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from solvers.astro.earth import AE_EARTH
from solvers.common import SolveStatus
from solvers.intercept.branches import Branch
from solvers.intercept.porkchop import Porkchop, PorkchopSettings
from solvers.intercept.scenario import InterceptScenario
from solvers.intercept.thrust.problem import FiniteThrustSolution, MeshOptions


@dataclass(frozen=True)
class ScanSettings:
    """Maneuver-time enumeration and the Lambert branches searched."""

    step_s: float = 0.5
    t_start_s: float = 0.0           # window start (the epoch t0 = 0)
    t_end_s: float | None = None     # window end, exclusive; None means t1
    max_revolutions: int = 0         # also search 1..max_revolutions full revolutions
    retrograde: bool = True          # also search retrograde transfers
    refine: bool = True              # bounded minimization around the best grid point
    # Lambert arcs that dip below this radius pass through the planet: left out of the scan,
    # the refinement and the porkchop (and counted) unless exclude_through_planet is False
    exclude_through_planet: bool = True
    body_radius_m: float = AE_EARTH

    @property
    def excluded_below_m(self) -> float | None:
        return self.body_radius_m if self.exclude_through_planet else None


@dataclass(frozen=True)
class InterceptProblem:
    """The scenario and how to solve it: which methods, the scan, the mesh, the porkchop."""

    scenario: InterceptScenario
    methods: tuple[str, ...] = ("impulsive",)
    scan: ScanSettings = field(default_factory=ScanSettings)
    mesh: MeshOptions = field(default_factory=MeshOptions)   # finite-thrust collocation
    porkchop: PorkchopSettings | None = None


@dataclass
class ImpulsiveSolution:
    status: SolveStatus
    t_man_s: np.ndarray                  # scan grid
    delta_v_mps: np.ndarray              # min over branches, NaN where no branch converged
    branch_index: np.ndarray             # index into ``branches`` of the minimum, -1 if none
    branches: list[Branch]
    best_t_man_s: float = float("nan")
    best_delta_v_mps: float = float("nan")
    delta_v_vector_mps: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    fuel_kg: float = float("nan")
    best_branch: Branch | None = None
    tf_s: float = float("nan")                  # the interception time
    burn_position_m: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    velocity_before_mps: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    velocity_after_mps: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    relative_velocity_at_intercept_mps: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    miss_distance_m: float = float("nan")    # post-burn state re-propagated to t1 vs target
    porkchop: Porkchop | None = None
    # Lambert solutions (maneuver time x branch) left out because their arc passes through the
    # planet, and maneuver times left with no admissible branch because of that
    excluded_through_planet: int = 0
    points_only_through_planet: int = 0


@dataclass
class InterceptSolution:
    """What ``solve`` returns: one entry per requested method."""

    status: SolveStatus
    impulsive: ImpulsiveSolution | None = None
    finite_thrust: FiniteThrustSolution | None = None
