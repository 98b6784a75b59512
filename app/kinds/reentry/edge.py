"""The reentry family's public edge: parameters to a solver problem, a stored result to a warm
start, and the result blocks both ``reentry`` and ``robust_reentry`` report.

Radians in the solver become degrees here, by the state declaration
(:mod:`solvers.models.reentry_state`: ``latitude_rad`` is ``latitude_deg`` at the API); every
number goes through :func:`app.kinds.base.json_float` (non-finite is ``null``).  Heavy solver
modules are imported inside the functions so the API process starts without CasADi.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from app.kinds.base import json_float, json_value
from app.kinds.reentry.params import ReentryParams
from app.kinds.reentry.vehicle import named_atmosphere
from solvers.models.reentry_state import CONTROLS, STATE_INDEX, STATES, Trajectory

MAX_DENSE_POINTS = 500   # points of the verification's dense trajectory kept in a result


def json_list(values) -> list:
    """A 1-D array as a JSON list (non-finite: null)."""
    return [json_float(v) for v in np.asarray(values, float).ravel()]


def _radians_pair(deg) -> tuple[float, float]:
    lo, hi = deg
    return math.radians(lo), math.radians(hi)


def to_problem(params: ReentryParams):
    """The :class:`solvers.reentry.ReentryProblem` of validated parameters (degrees to radians)."""
    from solvers import reentry as rs

    vehicle = vehicle_of(params)
    s0, t = params.initial_state, params.terminal
    terminal = {c.name: None if getattr(t, c.api_name) is None else c.from_api(getattr(t, c.api_name))
                for c in STATES}
    return rs.ReentryProblem(
        vehicle=vehicle,
        initial_state=tuple(c.from_api(getattr(s0, c.api_name)) for c in STATES),
        terminal=rs.Terminal(**terminal),
        objective=params.objective,
        alpha_bounds_rad=_radians_pair(params.bounds.alpha_deg),
        bank_bounds_rad=_radians_pair(params.bounds.bank_deg),
        max_heat_rate_w_m2=params.path.max_heat_rate_w_m2,
        max_dynamic_pressure_pa=params.path.max_dynamic_pressure_pa,
        max_load_factor=params.path.max_load_factor,
        path_enforcement=params.path.enforcement, limit_tolerance=params.path.limit_tolerance,
        limit_rounds=params.path.limit_rounds,
        terminal_tolerance=rs.TerminalTolerance(altitude_m=params.terminal_check.altitude_m,
                                                speed_mps=params.terminal_check.speed_mps,
                                                angle_rad=math.radians(params.terminal_check.angle_deg)),
        terminal_rounds=params.terminal_check.rounds,
        intervals=params.grid.intervals, control=params.grid.control, substeps=params.grid.substeps,
        accuracy=params.accuracy, accuracy_required=params.accuracy_required,
        max_refinements=params.grid.max_refinements)


def vehicle_of(params: ReentryParams):
    """The solver's :class:`solvers.models.shuttle.Vehicle`: the named preset with the job's overrides
    (mass, area, aerodynamics, heating), planet, atmosphere and rotation flag."""
    import dataclasses

    from solvers.models import vehicles
    from solvers.models.heating import SuttonGraves

    v = params.vehicle
    base = vehicles.vehicle_preset(v.preset).vehicle
    over: dict[str, Any] = {k: val for k, val in {"mass_kg": v.mass_kg, "area_m2": v.area_m2}.items()
                            if val is not None}
    if v.cl_coeffs is not None or v.cd_coeffs is not None:
        # polynomials replace a preset's table (then both are given: ReentryVehicle checks it)
        over.update(aero_table=None, cl_coeffs=tuple(v.cl_coeffs or base.cl_coeffs),
                    cd_coeffs=tuple(v.cd_coeffs or base.cd_coeffs))
    if v.aero_table is not None:
        over["aero_table"] = v.aero_table.to_solver()
    if v.heating is not None and v.heating.model == "betts":
        over["heating"] = None
    elif v.heating is not None:
        assert v.heating.nose_radius_m is not None  # ReentryHeating requires it for sutton_graves
        over["heating"] = SuttonGraves(nose_radius_m=v.heating.nose_radius_m, k=v.heating.k)
    if isinstance(params.planet, str):
        over["planet"] = vehicles.PLANETS[params.planet]
    elif params.planet is not None:
        over["planet"] = params.planet.to_solver()
    if isinstance(params.atmosphere, str):
        over["atmosphere"] = named_atmosphere(params.atmosphere)
    elif params.atmosphere is not None:
        over["atmosphere"] = params.atmosphere.to_solver()
    return dataclasses.replace(base, rotating_earth=params.rotating_earth, **over)


def _from_api(component, values) -> np.ndarray:
    values = np.asarray(values, float)   # null (a non-finite value) becomes NaN
    return np.radians(values) if component.is_angle else values


def guess_from_result(result: dict):
    """A :class:`solvers.reentry.InitialGuess` from a stored reentry (or robust) result's trajectory.

    Raises ``KeyError``/``ValueError`` when the result has no usable time series.
    """
    from solvers.reentry import InitialGuess

    tr = result["trajectory"]
    t = np.asarray(tr["t_s"], float)
    x = np.vstack([_from_api(c, tr[c.api_name]) for c in STATES])
    u = np.vstack([_from_api(c, tr[c.api_name]) for c in CONTROLS])
    if t.size < 2 or not np.all(np.diff(t) > 0) or not np.all(np.isfinite(x)):
        raise ValueError("trajectory is not a usable time series")
    return InitialGuess(t=t, x=x, u=u)


# --- result blocks -------------------------------------------------------------------------------
def objective_block(*, name: str, value: float, unit: str) -> dict:
    """The objective in API units: the solver's ``rad`` becomes ``deg``, other units are kept."""
    if unit == "rad":
        value, unit = math.degrees(value), "deg"
    return {"name": name, "value": json_float(value), "unit": unit}


def final_block(trajectory: Trajectory) -> dict:
    """The final state by API name."""
    order = ("altitude_m", "speed_mps", "flight_path_rad", "latitude_rad", "longitude_rad", "heading_rad")
    comps = [STATES[STATE_INDEX[n]] for n in order]
    return {c.api_name: json_float(c.to_api(trajectory.state(c.name)[-1])) for c in comps}


def trajectory_block(trajectory: Trajectory) -> dict:
    """Time, states, controls and path quantities at the nodes, by API name."""
    out = {"t_s": json_list(trajectory.t)}
    for rows, comps in ((trajectory.x, STATES), (trajectory.u, CONTROLS)):
        for row, c in zip(rows, comps):
            out[c.api_name] = json_list(c.to_api(row))
    for name, values in trajectory.path.items():
        out[name] = json_list(values)
    return out


def solver_block(status, stages: list[dict]) -> dict:
    """IPOPT's account of the solve (iterations and times summed over the stages)."""
    return {"status": status.solver_status, "iterations": int(status.iterations),
            "solve_time_s": json_float(status.solve_time_s), "build_time_s": json_float(status.build_time_s),
            "max_constraint_violation": json_float(status.max_constraint_violation),
            "cached_build": bool(status.details.get("solver_cached", False)),
            "stages": [{k: (json_float(v) if isinstance(v, float) else v) for k, v in s.items()}
                       for s in stages],
            **{k: json_value(status.details[k]) for k in ("refinement", "accuracy", "accuracy_reached")
               if k in status.details}}


def _dense_trajectory(ver) -> dict:
    """The verification's dense re-simulation, at most ``MAX_DENSE_POINTS`` points (for plots)."""
    n = ver.t.size
    keep = np.unique(np.linspace(0, n - 1, min(n, MAX_DENSE_POINTS)).round().astype(int))
    out = {"t_s": json_list(ver.t[keep])}
    for name in ("altitude_m", "speed_mps", "flight_path_rad", "latitude_rad", "longitude_rad"):
        i = STATE_INDEX[name]
        out[STATES[i].api_name] = json_list(STATES[i].to_api(ver.x[i, keep]))
    for name in ("heat_rate_w_m2", "dynamic_pressure_pa", "load_factor"):
        if name in ver.path_values:
            out[name] = json_list(np.asarray(ver.path_values[name])[..., keep])
    return out


def verification_block(ver, *, node_heat_rate, time_s: float) -> dict | None:
    """The independent re-propagation (:mod:`solvers.verification`) in API units; None when not run."""
    if ver is None:
        return None
    dfx, worst = ver.final_difference, ver.max_node_difference
    out = {"method": ver.method}
    for i, c in enumerate(STATES):
        unit = "deg" if c.is_angle else c.name.rsplit("_", 1)[1]
        out[f"final_{c.name.rsplit('_', 1)[0]}_diff_{unit}"] = json_float(c.to_api(dfx[i]))
    for name in ("altitude_m", "latitude_rad"):
        i = STATE_INDEX[name]
        unit = "deg" if STATES[i].is_angle else "m"
        out[f"max_node_{name.rsplit('_', 1)[0]}_diff_{unit}"] = json_float(STATES[i].to_api(worst[i]))
    out.update({
        "max_heat_rate_w_m2": json_float(ver.path_max["heat_rate_w_m2"]),
        "max_heat_rate_t_s": json_float(ver.path_argmax_t["heat_rate_w_m2"]),
        "max_heat_rate_nodes_w_m2": json_float(np.max(node_heat_rate)),
        "max_dynamic_pressure_pa": json_float(ver.path_max["dynamic_pressure_pa"]),
        "max_load_factor": json_float(ver.path_max["load_factor"]),
        "dense_samples": int(ver.t.size), "samples_per_interval": int(ver.samples_per_interval),
        "ok": bool(ver.ok), "message": ver.message,
        "time_s": json_float(time_s),
    })
    if ver.error_estimate is not None:
        for name in ("altitude_m", "speed_mps", "latitude_rad"):
            c = STATES[STATE_INDEX[name]]
            unit = "deg" if c.is_angle else c.name.rsplit("_", 1)[1]
            out[f"error_estimate_{name.rsplit('_', 1)[0]}_{unit}"] = json_float(
                c.to_api(ver.error_estimate[STATE_INDEX[name]]))
    out.update(limits_block(ver.limits))
    out.update(terminal_block(ver.terminal))
    out["trajectory"] = _dense_trajectory(ver)
    return out


def limits_block(limits: dict) -> dict:
    """Limits that hold: per limited quantity, the worst value on the dense grid, the limit and
    whether it held within the tolerance; ``limits_held`` over all (null when no limit is set)."""
    if not limits:
        return {"limits": {}, "limits_held": None}
    block = {q: {"limit": json_float(c["limit"]), "max": json_float(c["max"]),
                 "max_t_s": json_float(c["max_t_s"]), "excess_percent": json_float(100 * c["excess"]),
                 "tolerance_percent": json_float(100 * c["tolerance"]), "held": bool(c["held"])}
             for q, c in limits.items()}
    return {"limits": block, "limits_held": all(c["held"] for c in block.values())}


def terminal_block(terminal: dict) -> dict:
    """Terminal conditions that hold: per requested final value (API name and unit), the requested and
    re-propagated values, the miss and its tolerance; ``terminal_held`` over all (null: none requested)."""
    if not terminal:
        return {"terminal": {}, "terminal_held": None}
    block = {}
    for name, c in terminal.items():
        comp = STATES[STATE_INDEX[name]]
        block[comp.api_name] = {k: json_float(comp.to_api(c[k])) for k in ("requested", "reached", "miss",
                                                                          "tolerance", "error_estimate")
                                if c[k] is not None}
        block[comp.api_name]["held"] = bool(c["held"])
    return {"terminal": block, "terminal_held": all(c["held"] for c in block.values())}


def result_blocks(*, trajectory: Trajectory, tf_s: float, status, stages: list[dict], notes: list[str],
                  verification) -> dict:
    """The blocks every reentry-family result has besides its objective."""
    return {
        "tf_s": json_float(tf_s),
        "final": final_block(trajectory),
        "trajectory": trajectory_block(trajectory),
        "solver": solver_block(status, stages),
        "notes": list(notes),
        "verification": verification_block(
            verification, node_heat_rate=trajectory.path["heat_rate_w_m2"],
            time_s=status.details.get("verification_time_s", 0.0)),
    }


def reentry_result(sol) -> dict:
    """The ``reentry`` kind's result of a :class:`solvers.reentry.ReentrySolution`."""
    return {"objective": objective_block(name=sol.objective_name, value=sol.objective_value,
                                         unit=sol.objective_unit),
            **result_blocks(trajectory=sol.trajectory, tf_s=sol.tf_s, status=sol.status, stages=sol.stages,
                            notes=sol.notes, verification=sol.verification)}


def shooting_cost(params: dict) -> float:
    """The reentry job's cost in :mod:`app.service.quota`'s work units: intervals x substeps (one unit is
    one RK4 step of one shooting interval), times the solves of the refinement rounds with ``accuracy``
    (each round may solve again, on more intervals, as ocp's cost counts).  The robust kind builds on it."""
    grid = params.get("grid") or {}
    rounds = 1.0 + (float(grid.get("max_refinements", 8)) if params.get("accuracy") else 0.0)
    return float(grid.get("intervals", 100)) * float(grid.get("substeps", 2)) * rounds


def compare_series(result: dict):
    """Altitude against speed, the curve that best shows a reentry (the console's compare plot)."""
    from app.kinds.base import CompareSeries

    tr = result["trajectory"]
    return CompareSeries([v / 1000 if v is not None else None for v in tr["speed_mps"]],
                         [v / 1000 if v is not None else None for v in tr["altitude_m"]],
                         "speed (km/s)", "altitude (km)")
