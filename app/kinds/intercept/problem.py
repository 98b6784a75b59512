"""The ``intercept`` job's solver problem (SI, radians) from its API parameters: what ``run`` solves and
what the OEM export (:mod:`app.kinds.intercept.oem`) converts with."""
from __future__ import annotations

import math

from app.kinds.intercept.params import InterceptParams


def to_problem(params: InterceptParams):
    """Solver problem (SI, radians) from API parameters."""
    from solvers.astro.elements import Elements
    from solvers.intercept import InterceptProblem, PorkchopSettings, ScanSettings
    from solvers.intercept.scenario import InterceptScenario
    from solvers.intercept.thrust import MeshOptions

    i, t, r = params.interceptor, params.target, math.radians
    pc, ft = params.porkchop, params.finite_thrust
    scenario = InterceptScenario(
        interceptor_orbit=Elements(a=i.semi_major_axis_m, e=i.eccentricity, i=r(i.inclination_deg),
                                   raan=r(i.raan_deg), argp=r(i.arg_perigee_deg), nu=r(i.true_anomaly_deg)),
        target_orbit=Elements(a=t.semi_major_axis_m, e=0.0, i=r(t.inclination_deg), raan=r(t.raan_deg),
                              argp=0.0, nu=r(t.arg_latitude_deg)),
        mass_kg=i.mass_kg, propellant_kg=i.propellant_kg, isp_s=i.isp_s, max_thrust_n=i.max_thrust_n,
        tf_s=params.intercept_time_s, free_final_time=params.free_final_time,
        tf_bounds_s=(params.tf_bounds_s[0], params.tf_bounds_s[1]), mu_m3_s2=params.mu_m3_s2,
        g0_mps2=params.g0_mps2, body_radius_m=params.scan.body_radius_m)
    return InterceptProblem(
        scenario=scenario,
        methods=tuple(params.methods),
        scan=ScanSettings(step_s=params.scan.step_s, t_start_s=params.scan.t_start_s,
                          t_end_s=params.scan.t_end_s, max_revolutions=params.scan.max_revolutions,
                          retrograde=params.scan.retrograde, refine=params.scan.refine,
                          exclude_through_planet=params.scan.exclude_through_planet,
                          body_radius_m=params.scan.body_radius_m),
        mesh=MeshOptions(nodes=ft.nodes_per_segment, coast_segment_s=ft.coast_segment_s,
                         burn_segment_s=ft.burn_segment_s, miss_tolerance_m=ft.miss_tolerance_m,
                         max_refinements=ft.max_refinements, max_iterations=ft.max_iterations),
        porkchop=(PorkchopSettings(t_man_points=pc.t_man_points, t_intercept_points=pc.t_intercept_points,
                                   t_man_min_s=pc.t_man_min_s, t_man_max_s=pc.t_man_max_s,
                                   t_intercept_min_s=pc.t_intercept_min_s,
                                   t_intercept_max_s=pc.t_intercept_max_s) if pc.enabled else None),
    )
