"""The reentry kind's problem and solution: :class:`ReentryProblem` (SI, radians, the limits and
the transcription's settings), :class:`Terminal`, :class:`ReentrySolution`.

Held apart from :mod:`solvers.reentry.solve` so that the guesses (:mod:`solvers.reentry.guess`)
and the solve both read them without importing each other.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from solvers.common import SolveStatus
from solvers.models import shuttle as sh
from solvers.models.reentry_state import STATE_NAMES, Trajectory
from solvers.reentry.terminal import TerminalTolerance
from solvers.verification import Verification

OBJECTIVES = ("max_crossrange", "max_downrange", "max_great_circle_range", "min_heat_load",
              "min_time")
# State and control scaling: solvers.models.reentry_state; time in 1000 s (Betts).
T_SCALE = 1000.0
HEAT_LOAD_SCALE = 1e12    # sqrt(kg/m^3) m^3/s^2 s: J is ~5e12 for paper 000's case 3


@dataclass
class Terminal:
    """Terminal equalities; ``None`` leaves that component free."""

    altitude_m: float | None = None
    longitude_rad: float | None = None
    latitude_rad: float | None = None
    speed_mps: float | None = None
    flight_path_rad: float | None = None
    heading_rad: float | None = None

    def as_array(self) -> np.ndarray:
        """(NX,) in the state's order, NaN where free."""
        values = (getattr(self, name) for name in STATE_NAMES)
        return np.array([np.nan if v is None else v for v in values], float)


@dataclass
class ReentryProblem:
    vehicle: sh.Vehicle = field(default_factory=lambda: sh.SHUTTLE)
    initial_state: tuple = sh.BETTS_INITIAL_STATE
    terminal: Terminal = field(default_factory=lambda: Terminal(
        altitude_m=sh.BETTS_TERMINAL["altitude_m"], speed_mps=sh.BETTS_TERMINAL["speed_mps"],
        flight_path_rad=sh.BETTS_TERMINAL["flight_path_rad"]))
    objective: str = "max_crossrange"
    alpha_bounds_rad: tuple[float, float] = sh.BETTS_ALPHA_BOUNDS_RAD
    bank_bounds_rad: tuple[float, float] = sh.BETTS_BANK_BOUNDS_RAD
    max_heat_rate_w_m2: float | None = None
    max_dynamic_pressure_pa: float | None = None
    max_load_factor: float | None = None
    # "substeps" by default: the limit at every RK4 step point (nodes and, with 2 substeps, each
    # midpoint) leaves a fifth of the overshoot between points that "nodes" leaves (0.09% vs 1.15%
    # at 50 intervals), so the answer gives up less to the tightening rounds.
    path_enforcement: str = "substeps"     # "nodes" | "midpoints" | "substeps" | "integral"
    intervals: int = 100
    control: str = "linear"                # "linear" | "constant"
    # RK4 steps per interval: at 100 intervals, 2 steps put the final state within 0.13 m and
    # 5 mm/s of DOP853 at rtol 1e-10 (4 steps: 5 mm) for half the Hessian cost of 4.
    substeps: int = 2
    tf_bounds_s: tuple[float, float] = (100.0, 10000.0)
    min_speed_mps: float = sh.BETTS_MIN_SPEED_MPS
    verify: bool = True
    # Limits that hold: the answer must keep every path limit on the verification's dense grid
    # (``verify_samples`` points per interval) to ``limit_tolerance`` of the limit; up to
    # ``limit_rounds`` warm-started re-solves tighten the limit on the intervals that overshoot.
    limit_tolerance: float | None = 1e-3     # None: report the dense maximum only, never fail
    limit_rounds: int = 6
    verify_samples: int = 20
    # Terminal conditions that hold (solvers.reentry.terminal): the re-propagated final state must
    # meet every fixed terminal value to ``terminal_tolerance``; up to ``terminal_rounds`` warm
    # re-solves with more substeps, else ``terminal_not_held``.  None: report the miss, never fail.
    terminal_tolerance: TerminalTolerance | None = field(default_factory=TerminalTolerance)
    terminal_rounds: int = 3
    # Mesh refinement (solvers.reentry.refine): the intervals raised until the re-propagated states
    # agree with the answer to ``accuracy`` (scaled by each state's scale), at most
    # ``max_refinements`` rounds; short of it ``accuracy_not_reached`` unless not ``accuracy_required``.
    accuracy: float | None = None
    accuracy_required: bool = True
    max_refinements: int = 8
    ipopt: dict = field(default_factory=dict)

    def __post_init__(self):
        if self.objective not in OBJECTIVES:
            raise ValueError(f"objective must be one of {OBJECTIVES}")
        if self.control not in ("linear", "constant"):
            raise ValueError("control must be 'linear' or 'constant'")


@dataclass
class ReentrySolution:
    status: SolveStatus
    objective_name: str
    objective_value: float          # in objective_unit
    objective_unit: str             # "rad", "s" or the heat load's SI unit
    tf_s: float
    t: np.ndarray
    x: np.ndarray                   # (6, m+1)
    u: np.ndarray                   # (2, m+1) linear or (2, m) constant
    u_nodes_at_t: np.ndarray        # controls at every node (2, m+1), as the transcription defines
    heat_rate: np.ndarray           # W/m^2 at the nodes
    verification: Verification | None
    notes: list[str] = field(default_factory=list)
    stages: list[dict] = field(default_factory=list)

    @property
    def trajectory(self) -> Trajectory:
        """The nodes as a :class:`Trajectory` (controls at every node, heating rate)."""
        return Trajectory(t=self.t, x=self.x, u=self.u_nodes_at_t, path={"heat_rate_w_m2": self.heat_rate})
