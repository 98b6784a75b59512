"""The robust reentry kind's problem and solution: :class:`RobustReentryProblem` (the deterministic
problem, the :class:`Uncertainty`, the :class:`RobustSettings`), :class:`Prediction`,
:class:`RobustReentrySolution`, and the NLP's scaling constants.

Held apart from :mod:`solvers.robust_reentry.solver` so that the Monte Carlo model
(:mod:`solvers.robust_reentry.mc`) and the solve both read them without importing each other.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from solvers.reentry.problem import ReentryProblem, ReentrySolution
from solvers.common import SolveStatus
from solvers.models import shuttle as sh
from solvers.models.reentry_state import NX, Trajectory

if TYPE_CHECKING:
    from solvers.transcription.multiple_shooting import ShootingResult

NS = 2   # uncertain parameters: relative errors of (CD, CL)
# IPOPT restarted from a converged neighbour's primal and dual point (stage 2, the confirmation
# re-solves): a small barrier parameter and small pushes off the bounds keep that point.
WARM_IPOPT = {"warm_start_init_point": "yes", "mu_init": 1e-5, "warm_start_bound_push": 1e-6,
              "warm_start_mult_bound_push": 1e-6}
# Typical 1-sigma spreads, for scaling the covariance entries to O(1) in the NLP.
SIGMA_SCALE = (3000.0, 0.005, 0.005, 100.0, 0.01, 0.01)
S_SCALE = (0.01, 0.01)
# Normalizers of the terminal variance constraints (the paper's limits)
SIGMA_NORM = {"altitude_m": 4500.0, "speed_mps": 250.0, "flight_path_rad": 3.0 * sh.DEG}


@dataclass
class Uncertainty:
    """Relative aerodynamic errors (paper 001 eq. 12) and optional initial-state dispersions (SI, rad)."""

    s_mean: tuple[float, float] = (0.01, -0.01)       # (cd, cl)
    s_std: tuple[float, float] = (0.01, 0.01)
    x0_std: tuple[float, ...] | None = None

    @property
    def s_cov(self) -> np.ndarray:
        return np.diag(np.asarray(self.s_std, float) ** 2)

    @property
    def r0(self) -> int:
        """Rank of the initial covariance: the number of initial-state error directions."""
        return 0 if self.x0_std is None else int(np.count_nonzero(np.asarray(self.x0_std, float)))

    @property
    def x0_cov(self) -> np.ndarray:
        if self.x0_std is None:
            return np.zeros((NX, NX))
        return np.diag(np.asarray(self.x0_std, float) ** 2)


@dataclass
class RobustSettings:
    k_objective: float = 3.0
    k_constraint: float = 3.0
    # sigma(h_f) [m], sigma(v_f) [m/s], sigma(gamma_f) [rad]; None drops a limit.
    sigma_limits: dict = field(default_factory=lambda: {
        "altitude_m": 4500.0, "speed_mps": 250.0, "flight_path_rad": 3.0 * sh.DEG})
    # First-order CADET in the NLP (second order costs 4x per iteration); the reported
    # predictions use the second-order mean (see predict()).
    second_order: bool = False
    # The robust heating limit is checked at the nodes and every RK4 substep; a relative
    # margin on top covers what still slips between substeps.
    heat_margin: float = 0.0
    substeps: int = 2
    # Paper 001's pitfall: single-stage solves diverged, so stage 1 (kJ = kC = 0, no sigma
    # limits) precedes the full problem.  Stage 1 is only a guess, so it stops at a loose
    # tolerance.  With the consistent CADET guess and a monotone barrier the full problem
    # also converges directly ("direct"): same optimum, about half the time (benchmarks/robust.py).
    continuation: str = "two_stage"        # "two_stage" | "direct"
    stage1_tol: float = 1e-4
    # Stage 1 starts at the CADET propagation along the DO controls, already near its optimum
    # (the DO re-solved with s = mu_s): a barrier of 1e-3 pushed it back into the interior and
    # took 27 iterations to return; 3e-5 takes 14 (stage 2 then 18: 32 in all instead of 45;
    # 1e-5 .. 1e-4 gave 35-45, same optimum within 1e-6 s).
    stage1_mu_init: float = 3e-5


@dataclass
class RobustReentryProblem:
    base: ReentryProblem = field(default_factory=lambda: ReentryProblem(
        max_heat_rate_w_m2=sh.BETTS_HEAT_LIMIT_W_M2))
    uncertainty: Uncertainty = field(default_factory=Uncertainty)
    robust: RobustSettings = field(default_factory=RobustSettings)

    def __post_init__(self):
        if self.base.objective != "max_crossrange":
            raise ValueError("robust_reentry supports objective 'max_crossrange' (paper 001)")
        if self.base.max_heat_rate_w_m2 is None:
            raise ValueError("robust_reentry needs a heating limit (paper 001's active constraint)")
        if self.base.control != "linear":
            raise ValueError("robust_reentry uses piecewise-linear controls")


@dataclass
class Prediction:
    """CADET statistics along a solution's controls: means and sigmas at the nodes."""

    t: np.ndarray
    mean: np.ndarray          # (6, m+1)
    sigma: np.ndarray         # (6, m+1)
    heat_mean: np.ndarray     # (m+1,) W/m^2
    heat_sigma: np.ndarray    # (m+1,) W/m^2

    @property
    def terminal_sigma(self) -> np.ndarray:
        return self.sigma[:, -1]


@dataclass
class RobustReentrySolution:
    status: SolveStatus
    deterministic: ReentrySolution
    tf_s: float
    t: np.ndarray
    x: np.ndarray                 # mean states (6, m+1)
    u: np.ndarray                 # (2, m+1)
    objective_value: float        # mu(lat_f) - kJ sigma(lat_f), in objective_unit
    heat_rate: np.ndarray         # mean heating rate at the nodes, W/m^2
    robust_prediction: Prediction | None
    deterministic_prediction: Prediction | None
    verification: object | None   # nominal (s = mu_s) re-propagation, solvers.verification
    stages: list[dict] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    objective_unit: str = "rad"
    augmented: np.ndarray | None = None   # packed CADET nodes (nz, m+1): the warm start of resolve()
    shooting: ShootingResult | None = None        # the NLP result (multipliers): resolve()'s dual warm start

    @property
    def trajectory(self) -> Trajectory:
        """The mean nodes as a :class:`Trajectory` (mean heating rate)."""
        return Trajectory(t=self.t, x=self.x, u=self.u, path={"heat_rate_w_m2": self.heat_rate})
