"""A catalogue of ``ocp`` presets from the published literature (issue 35 item 7), one module per problem.

Each module defines ``NAME`` (the preset's name) and ``PRESET``: ``{"description", "optimum",
"tolerance", "params"}`` as in :mod:`solvers.ocp.cases` (the description names the source of the
optimum, and why the tolerance fits the preset's grid).  :data:`CATALOGUE` collects them in the
order of :data:`MODULES`; :mod:`solvers.ocp.cases` merges it into the preset list.  Standard
library only, like every preset module (the API lists presets without loading numpy).
"""
from __future__ import annotations

import importlib

MODULES = (
    "double_integrator_min_time",
    "dubins_car_min_time",
    "block_move",
    "lunar_lander_bang_bang",
    "particle_steering",
    "catalyst_mixing",
    "tumor_antiangiogenesis",
    "rayleigh_mixed_constraint",
    "hypersensitive",
    "unstable_min_energy",
    "hang_glider_thermal_table",
    "isoperimetric",
    "scalar_lq_riccati",
    "tumor_two_phases",
    "van_der_pol_state_limit",
    "free_flying_robot",
)


def _load() -> dict[str, dict]:
    out = {}
    for name in MODULES:
        module = importlib.import_module(f"{__name__}.{name}")
        out[module.NAME] = module.PRESET
    return out


CATALOGUE: dict[str, dict] = _load()
