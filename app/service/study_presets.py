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
        "description": "Finite-thrust interception: the least propellant that intercepts by time U, for U from "
                       "7000 to 12000 s in 20 steps plus the paper's 8080.5 s. Each point lets the interception "
                       "time vary in [2000 s, U] (free_final_time), so the curve is what a planner reads off and "
                       "never rises with U. Every point starts cold from the kind's maneuver x interception-time "
                       "map (fanned out over the workers); a point that fails is retried from a solved neighbour. "
                       "The curve starts at 7000 s (386.2 kg of the 400 kg on board): below it no interception "
                       "that stays outside the Earth suffices. The cheaper answer found there before Lambert arcs "
                       "through the planet were left out (290.49 kg at tf = 4527.8 s) flew 2,840 km below the "
                       "surface (smallest radius 3,535 km).",
        "kind": "intercept", "preset": "long-range-intercept",
        "params": {"free_final_time": True, "tf_bounds_s": [2000.0, 7000.0]},
        "sweeps": [{"path": "tf_bounds_s.1", "values": sorted({7000.0 + 250.0 * i for i in range(21)} | {8080.5})}],
        "mode": "independent",
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
