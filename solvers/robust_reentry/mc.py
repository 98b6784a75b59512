"""Monte Carlo of the robust reentry designs: the shuttle as a :mod:`solvers.uncertainty.montecarlo` model.

:func:`monte_carlo_spec` turns a design's node controls into the JSON spec a worker runs;
:func:`monte_carlo_model` rebuilds the dynamics from it (registered in the Monte Carlo module as
``"shuttle_reentry"``).  Besides the terminal statistics, the model names what the results
plot: an envelope (mean and std over time) of altitude, speed and heating rate, and the
terminal altitude, speed and flight-path angle of individual samples.  Vehicles the compiled
propagation handles (:func:`solvers.robust_reentry.kernel.supports`) run through it; the numpy
right-hand side stays the reference and the path for every other vehicle.
"""
from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

import numpy as np

from solvers.models import reentry_dynamics as dyn
from solvers.models import shuttle as sh
from solvers.models.aerodynamics import AeroTable
from solvers.models.atmosphere import Atmosphere
from solvers.models.heating import SuttonGraves
from solvers.models.reentry_state import ALTITUDE, NU, NX, SPEED, STATE_INDEX, STATE_NAMES
from solvers.robust_reentry import kernel as rk
from solvers.uncertainty.montecarlo import MCModel
from solvers.uncertainty.montecarlo import PathConstraint as MCPath

if TYPE_CHECKING:
    from solvers.robust_reentry.problem import RobustReentryProblem

# The terminal quantities with required values and sigma limits (paper 001), by state index.
TERMINAL_INDEX = {name: STATE_INDEX[name] for name in ("altitude_m", "speed_mps", "flight_path_rad")}


def vehicle_to_dict(v: sh.Vehicle) -> dict:
    return {"mass_kg": float(v.mass_kg), "area_m2": float(v.area_m2),
            "cl_coeffs": [float(c) for c in v.cl_coeffs], "cd_coeffs": [float(c) for c in v.cd_coeffs],
            "heat_coeffs": [float(c) for c in v.heat_coeffs],
            "atmosphere": dataclasses.asdict(v.atmosphere), "planet": dataclasses.asdict(v.planet),
            "rotating_earth": bool(v.rotating_earth), "cd_scale": float(v.cd_scale),
            "cl_scale": float(v.cl_scale),
            "aero_table": None if v.aero_table is None else dataclasses.asdict(v.aero_table),
            "heating": None if v.heating is None else dataclasses.asdict(v.heating)}


def vehicle_from_dict(d: dict) -> sh.Vehicle:
    return sh.Vehicle(mass_kg=d["mass_kg"], area_m2=d["area_m2"], cl_coeffs=tuple(d["cl_coeffs"]),
                      cd_coeffs=tuple(d["cd_coeffs"]), heat_coeffs=tuple(d["heat_coeffs"]),
                      atmosphere=Atmosphere(**d["atmosphere"]), planet=sh.Planet(**d["planet"]),
                      rotating_earth=d["rotating_earth"], cd_scale=d["cd_scale"], cl_scale=d["cl_scale"],
                      aero_table=AeroTable(**d["aero_table"]) if d.get("aero_table") else None,
                      heating=SuttonGraves(**d["heating"]) if d.get("heating") else None)


def monte_carlo_model(params: dict) -> MCModel:
    """The shuttle with sampled ``(s1, s2)``: ``CD (1 + s1)``, ``CL (1 + s2)``."""
    v = vehicle_from_dict(params["vehicle"])

    def rhs(x, u, s):
        return dyn.eom(x, u, v, np, cd_scale=1.0 + s[0], cl_scale=1.0 + s[1])

    def trace(x, u, s):  # s unused: the heating fit does not depend on the aero errors
        return {"altitude_m": x[ALTITUDE], "speed_mps": x[SPEED], "heat_rate_w_m2": dyn.heat_rate(x, u, v, np)}

    path = {}
    if params.get("max_heat_rate_w_m2") is not None:
        path["heat_rate"] = MCPath(fn=lambda x, u, s: dyn.heat_rate(x, u, v, np),
                                   limit=float(params["max_heat_rate_w_m2"]))
    if params.get("max_dynamic_pressure_pa") is not None:
        path["dynamic_pressure"] = MCPath(fn=lambda x, u, s: dyn.dynamic_pressure(x, v, np),
                                          limit=float(params["max_dynamic_pressure_pa"]))
    if params.get("max_load_factor") is not None:
        path["load_factor"] = MCPath(
            fn=lambda x, u, s: dyn.load_factor(x, u, v, np, cd_scale=1.0 + s[0], cl_scale=1.0 + s[1]),
            limit=float(params["max_load_factor"]))
    kernel = None
    if rk.supports(v):
        def kernel(*, x0, s, t_nodes, controls, substeps, kept_nodes):
            return rk.run_chunk(v, x0=x0, s=s, t_nodes=t_nodes, controls=controls, substeps=substeps,
                                kept_nodes=kept_nodes, path=tuple(path))
    return MCModel(nx=NX, nu=NU, ns=2, rhs=rhs,
                   terminal=lambda x, **_: {n: x[i] for i, n in enumerate(STATE_NAMES)}, path=path,
                   trace=trace, sampled_terminal=tuple(TERMINAL_INDEX), kernel=kernel)


def monte_carlo_spec(problem: RobustReentryProblem, *, t, u, cadet_sigma=None, substeps: int = 5) -> dict:
    """JSON-serializable Monte Carlo spec for node controls ``u`` (2, m+1) at times ``t``.

    ``cadet_sigma`` (6,) are CADET's terminal sigmas of this design: the "required value
    +- sigma" band, known before the run so every chunk counts against the same band.
    """
    base, unc = problem.base, problem.uncertainty
    required = {n: float(getattr(base.terminal, n)) for n in TERMINAL_INDEX
                if getattr(base.terminal, n) is not None}
    bands: dict = {}
    for n in required:
        b = {}
        lim = problem.robust.sigma_limits.get(n)
        if lim is not None:
            b["sigma_limit"] = float(lim)
        if cadet_sigma is not None:
            b["sigma_cadet"] = float(cadet_sigma[TERMINAL_INDEX[n]])
        bands[n] = b
    return {
        "model": "shuttle_reentry",
        "model_params": {"vehicle": vehicle_to_dict(base.vehicle),
                         "max_heat_rate_w_m2": base.max_heat_rate_w_m2,
                         "max_dynamic_pressure_pa": base.max_dynamic_pressure_pa,
                         "max_load_factor": base.max_load_factor},
        "t_nodes": [float(v) for v in t],
        "controls": [[float(v) for v in row] for row in np.asarray(u, float)],
        "x0_mean": [float(v) for v in base.initial_state],
        "x0_cov": None if unc.x0_std is None else unc.x0_cov.tolist(),
        "s_mean": [float(v) for v in unc.s_mean],
        "s_cov": unc.s_cov.tolist(),
        "substeps": int(substeps),
        "required": required,
        "bands": bands,
    }
