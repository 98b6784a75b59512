"""Parameters of the ``intercept`` kind (the API edge: SI units, angles in degrees).

The defaults are paper 003's case as printed; ``solvers.intercept.cases.PAPER_003``
holds the same case in SI and radians and a test keeps the two equal.
"""
from __future__ import annotations

from typing import Literal

from pydantic import Field, field_validator, model_validator

from app.kinds.base import StrictModel
from app.kinds.renamed import move_renamed
from solvers.astro.earth import AE_EARTH, MU_EARTH
from solvers.constants import G0_MPS2

MAX_SCAN_POINTS = 2_000_000
MAX_PORKCHOP_POINTS = 250_000

_ALL_METHODS: list[Literal["impulsive", "finite_thrust"]] = ["impulsive", "finite_thrust"]


class InterceptInterceptor(StrictModel):
    """The interceptor: vehicle data and its orbit at t0 (classical elements)."""

    mass_kg: float = Field(500.0, gt=0, description="Initial (wet) mass", examples=[500.0])
    propellant_kg: float = Field(400.0, ge=0, description="Propellant on board (part of mass_kg)",
                                 examples=[400.0])
    isp_s: float = Field(300.0, gt=0, description="Specific impulse", examples=[300.0])
    max_thrust_n: float = Field(2000.0, gt=0, description="Maximum thrust (finite-thrust method)",
                                examples=[2000.0])
    semi_major_axis_m: float = Field(16678.137e3, gt=0, description="Semi-major axis", examples=[16678137.0])
    eccentricity: float = Field(0.2, ge=0, lt=1, description="Eccentricity, 0 <= e < 1 (closed orbit)",
                                examples=[0.2])
    inclination_deg: float = Field(28.5, ge=0, le=180, description="Inclination", examples=[28.5])
    raan_deg: float = Field(0.0, description="Right ascension of the ascending node", examples=[0.0])
    arg_perigee_deg: float = Field(0.0, description="Argument of perigee", examples=[0.0])
    true_anomaly_deg: float = Field(1.54, description="True anomaly at t0", examples=[1.54])

    @model_validator(mode="after")
    def _propellant_within_mass(self):
        if self.propellant_kg >= self.mass_kg:
            raise ValueError("propellant_kg must be less than mass_kg (the dry mass must be positive)")
        return self


class InterceptTarget(StrictModel):
    """The target: a circular orbit, no maneuvers."""

    semi_major_axis_m: float = Field(6878.137e3, gt=0, description="Orbit radius", examples=[6878137.0])
    inclination_deg: float = Field(30.0, ge=0, le=180, description="Inclination", examples=[30.0])
    raan_deg: float = Field(0.0, description="Right ascension of the ascending node", examples=[0.0])
    arg_latitude_deg: float = Field(2.05, description="Argument of latitude at t0 (from the ascending node)",
                                    examples=[2.05])


class InterceptScan(StrictModel):
    """Impulsive method: enumeration of the maneuver time over [t_start_s, t_end_s)."""

    step_s: float = Field(0.5, gt=0, description="Grid step of the maneuver-time scan", examples=[0.5])
    t_start_s: float = Field(0.0, ge=0, description="Start of the maneuver window", examples=[0.0])
    t_end_s: float | None = Field(None, gt=0, description="End of the maneuver window (exclusive); "
                                  "null means the interception time", examples=[None])
    max_revolutions: int = Field(0, ge=0, le=5, description="Also search Lambert arcs with "
                                 "1..max_revolutions full revolutions (both paths)", examples=[0])
    retrograde: bool = Field(True, description="Also search retrograde transfers", examples=[True])
    refine: bool = Field(True, description="Refine the best grid point with a bounded 1-D minimization",
                         examples=[True])
    exclude_through_planet: bool = Field(True, description="Leave out Lambert arcs that pass below "
                                         "body_radius_m (through the planet) from the scan, its refinement and "
                                         "the porkchop; the result counts them", examples=[True])
    body_radius_m: float = Field(AE_EARTH, gt=0, description="Radius of the central body for "
                                 "exclude_through_planet (default: the Earth's equatorial radius, WGS-84)",
                                 examples=[AE_EARTH])


class InterceptPorkchop(StrictModel):
    """Optional 2-D delta-v map over maneuver time x interception time."""

    enabled: bool = Field(False, description="Compute the porkchop map", examples=[True])
    t_man_points: int = Field(60, ge=2, description="Grid points in maneuver time", examples=[60])
    t_intercept_points: int = Field(60, ge=2, description="Grid points in interception time", examples=[60])
    t_man_min_s: float = Field(0.0, ge=0, description="First maneuver time", examples=[0.0])
    t_man_max_s: float | None = Field(None, gt=0, description="Last maneuver time; null means up to "
                                      "the last interception time", examples=[None])
    t_intercept_min_s: float | None = Field(None, gt=0, description="First interception time; null: "
                                            "half the interception time", examples=[None])
    t_intercept_max_s: float | None = Field(None, gt=0, description="Last interception time; null: "
                                            "1.5 x the interception time", examples=[None])

    @model_validator(mode="after")
    def _grid(self):
        if self.t_man_points * self.t_intercept_points > MAX_PORKCHOP_POINTS:
            raise ValueError(f"t_man_points * t_intercept_points must be <= {MAX_PORKCHOP_POINTS}")
        if (self.t_intercept_min_s is not None and self.t_intercept_max_s is not None
                and self.t_intercept_max_s <= self.t_intercept_min_s):
            raise ValueError("t_intercept_max_s must be greater than t_intercept_min_s")
        if self.t_man_max_s is not None and self.t_man_max_s <= self.t_man_min_s:
            raise ValueError("t_man_max_s must be greater than t_man_min_s")
        return self


class InterceptFiniteThrust(StrictModel):
    """Finite-thrust method: collocation mesh and accuracy (its warm start: initial_guess.from_job)."""

    nodes_per_segment: int = Field(10, ge=4, le=40, description="LGL nodes per collocation segment",
                                   examples=[10])
    coast_segment_s: float = Field(1000.0, ge=50.0, le=1e5, description="Initial segment length on coast arcs",
                                   examples=[1000.0])
    burn_segment_s: float = Field(250.0, ge=5.0, le=1e4, description="Initial segment length on burn arcs",
                                  examples=[250.0])
    miss_tolerance_m: float = Field(100.0, gt=0, description="Refine the mesh until the re-propagated "
                                    "trajectory misses the target by less than this", examples=[100.0])
    max_refinements: int = Field(3, ge=0, le=6, description="Mesh refinements at most", examples=[3])
    max_iterations: int = Field(500, ge=1, le=5000, description="IPOPT iterations per mesh", examples=[500])
    # the old spelling of initial_guess.from_job, moved there before validation (app.kinds.renamed)
    from_job: str | None = Field(None, deprecated="use initial_guess.from_job", exclude=True,
                                 description="Deprecated: initial_guess.from_job", examples=[None])


class InterceptGuess(StrictModel):
    """The finite-thrust method's initial guess: the impulsive answer, or a stored intercept result."""

    from_job: str | None = Field(None, description="Warm start from this succeeded intercept job's "
                                 "finite-thrust trajectory instead of the impulsive answer", examples=[None])


class InterceptParams(StrictModel):
    """Parameters of an intercept job (SI units, angles in degrees, ECI frame of the epoch t0 = 0)."""

    methods: list[Literal["impulsive", "finite_thrust"]] = Field(
        default_factory=lambda: list(_ALL_METHODS),
        description="Methods to run: impulsive (Lambert scan) and/or finite_thrust (pseudospectral)",
        examples=[["impulsive"]])
    interceptor: InterceptInterceptor = Field(default_factory=InterceptInterceptor,
                                           description="Interceptor vehicle and orbit at t0")
    target: InterceptTarget = Field(default_factory=InterceptTarget, description="Target circular orbit at t0")
    intercept_time_s: float = Field(8080.5, gt=0, description="Fixed interception time t1 after t0",
                                    examples=[8080.5])
    free_final_time: bool = Field(False, description="Finite thrust: let the interception time vary "
                                  "within tf_bounds_s", examples=[False])
    tf_bounds_s: list[float] = Field(default_factory=lambda: [6000.0, 10200.0], min_length=2, max_length=2,
                                     description="Finite thrust with free final time: [lower, upper] bounds "
                                     "on the interception time", examples=[[6000.0, 10200.0]])
    g0_mps2: float = Field(G0_MPS2, gt=0, description="Standard gravity in the rocket equation "
                           "(the paper uses 9.8)", examples=[G0_MPS2])
    mu_m3_s2: float = Field(MU_EARTH, gt=0, description="Gravitational parameter of the Earth",
                            examples=[MU_EARTH])
    scan: InterceptScan = Field(default_factory=InterceptScan, description="Impulsive method: maneuver-time scan")
    porkchop: InterceptPorkchop = Field(default_factory=InterceptPorkchop,
                                     description="Impulsive method: optional porkchop map")
    finite_thrust: InterceptFiniteThrust = Field(default_factory=InterceptFiniteThrust,
                                              description="Finite-thrust method: mesh and accuracy")
    initial_guess: InterceptGuess = Field(default_factory=InterceptGuess,
                                          description="Finite-thrust method: warm start")

    @model_validator(mode="before")
    @classmethod
    def _renamed(cls, data):
        return move_renamed(data, ("finite_thrust", "from_job"), ("initial_guess", "from_job"))

    @field_validator("methods")
    @classmethod
    def _methods(cls, v):
        if not v:
            raise ValueError("methods must name at least one of impulsive, finite_thrust")
        if len(set(v)) != len(v):
            raise ValueError("methods must not repeat a method")
        return v

    @field_validator("tf_bounds_s")
    @classmethod
    def _tf_bounds(cls, v):
        if not (0 < v[0] < v[1]):
            raise ValueError("tf_bounds_s must be [lower, upper] with 0 < lower < upper")
        return v

    @model_validator(mode="after")
    def _scan_size(self):
        start = self.scan.t_start_s
        end = self.intercept_time_s if self.scan.t_end_s is None else min(self.scan.t_end_s, self.intercept_time_s)
        if end <= start:
            raise ValueError("scan.t_start_s must be before the end of the maneuver window "
                             "(scan.t_end_s or intercept_time_s)")
        if (end - start) / self.scan.step_s > MAX_SCAN_POINTS:
            raise ValueError(f"scan.step_s gives more than {MAX_SCAN_POINTS} maneuver times; use a larger step")
        return self
