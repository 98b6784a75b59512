"""The typed result of a ``midcourse`` job (paper 002): the Pareto front of correction schedules.

Conventions and the drift test: :mod:`app.kinds.result_models`.
"""
from __future__ import annotations

from typing import Literal

from pydantic import Field

from app.kinds.result_models import Num, ResultModel


class MidcourseResultStatistics(ResultModel):
    """The three objectives of a schedule under one statistic over the dispersion samples."""

    delta_v_mps: Num = Field(description="Total correction delta-v (m/s)")
    position_error_m: Num = Field(description="Final position error against the target (m)")
    velocity_error_mps: Num = Field(description="Final velocity error against the target (m/s)")


class MidcourseResultPoint(ResultModel):
    """One correction schedule: its times and objectives (a front point, or an evaluated schedule)."""

    times_s: list[float] = Field(description="Correction times after t0 (s); empty: no correction")
    delta_v_mps: Num = Field(description="Total correction delta-v (m/s); with a dispersion, the statistic minimized")
    position_error_m: Num = Field(description="Final position error (m)")
    velocity_error_mps: Num = Field(description="Final velocity error (m/s)")
    mean: MidcourseResultStatistics | None = Field(None, description="Mean over the dispersion samples")
    percentile: MidcourseResultStatistics | None = Field(
        None, description="The dispersion's percentile (settings.dispersion.percentile) over the samples")
    impulses_mps: list[list[Num]] | None = Field(
        None, description="evaluate mode without a dispersion: each correction's impulse (m/s, frame axes)")
    lambert_converged: bool | None = Field(None, description="evaluate mode: every Lambert problem converged")


class MidcourseResultObjectiveBox(ResultModel):
    """A point in objective space (the hypervolume's reference)."""

    delta_v_mps: Num = Field(description="Delta-v (m/s)")
    position_error_m: Num = Field(description="Position error (m)")
    velocity_error_mps: Num = Field(description="Velocity error (m/s)")


class MidcourseResultNominalMiss(ResultModel):
    """The error-free nominal coast against the target: how well the nominal itself lands."""

    position_m: Num = Field(description="Final position miss of the nominal (m)")
    velocity_mps: Num = Field(description="Final velocity miss of the nominal (m/s)")


class MidcourseResultDispersion(ResultModel):
    """The Monte Carlo over the initial error, as run."""

    samples: int = Field(description="Samples of the initial error")
    percentile: Num = Field(description="Percentile reported (and minimized when statistic is percentile)")
    seed: int = Field(description="Seed of the samples")
    statistic: str = Field(description="What the GA minimizes: mean or percentile")


class MidcourseResultSettings(ResultModel):
    """The settings the run used (echoed from the parameters)."""

    corrections: int = Field(description="Corrections per schedule (optimize mode)")
    population: int = Field(description="NSGA-II population")
    generations: int = Field(description="NSGA-II generations asked for")
    crossover_prob: Num = Field(description="Crossover probability per mating pair")
    mutation_prob: Num = Field(description="Mutation probability per variable")
    eliminate_duplicates: bool = Field(description="Offspring that copy a member were mated again")
    time_bounds_s: list[float] = Field(description="Bounds of the correction times (s)")
    min_spacing_s: Num = Field(description="Minimum spacing between corrections (s)")
    tf_s: Num = Field(description="Time at which the target is reached (s)")
    frame: str = Field(description="Frame of positions and velocities: launch (launch-inertial) or eci")
    seed: int | None = Field(description="GA seed")
    dispersion: MidcourseResultDispersion | None = Field(description="Monte Carlo over the initial error; null: fixed error")
    objectives: str = Field(description="What the objectives are: 'fixed initial error', 'mean' or 'percentile'")


class MidcourseResultSolver(ResultModel):
    """The search's account (NSGA-II or direct evaluation)."""

    status: str = Field(description="finished or cancelled")
    iterations: int = Field(description="Generations run (0 in evaluate mode)")
    solve_time_s: Num = Field(description="Search time (s)")
    build_time_s: Num = Field(description="Set-up time: integrator compilation, uncorrected coasts (s)")
    max_constraint_violation: Num = Field(description="Always 0 (no constraints beyond the bounds)")
    evaluation_time_s: Num = Field(description="Time spent evaluating schedules (s)")


class MidcourseResult(ResultModel):
    """Result of a ``midcourse`` job: the non-dominated correction schedules and their quality."""

    mode: Literal["optimize", "evaluate"] = Field(description="optimize (NSGA-II) or evaluate (given schedules)")
    pareto_front: list[MidcourseResultPoint] = Field(
        description="Non-dominated schedules, by delta-v then position error")
    hypervolume: Num = Field(description="Dominated fraction (0-1) of the reference box, objectives normalized")
    hypervolume_reference: MidcourseResultObjectiveBox = Field(description="The hypervolume's reference point")
    hypervolume_definition: str = Field(description="How the hypervolume is computed")
    generations: int = Field(description="Generations run (0 in evaluate mode)")
    evaluations: int = Field(description="Schedules evaluated")
    seed: int | None = Field(description="GA seed (optimize mode)")
    schedules: list[MidcourseResultPoint] | None = Field(
        description="evaluate mode: one entry per requested schedule, in order; null in optimize mode")
    uncorrected: MidcourseResultStatistics | None = Field(description="Objectives with no correction at all")
    nominal_miss: MidcourseResultNominalMiss = Field(description="Miss of the error-free nominal coast")
    settings: MidcourseResultSettings = Field(description="Settings the run used")
    lambert_failures: int = Field(description="Candidate evaluations whose Lambert problem did not converge")
    solver: MidcourseResultSolver = Field(description="The search's account")
    wall_time_s: Num = Field(description="Wall time of the job's run (s)")
    notes: list[str] = Field(description="Frame, fit to the paper, dispersion, failures")
