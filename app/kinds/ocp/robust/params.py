"""The request models of robust design in an ``ocp`` problem (``shared/specs/ocp.md``, "Robust design"):
``uncertainty`` and ``robust``, field shapes for ``/docs``; what they mean together (constants and states
that exist, sigmas that are positive, constraint names the problem has) is decided by the parser
(:mod:`solvers.ocp.robust.spec`), as for the rest of the problem (:mod:`app.kinds.ocp.params`)."""
from __future__ import annotations

from typing import Literal

from pydantic import Field

from app.kinds.base import StrictModel


class OcpUncertainConstant(StrictModel):
    """An uncertain constant: normal (``sigma``, ``mean`` defaulting to the declared value) or uniform
    (``lower`` < ``upper``)."""

    distribution: Literal["normal", "uniform"] = Field(description="The law the constant is drawn from",
                                                       examples=["normal"])
    sigma: float | None = Field(None, description="normal: standard deviation (positive)", examples=[0.05])
    mean: float | None = Field(None, description="normal: mean; null: the constant's declared value",
                               examples=[None])
    lower: float | None = Field(None, description="uniform: lower end", examples=[None])
    upper: float | None = Field(None, description="uniform: upper end", examples=[None])


class OcpInitialSigma(StrictModel):
    """A state's initial value drawn from a normal law around its (mean) initial value."""

    sigma: float = Field(description="Standard deviation of the initial value (positive)", examples=[10.0])


class OcpUncertainty(StrictModel):
    """What is uncertain: constants and initial states."""

    parameters: dict[str, OcpUncertainConstant] = Field(
        default_factory=dict, description="constant name -> its law",
        examples=[{"cd": {"distribution": "normal", "sigma": 0.05}}])
    initial: dict[str, OcpInitialSigma] = Field(default_factory=dict,
                                                description="state name -> its initial sigma", examples=[{}])


class OcpMonteCarlo(StrictModel):
    """The confirmation by Monte Carlo."""

    samples: int | None = Field(None, description="Draws re-flown (default 2000; at most the setting "
                                "TRAJLAB_OCP_MAX_MONTE_CARLO_SAMPLES)", examples=[2000])
    rounds: int | None = Field(None, description="Rounds that raise the constraints' k where the Monte Carlo "
                               "keeps less than promised, re-solve and re-fly (default 2; 0: one design)",
                               examples=[2])
    sigma_factor: float | None = Field(None, description="The Monte Carlo's sigmas over the design's (default 1; "
                                       "2: is the design robust to doubled dispersions?)", examples=[1.0])


class OcpRobust(StrictModel):
    """Robust design: the objective and the named constraints held at mean +- k sigma (CADET), confirmed
    by a Monte Carlo."""

    k: float | None = Field(None, description="Sigmas of margin (default 3)", examples=[3.0])
    objective: Literal["mean_minus_k_sigma", "mean", "mean_plus_k_sigma"] | None = Field(
        None, description="The objective's statistic; default mean_minus_k_sigma for maximize, "
        "mean_plus_k_sigma for minimize", examples=[None])
    constraints: list[str] = Field(default_factory=list, description="Names of path and boundary constraints "
                                   "held at mean +- k sigma", examples=[["q_limit"]])
    monte_carlo: OcpMonteCarlo = Field(default_factory=OcpMonteCarlo, description="The Monte Carlo")
