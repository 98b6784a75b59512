"""The robust-design question of an ``ocp`` problem as typed, frozen data (parsed by
:mod:`solvers.ocp.robust.spec`, carried by :class:`solvers.ocp.problem.OcpProblem`).  Standard library only."""
from __future__ import annotations

from dataclasses import dataclass

DEFAULT_K = 3.0
DEFAULT_SAMPLES = 2000
DEFAULT_ROUNDS = 2
MAX_ROUNDS = 5


@dataclass(frozen=True)
class UncertainConstant:
    """A constant drawn from a normal or a uniform law; ``mean`` and ``sigma`` are the law's (a uniform's
    sigma is (upper - lower) / sqrt(12)), what CADET propagates."""

    name: str
    distribution: str                 # "normal" | "uniform"
    mean: float
    sigma: float
    lower: float | None = None        # uniform only
    upper: float | None = None


@dataclass(frozen=True)
class InitialSigma:
    state: str
    sigma: float


@dataclass(frozen=True)
class RobustSpec:
    """What robust design asks: the uncertainty, ``k``, the objective's statistic, the constraints held at
    mean +- k sigma (path and boundary names) and the Monte Carlo's sample count."""

    parameters: tuple[UncertainConstant, ...]
    initial: tuple[InitialSigma, ...]
    k: float = DEFAULT_K
    objective: str = "mean"
    constraints: tuple[str, ...] = ()
    samples: int = DEFAULT_SAMPLES
    rounds: int = DEFAULT_ROUNDS          # confirmation rounds that raise the constraints' k after a short Monte Carlo
    sigma_factor: float = 1.0             # the Monte Carlo's sigmas over the design's (a harsher world)

    @property
    def objective_sign(self) -> float:
        """-1, 0 or +1: the objective is mean + sign k sigma."""
        return {"mean_minus_k_sigma": -1.0, "mean": 0.0, "mean_plus_k_sigma": 1.0}[self.objective]
