"""The ``reentry`` kind's API edge: lifting reentry by direct multiple shooting.

Paper 000 (Qu Xiangju 1991, direct multiple shooting for Space Shuttle reentry) and the Betts
shuttle benchmark (Betts, *Practical Methods for Optimal Control*, sec. 6.3).  Parameters are in
SI and degrees; :mod:`solvers.reentry` works in SI and radians.
"""
from __future__ import annotations

import math
from typing import Literal

from pydantic import Field, field_validator, model_validator

from app.kinds.base import (
    JobContext, KindSpec, Preset, RunOutcome, StrictModel, outcome_from_status, warm_start_from_job,
)

FT = 0.3048
BETTS_HEAT_LIMIT_W_M2 = 794955.0   # 70 BTU/ft^2/s
Objective = Literal["max_crossrange", "max_downrange", "max_great_circle_range", "min_heat_load",
                    "min_time"]


def _max_intervals() -> int:
    try:
        from app.settings import get_settings
    except ImportError:  # settings module not present: fall back to the documented default
        return 1000
    return int(get_settings().max_grid_intervals)


class Grid(StrictModel):
    intervals: int = Field(100, ge=4, description="Shooting intervals m (nodes m+1); capped by the "
                           "service setting max_grid_intervals", examples=[100])
    control: Literal["linear", "constant"] = Field(
        "linear", description="Controls between nodes: continuous piecewise-linear (paper 000) or "
        "piecewise-constant", examples=["linear"])
    substeps: int = Field(2, ge=1, le=16, description="RK4 steps per interval", examples=[2])

    @field_validator("intervals")
    @classmethod
    def _cap(cls, v: int) -> int:
        cap = _max_intervals()
        if v > cap:
            raise ValueError(f"intervals must be <= max_grid_intervals ({cap})")
        return v


class PathLimits(StrictModel):
    max_heat_rate_w_m2: float | None = Field(None, gt=0, description="Stagnation heating-rate limit "
                                             "(Betts fit); 794955 W/m^2 = 70 BTU/ft^2/s", examples=[794955.0])
    max_dynamic_pressure_pa: float | None = Field(None, gt=0, description="Dynamic-pressure limit",
                                                  examples=[15000.0])
    max_load_factor: float | None = Field(None, gt=0, description="Aerodynamic load-factor limit "
                                          "sqrt(L^2+D^2)/(m g0)", examples=[2.5])
    enforcement: Literal["nodes", "midpoints", "substeps", "integral"] = Field(
        "nodes", description="Where path limits are enforced: at the nodes, also at interval "
        "midpoints or every RK4 substep, or by paper 000's integral penalty", examples=["nodes"])


class TerminalParams(StrictModel):
    altitude_m: float | None = Field(80000 * FT, ge=0, description="Final altitude (null: free)",
                                     examples=[24384.0])
    speed_mps: float | None = Field(2500 * FT, gt=0, description="Final speed (null: free)",
                                    examples=[762.0])
    flight_path_deg: float | None = Field(-5.0, ge=-89, le=89, description="Final flight-path angle "
                                          "(null: free)", examples=[-5.0])
    latitude_deg: float | None = Field(None, ge=-89, le=89, description="Final latitude (null: free)",
                                       examples=[32.0])
    longitude_deg: float | None = Field(None, description="Final longitude (null: free)", examples=[None])
    heading_deg: float | None = Field(None, description="Final heading from north (null: free)",
                                      examples=[None])


class InitialState(StrictModel):
    altitude_m: float = Field(260000 * FT, gt=0, description="Entry altitude", examples=[79248.0])
    longitude_deg: float = Field(0.0, description="Entry longitude", examples=[0.0])
    latitude_deg: float = Field(0.0, ge=-89, le=89, description="Entry latitude", examples=[0.0])
    speed_mps: float = Field(25600 * FT, gt=0, description="Entry speed", examples=[7802.88])
    flight_path_deg: float = Field(-1.0, ge=-89, le=89, description="Entry flight-path angle",
                                   examples=[-1.0])
    heading_deg: float = Field(90.0, description="Entry heading from north", examples=[90.0])


class VehicleParams(StrictModel):
    preset: Literal["shuttle"] = Field("shuttle", description="Base vehicle (Betts shuttle); the "
                                       "fields below override it", examples=["shuttle"])
    mass_kg: float | None = Field(None, gt=0, description="Mass", examples=[92079.2])
    area_m2: float | None = Field(None, gt=0, description="Reference area", examples=[249.91])
    cl_coeffs: list[float] | None = Field(None, min_length=1, max_length=6, description="CL polynomial "
                                          "in alpha degrees, lowest order first", examples=[[-0.20704, 0.029244]])
    cd_coeffs: list[float] | None = Field(None, min_length=1, max_length=6, description="CD polynomial "
                                          "in alpha degrees, lowest order first",
                                          examples=[[0.07854, -0.0061592, 0.000621408]])


def _interval(v: list[float], name: str) -> list[float]:
    if len(v) != 2 or not v[0] < v[1]:
        raise ValueError(f"{name} must be [lo, hi] with lo < hi")
    return v


class Bounds(StrictModel):
    alpha_deg: list[float] = Field([-90.0, 90.0], description="Angle-of-attack bounds [lo, hi]",
                                   examples=[[-90.0, 90.0]])
    bank_deg: list[float] = Field([-90.0, 1.0], description="Bank-angle bounds [lo, hi]",
                                  examples=[[-90.0, 1.0]])

    @field_validator("alpha_deg")
    @classmethod
    def _alpha(cls, v):
        _interval(v, "alpha_deg")
        if v[0] < -90 or v[1] > 90:
            raise ValueError("alpha_deg must lie within [-90, 90]")
        return v

    @field_validator("bank_deg")
    @classmethod
    def _bank(cls, v):
        _interval(v, "bank_deg")
        if v[0] < -180 or v[1] > 180:
            raise ValueError("bank_deg must lie within [-180, 180]")
        return v


class GuessParams(StrictModel):
    kind: Literal["linear", "simulate"] = Field("simulate", description="Cold start: straight lines "
                                                "between initial and terminal states, or a glide "
                                                "simulated with constant controls", examples=["simulate"])
    from_job: str | None = Field(None, description="Warm start from this succeeded reentry job's "
                                 "trajectory (interpolated onto the new grid)", examples=[None])


class Params(StrictModel):
    objective: Objective = Field("max_crossrange", description="max_crossrange (final latitude), "
                                 "max_downrange (final longitude), max_great_circle_range, "
                                 "min_heat_load (int sqrt(rho) v^3 dt), min_time", examples=["max_crossrange"])
    grid: Grid = Field(default_factory=Grid, description="Shooting grid")
    path: PathLimits = Field(default_factory=PathLimits, description="Path limits")
    terminal: TerminalParams = Field(default_factory=TerminalParams, description="Terminal equalities")
    initial_state: InitialState = Field(default_factory=InitialState, description="Entry state")
    vehicle: VehicleParams = Field(default_factory=VehicleParams, description="Vehicle")
    bounds: Bounds = Field(default_factory=Bounds, description="Control bounds")
    rotating_earth: bool = Field(False, description="Coriolis and centripetal terms (paper 000 eq. 22)",
                                 examples=[False])
    atmosphere: Literal["exponential", "us1976"] = Field("exponential", description="Betts exponential "
                                                         "or U.S. Standard Atmosphere 1976", examples=["exponential"])
    initial_guess: GuessParams = Field(default_factory=GuessParams, description="Initial guess")

    @model_validator(mode="after")
    def _consistent(self):
        t = self.terminal
        if t.altitude_m is not None and t.altitude_m >= self.initial_state.altitude_m:
            raise ValueError("terminal.altitude_m must be below initial_state.altitude_m")
        if t.speed_mps is not None and t.speed_mps >= self.initial_state.speed_mps:
            raise ValueError("terminal.speed_mps must be below initial_state.speed_mps")
        return self


_BETTS_NOTE = ("Betts shuttle (Practical Methods for Optimal Control, sec. 6.3): entry at 260000 ft, "
               "25600 ft/s, -1 deg; final 80000 ft, 2500 ft/s, -5 deg; alpha in [-90, 90], "
               "bank in [-90, 1] deg; non-rotating spherical Earth, exponential atmosphere.")
_PAPER000 = {"terminal": {"altitude_m": 39624.0, "speed_mps": None, "flight_path_deg": None},
             "bounds": {"alpha_deg": [-90.0, 40.0]}}

PRESETS = [
    Preset("betts-max-crossrange", "reentry",
           "Maximum final latitude. " + _BETTS_NOTE + " Betts: 34.1412 deg, tf 2008.59 s; this "
           "transcription gives 34.14118 deg, 2008.59 s at 100 intervals.", {}),
    Preset("betts-max-crossrange-heat-limited", "reentry",
           "Maximum final latitude with heating rate <= 70 BTU/ft^2/s (794955 W/m^2). " + _BETTS_NOTE +
           " Betts: 30.6255 deg, tf 2198.67 s; here 30.6279 deg at 100 intervals and 30.6256 deg / "
           "2198.66 s at 400. Solved warm-started from the unconstrained optimum. The limit holds at "
           "the nodes; between them the re-propagated trajectory exceeds it by about 0.6% at 100 "
           "intervals (reported in verification.max_heat_rate_w_m2).",
           {"path": {"max_heat_rate_w_m2": BETTS_HEAT_LIMIT_W_M2}}),
    Preset("shuttle-max-downrange", "reentry",
           "Paper 000 case 1 on the Betts vehicle (the paper's vehicle data are not public): final "
           "altitude 39624 m (130000 ft), alpha <= 40 deg. The paper's great-circle range "
           "(eqs. 24-26) is degenerate here: the glide reaches the antipode (180 deg) along several "
           "optimal trajectories, so this preset maximizes the final longitude instead "
           "(186.87 deg, tf about 3579 s); objective max_great_circle_range is offered too.",
           {**_PAPER000, "objective": "max_downrange"}),
    Preset("shuttle-max-crossrange", "reentry",
           "Paper 000 case 2 on the Betts vehicle: maximum final latitude at 39624 m, alpha <= 40 deg: "
           "33.513 deg, tf 1956.8 s (stable across grids and guesses). The paper's own figures used "
           "other vehicle data and are not reproducible.",
           {**_PAPER000, "objective": "max_crossrange"}),
    Preset("shuttle-min-heat-load", "reentry",
           "Paper 000 case 3: minimum total stagnation heat load J = int sqrt(rho) v^3 dt (SI) to "
           "39624 m, alpha <= 40 deg. Ill-posed as stated (the paper calls it unrealistic): the optimum "
           "dives to the final altitude as fast as it can, and IPOPT finds local minima that depend on "
           "the initial guess (initial_guess.kind changes the answer).",
           {**_PAPER000, "objective": "min_heat_load"}),
    Preset("shuttle-min-heat-load-terminal", "reentry",
           "Paper 000 case 4: minimum heat load with final latitude 34 deg and speed 1287.6 m/s at "
           "39624 m. Infeasible with this vehicle: the highest latitude reachable at that speed is "
           "32.86 deg. The job fails fast with code infeasible and IPOPT's diagnosis (its worst "
           "remaining defect is the 1.14 deg latitude shortfall); with terminal.latitude_deg 32 it "
           "solves (J = 4.71e12 SI).",
           {**_PAPER000, "objective": "min_heat_load",
            "terminal": {**_PAPER000["terminal"], "latitude_deg": 34.0, "speed_mps": 1287.6}}),
]

_UNITS = {"max_crossrange": "deg", "max_downrange": "deg", "max_great_circle_range": "deg",
          "min_heat_load": "kg^0.5 m^1.5 s^-2", "min_time": "s"}


def _problem(params: Params):
    import dataclasses

    from solvers import reentry as rs
    from solvers.models import shuttle as sh
    from solvers.models.atmosphere import Atmosphere

    d = math.radians
    v = params.vehicle
    veh = sh.SHUTTLE
    over = {k: val for k, val in {"mass_kg": v.mass_kg, "area_m2": v.area_m2,
                                  "cl_coeffs": tuple(v.cl_coeffs) if v.cl_coeffs else None,
                                  "cd_coeffs": tuple(v.cd_coeffs) if v.cd_coeffs else None}.items()
            if val is not None}
    if params.atmosphere == "us1976":
        over["atmosphere"] = Atmosphere(kind="us1976")
    veh = dataclasses.replace(veh, rotating_earth=params.rotating_earth, **over)
    s0 = params.initial_state
    t = params.terminal
    opt = lambda x: None if x is None else d(x)  # noqa: E731
    return rs.ReentryProblem(
        vehicle=veh,
        initial_state=(s0.altitude_m, d(s0.longitude_deg), d(s0.latitude_deg), s0.speed_mps,
                       d(s0.flight_path_deg), d(s0.heading_deg)),
        terminal=rs.Terminal(altitude_m=t.altitude_m, longitude_rad=opt(t.longitude_deg),
                             latitude_rad=opt(t.latitude_deg), speed_mps=t.speed_mps,
                             flight_path_rad=opt(t.flight_path_deg), heading_rad=opt(t.heading_deg)),
        objective=params.objective,
        alpha_bounds_rad=tuple(map(d, params.bounds.alpha_deg)),
        bank_bounds_rad=tuple(map(d, params.bounds.bank_deg)),
        max_heat_rate_w_m2=params.path.max_heat_rate_w_m2,
        max_dynamic_pressure_pa=params.path.max_dynamic_pressure_pa,
        max_load_factor=params.path.max_load_factor,
        path_enforcement=params.path.enforcement,
        intervals=params.grid.intervals, control=params.grid.control, substeps=params.grid.substeps)


def _guess_from_result(result: dict):
    import numpy as np

    from solvers.reentry import InitialGuess

    tr = result["trajectory"]
    r = np.radians
    t = np.asarray(tr["t_s"], float)
    x = np.vstack([tr["altitude_m"], r(tr["longitude_deg"]), r(tr["latitude_deg"]), tr["speed_mps"],
                   r(tr["flight_path_deg"]), r(tr["heading_deg"])]).astype(float)
    u = np.vstack([r(tr["alpha_deg"]), r(tr["bank_deg"])]).astype(float)
    if t.size < 2 or not np.all(np.diff(t) > 0) or not np.all(np.isfinite(x)):
        raise ValueError("trajectory is not a usable time series")
    return InitialGuess(t=t, x=x, u=u)


def _f(x) -> float:
    x = float(x)
    return x if math.isfinite(x) else 0.0


def _result(params: Params, sol) -> dict:
    import numpy as np

    deg = np.degrees
    x, u = sol.x, sol.u_nodes_at_t
    value = deg(sol.objective_value) if _UNITS[sol.objective_name] == "deg" else sol.objective_value
    st = sol.status
    res = {
        "objective": {"name": sol.objective_name, "value": _f(value), "unit": _UNITS[sol.objective_name]},
        "tf_s": _f(sol.tf),
        "final": {"altitude_m": _f(x[0, -1]), "speed_mps": _f(x[3, -1]),
                  "flight_path_deg": _f(deg(x[4, -1])), "latitude_deg": _f(deg(x[2, -1])),
                  "longitude_deg": _f(deg(x[1, -1])), "heading_deg": _f(deg(x[5, -1]))},
        "trajectory": {
            "t_s": [_f(v) for v in sol.t], "altitude_m": [_f(v) for v in x[0]],
            "longitude_deg": [_f(v) for v in deg(x[1])], "latitude_deg": [_f(v) for v in deg(x[2])],
            "speed_mps": [_f(v) for v in x[3]], "flight_path_deg": [_f(v) for v in deg(x[4])],
            "heading_deg": [_f(v) for v in deg(x[5])], "alpha_deg": [_f(v) for v in deg(u[0])],
            "bank_deg": [_f(v) for v in deg(u[1])], "heat_rate_w_m2": [_f(v) for v in sol.heat_rate]},
        "solver": {"status": st.solver_status, "iterations": int(st.iterations),
                   "solve_time_s": _f(st.solve_time_s), "build_time_s": _f(st.build_time_s),
                   "max_constraint_violation": _f(st.max_constraint_violation),
                   "cached_build": bool(st.details.get("solver_cached", False)),
                   "stages": [{k: (_f(v) if isinstance(v, float) else v) for k, v in s.items()}
                              for s in sol.stages]},
        "notes": list(sol.notes),
    }
    ver = sol.verification
    if ver is not None:
        dfx = ver.final_difference
        res["verification"] = {
            "method": "scipy DOP853, rtol 1e-10, controls interpolated as in the transcription",
            "final_altitude_diff_m": _f(dfx[0]), "final_longitude_diff_deg": _f(deg(dfx[1])),
            "final_latitude_diff_deg": _f(deg(dfx[2])), "final_speed_diff_mps": _f(dfx[3]),
            "final_flight_path_diff_deg": _f(deg(dfx[4])), "final_heading_diff_deg": _f(deg(dfx[5])),
            "max_node_altitude_diff_m": _f(ver.max_node_difference[0]),
            "max_node_latitude_diff_deg": _f(deg(ver.max_node_difference[2])),
            "max_heat_rate_w_m2": _f(ver.path_max["heat_rate_w_m2"]),
            "max_heat_rate_t_s": _f(ver.path_argmax_t["heat_rate_w_m2"]),
            "max_heat_rate_nodes_w_m2": _f(np.max(sol.heat_rate)),
            "max_dynamic_pressure_pa": _f(ver.path_max["dynamic_pressure_pa"]),
            "max_load_factor": _f(ver.path_max["load_factor"]),
            "dense_samples": int(ver.t.size), "ok": bool(ver.ok), "message": ver.message,
            "time_s": _f(st.details.get("verification_time_s", 0.0)),
        }
    else:
        res["verification"] = None
    return res


def run(params: Params, ctx: JobContext) -> RunOutcome:
    from solvers import reentry as rs

    problem = _problem(params)
    guess = params.initial_guess.kind
    notes = []
    if params.initial_guess.from_job:
        job = params.initial_guess.from_job
        guess = warm_start_from_job(ctx, job, _guess_from_result, field="initial_guess.from_job",
                                    what="reentry trajectory")
        notes.append(f"warm-started from job {job}")
    ctx.progress(0.0, "building the multiple-shooting NLP")
    sol = rs.solve(problem, initial_guess=guess, on_progress=ctx.progress, should_stop=ctx.should_stop)
    sol.notes[:0] = notes
    result = _result(params, sol)
    if sol.status.ok:
        ctx.progress(1.0, f"done: {sol.status.solver_status} after {sol.status.iterations} iterations")
    return outcome_from_status(sol.status, result)


SPEC = KindSpec(kind="reentry", params_model=Params, run=run, presets=PRESETS,
                summary="Lifting reentry (Space Shuttle, Betts benchmark and paper 000) by direct "
                        "multiple shooting with IPOPT")
