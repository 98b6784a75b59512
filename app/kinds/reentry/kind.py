"""The ``reentry`` kind's API edge: lifting reentry by direct multiple shooting.

Paper 000 (Qu Xiangju 1991, direct multiple shooting for Space Shuttle reentry) and the Betts
shuttle benchmark (Betts, *Practical Methods for Optimal Control*, sec. 6.3).  Parameters are in
SI and degrees; :mod:`solvers.reentry` works in SI and radians.
"""
from __future__ import annotations

import functools
import math
from typing import Any

from app.kinds.base import (JobContext, KindSpec, MemoryModel, Preset, RunOutcome, outcome_from_status,
                            warm_start_from_job)
from app.kinds.reentry.edge import compare_series, guess_from_result, reentry_result, shooting_cost, to_problem
from app.kinds.reentry.headlines import headlines
from app.kinds.reentry.plots import plots
from app.kinds.reentry.params import BETTS_HEAT_LIMIT_W_M2, PAPER000_TERMINAL_ALTITUDE_M, ReentryParams
from app.kinds.reentry.result_model import ReentryResult
from app.kinds.reentry.trade import key_numbers, trade_outputs
from app.results.tables import columns_at
from solvers.models import shuttle as sh

# Where a new job takes a stored job's id to warm-start from it (KindSpec.warm_start_field).
WARM_START_FIELD = "initial_guess.from_job"

_BETTS_NOTE = ("Betts shuttle (Practical Methods for Optimal Control, sec. 6.3): entry at 260000 ft, "
               "25600 ft/s, -1 deg; final 80000 ft, 2500 ft/s, -5 deg; alpha in [-90, 90], "
               "bank in [-90, 1] deg; non-rotating spherical Earth, exponential atmosphere.")
_PAPER000: dict[str, Any] = {"terminal": {"altitude_m": PAPER000_TERMINAL_ALTITUDE_M, "speed_mps": None, "flight_path_deg": None},
             "bounds": {"alpha_deg": [math.degrees(sh.BETTS_ALPHA_BOUNDS_RAD[0]),
                                      round(math.degrees(sh.PAPER000_ALPHA_MAX_RAD), 9)]}}

PRESETS = [
    Preset("betts-max-crossrange", "reentry",
           "Maximum final latitude. " + _BETTS_NOTE + " Betts: 34.1412 deg, tf 2008.59 s; this "
           "transcription gives 34.14118 deg, 2008.59 s at 100 intervals.", {}),
    Preset("betts-max-crossrange-heat-limited", "reentry",
           "Maximum final latitude with heating rate <= 70 BTU/ft^2/s (794955 W/m^2). " + _BETTS_NOTE +
           " Betts: 30.6255 deg, tf 2198.67 s. Solved warm-started from the unconstrained optimum. "
           "The limit holds everywhere, not only at the nodes: enforced at every RK4 step point and "
           "checked on the dense re-propagation (20 points per interval) to 0.1% of the limit "
           "(verification.limits). That costs a little crossrange against a node-only answer, which "
           "overshot between the nodes by 0.61% at 100 intervals: 30.6230 deg / 2198.71 s at 100 "
           "intervals (node-only 30.6279 deg), 30.6248 deg at 200.",
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
    Preset("mars-msl-max-crossrange", "reentry",
           "Mars entry of the Mars Science Laboratory capsule (vehicle preset msl, GET /v1/vehicles/msl): "
           "entry state of the MSL design (Way et al. 2007, 'Mars Science Laboratory: Entry, Descent, "
           "and Landing System Performance'): 125 km, 5.9 km/s, flight path -15.5 deg, heading east; "
           "ends at parachute-deploy conditions, 10 km and 450 m/s (Mach 1.9 in this atmosphere), "
           "flight path free; maximum final latitude (crossrange), bank in [-180, 180] deg as MSL's "
           "bank-modulation guidance (Mendeck & Craig 2011). Alpha held within 1 deg of the -16 deg "
           "trim (a capsule flies at trim). Differs from the flight: non-rotating Mars (relative and "
           "inertial speed are the same here), central gravity, the NASA Glenn Mars atmosphere as a "
           "log-density table (not Mars-GRAM), an aero table built to MSL's published trim values "
           "(not its aerodatabase). Here: 1.1005 deg (65 km) at 100 intervals, tf 287.2 s (1.10049 / "
           "1.10050 deg at 50 / 200 intervals); the re-propagation meets the terminal conditions within "
           "0.02 m and 0.001 m/s at 100 intervals.",
           {"vehicle": {"preset": "msl"}, "objective": "max_crossrange",
            "initial_state": {"altitude_m": 125000.0, "longitude_deg": 0.0, "latitude_deg": 0.0,
                              "speed_mps": 5900.0, "flight_path_deg": -15.5, "heading_deg": 90.0},
            "terminal": {"altitude_m": 10000.0, "speed_mps": 450.0, "flight_path_deg": None},
            "bounds": {"alpha_deg": [-17.0, -15.0], "bank_deg": [-180.0, 180.0]}}),
]


@functools.cache
def _preset_problems() -> tuple:
    return tuple((p, ReentryParams.model_validate(p.params).model_dump(exclude={"initial_guess"})) for p in PRESETS)


def preset_posed(params: ReentryParams) -> Preset | None:
    """The preset whose problem ``params`` pose (the initial guess aside), or None.  Its result repeats
    the preset's description: where and why the answer differs from the paper or the flight belongs
    beside the answer, not only in the catalogue."""
    posed = params.model_dump(exclude={"initial_guess"})
    return next((p for p, dumped in _preset_problems() if dumped == posed), None)


def run(params: ReentryParams, ctx: JobContext) -> RunOutcome:
    from solvers import reentry as rs

    problem = to_problem(params)
    guess = params.initial_guess.kind
    posed = preset_posed(params)
    notes = [] if posed is None else [f"preset {posed.name}: {posed.description}"]
    if params.initial_guess.from_job:
        job = params.initial_guess.from_job
        guess = warm_start_from_job(ctx, job, guess_from_result, field=WARM_START_FIELD,
                                    what="reentry trajectory")
        notes.append(f"warm-started from job {job}")
    ctx.progress(0.0, "building the multiple-shooting NLP")
    sol = rs.solve(problem, initial_guess=guess, on_progress=ctx.progress, should_stop=ctx.should_stop)
    sol.notes[:0] = notes
    result = reentry_result(sol)
    if sol.status.ok:
        ctx.progress(1.0, f"done: {sol.status.solver_status} after {sol.status.iterations} iterations")
    return outcome_from_status(sol.status, result)


# Measured (README "Limits and data"): 167 MB resident for the preset (100 intervals) in a fresh pool process,
# 0.12 MB more per interval: the peak is at the end, in the dense re-propagation and the result (the NLP itself
# grows little: 151 MB at 1000 intervals x 16 substeps while IPOPT runs).
MEMORY = MemoryModel(floor_mb=167.0, size=lambda p: float((p.get("grid") or {}).get("intervals", 100)),
                     floor_size=100.0, per_unit_mb=0.12, grows_with="grid.intervals")

SPEC = KindSpec(kind="reentry", params_model=ReentryParams, run=run, presets=PRESETS, result_model=ReentryResult,
                plots=plots, headlines=headlines, cost=shooting_cost, memory=MEMORY,
                key_numbers=key_numbers, trade_outputs=trade_outputs,
                tables={"trajectory": columns_at("trajectory"), "verification": columns_at("verification.trajectory")},
                warm_start_field=WARM_START_FIELD, compare=compare_series,
                summary="Lifting reentry (Space Shuttle, Betts benchmark and paper 000) by direct "
                        "multiple shooting with IPOPT")
