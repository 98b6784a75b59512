"""The ``reentry`` kind's typed result (``ReentryResult``) and its blocks, which the robust kind's
result reuses. Conventions: :mod:`app.kinds.result_models`."""
from __future__ import annotations

from typing import Any

from pydantic import Field

from app.kinds.result_models import Num, ResultModel, Series, series


# --- blocks shared by the reentry family (reentry, robust_reentry) -------------------------------------
class ReentryResultObjective(ResultModel):
    """The objective the solver optimized, in API units (the solver's rad reported as deg)."""

    name: str = Field(description="Objective name, e.g. max_crossrange, max_downrange, min_heat_load")
    value: Num = Field(description="Optimal value, in `unit`")
    unit: str = Field(description="Unit of `value`: deg for angles, J/m^2-like SI for heat load")


class ReentryResultFinalState(ResultModel):
    """The state at the final time."""

    altitude_m: Num = Field(description="Altitude above the spherical Earth (m)")
    speed_mps: Num = Field(description="Earth-relative speed (m/s)")
    flight_path_deg: Num = Field(description="Flight-path angle (deg)")
    latitude_deg: Num = Field(description="Geocentric latitude (deg)")
    longitude_deg: Num = Field(description="Longitude (deg)")
    heading_deg: Num = Field(description="Heading, clockwise from north (deg)")


class ReentryResultTrajectory(ResultModel):
    """States, controls and path quantities at the transcription's nodes (equal-length arrays)."""

    t_s: Series = series("Time since entry", "s")
    altitude_m: Series = series("Altitude", "m")
    longitude_deg: Series = series("Longitude", "deg")
    latitude_deg: Series = series("Latitude", "deg")
    speed_mps: Series = series("Speed", "m/s")
    flight_path_deg: Series = series("Flight-path angle", "deg")
    heading_deg: Series = series("Heading", "deg")
    alpha_deg: Series = series("Angle of attack", "deg")
    bank_deg: Series = series("Bank angle", "deg")
    heat_rate_w_m2: Series = series("Stagnation-point heating rate", "W/m^2")
    dynamic_pressure_pa: Series | None = Field(None, description="Dynamic pressure (Pa), when computed")
    load_factor: Series | None = Field(None, description="Aerodynamic load factor (g, dimensionless), when computed")


class ReentryResultSolverStage(ResultModel):
    """One IPOPT solve of the run (e.g. without path limits, then the full problem)."""

    stage: str = Field(description="Which solve: 'without path limits', 'full problem', 'deterministic', 'robust ...'")
    status: str = Field(description="IPOPT's return status of this stage")
    iterations: int = Field(description="IPOPT iterations of this stage")
    solve_time_s: Num = Field(description="Wall time of this stage's solve (s)")
    sub_stage: str | None = Field(None, description="robust_reentry: the deterministic solver's own stage")


class ReentryResultSolver(ResultModel):
    """IPOPT's account of the solve (iterations and times summed over the stages)."""

    status: str = Field(description="IPOPT's return status, e.g. Solve_Succeeded")
    iterations: int = Field(description="IPOPT iterations, all stages")
    solve_time_s: Num = Field(description="Solve wall time (s)")
    build_time_s: Num = Field(description="NLP and solver build time (s); ~0 when cached")
    max_constraint_violation: Num = Field(description="Worst constraint violation at the solution (scaled NLP units)")
    cached_build: bool = Field(description="The compiled NLP came from the per-process cache")
    stages: list[ReentryResultSolverStage] = Field(description="One entry per IPOPT solve")
    refinement: list[dict[str, Any]] | None = Field(
        None, description="With `accuracy`: each round's intervals, worst scaled state error (max_error), "
        "objective, iterations and time_s; absent without accuracy")
    accuracy: Num = Field(None, description="The accuracy the grid was refined to (absent: none asked)")
    accuracy_reached: bool | None = Field(None, description="The refinement reached `accuracy`")


class ReentryResultDenseTrajectory(ResultModel):
    """The verification's re-propagated trajectory, at most 500 evenly spaced points (for plots)."""

    t_s: Series = series("Time since entry", "s")
    altitude_m: Series = series("Altitude", "m")
    speed_mps: Series = series("Speed", "m/s")
    flight_path_deg: Series = series("Flight-path angle", "deg")
    latitude_deg: Series = series("Latitude", "deg")
    longitude_deg: Series = series("Longitude", "deg")
    heat_rate_w_m2: Series | None = Field(None, description="Heating rate (W/m^2)")
    dynamic_pressure_pa: Series | None = Field(None, description="Dynamic pressure (Pa)")
    load_factor: Series | None = Field(None, description="Load factor (g, dimensionless)")


class ReentryResultLimitCheck(ResultModel):
    """One path limit checked on the dense re-propagation (limits that hold)."""

    limit: Num = Field(description="The limit, in the quantity's unit (W/m^2, Pa or g)")
    max: Num = Field(description="Worst value on the dense grid (same unit)")
    max_t_s: Num = Field(description="Time of that worst value (s)")
    excess_percent: Num = Field(description="Worst value over the limit, in percent of the limit (negative: margin)")
    tolerance_percent: Num = Field(description="How far above the limit still counts as held (percent)")
    held: bool = Field(description="The worst value is within the tolerance of the limit")


class ReentryResultTerminalCheck(ResultModel):
    """One requested final value checked on the dense re-propagation (terminal conditions that hold)."""

    requested: Num = Field(description="The requested final value (m, m/s or deg)")
    reached: Num = Field(description="Where the re-propagated controls end (same unit)")
    miss: Num = Field(description="reached - requested (same unit)")
    tolerance: Num = Field(description="The largest |miss| that counts as held (terminal_check)")
    error_estimate: Num = Field(None, description="The re-propagation's own step-doubling error estimate there")
    held: bool = Field(description="|miss| <= tolerance")


class ReentryResultVerification(ResultModel):
    """The optimal controls re-propagated with an accurate integrator, independent of the transcription."""

    method: str = Field(description="Integrator and tolerance used")
    final_altitude_diff_m: Num = Field(description="Re-propagated minus optimized final altitude (m)")
    final_longitude_diff_deg: Num = Field(description="Final longitude difference (deg)")
    final_latitude_diff_deg: Num = Field(description="Final latitude difference (deg)")
    final_speed_diff_mps: Num = Field(description="Final speed difference (m/s)")
    final_flight_path_diff_deg: Num = Field(description="Final flight-path angle difference (deg)")
    final_heading_diff_deg: Num = Field(description="Final heading difference (deg)")
    max_node_altitude_diff_m: Num = Field(description="Largest altitude difference at any node (m)")
    max_node_latitude_diff_deg: Num = Field(description="Largest latitude difference at any node (deg)")
    max_heat_rate_w_m2: Num = Field(description="Peak heating rate on the dense re-propagation (W/m^2)")
    max_heat_rate_t_s: Num = Field(description="Time of that peak (s)")
    max_heat_rate_nodes_w_m2: Num = Field(description="Peak heating rate at the NLP nodes only (W/m^2)")
    max_dynamic_pressure_pa: Num = Field(description="Peak dynamic pressure, dense (Pa)")
    max_load_factor: Num = Field(description="Peak load factor, dense (g, dimensionless)")
    dense_samples: int = Field(description="Points of the dense re-propagation")
    samples_per_interval: int | None = Field(None, description="Dense points per shooting interval")
    error_estimate_altitude_m: Num = Field(None, description="Step-doubling estimate of the dense "
                                           "trajectory's altitude error, worst over time (m)")
    error_estimate_speed_mps: Num = Field(None, description="Same for speed (m/s)")
    error_estimate_latitude_deg: Num = Field(None, description="Same for latitude (deg)")
    limits: dict[str, ReentryResultLimitCheck] | None = Field(
        None, description="Per limited path quantity (heat_rate_w_m2, dynamic_pressure_pa, load_factor): "
        "worst dense value, limit, held")
    limits_held: bool | None = Field(None, description="Every path limit held on the dense grid "
                                     "(null: no limit set)")
    terminal: dict[str, ReentryResultTerminalCheck] | None = Field(
        None, description="Per requested final value (altitude_m, speed_mps, flight_path_deg, ...): "
        "requested, re-propagated, miss, tolerance, held")
    terminal_held: bool | None = Field(None, description="Every requested final value met on the dense "
                                       "re-propagation within its tolerance (null: none requested)")
    ok: bool = Field(description="The integrator reached the final time")
    message: str = Field(description="The integrator's message (empty when ok)")
    time_s: Num = Field(description="Wall time of the verification (s)")
    trajectory: ReentryResultDenseTrajectory | None = Field(None, description="The dense trajectory, thinned")


class ReentryResult(ResultModel):
    """Result of a ``reentry`` job: the optimal trajectory, its solve and its independent verification."""

    objective: ReentryResultObjective = Field(description="The optimized objective")
    tf_s: Num = Field(description="Final time (s)")
    final: ReentryResultFinalState = Field(description="State at the final time")
    trajectory: ReentryResultTrajectory = Field(description="Time series at the nodes")
    solver: ReentryResultSolver = Field(description="IPOPT's account of the solve")
    notes: list[str] = Field(description="Where this result differs from a paper or how it was obtained")
    verification: ReentryResultVerification | None = Field(
        description="The controls re-propagated independently; null when not run")
