"""The reentry problem as a multiple-shooting NLP: its parameter vector, the transcription's problem
(dynamics, path limits, objective, scales) and the box bounds on a grid.

Shared by the main solve (:mod:`solvers.reentry.solver`), the grid's error estimate
(:mod:`solvers.reentry.refine`) and the least-peak check (:mod:`solvers.reentry.minmax`), which is why it
is a module of its own: each of them poses the same NLP, and none imports another to get it.
"""
from __future__ import annotations

import dataclasses

import casadi as ca
import numpy as np

from solvers.models import reentry_dynamics as dyn
from solvers.models import shuttle as sh
from solvers.models import vehicle_data as vd
from solvers.models.reentry_state import (ALPHA, BANK, LATITUDE, LONGITUDE, NU, NX, U_SCALE, X_SCALE,
                                          box_bounds)
from solvers.reentry.problem import HEAT_LOAD_SCALE, T_SCALE, ReentryProblem
from solvers.transcription.multiple_shooting import PathConstraint, ShootingProblem


# --- NLP parameters: vehicle data and limits are numbers, not structure ----------------------
# Layout: [mass, area, aero numbers, cd_scale, cl_scale, q_max, qbar_max, n_max, lon0, lat0,
# heating numbers] (solvers.models.vehicle_data: polynomial coefficients, none for a table; the
# Sutton-Graves nose radius and constant).
def param_vector(problem: ReentryProblem) -> np.ndarray:
    """The NLP's parameter vector ``p`` of ``problem`` (vehicle numbers, limits, start position), which
    :func:`shooting_problem`'s transcription takes: one compiled structure serves every vehicle of a model."""
    v = problem.vehicle
    return np.array([v.mass_kg, v.area_m2, *vd.aero_numbers(v), v.cd_scale, v.cl_scale,
                     problem.max_heat_rate_w_m2 or 1.0, problem.max_dynamic_pressure_pa or 1.0,
                     problem.max_load_factor or 1.0, problem.initial_state[LONGITUDE],
                     problem.initial_state[LATITUDE], *vd.heating_numbers(v)], float)


def _symbolic_vehicle(vehicle: sh.Vehicle, p):
    i = 2 + len(vd.aero_numbers(vehicle))
    over = vd.with_symbols(vehicle, p[2:i], p[i + 7:i + 7 + len(vd.heating_numbers(vehicle))])
    veh = dataclasses.replace(vehicle, mass_kg=p[0], area_m2=p[1], cd_scale=p[i], cl_scale=p[i + 1], **over)
    return veh, p[i + 2], p[i + 3], p[i + 4], p[i + 5], p[i + 6]


def shooting_problem(problem: ReentryProblem, *, with_path: bool = True) -> ShootingProblem:
    """``problem`` as the multiple-shooting transcription's problem (scaled, parameters ``param_vector``);
    ``with_path=False`` leaves the path limits out (the first stage of a limited solve)."""
    veh0 = problem.vehicle
    n_params = len(param_vector(problem))

    def unpack(p):
        return _symbolic_vehicle(veh0, p)

    def dynamics(x, u, p):
        return dyn.eom(x, u, unpack(p)[0], ca)

    path = []
    where = "nodes" if problem.path_enforcement == "integral" else problem.path_enforcement
    integral = problem.path_enforcement == "integral"
    if with_path and problem.max_heat_rate_w_m2 is not None:
        path.append(PathConstraint("heat_rate", lambda x, u, p: dyn.heat_rate(
            x, u, unpack(p)[0], ca) / unpack(p)[1] - 1.0, where=where, integral=integral))
    if with_path and problem.max_dynamic_pressure_pa is not None:
        path.append(PathConstraint("dynamic_pressure", lambda x, u, p: dyn.dynamic_pressure(
            x, unpack(p)[0], ca) / unpack(p)[2] - 1.0, where=where, integral=integral))
    if with_path and problem.max_load_factor is not None:
        path.append(PathConstraint("load_factor", lambda x, u, p: dyn.load_factor(
            x, u, unpack(p)[0], ca) / unpack(p)[3] - 1.0, where=where, integral=integral))

    mayer, lagrange, scale = None, None, 1.0
    obj = problem.objective
    if obj == "max_crossrange":
        mayer = lambda xf, T, p: -xf[LATITUDE]  # noqa: E731
    elif obj == "max_downrange":
        mayer = lambda xf, T, p: -xf[LONGITUDE]  # noqa: E731
    elif obj == "max_great_circle_range":
        def mayer(xf, T, p):
            lon0, lat0 = unpack(p)[4], unpack(p)[5]
            # Minimizing the cosine of the central angle avoids arccos' infinite slope at 180 deg.
            return (ca.sin(lat0) * ca.sin(xf[LATITUDE])
                    + ca.cos(lat0) * ca.cos(xf[LATITUDE]) * ca.cos(xf[LONGITUDE] - lon0))
    elif obj == "min_heat_load":
        lagrange = lambda x, u, p: dyn.stagnation_heat_integrand(x, unpack(p)[0], ca)  # noqa: E731
        scale = HEAT_LOAD_SCALE
    elif obj == "min_time":
        mayer = lambda xf, T, p: T  # noqa: E731
        scale = T_SCALE
    key = ("reentry", obj, *vd.model_key(veh0))
    # IPOPT's Hessian and Jacobian from per-interval SX blocks (solvers.transcription.blocks),
    # for every objective, control mode, path enforcement and vehicle model: the same values as
    # CasADi's AD of the whole NLP (to 1e-13), half the CPU in the virtual machine (Betts at 100
    # intervals: IPOPT 0.73 -> 0.34 s, 14 iterations either way; integral path limits 58 -> 3.3 s)
    # and, compiled, a 0.4 MB library instead of 2.4 MB (IPOPT 84 -> 63 ms).
    return ShootingProblem(
        key=key, nx=NX, nu=NU, n_params=n_params, dynamics=dynamics, x_scale=X_SCALE,
        u_scale=U_SCALE, t_scale=T_SCALE, intervals=problem.intervals, control=problem.control,
        substeps=problem.substeps, mayer=mayer, lagrange=lagrange, objective_scale=scale,
        path=tuple(path), ipopt=dict(problem.ipopt), block_derivatives=True)


def state_bounds(problem: ReentryProblem, m: int):
    """Box bounds of the NLP on ``m`` intervals: ``x_lb, x_ub`` (NX, m+1) with the initial state and
    the fixed terminal components pinned, and ``u_lb, u_ub`` (NU,)."""
    lo, hi = box_bounds(min_speed_mps=problem.min_speed_mps)
    x_lb = np.tile(lo[:, None], (1, m + 1))
    x_ub = np.tile(hi[:, None], (1, m + 1))
    x0 = np.asarray(problem.initial_state, float)
    x_lb[:, 0] = x0
    x_ub[:, 0] = x0
    xf = problem.terminal.as_array()
    fixed = ~np.isnan(xf)
    x_lb[fixed, m] = xf[fixed]
    x_ub[fixed, m] = xf[fixed]
    u_lb = np.empty(NU)
    u_ub = np.empty(NU)
    u_lb[ALPHA], u_ub[ALPHA] = problem.alpha_bounds_rad
    u_lb[BANK], u_ub[BANK] = problem.bank_bounds_rad
    return x_lb, x_ub, u_lb, u_ub
