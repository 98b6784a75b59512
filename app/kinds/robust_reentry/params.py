"""Parameters of the ``robust_reentry`` kind: the reentry parameters plus the uncertainty, the robust
design's weights and limits, the Monte Carlo and the confirmation loop (API units)."""
from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from app.kinds.base import StrictModel
from app.kinds.reentry.params import BETTS_HEAT_LIMIT_W_M2, ReentryParams, ReentryPathLimits
from solvers.models.reentry_state import STATES

STATES_BY_NAME = {c.name: c for c in STATES}


class RobustUncertainParameter(StrictModel):
    mean: float = Field(0.0, ge=-0.5, le=0.5, description="Mean of the relative error", examples=[0.01])
    std: float = Field(0.01, ge=0.0, le=0.5, description="Standard deviation of the relative error",
                       examples=[0.01])


class RobustInitialStateStd(StrictModel):
    altitude_m: float = Field(0.0, ge=0, description="1-sigma entry altitude error", examples=[0.0])
    longitude_deg: float = Field(0.0, ge=0, description="1-sigma entry longitude error", examples=[0.0])
    latitude_deg: float = Field(0.0, ge=0, description="1-sigma entry latitude error", examples=[0.0])
    speed_mps: float = Field(0.0, ge=0, description="1-sigma entry speed error", examples=[0.0])
    flight_path_deg: float = Field(0.0, ge=0, description="1-sigma entry flight-path error", examples=[0.0])
    heading_deg: float = Field(0.0, ge=0, description="1-sigma entry heading error", examples=[0.0])


class RobustUncertainty(StrictModel):
    cd: RobustUncertainParameter = Field(default_factory=lambda: RobustUncertainParameter(mean=0.01, std=0.01),
                                   description="s1 in CD = CD_N (1 + s1), Gaussian, constant over the flight "
                                   "(paper 001: N(0.01, 0.01^2))")
    cl: RobustUncertainParameter = Field(default_factory=lambda: RobustUncertainParameter(mean=-0.01, std=0.01),
                                   description="s2 in CL = CL_N (1 + s2) (paper 001: N(-0.01, 0.01^2))")
    initial_state_std: RobustInitialStateStd | None = Field(None, description="Optional independent Gaussian "
                                                      "entry-state dispersions (null: exact entry state, "
                                                      "as in paper 001)")


class RobustSigmaLimits(StrictModel):
    altitude_m: float | None = Field(4500.0, gt=0, description="Limit on sigma(h_f) (null: none)",
                                     examples=[4500.0])
    speed_mps: float | None = Field(250.0, gt=0, description="Limit on sigma(v_f)", examples=[250.0])
    flight_path_deg: float | None = Field(3.0, gt=0, description="Limit on sigma(gamma_f)", examples=[3.0])


class RobustDesign(StrictModel):
    k_objective: float = Field(3.0, ge=0, le=10, description="kJ in max mu(lat_f) - kJ sigma(lat_f)",
                               examples=[3.0])
    k_constraint: float = Field(3.0, ge=0, le=10, description="kC in mu(q) + kC sigma(q) <= q_max",
                                examples=[3.0])
    sigma_limits: RobustSigmaLimits = Field(default_factory=RobustSigmaLimits, description="Terminal sigma limits")
    second_order: bool = Field(False, description="Add CADET's second-order mean term 0.5 tr(H P) in "
                               "the NLP (the reported CADET prediction always includes it)", examples=[False])
    heat_margin: float = Field(0.0, ge=0, lt=0.2, description="Extra relative margin on the robust "
                               "heating limit", examples=[0.0])
    substeps: int = Field(2, ge=1, le=8, description="RK4 steps per interval of the augmented system; "
                          "the robust heating limit is enforced at each of them", examples=[2])


class RobustMonteCarlo(StrictModel):
    samples: int = Field(10000, ge=10, le=200000, description="Samples per design", examples=[10000])
    seed: int = Field(2020, ge=0, description="Seed; sample i always draws the same numbers", examples=[2020])
    chunk_size: int = Field(2500, ge=10, le=200000, description="Samples per chunk (unit of scale-out)",
                            examples=[2500])
    substeps: int = Field(5, ge=2, le=50, description="RK4 steps per NLP interval (5: 4.4 s steps, results identical to 10 and 20); also the fine grid "
                          "on which path limits are checked", examples=[5])


class RobustConfirmation(StrictModel):
    max_rounds: int = Field(3, ge=1, le=6, description="Robust solves at most (the first plus corrected "
                            "re-solves) until the Monte Carlo of the robust design confirms it", examples=[3])
    heat_rate_target: float | None = Field(
        None, gt=0.5, lt=1.0, description="Target probability that a sample keeps the heating limit over "
        "the WHOLE flight, judged on the Monte Carlo's fine grid (every RK4 step, not only the nodes). "
        "null: the one-sided normal share of robust.k_constraint sigma, Phi(kC) (kC = 3: 0.99865). The "
        "terminal sigma limits are confirmed by comparing the Monte Carlo's standard deviation with the "
        "limit.", examples=[None])
    confidence: float = Field(0.99, ge=0.5, le=0.9999, description="Sampling tolerance of the heating "
                              "share: the Monte Carlo disagrees when its share is below target - z sqrt(target "
                              "(1 - target) / samples), z = Phi^-1(confidence) (binomial standard error)",
                              examples=[0.99])


def _heat_limited_path() -> ReentryPathLimits:
    return ReentryPathLimits(max_heat_rate_w_m2=BETTS_HEAT_LIMIT_W_M2)


class RobustReentryParams(ReentryParams):
    objective: Literal["max_crossrange"] = Field("max_crossrange", description="Paper 001 maximizes "
                                                 "mu(lat_f) - kJ sigma(lat_f); only max_crossrange", examples=["max_crossrange"])
    path: ReentryPathLimits = Field(default_factory=_heat_limited_path, description="Path limits; the "
                                "heating limit is required (paper 001's active constraint)")
    uncertainty: RobustUncertainty = Field(default_factory=RobustUncertainty, description="Uncertain parameters")
    robust: RobustDesign = Field(default_factory=RobustDesign, description="Robust design settings")
    monte_carlo: RobustMonteCarlo = Field(default_factory=RobustMonteCarlo, description="Monte Carlo validation")
    confirmation: RobustConfirmation = Field(default_factory=RobustConfirmation, description="The loop that "
                                             "re-solves until the Monte Carlo confirms the robust design "
                                             "(else the job fails with not_robust)")

    @model_validator(mode="after")
    def _robust_consistent(self):
        if self.path.max_heat_rate_w_m2 is None:
            raise ValueError("path.max_heat_rate_w_m2 is required for robust_reentry")
        if self.grid.control != "linear":
            raise ValueError("grid.control must be 'linear' for robust_reentry")
        if self.accuracy is not None:
            # the robust stage solves on grid.intervals; a refined deterministic stage would not match it
            raise ValueError("accuracy (mesh refinement) is offered by the reentry kind, not by robust_reentry: "
                             "set grid.intervals")
        return self
