"""What the finite-thrust method is asked and what it answers: mesh options, the
problem (an :class:`~solvers.intercept.scenario.InterceptScenario` and a mesh), the two
kinds of warm start, the solution, the problem in nondimensional Hill units, and a warm start's control
:class:`Plan` (here, not in planning, so that the layout reads it without importing planning)."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from solvers.common import SolveStatus
from solvers.intercept.scenario import InterceptScenario
from solvers.models import relative_motion as rm

@dataclass(frozen=True)
class MeshOptions:
    """Collocation mesh and refinement controls.

    ``structure="switching"`` (default) solves for the switch times on
    coast/burn arcs; ``structure="free_throttle"`` is the paper's formulation:
    ``segments`` equal segments with a free throttle (``segments=1, nodes=60``
    is paper 003's single 60-node LGL grid).
    """

    structure: str = "switching"
    nodes: int = 10                   # LGL nodes per segment
    coast_segment_s: float = 1000.0   # initial segment length on coasts
    burn_segment_s: float = 250.0     # initial segment length on burns
    segments: int = 1                 # free_throttle only
    refine: bool = True
    miss_tolerance_m: float = 100.0   # refine until the re-propagated miss is below this
    max_refinements: int = 3
    max_new_burns: int = 2            # burns the switching function may add
    max_segments: int = 80
    max_iterations: int = 500         # IPOPT iterations per solve
    min_arc_s: float = 1e-3           # arcs shorter than this are removed and the problem solved again

    def __post_init__(self):
        if self.structure not in ("switching", "free_throttle"):
            raise ValueError(f"unknown structure {self.structure!r}")


@dataclass(frozen=True)
class FiniteThrustProblem:
    """The scenario (its ``tf_s`` fixed, or the first guess when free) and the mesh."""

    scenario: InterceptScenario
    mesh: MeshOptions = field(default_factory=MeshOptions)


@dataclass(frozen=True)
class ImpulsiveGuess:
    """Warm start from a single impulse: a burn of ``|dv| m / T`` centred on ``t_man_s``,
    along the impulse's inertial direction."""

    t_man_s: float
    delta_v_mps: np.ndarray      # inertial (ECI) vector


@dataclass(frozen=True)
class TrajectoryGuess:
    """Warm start from a previous solution (e.g. a stored job result), Hill frame, SI."""

    t_s: np.ndarray              # (K,), nondecreasing
    states: np.ndarray           # (7, K): x, y, z [m], vx, vy, vz [m/s], mass [kg]
    thrust_n: np.ndarray         # (3, K)


@dataclass
class FiniteThrustSolution:
    """What the finite-thrust method returns: SI states in the Hill frame, arcs, burns, checks."""

    status: SolveStatus
    tf_s: float = float("nan")
    final_mass_kg: float = float("nan")
    fuel_kg: float = float("nan")
    t_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    states: np.ndarray = field(default_factory=lambda: np.zeros((7, 0)))    # Hill, SI, mass kg
    thrust_n: np.ndarray = field(default_factory=lambda: np.zeros((3, 0)))  # Hill
    arcs: list[dict] = field(default_factory=list)
    burns: list[dict] = field(default_factory=list)
    verification: dict = field(default_factory=dict)
    optimality: dict = field(default_factory=dict)
    mesh: dict = field(default_factory=dict)
    history: list[dict] = field(default_factory=list)
    warm_start: str = ""
    # along the nodes: t_s, hamiltonian, switching_function (nondimensional), interior (bool)
    optimality_history: dict = field(default_factory=dict)


@dataclass
class Scaled:
    """The problem's numbers in the nondimensional Hill frame (states, thrust, exhaust speed, tf)."""

    sc: rm.HillScales
    x0: np.ndarray       # nondim initial Hill state (7)
    tmax: float
    c: float
    m_dry: float
    tf: float
    tf_lo: float
    tf_hi: float


def nondimensionalise(problem: FiniteThrustProblem) -> Scaled:
    """The problem in the nondimensional Hill frame of the target (length: its radius, time: 1/n)."""
    sn = problem.scenario
    r_i, v_i, r_t, v_t = sn.initial_states()
    a = float(np.linalg.norm(r_t))
    sc = rm.HillScales.of(mu_m3_s2=sn.mu_m3_s2, radius_m=a, mass_kg=sn.mass_kg)
    rho, rho_dot = rm.inertial_to_hill(r_i=r_i, v_i=v_i, r_t=r_t, v_t=v_t)
    x0 = np.concatenate([rho / sc.length_m, rho_dot / sc.speed_mps, [1.0]])
    tf_lo, tf_hi = sn.tf_bounds_s
    tf = min(max(sn.tf_s, tf_lo), tf_hi) if sn.free_final_time else sn.tf_s
    return Scaled(sc=sc, x0=x0, tmax=sn.max_thrust_n / sc.force_n, c=sn.exhaust_speed_mps / sc.speed_mps,
                  m_dry=(sn.mass_kg - sn.propellant_kg) / sn.mass_kg,
                  tf=tf / sc.time_s, tf_lo=tf_lo / sc.time_s, tf_hi=tf_hi / sc.time_s)


@dataclass
class Plan:
    """A control history to start from (nondimensional time)."""

    windows: list[tuple[float, float]]                # burn intervals
    direction: Callable[[np.ndarray], np.ndarray]     # t (K,) -> Hill unit vectors (3, K)
    tf: float
    states: Callable[[np.ndarray], np.ndarray] | None = None   # t -> (7, K); None: propagate

    def on(self, t: np.ndarray) -> np.ndarray:
        t = np.atleast_1d(t)
        return np.any([(t >= a) & (t <= b) for a, b in self.windows], axis=0) if self.windows else np.zeros(t.size, bool)
