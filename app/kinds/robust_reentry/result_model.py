"""The typed result of a ``robust_reentry`` job (paper 001): the robust design with its CADET
sigmas, the deterministic design, and the Monte Carlo of both.

Conventions and the drift test: :mod:`app.kinds.result_models`.  The reentry blocks (final state,
solver, verification) are the ``reentry`` kind's.  The default ``GET /result`` body keeps 20
``sample_traces`` per quantity and design; ``?include=samples`` returns them all: same fields.
"""
from __future__ import annotations

from pydantic import Field

from app.kinds.reentry.result_model import (
    ReentryResultFinalState, ReentryResultObjective, ReentryResultSolver, ReentryResultTrajectory,
    ReentryResultVerification,
)
from app.kinds.result_models import Num, ResultModel, Series, series


class RobustResultObjective(ReentryResultObjective):
    """mu(lat_f) - kJ sigma(lat_f) of the robust design, with its parts (CADET prediction)."""

    mean_latitude_deg: Num = Field(description="CADET mean of the final latitude (deg)")
    sigma_latitude_deg: Num = Field(description="CADET standard deviation of the final latitude (deg)")
    k_objective: Num = Field(description="kJ, the sigma multiplier of the objective (dimensionless)")
    source: str | None = Field(None, description="Where `value` comes from: monte_carlo (mean - kJ std of "
                               "the design's Monte Carlo, the default) or cadet (the NLP's first-order "
                               "prediction, when the Monte Carlo gave no estimate; the notes say why)")
    cadet_value: Num = Field(None, description="CADET's mean - kJ sigma, the figure the NLP optimized (deg)")
    standard_error: Num = Field(None, description="Standard error of the Monte Carlo's value (deg)")


class RobustResultTrajectory(ReentryResultTrajectory):
    """The robust design's nodes, with CADET's 1-sigma of the main states along them."""

    heat_rate_sigma_w_m2: Series = series("CADET 1-sigma of the heating rate", "W/m^2")
    altitude_sigma_m: Series = series("CADET 1-sigma of the altitude", "m")
    latitude_sigma_deg: Series = series("CADET 1-sigma of the latitude", "deg")
    speed_sigma_mps: Series = series("CADET 1-sigma of the speed", "m/s")
    flight_path_sigma_deg: Series = series("CADET 1-sigma of the flight-path angle", "deg")


class RobustResultFinalSigma(ResultModel):
    """CADET's 1-sigma of the final state of the robust design."""

    altitude_m: Num = Field(description="sigma of the final altitude (m)")
    speed_mps: Num = Field(description="sigma of the final speed (m/s)")
    flight_path_deg: Num = Field(description="sigma of the final flight-path angle (deg)")
    latitude_deg: Num = Field(description="sigma of the final latitude (deg)")


class RobustResultDeterministic(ResultModel):
    """The deterministic design (no uncertainty), solved first and reported side by side."""

    objective: ReentryResultObjective = Field(description="Its objective (final latitude, deg)")
    tf_s: Num = Field(description="Its final time (s)")
    final: ReentryResultFinalState = Field(description="Its final state")
    trajectory: ReentryResultTrajectory = Field(description="Its nodes")
    solver: ReentryResultSolver = Field(description="Its IPOPT solve")


class RobustResultTerminalStatistic(ResultModel):
    """One terminal quantity over the Monte Carlo samples, CADET's prediction beside it (unit: the key's)."""

    mean: Num = Field(description="Monte Carlo mean (unit of the quantity)")
    std: Num = Field(description="Monte Carlo standard deviation (unit of the quantity)")
    cadet_mean: Num = Field(description="CADET second-order mean prediction (unit of the quantity)")
    cadet_std: Num = Field(description="CADET standard deviation prediction (unit of the quantity)")
    mean_difference_in_sigma: Num = Field(description="(mean - cadet_mean) / cadet_std (dimensionless)")


class RobustResultTerminalStatistics(ResultModel):
    """Each terminal state over the samples."""

    altitude_m: RobustResultTerminalStatistic = Field(description="Final altitude (m)")
    longitude_deg: RobustResultTerminalStatistic = Field(description="Final longitude (deg)")
    latitude_deg: RobustResultTerminalStatistic = Field(description="Final latitude (deg)")
    speed_mps: RobustResultTerminalStatistic = Field(description="Final speed (m/s)")
    flight_path_deg: RobustResultTerminalStatistic = Field(description="Final flight-path angle (deg)")
    heading_deg: RobustResultTerminalStatistic = Field(description="Final heading (deg)")


class RobustResultMonteCarloObjective(ResultModel):
    """The objective's quantity (final latitude) over the samples."""

    name: str = Field(description="The quantity: latitude_deg")
    mean: Num = Field(description="Monte Carlo mean (deg)")
    std: Num = Field(description="Monte Carlo standard deviation (deg)")
    mean_minus_k_std: Num = Field(description="mean - kJ std, the robust objective measured (deg)")
    standard_error: Num = Field(None, description="Its standard error: std sqrt(1/n + kJ^2 / (2 (n - 1))) (deg)")
    cadet_mean: Num = Field(description="CADET mean (deg)")
    cadet_std: Num = Field(description="CADET standard deviation (deg)")


class RobustResultWithin(ResultModel):
    """Fraction of samples whose terminal value lies within the required value +- a band."""

    within_required_pm_sigma_cadet: Num = Field(None, description="Band: the design's CADET sigma (fraction 0-1)")
    within_required_pm_sigma_limit: Num = Field(None, description="Band: the sigma limit (fraction 0-1)")


class RobustResultTerminalWithin(ResultModel):
    """Terminal requirements met, per constrained terminal quantity."""

    altitude_m: RobustResultWithin | None = Field(None, description="Final altitude")
    speed_mps: RobustResultWithin | None = Field(None, description="Final speed")
    flight_path_deg: RobustResultWithin | None = Field(None, description="Final flight-path angle")
    latitude_deg: RobustResultWithin | None = Field(None, description="Final latitude")
    longitude_deg: RobustResultWithin | None = Field(None, description="Final longitude")
    heading_deg: RobustResultWithin | None = Field(None, description="Final heading")


class RobustResultBand(ResultModel):
    """Mean and standard deviation of one quantity over the samples, at the envelope's times."""

    mean: Series = Field(description="Mean over the samples (unit of the quantity)")
    std: Series = Field(description="Standard deviation over the samples (unit of the quantity)")


class RobustResultEnvelope(ResultModel):
    """Monte Carlo envelopes for the plots (mean and std against time)."""

    t_s: Series = series("Time since entry", "s")
    altitude_m: RobustResultBand | None = Field(None, description="Altitude (m)")
    speed_mps: RobustResultBand | None = Field(None, description="Speed (m/s)")
    heat_rate_w_m2: RobustResultBand | None = Field(None, description="Heating rate (W/m^2)")


class RobustResultSampleTraces(ResultModel):
    """A few sampled trajectories at the envelope's times (20 in the default body, all with ?include=samples)."""

    altitude_m: list[Series] | None = Field(None, description="Altitude traces (m)")
    speed_mps: list[Series] | None = Field(None, description="Speed traces (m/s)")
    heat_rate_w_m2: list[Series] | None = Field(None, description="Heating-rate traces (W/m^2)")


class RobustResultTerminalSamples(ResultModel):
    """Terminal values of the samples (for the terminal scatter)."""

    altitude_m: Series | None = Field(None, description="Final altitudes (m)")
    speed_mps: Series | None = Field(None, description="Final speeds (m/s)")
    flight_path_deg: Series | None = Field(None, description="Final flight-path angles (deg)")


class RobustResultDistribution(ResultModel):
    """Which workers computed which chunks, when the Monte Carlo was fanned out."""

    chunks: int = Field(description="Chunks the samples were split into")
    chunk_size: int = Field(description="Samples per chunk")
    computed_by: dict[str, int] = Field(description="Chunks computed, per worker name")


class RobustResultMonteCarloDesign(ResultModel):
    """One design's open-loop controls flown over the Monte Carlo samples."""

    samples: int = Field(description="Samples flown")
    failed_samples: int = Field(description="Samples whose integration failed")
    distribution: RobustResultDistribution | None = Field(None, description="Fan-out over workers (large runs)")
    terminal: RobustResultTerminalStatistics = Field(description="Terminal statistics")
    objective: RobustResultMonteCarloObjective = Field(description="The objective's quantity")
    terminal_within_required: RobustResultTerminalWithin = Field(description="Terminal requirements met")
    heat_rate_kept_fraction: Num = Field(description="Share of samples keeping the heating limit over the "
                                                     "whole flight, fine grid (fraction 0-1)")
    heat_rate_kept_fraction_nodes: Num = Field(description="The same at the NLP nodes only (fraction 0-1)")
    heat_rate_worst_w_m2: Num = Field(description="Worst heating rate of any sample (W/m^2)")
    heat_rate_limit_w_m2: Num = Field(description="The heating limit (W/m^2)")
    dynamic_pressure_kept_fraction: Num = Field(None, description="Dynamic-pressure limit kept, fine grid (0-1)")
    dynamic_pressure_kept_fraction_nodes: Num = Field(None, description="The same at the nodes (0-1)")
    dynamic_pressure_worst_pa: Num = Field(None, description="Worst dynamic pressure (Pa)")
    dynamic_pressure_limit_pa: Num = Field(None, description="Dynamic-pressure limit (Pa)")
    load_factor_kept_fraction: Num = Field(None, description="Load-factor limit kept, fine grid (0-1)")
    load_factor_kept_fraction_nodes: Num = Field(None, description="The same at the nodes (0-1)")
    load_factor_worst: Num = Field(None, description="Worst load factor (g, dimensionless)")
    load_factor_limit: Num = Field(None, description="Load-factor limit (g, dimensionless)")
    cadet_heat_rate_mean_plus_k_sigma_max_w_m2: Num = Field(
        description="CADET's largest mu(q) + kJ sigma(q) along the design (W/m^2)")
    envelope: RobustResultEnvelope | None = Field(None, description="Envelopes for the plots")
    sample_traces: RobustResultSampleTraces | None = Field(None, description="Sampled trajectories")
    terminal_samples: RobustResultTerminalSamples | None = Field(None, description="Terminal values")


class RobustResultMonteCarlo(ResultModel):
    """The Monte Carlo validation of both designs (same samples for both)."""

    samples: int = Field(description="Samples per design")
    seed: int = Field(description="Seed: sample i always draws the same numbers")
    chunk_size: int = Field(description="Samples per chunk (the unit of scale-out)")
    substeps_per_interval: int = Field(description="RK4 steps per NLP interval (the fine grid)")
    executed: str = Field(description="Where the chunks ran")
    deterministic: RobustResultMonteCarloDesign = Field(description="The deterministic design")
    robust: RobustResultMonteCarloDesign = Field(description="The robust design")


class RobustResultHeatCheck(ResultModel):
    """The heating limit in one confirmation round: what the design promised and what the Monte Carlo kept."""

    target: Num = Field(description="Share of samples that must keep the limit over the whole flight (0-1)")
    acceptance: Num = Field(description="target - tolerance: the least share accepted (0-1)")
    tolerance: Num = Field(description="Sampling tolerance of the share at the loop's confidence (0-1)")
    promised: Num = Field(description="Share CADET promises at the tightest instant, Phi(k effective) (0-1)")
    monte_carlo: Num = Field(description="Share the Monte Carlo kept, fine grid (0-1)")
    monte_carlo_nodes: Num = Field(description="The same at the NLP nodes only (0-1)")
    k_constraint: Num = Field(description="kC the NLP used in this round (dimensionless)")
    agrees: bool = Field(description="monte_carlo >= acceptance")


class RobustResultSigmaCheck(ResultModel):
    """A terminal sigma limit in one confirmation round (unit: the key's, m, m/s or deg)."""

    limit: Num = Field(description="The user's sigma limit (unit of the quantity)")
    limit_in_nlp: Num = Field(description="The limit the NLP used in this round (unit of the quantity)")
    promised: Num = Field(description="CADET's sigma of the design (unit of the quantity)")
    monte_carlo: Num = Field(description="Monte Carlo standard deviation (unit of the quantity)")
    monte_carlo_relative_standard_error: Num = Field(description="Relative standard error of that estimate")
    agrees: bool = Field(description="monte_carlo <= limit")


class RobustResultRoundChecks(ResultModel):
    """The constraints checked in a round (each present when its limit is set)."""

    heat_rate: RobustResultHeatCheck | None = Field(None, description="The heating limit (shares 0-1)")
    sigma_altitude_m: RobustResultSigmaCheck | None = Field(None, description="sigma of the final altitude (m)")
    sigma_speed_mps: RobustResultSigmaCheck | None = Field(None, description="sigma of the final speed (m/s)")
    sigma_flight_path_deg: RobustResultSigmaCheck | None = Field(
        None, description="sigma of the final flight-path angle (deg)")


class RobustResultPromisedVsMonteCarlo(ResultModel):
    """mu(lat_f) - kJ sigma(lat_f): the NLP's value against the Monte Carlo's."""

    promised: Num = Field(description="The NLP's (CADET's) robust objective (deg)")
    monte_carlo: Num = Field(description="Monte Carlo mean - kJ std of the final latitude (deg)")


class RobustResultRound(ResultModel):
    """One round of the confirmation loop: a robust design, its Monte Carlo, and the verdict."""

    round: int = Field(description="Round number, from 1")
    tf_s: Num = Field(description="Final time of the round's design (s)")
    solver_status: str = Field(description="IPOPT's status of the round's solve")
    iterations: int = Field(description="IPOPT iterations of the round's solve")
    agrees: bool = Field(description="Every checked constraint agrees with the Monte Carlo")
    constraints: RobustResultRoundChecks = Field(description="Promised vs Monte Carlo per constraint")
    objective_deg: RobustResultPromisedVsMonteCarlo = Field(description="The objective, promised vs Monte Carlo (deg)")


class RobustResultConfirmation(ResultModel):
    """The Monte Carlo confirms the robust design, or corrects kC / the sigma limits and re-solves."""

    agrees: bool = Field(description="The reported design's Monte Carlo agrees with its promises")
    design_round: int = Field(description="The round whose design is reported")
    max_rounds: int = Field(description="Rounds allowed")
    confidence: Num = Field(description="Confidence of the sampling tolerance (0-1)")
    rounds: list[RobustResultRound] = Field(description="Every round, in order")
    stop_reason: str | None = Field(description="Why the loop stopped before the Monte Carlo agreed (a corrected "
                                                "re-solve failed, or no correction applies); null otherwise")


class RobustReentryResult(ResultModel):
    """Result of a ``robust_reentry`` job: robust and deterministic designs and their Monte Carlo."""

    objective: RobustResultObjective = Field(description="The robust objective and its parts")
    tf_s: Num = Field(description="Final time of the robust design (s)")
    final: ReentryResultFinalState = Field(description="Final state of the robust design (nominal)")
    trajectory: RobustResultTrajectory = Field(description="The robust design's nodes with CADET sigmas")
    solver: ReentryResultSolver = Field(description="IPOPT's account of all stages")
    notes: list[str] = Field(description="Findings, comparisons with paper 001, caveats")
    verification: ReentryResultVerification | None = Field(
        description="The robust controls re-propagated (nominal parameters); null when not run")
    final_sigma: RobustResultFinalSigma = Field(description="CADET 1-sigma of the final state")
    deterministic: RobustResultDeterministic = Field(description="The deterministic design")
    monte_carlo: RobustResultMonteCarlo = Field(description="Monte Carlo validation of both designs")
    confirmation: RobustResultConfirmation | None = Field(
        None, description="The Monte Carlo confirmation loop (rounds of promised vs Monte Carlo)")
