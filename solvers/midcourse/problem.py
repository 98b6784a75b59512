"""The midcourse kind's problem and solution: :class:`MidcourseProblem` (one transfer with its
navigation error, SI), :class:`Dispersion`, :class:`GASettings`, :class:`ScheduleResult`,
:class:`MidcourseSolution`, and :func:`paper_problem` (paper 002's case built from the numbers in
:mod:`solvers.midcourse.cases`).

Held apart from :mod:`solvers.midcourse.solver` so that the search (:mod:`.search`), the
trajectories (:mod:`.trajectory`) and the paper's case read them without importing the solve.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from solvers.astro.j2 import GravityConstants, LaunchFrame
from solvers.common import SolveStatus
from solvers.midcourse import cases

OBJECTIVE_NAMES = ("delta_v_mps", "position_error_m", "velocity_error_mps")


@dataclass(frozen=True)
class Dispersion:
    """Monte Carlo over the initial error: Gaussian, with the problem's errors as 3-sigma."""

    samples: int = 100
    percentile: float = 99.0
    seed: int = 0
    statistic: Literal["mean", "percentile"] = "percentile"   # what the GA minimizes


@dataclass(frozen=True)
class GASettings:
    """NSGA-II settings (paper Table 4: 100 x 500, crossover 0.8, mutation 0.1)."""

    population: int = 100
    generations: int = 500
    crossover_prob: float = 0.8       # per mating pair (SBX)
    mutation_prob: float = 0.1        # per decision variable (polynomial mutation)
    crossover_eta: float = 15.0
    mutation_eta: float = 20.0
    # Off by default: with the paper's low mutation rate most offspring copy a
    # parent, and eliminating them makes pymoo re-mate ~5 times per generation
    # (2x the run time) for no gain in hypervolume; the survival gives exact
    # copies zero crowding distance instead, so they are dropped first.
    eliminate_duplicates: bool = False


@dataclass
class MidcourseProblem:
    """One transfer with its navigation error; positions in the problem's frame (m, m/s, s).

    ``frame.r0`` is the geocentric vector of the frame origin: zero for an
    Earth-centred inertial frame.  ``position_error``/``velocity_error`` are a
    fixed offset, or the 3-sigma of the Gaussian when ``dispersion`` is set.
    """

    r0: np.ndarray
    v0: np.ndarray
    r_target: np.ndarray
    v_target: np.ndarray
    tf_s: float = 12900.0                  # the target is reached at tf_s
    position_error: np.ndarray = field(default_factory=lambda: np.zeros(3))
    velocity_error: np.ndarray = field(default_factory=lambda: np.zeros(3))
    frame: LaunchFrame = field(default_factory=LaunchFrame.eci)
    constants: GravityConstants = GravityConstants()
    mode: Literal["evaluate", "optimize"] = "optimize"
    schedules: list[list[float]] = field(default_factory=list)
    corrections: int = 2
    time_bounds: tuple[float, float] = (0.0, 12800.0)
    min_spacing: float = cases.MIN_SPACING_S
    ga: GASettings = GASettings()
    dispersion: Dispersion | None = None
    hypervolume_reference: tuple[float, float, float] = (150.0, 2000.0, 70.0)
    tol: float = 1e-12


@dataclass
class ScheduleResult:
    times: np.ndarray               # (k,) s
    objectives: np.ndarray          # (3,) the statistic minimized (or the only sample)
    mean: np.ndarray | None = None  # (3,) with a dispersion
    percentile: np.ndarray | None = None
    impulses: np.ndarray | None = None   # (k, 3) m/s, fixed-offset case only
    lambert_failures: int = 0            # samples whose Lambert problem did not converge


@dataclass
class MidcourseSolution:
    status: SolveStatus
    pareto_times: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))   # (n, k) s
    pareto_objectives: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    pareto_mean: np.ndarray | None = None
    pareto_percentile: np.ndarray | None = None
    hypervolume: float = 0.0
    hypervolume_reference: tuple[float, float, float] = (0.0, 0.0, 0.0)
    generations: int = 0
    evaluations: int = 0
    seed: int | None = None
    schedules: list[ScheduleResult] = field(default_factory=list)
    uncorrected: np.ndarray | None = None      # (3,) objectives with no correction
    nominal_miss: tuple[float, float] = (0.0, 0.0)   # error-free coast: |dr| m, |dv| m/s
    lambert_failures: int = 0
    evaluation_time_s: float = 0.0


def paper_problem(**overrides) -> MidcourseProblem:
    """Paper 002's transfer with its initial error; ``overrides`` replace any field (mode, schedules, ga, ...)."""
    base = dict(r0=np.array(cases.R0_M), v0=np.array(cases.V0_MPS), r_target=np.array(cases.R_TARGET_M),
                v_target=np.array(cases.V_TARGET_MPS), tf_s=cases.TF_S,
                position_error=np.array(cases.POSITION_ERROR_M),
                velocity_error=np.array(cases.VELOCITY_ERROR_MPS), frame=cases.paper_frame())
    return MidcourseProblem(**{**base, **overrides})
