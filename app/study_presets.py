"""Named trade studies (``GET /v1/studies/presets``): the trades our users ask for first.

Each is a partial study body: a base job (kind, preset, params), sweeps and a mode.
"""
from __future__ import annotations

STUDY_PRESETS: dict[str, dict] = {
    "crossrange-vs-heating": {
        "description": "Betts shuttle maximum crossrange against the stagnation heating limit: 10 limits from "
                       "the unconstrained peak (1.90e6 W/m^2, 50 intervals) down to 2.0e5 W/m^2, where no "
                       "trajectory keeps it (the curve ends with an infeasible point: an answer, not an error). "
                       "Continuation: each limit starts from the solution at the next looser one.",
        "kind": "reentry", "preset": "betts-max-crossrange", "params": {"grid": {"intervals": 50}},
        "sweeps": [{"path": "path.max_heat_rate_w_m2", "start": 1.9e6, "stop": 2.0e5, "count": 10}],
        "mode": "continuation",
    },
    "fuel-vs-intercept-time": {
        "description": "Finite-thrust interception fuel against the fixed interception time, 6000 to 12000 s "
                       "in 25 steps, by continuation in tf (each point warm-started from its solved neighbour; "
                       "a point that fails cold is retried from its other neighbour on the way back).",
        "kind": "intercept", "preset": "long-range-intercept", "params": {},
        "sweeps": [{"path": "intercept_time_s", "start": 6000.0, "stop": 12000.0, "count": 25}],
        "mode": "continuation",
    },
    "robust-objective-vs-k": {
        "description": "Robust reentry: mean - k sigma of the final latitude against the confidence level k "
                       "(the same k on the objective and the heating constraint), k = 0, 1, 2, 3.",
        "kind": "robust_reentry", "preset": "robust-max-crossrange", "params": {},
        "sweeps": [{"path": ["robust.k_objective", "robust.k_constraint"], "values": [0.0, 1.0, 2.0, 3.0]}],
        "mode": "independent",
    },
    "hypervolume-vs-corrections": {
        "description": "Midcourse corrections: the Pareto front's hypervolume against the number of "
                       "corrections (1 to 4), NSGA-II 100 x 200 each, fanned out over the workers.",
        "kind": "midcourse", "preset": "upper-stage-two-corrections", "params": {"generations": 200},
        "sweeps": [{"path": "corrections", "values": [1, 2, 3, 4]}],
        "mode": "independent",
    },
}
