"""The typed result of an ``intercept`` job (paper 003): impulsive (Lambert scan) and finite-thrust.

Conventions and the drift test: :mod:`app.kinds.result_models`.  The default ``GET /result`` body
thins ``impulsive.scan`` to its extrema plus an even subsample and says so in ``points_stored`` and
``thinned``; ``?include=scan`` returns every point without those two fields.
"""
from __future__ import annotations

from pydantic import Field

from app.kinds.result_models import Num, ResultModel, Series, series


class InterceptResultScan(ResultModel):
    """Best single-impulse delta-v against the maneuver time."""

    t_man_s: Series = Field(description="Maneuver times after t0 (s)")
    delta_v_mps: Series = Field(description="Best delta-v over the searched branches (m/s); null: no transfer")
    points_stored: int | None = Field(None, description="Default (thinned) body only: points in the full scan")
    thinned: str | None = Field(None, description="Default (thinned) body only: how the scan was thinned")


class InterceptResultImpulse(ResultModel):
    """The best single impulse and its Lambert branch (inertial frame of the epoch t0)."""

    t_man_s: Num = Field(description="Maneuver time (s)")
    delta_v_mps: Num = Field(description="Impulse magnitude (m/s)")
    delta_v_vector_mps: list[Num] = Field(description="Impulse vector, inertial (m/s)")
    fuel_kg: Num = Field(description="Propellant of the impulse by the rocket equation (kg)")
    g0_mps2: Num = Field(description="Standard gravity used for the fuel (m/s^2)")
    prograde: bool | None = Field(description="Lambert branch: prograde transfer")
    revolutions: int | None = Field(description="Lambert branch: full revolutions")
    low_path: bool | None = Field(description="Lambert branch: low path (multi-revolution)")
    branch: str | None = Field(description="The branch as a label")
    position_m: list[Num] = Field(description="Interceptor position at the burn, inertial (m)")
    velocity_before_mps: list[Num] = Field(description="Velocity before the burn, inertial (m/s)")
    velocity_after_mps: list[Num] = Field(description="Velocity after the burn, inertial (m/s)")
    relative_velocity_at_intercept_mps: list[Num] = Field(
        description="Interceptor minus target velocity at interception, inertial (m/s)")


class InterceptResultThroughPlanet(ResultModel):
    """Lambert arcs whose smallest radius is below the body's: left out of the scan by default."""

    excluded: bool = Field(description="Whether such arcs were left out (scan.exclude_through_planet)")
    body_radius_m: Num = Field(description="The body radius they were checked against (m)")
    excluded_solutions: int = Field(description="Converged Lambert solutions (maneuver time x branch) left out")
    points_only_through_planet: int = Field(
        description="Maneuver times whose every converged branch passes through the planet (no transfer left)")


class InterceptResultPorkchopBest(ResultModel):
    """The porkchop map's minimum."""

    t_man_s: Num = Field(description="Maneuver time (s)")
    t_intercept_s: Num = Field(description="Interception time (s)")
    delta_v_mps: Num = Field(description="Delta-v (m/s)")


class InterceptResultPorkchop(ResultModel):
    """Delta-v over maneuver and interception times (rows: t_man_s, columns: t_intercept_s)."""

    t_man_s: Series = Field(description="Maneuver times (s)")
    t_intercept_s: Series = Field(description="Interception times (s)")
    delta_v_mps: list[Series] = Field(description="Delta-v (m/s), [i][j] at t_man_s[i], t_intercept_s[j]; null: none")
    best: InterceptResultPorkchopBest = Field(description="The map's minimum")


class InterceptResultSolver(ResultModel):
    """A method's solver account."""

    status: str = Field(description="The solver's own status word")
    iterations: int = Field(description="Iterations (IPOPT, or the scan's refinements)")
    solve_time_s: Num = Field(description="Solve time (s)")
    max_constraint_violation: Num = Field(description="Worst constraint violation at the solution")
    build_time_s: Num = Field(None, description="finite_thrust: NLP build time (s)")
    total_time_s: Num = Field(None, description="finite_thrust: all mesh rounds and checks (s)")


class InterceptResultImpulsiveVerification(ResultModel):
    """The post-burn state propagated to the interception time."""

    miss_distance_m: Num = Field(description="Distance to the target at the interception time (m)")
    method: str = Field(description="How it was propagated")


class InterceptResultImpulsive(ResultModel):
    """The single-impulse method: the delta-v scan, its best impulse, optionally the porkchop map."""

    status: str = Field(description="optimal, infeasible, ...")
    message: str = Field(description="The solver's message")
    scan: InterceptResultScan = Field(description="Delta-v against maneuver time")
    best: InterceptResultImpulse = Field(description="The best impulse")
    intercept_time_s: Num = Field(description="Interception time (s)")
    branches_searched: list[str] = Field(description="Lambert branches searched")
    through_planet: InterceptResultThroughPlanet | None = Field(
        None, description="Lambert arcs through the planet left out of the scan (scan.exclude_through_planet)")
    solver: InterceptResultSolver = Field(description="The scan's account")
    verification: InterceptResultImpulsiveVerification = Field(description="Independent propagation")
    porkchop: InterceptResultPorkchop | None = Field(None, description="With porkchop.enabled: the map")


class InterceptResultArc(ResultModel):
    """A coast or burn arc of the finite-thrust solution."""

    kind: str = Field(description="coast or burn")
    start_s: Num = Field(description="Start time (s)")
    end_s: Num = Field(description="End time (s)")
    duration_s: Num = Field(description="Duration (s)")
    segments: int | None = Field(None, description="Collocation segments of the arc")
    propellant_kg: Num = Field(None, description="Propellant burnt on the arc (kg)")


class InterceptResultTrajectory(ResultModel):
    """The interceptor relative to the target in the target's Hill frame (see `frame`), at the nodes."""

    t_s: Series = series("Time after t0", "s")
    x_m: Series = series("Radial position relative to the target", "m")
    y_m: Series = series("Along-track position", "m")
    z_m: Series = series("Orbit-normal position", "m")
    vx_mps: Series = series("Radial velocity in the rotating frame", "m/s")
    vy_mps: Series = series("Along-track velocity", "m/s")
    vz_mps: Series = series("Orbit-normal velocity", "m/s")
    thrust_x_n: Series = series("Thrust, radial component", "N")
    thrust_y_n: Series = series("Thrust, along-track component", "N")
    thrust_z_n: Series = series("Thrust, orbit-normal component", "N")
    thrust_n: Series = series("Thrust magnitude", "N")
    mass_kg: Series = series("Interceptor mass", "kg")


class InterceptResultFiniteVerification(ResultModel):
    """The optimal thrust re-propagated with an accurate integrator, both bodies inertial."""

    miss_distance_m: Num = Field(description="Distance to the target at the final time (m)")
    relative_speed_mps: Num = Field(description="Relative speed at the final time (m/s)")
    propellant_kg: Num = Field(description="Propellant used on the re-propagation (kg)")
    final_mass_kg: Num = Field(description="Final mass on the re-propagation (kg)")
    collocation_propellant_kg: Num = Field(description="Propellant of the collocation solution (kg)")
    integrator: str = Field(description="Integrator and tolerance")
    function_evaluations: int = Field(description="Right-hand-side evaluations")
    min_radius_m: Num = Field(None, description="Smallest distance of the interceptor from the Earth's centre "
                              "along the re-propagation (m, sampled 64 times per segment)")
    through_planet: bool | None = Field(None, description="min_radius_m is below scan.body_radius_m: the "
                                        "trajectory passes through the planet (the collocation has no such limit)")


class InterceptResultOptimalityHistory(ResultModel):
    """Hamiltonian and switching function at the nodes (for the plot)."""

    t_s: Series = series("Time after t0", "s")
    hamiltonian: Series = Field(description="Hamiltonian (nondimensional: mass m0, time 1/n)")
    switching_function: Series = Field(description="Switching function (nondimensional); > 0: thrust on")
    interior: list[bool] = Field(description="The node is inside a segment (not on a boundary)")


class InterceptResultOptimality(ResultModel):
    """First-order optimality checks from the NLP multipliers (Pontryagin)."""

    hamiltonian_mean: Num = Field(description="Mean Hamiltonian (nondimensional)")
    hamiltonian_std: Num = Field(description="Its standard deviation (nondimensional)")
    hamiltonian_relative_variation: Num = Field(description="(max - min) / scale (dimensionless)")
    hamiltonian_expected: Num = Field(description="Expected value: 0 with a free final time (nondimensional)")
    hamiltonian_relative_error: Num = Field(description="|mean - expected| / scale (dimensionless)")
    tf_free_and_off_bounds: bool = Field(description="Free final time strictly inside its bounds")
    hamiltonian_scale: Num = Field(description="Scale of the Hamiltonian's terms (nondimensional)")
    hamiltonian_units: str = Field(description="Units of the Hamiltonian")
    costate_mass_final: Num = Field(description="Mass costate at the final time (nondimensional)")
    switching_function_agreement: Num = Field(description="Share of decided nodes where thrust follows the "
                                                          "switching function's sign (0-1)")
    switching_function_mismatches: int = Field(description="Decided nodes where it does not")
    switching_function_max_on_coasts: Num = Field(description="Largest switching function on a coast (nondimensional)")
    nodes_checked: int = Field(description="Nodes where the sign is decided")
    thrust_primer_alignment_min_cos: Num = Field(description="Smallest cosine between thrust and primer vector")
    along_trajectory: InterceptResultOptimalityHistory = Field(description="The checks' quantities at the nodes")


class InterceptResultMesh(ResultModel):
    """The final collocation mesh."""

    structure: str = Field(description="switching (coast/burn arcs) or free_throttle")
    segments: int = Field(description="Segments")
    nodes_per_segment: int = Field(description="LGL nodes per segment")
    total_nodes: int = Field(description="Nodes in all")
    boundaries_s: Series = Field(description="Segment boundaries (s)")
    rounds: int = Field(description="Mesh rounds run")


class InterceptResultMeshRound(ResultModel):
    """One mesh round."""

    round: int = Field(description="Round number, from 1")
    arcs: str = Field(description="The arc structure, one letter per arc (c: coast, b: burn)")
    segments: int = Field(description="Segments")
    nodes: int = Field(description="Nodes per segment")
    iterations: int = Field(description="IPOPT iterations of the round")
    solver_status: str = Field(description="IPOPT's status of the round")
    final_mass_kg: Num = Field(description="Final mass of the round (kg)")
    miss_distance_m: Num = Field(None, description="Re-propagated miss of the round (m)")
    next: str | None = Field(None, description="What the next round changes")


class InterceptResultFinite(ResultModel):
    """The finite-thrust fuel-optimal method; trajectory fields are absent when the solve produced none."""

    status: str = Field(description="optimal, not_converged, ...")
    message: str = Field(description="The solver's message")
    warm_start: str | None = Field(description="Where the initial guess came from")
    tf_s: Num = Field(None, description="Interception time (s)")
    final_mass_kg: Num = Field(None, description="Final mass (kg)")
    fuel_kg: Num = Field(None, description="Propellant used (kg)")
    delta_v_mps: Num = Field(None, description="Equivalent delta-v by the rocket equation (m/s)")
    g0_mps2: Num = Field(None, description="Standard gravity used (m/s^2)")
    free_final_time: bool | None = Field(None, description="The final time was free")
    burns: list[InterceptResultArc] | None = Field(None, description="Burn arcs")
    arcs: list[InterceptResultArc] | None = Field(None, description="All arcs, coasts and burns")
    frame: str | None = Field(None, description="The frame of the trajectory")
    trajectory: InterceptResultTrajectory | None = Field(None, description="Relative trajectory at the nodes")
    solver: InterceptResultSolver = Field(description="IPOPT's account, all rounds")
    verification: InterceptResultFiniteVerification | None = Field(description="Independent re-propagation")
    optimality: InterceptResultOptimality | None = Field(description="Optimality checks")
    mesh: InterceptResultMesh | None = Field(description="The final mesh")
    history: list[InterceptResultMeshRound] = Field(description="One entry per mesh round")


class InterceptResultBurn(ResultModel):
    """A burn in the comparison table."""

    start_s: Num = Field(description="Start (s)")
    duration_s: Num = Field(description="Duration (s); 0 for an impulse")


class InterceptResultComparison(ResultModel):
    """One row per method that produced an answer."""

    method: str = Field(description="impulsive or finite_thrust")
    fuel_kg: Num = Field(description="Propellant (kg)")
    delta_v_mps: Num = Field(description="Delta-v (m/s)")
    tf_s: Num = Field(description="Interception time (s)")
    burns: list[InterceptResultBurn] = Field(description="Burns")
    miss_distance_m: Num = Field(description="Independently propagated miss (m)")


class InterceptResult(ResultModel):
    """Result of an ``intercept`` job: each requested method's answer and a comparison table."""

    impulsive: InterceptResultImpulsive | None = Field(description="Single-impulse method; null if not requested")
    finite_thrust: InterceptResultFinite | None = Field(description="Finite-thrust method; null if not requested")
    comparison: list[InterceptResultComparison] = Field(description="Fuel, delta-v, time and miss per method")
    notes: list[str] = Field(description="Differences from paper 003 and how the answer was obtained")
