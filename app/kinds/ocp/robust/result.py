"""The ``robust`` block of an ``ocp`` result (``shared/specs/ocp.md``, "Robust design"): the design's
statistics over its Monte Carlo beside CADET's, each named constraint's kept share, and ``confirmed``."""
from __future__ import annotations

from typing import Any

from pydantic import Field

from app.kinds.result_models import Num, ResultModel, Series


class OcpRobustObjective(ResultModel):
    """The objective of the design over the draws, beside CADET's first-order prediction."""

    mean: Num = Field(None, description="Monte Carlo mean of the objective")
    std: Num = Field(None, description="Monte Carlo standard deviation of the objective")
    cadet_mean: Num = Field(None, description="CADET's mean (first order: the mean trajectory's objective)")
    cadet_std: Num = Field(None, description="CADET's standard deviation")


class OcpRobustConstraint(ResultModel):
    """One named constraint: the share of the Monte Carlo's flights that kept it on the dense grid."""

    kept_fraction: Num = Field(None, description="Share of the draws that kept the constraint (path: at every "
                               "RK4 step of the re-flight, between the nodes too)")
    required_fraction: Num = Field(None, description="Phi(k): the one-sided normal share of k sigma "
                                   "(k = 2: 0.9772, k = 3: 0.99865)")
    kept: bool | None = Field(None, description="kept_fraction within the sampling tolerance of required_fraction")
    sampling_tolerance: Num = Field(None, description="How far below required_fraction the share may fall by "
                                    "chance (binomial, 99% confidence)")
    cadet: dict[str, Any] | None = Field(None, description="CADET's worst mean +- k sigma against the bounds "
                                         "(scaled excess; <= 0 held), at the nodes and between them")


class OcpRobustBand(ResultModel):
    """One quantity over the Monte Carlo's draws at the kept node times."""

    mean: Series = Field(description="Mean over the draws that stayed finite")
    std: Series = Field(description="Standard deviation over the same draws")


class OcpRobustEnvelope(ResultModel):
    """The Monte Carlo's envelope: mean and standard deviation of every state and of each named path
    constraint's value at the node times (at most 200 of them, evenly picked), the phases one after another
    (null where a phase has not the quantity)."""

    t: Series = Field(description="Node times, in the problem's time unit")
    states: dict[str, OcpRobustBand] = Field(default_factory=dict, description="state name -> mean and std")
    constraints: dict[str, OcpRobustBand] = Field(default_factory=dict,
                                                  description="named path constraint -> mean and std of its value")


class OcpRobustCadetEnvelope(ResultModel):
    """CADET's prediction over time: the design's mean and the propagated standard deviation of every state
    and of each named path constraint at every node, the phases one after another (null where a phase has
    not the quantity)."""

    t: Series = Field(description="Node times of every phase, in the problem's time unit")
    states: dict[str, OcpRobustBand] = Field(default_factory=dict, description="state name -> mean and std")
    constraints: dict[str, OcpRobustBand] = Field(default_factory=dict,
                                                  description="named path constraint -> mean and std of its value")


class OcpRobustSamples(ResultModel):
    """Per-draw values (the first 2000 draws; a draw that did not stay finite is null)."""

    objective: Series = Field(description="The objective of each draw, in the user's sense")
    boundary: dict[str, Series] = Field(default_factory=dict,
                                        description="named boundary constraint -> its value in each draw")


class OcpRobustMonteCarlo(ResultModel):
    """What the plots, the CSV tables and a study read of the Monte Carlo beyond its statistics."""

    envelope: OcpRobustEnvelope | None = Field(None, description="Mean and std over time")
    samples: OcpRobustSamples | None = Field(None, description="Per-draw terminal values")


class OcpRobustResult(ResultModel):
    """Robust design: the statistics of the design over its Monte Carlo and whether it is confirmed."""

    k: Num = Field(None, description="Sigmas of margin asked")
    statistic: str | None = Field(None, description="The objective's statistic optimized")
    objective: OcpRobustObjective = Field(description="The objective over the draws and by CADET")
    constraints: dict[str, OcpRobustConstraint] = Field(default_factory=dict, description="name -> kept share")
    samples: int = Field(description="Monte Carlo draws")
    failed_samples: int | None = Field(None, description="Draws whose re-flight did not stay finite")
    confirmed: bool = Field(description="Every named constraint kept its required share")
    deterministic_objective: Num = Field(None, description="The deterministic twin's optimum (every constant at "
                                         "its mean, no margin)")
    robust_objective: Num = Field(None, description="The robust NLP's objective (mean +- k sigma as asked)")
    cost_of_robustness: Num = Field(None, description="robust_objective - deterministic_objective")
    k_constraints: Num = Field(None, description="The constraints' k of the last round (raised by the rounds "
                               "where the Monte Carlo kept less than promised)")
    sigma_factor: Num = Field(None, description="The Monte Carlo's sigmas over the design's")
    rounds: list[dict[str, Any]] = Field(default_factory=list, description="Each design and its Monte Carlo")
    distribution: dict[str, Any] | None = Field(None, description="A Monte Carlo fanned across the workers: its "
                                                "chunks, their size and who computed them")
    timing: dict[str, Any] = Field(default_factory=dict, description="Seconds: deterministic twin, robust NLP, "
                                   "Monte Carlo; iterations")
    cadet_envelope: OcpRobustCadetEnvelope | None = Field(None, description="CADET's mean and sigma of every "
                                                          "state over time (the design's sigmas)")
    monte_carlo: OcpRobustMonteCarlo | None = Field(None, description="The Monte Carlo's envelope and per-draw "
                                                    "values (the plots, the CSV tables)")
