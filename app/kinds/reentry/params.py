"""The ``reentry`` kind's parameter models (SI and degrees), shared by ``robust_reentry``.

Defaults are the Betts shuttle case (Betts, *Practical Methods for Optimal Control*, sec. 6.3),
taken from :mod:`solvers.models.shuttle` (the one place its English units are converted) and
turned into degrees here.  Every model has its own name, so OpenAPI titles are unique.
"""
from __future__ import annotations

import math
from typing import Literal

from pydantic import Field, ValidationInfo, field_validator, model_validator

from app.kinds.base import StrictModel
from app.kinds.reentry.vehicle import (AtmosphereName, PlanetName, ReentryAeroTable, ReentryAtmosphereModel,
                                       ReentryHeating, ReentryPlanet, VehicleName, has_aero_table)
from solvers.models import shuttle as sh
from solvers.models.reentry_state import (
    ALTITUDE,
    FLIGHT_PATH,
    HEADING,
    LATITUDE,
    LONGITUDE,
    SPEED,
)

BETTS_HEAT_LIMIT_W_M2 = sh.BETTS_HEAT_LIMIT_W_M2   # 70 BTU/ft^2/s
PAPER000_TERMINAL_ALTITUDE_M = sh.PAPER000_TERMINAL_ALTITUDE_M
Objective = Literal["max_crossrange", "max_downrange", "max_great_circle_range", "min_heat_load",
                    "min_time"]


def _deg(rad: float) -> float:
    """Degrees for a default shown in the API (rounded so 1e-15 noise does not show)."""
    return round(math.degrees(rad), 9)


def _max_intervals() -> int:
    try:
        from app.runtime.settings import get_settings
    except ImportError:  # settings module not present: fall back to the documented default
        return 1000
    return int(get_settings().max_grid_intervals)


class ReentryGrid(StrictModel):
    intervals: int = Field(100, ge=4, description="Shooting intervals m (nodes m+1); capped by the "
                           "service setting max_grid_intervals", examples=[100])
    control: Literal["linear", "constant"] = Field(
        "linear", description="Controls between nodes: continuous piecewise-linear (paper 000) or "
        "piecewise-constant", examples=["linear"])
    substeps: int = Field(2, ge=1, le=16, description="RK4 steps per interval", examples=[2])
    max_refinements: int = Field(8, ge=0, description="With `accuracy`: rounds of raising the intervals at "
                                 "most (capped by the service setting max_grid_refinements)", examples=[8])

    @field_validator("intervals")
    @classmethod
    def _cap(cls, v: int) -> int:
        cap = _max_intervals()
        if v > cap:
            raise ValueError(f"intervals must be <= max_grid_intervals ({cap})")
        return v

    @field_validator("max_refinements")
    @classmethod
    def _cap_rounds(cls, v: int) -> int:
        from app.runtime.settings import get_settings

        cap = int(get_settings().max_grid_refinements)
        if v > cap:
            raise ValueError(f"max_refinements must be <= max_grid_refinements ({cap}; setting "
                             "TRAJLAB_MAX_GRID_REFINEMENTS)")
        return v


class ReentryPathLimits(StrictModel):
    max_heat_rate_w_m2: float | None = Field(None, gt=0, description="Stagnation heating-rate limit, by "
                                             "the vehicle's heating model (shuttle: Betts' fit; msl: "
                                             "Sutton-Graves); 794955 W/m^2 = 70 BTU/ft^2/s", examples=[794955.0])
    max_dynamic_pressure_pa: float | None = Field(None, gt=0, description="Dynamic-pressure limit",
                                                  examples=[15000.0])
    max_load_factor: float | None = Field(None, gt=0, description="Aerodynamic load-factor limit "
                                          "sqrt(L^2+D^2)/(m g0)", examples=[2.5])
    enforcement: Literal["nodes", "midpoints", "substeps", "integral"] = Field(
        "substeps", description="Where the NLP enforces path limits: at the nodes, also at interval "
        "midpoints or every RK4 substep (the default), or by paper 000's integral penalty. Whatever "
        "is chosen, the answer is re-checked on the dense re-propagation (20 points per interval) "
        "and tightened until every limit holds there (limit_rounds, limit_tolerance)",
        examples=["substeps"])
    limit_tolerance: float = Field(1e-3, gt=0, le=0.1, description="Limits that hold: the worst "
                                   "dense value may exceed a limit by at most this fraction of it",
                                   examples=[0.001])
    limit_rounds: int = Field(6, ge=0, le=20, description="Warm-started re-solves that lower the "
                              "limit on the intervals where the dense re-propagation overshoots it; "
                              "if the limits still do not hold, the job fails with code "
                              "limit_not_held and stores the best answer", examples=[6])


class ReentryTerminalCheck(StrictModel):
    altitude_m: float = Field(1.0, gt=0, description="Terminal conditions that hold: the dense "
                              "re-propagation's final altitude may miss the requested one by this much",
                              examples=[1.0])
    speed_mps: float = Field(0.01, gt=0, description="Same for the final speed", examples=[0.01])
    angle_deg: float = Field(0.001, gt=0, description="Same for the final angles (flight path, latitude, "
                             "longitude, heading)", examples=[0.001])
    rounds: int = Field(3, ge=0, le=6, description="Warm-started re-solves with more RK4 substeps when a "
                        "final value is missed; if it is still missed, the job fails with code "
                        "terminal_not_held and stores the best answer", examples=[3])


class ReentryTerminal(StrictModel):
    altitude_m: float | None = Field(sh.BETTS_TERMINAL["altitude_m"], ge=0, description="Final altitude (null: free)",
                                     examples=[24384.0])
    speed_mps: float | None = Field(sh.BETTS_TERMINAL["speed_mps"], gt=0, description="Final speed (null: free)",
                                    examples=[762.0])
    flight_path_deg: float | None = Field(_deg(sh.BETTS_TERMINAL["flight_path_rad"]), ge=-89, le=89,
                                          description="Final flight-path angle "
                                          "(null: free)", examples=[-5.0])
    latitude_deg: float | None = Field(None, ge=-89, le=89, description="Final latitude (null: free)",
                                       examples=[32.0])
    longitude_deg: float | None = Field(None, description="Final longitude (null: free)", examples=[None])
    heading_deg: float | None = Field(None, description="Final heading from north (null: free)",
                                      examples=[None])


class ReentryInitialState(StrictModel):
    altitude_m: float = Field(sh.BETTS_INITIAL_STATE[ALTITUDE], gt=0, description="Entry altitude", examples=[79248.0])
    longitude_deg: float = Field(_deg(sh.BETTS_INITIAL_STATE[LONGITUDE]), description="Entry longitude", examples=[0.0])
    latitude_deg: float = Field(_deg(sh.BETTS_INITIAL_STATE[LATITUDE]), ge=-89, le=89,
                                description="Entry latitude", examples=[0.0])
    speed_mps: float = Field(sh.BETTS_INITIAL_STATE[SPEED], gt=0, description="Entry speed", examples=[7802.88])
    flight_path_deg: float = Field(_deg(sh.BETTS_INITIAL_STATE[FLIGHT_PATH]), ge=-89, le=89,
                                   description="Entry flight-path angle", examples=[-1.0])
    heading_deg: float = Field(_deg(sh.BETTS_INITIAL_STATE[HEADING]), description="Entry heading from north",
                               examples=[90.0])


class ReentryVehicle(StrictModel):
    preset: VehicleName = Field("shuttle", description="Base vehicle (GET /v1/vehicles: shuttle, msl); "
                                "the fields below override it", examples=["shuttle"])
    mass_kg: float | None = Field(None, gt=0, description="Mass", examples=[92079.2])
    area_m2: float | None = Field(None, gt=0, description="Reference area", examples=[249.91])
    cl_coeffs: list[float] | None = Field(None, min_length=1, max_length=6, description="CL polynomial "
                                          "in alpha degrees, lowest order first (replaces a table)",
                                          examples=[[-0.20704, 0.029244]])
    cd_coeffs: list[float] | None = Field(None, min_length=1, max_length=6, description="CD polynomial "
                                          "in alpha degrees, lowest order first (replaces a table)",
                                          examples=[[0.07854, -0.0061592, 0.000621408]])
    aero_table: ReentryAeroTable | None = Field(None, description="CL and CD tables against alpha and "
                                                "Mach (cubic B-spline; replaces the polynomials)", examples=[None])
    heating: ReentryHeating | None = Field(None, description="Heating model; null: the preset's (shuttle: "
                                           "Betts' fit, msl: Sutton-Graves r_n 1.125 m)", examples=[None])

    @model_validator(mode="after")
    def _one_aero_model(self):
        if self.aero_table is not None and (self.cl_coeffs is not None or self.cd_coeffs is not None):
            raise ValueError("give either aero_table or cl_coeffs/cd_coeffs, not both")
        if (self.cl_coeffs is None) != (self.cd_coeffs is None) and has_aero_table(self.preset):
            raise ValueError(f"vehicle {self.preset} has an aero table: give both cl_coeffs and cd_coeffs "
                             "to replace it")
        return self


def _interval(v: list[float], name: str) -> list[float]:
    if len(v) != 2 or not v[0] < v[1]:
        raise ValueError(f"{name} must be [lo, hi] with lo < hi")
    return v


_CONTROL_LIMITS_DEG = {"alpha_deg": 90.0, "bank_deg": 180.0}   # the widest bounds a user may set


class ReentryControlBounds(StrictModel):
    alpha_deg: list[float] = Field([_deg(v) for v in sh.BETTS_ALPHA_BOUNDS_RAD],
                                   description="Angle-of-attack bounds [lo, hi]", examples=[[-90.0, 90.0]])
    bank_deg: list[float] = Field([_deg(v) for v in sh.BETTS_BANK_BOUNDS_RAD],
                                  description="Bank-angle bounds [lo, hi]", examples=[[-90.0, 1.0]])

    @field_validator("alpha_deg", "bank_deg")
    @classmethod
    def _within(cls, v, info: ValidationInfo):
        name = info.field_name
        assert name is not None  # a field validator's
        _interval(v, name)
        limit = _CONTROL_LIMITS_DEG[name]
        if v[0] < -limit or v[1] > limit:
            raise ValueError(f"{name} must lie within [-{limit:g}, {limit:g}]")
        return v


class ReentryGuess(StrictModel):
    kind: Literal["linear", "simulate"] = Field("simulate", description="Cold start: straight lines "
                                                "between initial and terminal states, or a glide "
                                                "simulated with constant controls", examples=["simulate"])
    from_job: str | None = Field(None, description="Warm start from this succeeded reentry job's "
                                 "trajectory (interpolated onto the new grid)", examples=[None])


class ReentryParams(StrictModel):
    objective: Objective = Field("max_crossrange", description="max_crossrange (final latitude), "
                                 "max_downrange (final longitude), max_great_circle_range, "
                                 "min_heat_load (int sqrt(rho) v^3 dt), min_time", examples=["max_crossrange"])
    grid: ReentryGrid = Field(default_factory=ReentryGrid, description="Shooting grid")
    accuracy: float | None = Field(None, gt=0, lt=1, description="Target relative error of the re-propagated "
                                   "states (each by its scale): the intervals are raised from grid.intervals "
                                   "until it is met (mesh refinement); null: the grid as given", examples=[None])
    accuracy_required: bool = Field(True, description="With `accuracy`: true fails the job as "
                                    "accuracy_not_reached when the rounds end short of it (the best round "
                                    "stored); false accepts the best round with a note", examples=[True])
    path: ReentryPathLimits = Field(default_factory=ReentryPathLimits, description="Path limits")
    terminal: ReentryTerminal = Field(default_factory=ReentryTerminal, description="Terminal equalities")
    terminal_check: ReentryTerminalCheck = Field(default_factory=ReentryTerminalCheck, description="How "
                                                 "closely the re-propagated final state must meet `terminal`")
    initial_state: ReentryInitialState = Field(default_factory=ReentryInitialState, description="Entry state")
    vehicle: ReentryVehicle = Field(default_factory=ReentryVehicle, description="Vehicle")
    bounds: ReentryControlBounds = Field(default_factory=ReentryControlBounds, description="Control bounds")
    rotating_earth: bool = Field(False, description="Coriolis and centripetal terms (paper 000 eq. 22)",
                                 examples=[False])
    atmosphere: AtmosphereName | ReentryAtmosphereModel | None = Field(
        None, description="null: the vehicle preset's (shuttle: Betts' exponential; msl: the Mars table); "
        "exponential (Betts' Earth), us1976 (U.S. Standard Atmosphere 1976), mars (log-density table of "
        "the NASA Glenn Mars model), or your own model", examples=["exponential"])
    planet: PlanetName | ReentryPlanet | None = Field(
        None, description="null: the vehicle preset's (shuttle: earth with Betts' constants; msl: mars); "
        "a name, or a planet with overrides", examples=[None])
    initial_guess: ReentryGuess = Field(default_factory=ReentryGuess, description="Initial guess")

    @model_validator(mode="after")
    def _consistent(self):
        t = self.terminal
        if t.altitude_m is not None and t.altitude_m >= self.initial_state.altitude_m:
            raise ValueError("terminal.altitude_m must be below initial_state.altitude_m")
        if t.speed_mps is not None and t.speed_mps >= self.initial_state.speed_mps:
            raise ValueError("terminal.speed_mps must be below initial_state.speed_mps")
        return self
