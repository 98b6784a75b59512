"""Parameters of the ``midcourse`` kind (the API edge: SI units, angles in degrees).

The defaults are paper 002's case (:mod:`solvers.midcourse.cases`, read from there;
the launch angles are printed here in degrees and a test keeps them equal to the case).
"""
from __future__ import annotations

from collections.abc import Sequence
from typing import Literal

from pydantic import Field, field_validator, model_validator

from app.kinds.base import StrictModel
from solvers.midcourse import cases
from solvers.astro.earth import AE_EARTH, J2_EARTH, MU_EARTH

MAX_POPULATION = 1000
MAX_GENERATIONS = 5000
MAX_SAMPLES = 1000
MAX_SCHEDULES = 1000
# Candidate x sample evaluations per generation: ~25 us each, so 200k is ~5 s per generation.
MAX_ROWS_PER_GENERATION = 200_000
MAX_CORRECTIONS = 5

# The fitted launch site in degrees (solvers.midcourse.cases holds it in radians).
PAPER_LATITUDE_DEG = 28.3214
PAPER_AZIMUTH_DEG = 135.7033


def _vec3(description: str, default: Sequence[float]):
    return Field(default_factory=lambda: list(default), min_length=3, max_length=3,
                 description=description, examples=[list(default)])


class MidcourseState(StrictModel):
    """A position and velocity in the chosen frame (launch-inertial: relative to the launch point)."""

    position_m: list[float] = _vec3("Position (x, y, z)", cases.R0_M)
    velocity_mps: list[float] = _vec3("Velocity (x, y, z)", cases.V0_MPS)


class MidcourseTarget(StrictModel):
    """The nominal target state at tf_s; corrections aim at its position."""

    position_m: list[float] = _vec3("Target position (x, y, z)", cases.R_TARGET_M)
    velocity_mps: list[float] = _vec3("Target velocity (x, y, z)", cases.V_TARGET_MPS)


class MidcourseInitialError(StrictModel):
    """Initial navigation error: a fixed offset, or the 3-sigma per axis when `dispersion` is set."""

    position_m: list[float] = _vec3("Position error (x, y, z)", cases.POSITION_ERROR_M)
    velocity_mps: list[float] = _vec3("Velocity error (x, y, z)", cases.VELOCITY_ERROR_MPS)


class MidcourseLaunchSite(StrictModel):
    """The launch-inertial frame: geodetic launch point on WGS-84 and launch azimuth."""

    latitude_deg: float = Field(PAPER_LATITUDE_DEG, ge=-90, le=90,
                                description="Geodetic latitude B0 of the launch point", examples=[28.3214])
    azimuth_deg: float = Field(PAPER_AZIMUTH_DEG, ge=-360, le=360,
                               description="Launch azimuth A0 (the frame's x axis), from north towards east",
                               examples=[135.7033])
    height_m: float = Field(cases.LAUNCH_HEIGHT_M, ge=-1000, le=1e5,
                            description="Height above the WGS-84 ellipsoid", examples=[1757.5])


class MidcourseDispersion(StrictModel):
    """Monte Carlo over the initial error (Gaussian, `initial_error` is its 3-sigma per axis)."""

    samples: int = Field(100, ge=2, le=MAX_SAMPLES, description="Error samples per candidate schedule",
                         examples=[100])
    percentile: float = Field(99.0, gt=0, lt=100, description="Percentile reported (and optimized if "
                              "statistic is 'percentile')", examples=[99.0])
    seed: int = Field(0, ge=0, description="Seed of the error samples (the same samples for every candidate)",
                      examples=[0])
    statistic: Literal["mean", "percentile"] = Field("percentile", description="What NSGA-II minimizes: "
                                                     "the mean or the percentile over samples",
                                                     examples=["percentile"])


class MidcourseGravity(StrictModel):
    """J2 gravity of the Earth."""

    mu_m3_s2: float = Field(MU_EARTH, gt=0, description="Earth's gravitational parameter",
                            examples=[MU_EARTH])
    j2: float = Field(J2_EARTH, ge=0, le=0.01, description="J2 zonal coefficient", examples=[J2_EARTH])
    ae_m: float = Field(AE_EARTH, gt=0, description="Equatorial radius used with J2", examples=[AE_EARTH])


class MidcourseHypervolumeReference(StrictModel):
    """Reference point of the hypervolume; each objective is divided by it first."""

    delta_v_mps: float = Field(150.0, gt=0, description="Reference total delta-v", examples=[150.0])
    position_error_m: float = Field(2000.0, gt=0, description="Reference final position error",
                                    examples=[2000.0])
    velocity_error_mps: float = Field(70.0, gt=0, description="Reference final velocity error",
                                      examples=[70.0])


class MidcourseParams(StrictModel):
    """Parameters of a midcourse job (SI units, angles in degrees)."""

    mode: Literal["evaluate", "optimize"] = Field(
        "optimize", description="optimize: NSGA-II over the correction times; evaluate: the given schedules",
        examples=["optimize"])
    schedules: list[list[float]] = Field(
        default_factory=list, max_length=MAX_SCHEDULES,
        description="evaluate mode: correction schedules (each a sorted list of 0-5 times in s; [] = no "
        "correction)", examples=[[[1000.0, 8000.0], [3000.0, 8000.0]]])
    corrections: int = Field(2, ge=1, le=MAX_CORRECTIONS, description="optimize mode: number of corrections",
                             examples=[2])
    population: int = Field(100, ge=4, le=MAX_POPULATION, description="NSGA-II population size", examples=[100])
    generations: int = Field(500, ge=1, le=MAX_GENERATIONS, description="NSGA-II generations", examples=[500])
    seed: int = Field(1, ge=0, description="Seed of the GA (the same seed and params give the same front)",
                      examples=[1])
    crossover_prob: float = Field(0.8, ge=0, le=1, description="SBX crossover probability per mating",
                                  examples=[0.8])
    mutation_prob: float = Field(0.1, ge=0, le=1, description="Polynomial mutation probability per "
                                 "correction time", examples=[0.1])
    eliminate_duplicates: bool = Field(False, description="Re-mate offspring that copy a population member "
                                       "(slower; copies are otherwise dropped first at survival)",
                                       examples=[False])
    time_bounds_s: list[float] = Field(default_factory=lambda: [0.0, 12800.0], min_length=2, max_length=2,
                                       description="[earliest, latest] correction time", examples=[[0.0, 12800.0]])
    min_spacing_s: float = Field(cases.MIN_SPACING_S, ge=0, description="Minimum time between corrections. Default "
                                 "60 s: a stage needs time between burns to settle, update its navigation "
                                 "solution and re-plan (a navigation update cycle or a thruster's minimum "
                                 "off-time is tens of seconds to minutes); 0 lets two corrections merge into "
                                 "one split burn", examples=[60.0])
    tf_s: float = Field(cases.TF_S, gt=0, le=1e7, description="Transfer time T: the target is reached at tf_s",
                        examples=[12900.0])
    frame: Literal["launch", "eci"] = Field(
        "launch", description="launch: launch-inertial frame at launch_site (origin at the launch point, y up, "
        "x downrange); eci: Earth-centred inertial with the spin axis along z", examples=["launch"])
    launch_site: MidcourseLaunchSite = Field(default_factory=MidcourseLaunchSite,
                                          description="Launch point and azimuth (frame 'launch' only)")
    initial: MidcourseState = Field(default_factory=MidcourseState, description="Nominal initial state at t = 0")
    target: MidcourseTarget = Field(default_factory=MidcourseTarget, description="Nominal target state at tf_s")
    initial_error: MidcourseInitialError = Field(default_factory=MidcourseInitialError,
                                       description="Initial error: fixed offset, or 3-sigma with dispersion")
    dispersion: MidcourseDispersion | None = Field(None, description="Monte Carlo over the initial error; null "
                                                "applies initial_error as a fixed offset")
    gravity: MidcourseGravity = Field(default_factory=MidcourseGravity, description="J2 gravity constants")
    hypervolume_reference: MidcourseHypervolumeReference = Field(default_factory=MidcourseHypervolumeReference,
                                                        description="Reference point of the hypervolume")

    @field_validator("time_bounds_s")
    @classmethod
    def _bounds(cls, v):
        if not (0.0 <= v[0] < v[1]):
            raise ValueError("time_bounds_s must be [earliest, latest] with 0 <= earliest < latest")
        return v

    @field_validator("schedules")
    @classmethod
    def _schedules_shape(cls, v):
        for i, s in enumerate(v):
            if len(s) > MAX_CORRECTIONS:
                raise ValueError(f"schedules[{i}] has {len(s)} corrections; at most {MAX_CORRECTIONS}")
            if any(b < a for a, b in zip(s, s[1:])):
                raise ValueError(f"schedules[{i}] must be sorted in increasing time")
        return v

    @model_validator(mode="after")
    def _consistent(self):
        lo, hi = self.time_bounds_s
        if hi >= self.tf_s:
            raise ValueError("time_bounds_s latest must be before tf_s (a correction needs time to act)")
        if (self.corrections - 1) * self.min_spacing_s > hi - lo:
            raise ValueError("min_spacing_s too large: (corrections - 1) * min_spacing_s must fit in time_bounds_s")
        if self.mode == "evaluate":
            if not self.schedules:
                raise ValueError("schedules must list at least one schedule in evaluate mode")
            for i, s in enumerate(self.schedules):
                if any(not (0.0 <= t < self.tf_s) for t in s):
                    raise ValueError(f"schedules[{i}]: every correction time must be within [0, tf_s)")
                if any(b - a < self.min_spacing_s for a, b in zip(s, s[1:])):
                    raise ValueError(f"schedules[{i}]: corrections must be at least min_spacing_s apart")
        elif self.dispersion is not None and self.population * self.dispersion.samples > MAX_ROWS_PER_GENERATION:
            raise ValueError(f"population * dispersion.samples must be <= {MAX_ROWS_PER_GENERATION}")
        return self
