"""The result blocks of the ``intercept`` kind (``shared/specs/api.md``): the impulsive
and finite-thrust blocks, the per-method comparison and the key numbers.  Every
number goes through :func:`app.kinds.base.json_value` (non-finite becomes ``null``)."""
from __future__ import annotations

import math

from app.kinds.base import json_float, json_value
from app.kinds.intercept.params import InterceptParams

FRAME = ("Hill frame of the target: origin at the target, x radial (outward), y along-track, "
         "z orbit normal (angular momentum); velocities as seen in the rotating frame")


def _solver_block(status, **extra) -> dict:
    return {"status": status.solver_status, "iterations": status.iterations, "solve_time_s": status.solve_time_s,
            **extra, "max_constraint_violation": status.max_constraint_violation}


def impulsive_result(sol, params: InterceptParams) -> dict:
    """The ``impulsive`` block of the result."""
    s = sol.status
    b = sol.best_branch
    out = {
        "status": s.outcome.value,
        "message": s.message,
        "scan": {"t_man_s": json_value(sol.t_man_s), "delta_v_mps": json_value(sol.delta_v_mps)},
        "best": {
            "t_man_s": json_float(sol.best_t_man_s),
            "delta_v_mps": json_float(sol.best_delta_v_mps),
            "delta_v_vector_mps": json_value(sol.delta_v_vector_mps),
            "fuel_kg": json_float(sol.fuel_kg),
            "g0_mps2": params.g0_mps2,
            "prograde": b.prograde if b else None,
            "revolutions": b.revolutions if b else None,
            "low_path": b.low_path if b else None,
            "branch": b.label() if b else None,
            "position_m": json_value(sol.burn_position_m),
            "velocity_before_mps": json_value(sol.velocity_before_mps),
            "velocity_after_mps": json_value(sol.velocity_after_mps),
            "relative_velocity_at_intercept_mps": json_value(sol.relative_velocity_at_intercept_mps),
        },
        "intercept_time_s": json_float(sol.tf_s),
        "branches_searched": [br.label() for br in sol.branches],
        "through_planet": {
            "excluded": params.scan.exclude_through_planet, "body_radius_m": params.scan.body_radius_m,
            "excluded_solutions": sol.excluded_through_planet,
            "points_only_through_planet": sol.points_only_through_planet},
        "solver": _solver_block(s),
        "verification": {"miss_distance_m": json_float(sol.miss_distance_m),
                         "method": "post-burn state propagated to the interception time (universal variables)"},
    }
    if sol.porkchop is not None:
        pc = sol.porkchop
        out["porkchop"] = {
            "t_man_s": json_value(pc.t_man_s), "t_intercept_s": json_value(pc.t_intercept_s),
            "delta_v_mps": json_value(pc.delta_v_mps),
            "best": {"t_man_s": json_float(pc.best_t_man_s), "t_intercept_s": json_float(pc.best_t_intercept_s),
                     "delta_v_mps": json_float(pc.best_delta_v_mps)},
        }
    return out


def finite_result(sol, params: InterceptParams) -> dict:
    """The ``finite_thrust`` block of the result."""
    import numpy as np

    s = sol.status
    out = {"status": s.outcome.value, "message": s.message, "warm_start": sol.warm_start}
    if sol.t_s.size:
        x = sol.states
        thrust = sol.thrust_n
        m0 = params.interceptor.mass_kg
        c = params.interceptor.isp_s * params.g0_mps2
        out.update({
            "tf_s": json_float(sol.tf_s),
            "final_mass_kg": json_float(sol.final_mass_kg),
            "fuel_kg": json_float(sol.fuel_kg),
            "delta_v_mps": json_float(c * math.log(m0 / sol.final_mass_kg)) if sol.final_mass_kg > 0 else None,
            "g0_mps2": params.g0_mps2,
            "free_final_time": params.free_final_time,
            "burns": json_value(sol.burns),
            "arcs": json_value(sol.arcs),
            "frame": FRAME,
            "trajectory": json_value({
                "t_s": sol.t_s,
                "x_m": x[0], "y_m": x[1], "z_m": x[2], "vx_mps": x[3], "vy_mps": x[4], "vz_mps": x[5],
                "thrust_x_n": thrust[0], "thrust_y_n": thrust[1], "thrust_z_n": thrust[2],
                "thrust_n": np.linalg.norm(thrust, axis=0),
                "mass_kg": x[6],
            }),
        })
    out.update({
        "solver": _solver_block(s, build_time_s=s.build_time_s,
                                total_time_s=json_float(s.details.get("total_time_s", math.nan))),
        "verification": json_value(sol.verification) or None,
        "optimality": ({**json_value(sol.optimality), "along_trajectory": json_value(sol.optimality_history)}
                       if sol.optimality else None),
        "mesh": json_value(sol.mesh) or None,
        "history": json_value(sol.history),
    })
    return out


def comparison(result: dict) -> list[dict]:
    """One row per method: fuel, delta-v, interception time, miss."""
    rows = []
    imp, fin = result.get("impulsive"), result.get("finite_thrust")
    if imp and imp.get("best", {}).get("fuel_kg") is not None:
        rows.append({"method": "impulsive", "fuel_kg": imp["best"]["fuel_kg"],
                     "delta_v_mps": imp["best"]["delta_v_mps"], "tf_s": imp["intercept_time_s"],
                     "burns": [{"start_s": imp["best"]["t_man_s"], "duration_s": 0.0}],
                     "miss_distance_m": imp["verification"]["miss_distance_m"]})
    if fin and fin.get("fuel_kg") is not None:
        rows.append({"method": "finite_thrust", "fuel_kg": fin["fuel_kg"], "delta_v_mps": fin["delta_v_mps"],
                     "tf_s": fin["tf_s"],
                     "burns": [{"start_s": b["start_s"], "duration_s": b["duration_s"]} for b in fin["burns"]],
                     "miss_distance_m": (fin["verification"] or {}).get("miss_distance_m")})
    return rows


def key_numbers(result: dict) -> dict:
    """Fuel, delta-v, interception time and miss of each method that ran."""
    out = {}
    for row in result["comparison"]:
        for key in ("fuel_kg", "delta_v_mps", "tf_s", "miss_distance_m"):
            out[f"{row['method']}.{key}"] = row[key]
    return out
