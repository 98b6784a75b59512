"""The ``midcourse`` job's solver problem (SI, radians) from its API parameters: what ``run`` solves and
what the OEM export (:mod:`app.kinds.midcourse.oem`) re-flies."""
from __future__ import annotations

import math

from app.kinds.midcourse.params import MidcourseParams


def to_problem(params: MidcourseParams):
    """Solver problem (SI, radians) from API parameters."""
    import numpy as np

    from solvers.astro.j2 import GravityConstants, LaunchFrame
    from solvers.midcourse import Dispersion, GASettings, MidcourseProblem

    g = params.gravity
    if params.frame == "eci":
        frame = LaunchFrame.eci()
    else:
        s = params.launch_site
        frame = LaunchFrame.from_geodetic(latitude_rad=math.radians(s.latitude_deg),
                                          azimuth_rad=math.radians(s.azimuth_deg), height_m=s.height_m)
    d = params.dispersion
    h = params.hypervolume_reference
    return MidcourseProblem(
        r0=np.array(params.initial.position_m), v0=np.array(params.initial.velocity_mps),
        r_target=np.array(params.target.position_m), v_target=np.array(params.target.velocity_mps),
        tf_s=params.tf_s,
        position_error=np.array(params.initial_error.position_m),
        velocity_error=np.array(params.initial_error.velocity_mps),
        frame=frame, constants=GravityConstants(mu=g.mu_m3_s2, j2=g.j2, ae=g.ae_m),
        mode=params.mode, schedules=[list(s) for s in params.schedules], corrections=params.corrections,
        time_bounds=(params.time_bounds_s[0], params.time_bounds_s[1]), min_spacing=params.min_spacing_s,
        ga=GASettings(population=params.population, generations=params.generations,
                      crossover_prob=params.crossover_prob, mutation_prob=params.mutation_prob,
                      eliminate_duplicates=params.eliminate_duplicates),
        dispersion=None if d is None else Dispersion(samples=d.samples, percentile=d.percentile, seed=d.seed,
                                                     statistic=d.statistic),
        hypervolume_reference=(h.delta_v_mps, h.position_error_m, h.velocity_error_mps),
    )
