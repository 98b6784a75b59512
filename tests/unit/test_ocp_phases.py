"""Several phases of the ``ocp`` kind (issue 26): parsing and its 422s, the presets against their
published or closed-form optima, the single- and multi-phase forms of one problem, links honoured
exactly, warm starts and a study path into a phase."""
from __future__ import annotations

import copy
import math

import numpy as np
import pytest
from pydantic import ValidationError
from scipy.optimize import fsolve

from app.kinds.base import JobFailure
from app.kinds.ocp.params import OcpParams
from app.kinds.ocp.warm_start import check_warm_start
from solvers.common import Outcome
from solvers.ocp import PRESETS, OcpInputError, OcpProblem, parse_problem, solve

GODDARD3 = PRESETS["goddard-three-phases"]["params"]


def fails(params, path: str, *words: str) -> str:
    with pytest.raises(OcpInputError) as e:
        parse_problem(params)
    assert e.value.path == path, (e.value.path, e.value.reason)
    for w in words:
        assert w in e.value.reason, e.value.reason
    return e.value.reason


def goddard(**edit):
    p = copy.deepcopy(GODDARD3)
    p.update(edit)
    return p


# --- parsing -------------------------------------------------------------------------------------
def test_default_linkage_is_time_and_every_shared_state():
    mp = parse_problem(GODDARD3)
    assert isinstance(mp, OcpProblem) and not mp.single and mp.phase_names == ("boost", "singular", "coast")
    assert mp.time_links == (0, 1)
    assert mp.state_links == tuple((k, x) for k in (0, 1) for x in ("h", "v", "m"))
    # each phase is a single-phase problem with the top-level constants
    assert [n for n, _ in mp.phases[1].problem.constants] == ["Tmax", "Dc", "hc", "c"]
    assert mp.phases[0].problem.objective.expr is None


def test_a_link_relating_both_sides_replaces_that_continuity_only():
    p = goddard(links=[{"expr": 'initial(m, "singular") - final(m, "boost")', "lower": -0.1, "upper": 0.0},
                       {"expr": 't0("coast") - tf("singular")', "lower": 0.0, "upper": 0.01}])
    mp = parse_problem(p)
    assert (0, "m") not in mp.state_links and (0, "h") in mp.state_links and (1, "m") in mp.state_links
    assert mp.time_links == (0,)
    # naming one side only (a phase's duration) replaces nothing
    mp = parse_problem(goddard(links=[{"expr": 'tf("boost") - t0("boost")', "lower": 0.01}]))
    assert mp.time_links == (0, 1) and len(mp.state_links) == 6


def test_duplicate_phase_names():
    p = goddard()
    p["phases"][2]["name"] = "boost"
    fails(p, "params.phases.2.name", "duplicated phase name 'boost'")


def test_a_phase_name_beginning_with_an_underscore_is_reserved():
    # as every other declared name (issue 36 item 5: __class__ was accepted as a state)
    for name in ("__class__", "_coast"):
        p = goddard()
        p["phases"][2]["name"] = name
        fails(p, "params.phases.2.name", f"'{name}' is reserved: a name cannot begin with an underscore")


def test_unknown_phase_and_state_in_events_name_the_closest():
    assert "did you mean 'coast'" in fails(goddard(objective={"sense": "maximize", "expr": 'final(h, "cost")'}),
                                           "params.objective.expr", "unknown phase 'cost'")
    fails(goddard(objective={"sense": "maximize", "expr": 'final(hh, "coast")'}), "params.objective.expr",
          "'hh'", "phase 'coast'", "did you mean 'h'")
    # T is a control of 'singular' only
    fails(goddard(links=[{"expr": 'final(T, "boost")', "lower": 0}]), "params.links.0.expr", "phase 'boost'")


def test_string_literals_only_as_the_phase_of_an_event_call():
    fails(goddard(objective={"sense": "maximize", "expr": 'final(h, coast)'}), "params.objective.expr",
          "string literal")
    fails(goddard(objective={"sense": "maximize", "expr": 'final(h, "coast") + sin("a")'}), "params.objective.expr",
          "only numbers")
    p = goddard()
    p["phases"][2]["dynamics"]["m"] = '"0"'
    fails(p, "params.phases.2.dynamics.m", "only numbers")
    fails(goddard(objective={"sense": "maximize", "expr": "tf"}), "params.objective.expr", "naming the phase")
    fails(goddard(objective={"sense": "maximize", "expr": "h"}), "params.objective.expr", 'final(h, "boost")')


def test_links_between_non_consecutive_phases_only_when_stated():
    link = {"expr": 'final(h, "coast") - initial(h, "boost")', "lower": 0.0}
    fails(goddard(links=[link]), "params.links.0.expr", "not consecutive", "non_consecutive")
    mp = parse_problem(goddard(links=[{**link, "non_consecutive": True}]))
    assert mp.links[0].phases == ("boost", "coast") and mp.links[0].non_consecutive


def test_phases_that_cannot_be_ordered_in_time():
    p = goddard()
    p["phases"][1]["time"].update(final_lower=0.3)
    p["phases"][2]["time"].update(initial_upper=0.2)
    fails(p, "params.phases.1.time.final", "cannot be ordered in time", "at least 0.3", "at most 0.2")
    p = goddard()
    p["phases"][0]["time"] = {"initial": 5.0, "final_upper": 1.0}
    fails(p, "params.phases.0.time.initial", "cannot be ordered", "at least 5", "at most 1")


def test_phases_and_single_phase_fields_together_and_phase_errors_located():
    fails(goddard(states=[{"name": "x"}]), "params.states", "belongs to a phase")
    p = goddard()
    p["phases"][1]["dynamics"]["v"] = "(T - dragg)/m - grav"
    fails(p, "params.phases.1.dynamics.v", "did you mean 'drag'")
    p = goddard()
    p["phases"][0]["guess"]["from_job"] = "0" * 32
    fails(p, "params.phases.0.guess.from_job", "params.guess.from_job")


def test_the_api_model_round_trips_and_422s_name_the_field():
    m = OcpParams.model_validate(GODDARD3)
    assert isinstance(m.problem, OcpProblem)
    again = OcpParams.model_validate(m.model_dump(mode="json"))      # a stored job's params, every default
    assert again.problem.structure() == m.problem.structure()
    bad = goddard()
    bad["phases"][2]["name"] = "boost"
    with pytest.raises(ValidationError) as e:
        OcpParams.model_validate(bad)
    assert e.value.errors()[0]["loc"] == ("phases", 2, "name")
    with pytest.raises(ValidationError) as e:
        OcpParams.model_validate({**PRESETS["brachistochrone"]["params"], "links": [{"expr": "1", "lower": 0}]})
    assert e.value.errors()[0]["loc"] == ("links",)


def test_a_study_sweeps_a_phase_bound_by_index_or_by_name():
    from app.service.params import resolve_params
    from app.kinds import KINDS
    from app.service.studies import expand

    spec = KINDS["ocp"]
    base = resolve_params(spec, GODDARD3, None)
    points = expand(base, [{"path": "phases.2.time.final_upper", "values": [0.5, 0.8]},
                           {"path": "phases.singular.transcription.intervals", "values": [30]}])
    assert [p.params["phases"][2]["time"]["final_upper"] for p in points] == [0.5, 0.8]
    for point in points:
        resolved = resolve_params(spec, point.params, None)
        problem = spec.params_model.model_validate(resolved).problem
        assert problem.named("singular").problem.transcription.intervals == 30


# --- solves --------------------------------------------------------------------------------------
def check(name: str):
    preset = PRESETS[name]
    sol = solve(parse_problem(preset["params"]))
    assert sol.status.outcome is Outcome.OPTIMAL, sol.status.message
    assert sol.status.solver_status == "Solve_Succeeded"
    assert abs(sol.objective - preset["optimum"]) <= preset["tolerance"], (sol.objective, preset["optimum"])
    assert sol.verification["ok"] and sol.verification["limits_held"] and sol.verification["terminal_held"]
    assert all(p["verification"]["optimality"]["held"] for p in sol.phases), \
        [p["verification"]["optimality"]["message"] for p in sol.phases]
    for a, b in zip(sol.phases, sol.phases[1:]):      # time and shared states continuous unless linked
        assert b["t0"] == pytest.approx(a["tf"], rel=1e-9)    # an equality of IPOPT's NLP (scaled 1e-9)
        assert a["trajectory"]["t"][-1] == pytest.approx(b["trajectory"]["t"][0], abs=1e-12)
    return sol


def test_goddard_in_three_phases_equals_the_single_phase_optimum():
    multi = check("goddard-three-phases")
    single = solve(parse_problem(PRESETS["goddard-rocket"]["params"]))
    assert single.status.outcome is Outcome.OPTIMAL
    # both transcriptions resolve the singular arc to ~1e-5 (the presets' tolerance), the multi-phase
    # form with its switches on phase boundaries
    assert multi.objective == pytest.approx(single.objective, abs=2e-5)
    assert multi.objective == pytest.approx(1.01283, abs=1e-4)
    b, s, c = multi.phases
    for x in ("h", "v", "m"):       # continuous at the boundaries (equality constraints, IPOPT's tolerance)
        assert s["initial"][x] == pytest.approx(b["final"][x], abs=1e-8)
        assert c["initial"][x] == pytest.approx(s["final"][x], abs=1e-8)
    assert s["final"]["m"] == pytest.approx(0.6) and 0.0 < b["tf"] < s["tf"] < c["tf"]
    # the singular arc's thrust lies strictly between its bounds, as Bryson's solution has it
    T = np.asarray(s["trajectory"]["T"])
    assert 0.5 < np.median(T) < 3.0
    assert multi.tf == pytest.approx(single.tf, rel=2e-3)


def _burn(v_a, h_a, m_a, m_b, thrust, ve, g):
    """Full thrust from mass m_a to m_b, straight up under uniform gravity: (v, h, burn time)."""
    q = thrust / ve
    tb = (m_a - m_b) / q
    v = v_a + ve * math.log(m_a / m_b) - g * tb
    h = h_a + v_a * tb + ve / q * ((m_a - m_b) - m_b * math.log(m_a / m_b)) - 0.5 * g * tb ** 2
    return v, h, tb


def test_two_stage_ascent_drops_its_stage_exactly_and_reaches_the_closed_form_apogee():
    sol = check("two-stage-ascent")
    c = dict(PRESETS["two-stage-ascent"]["params"]["constants"])
    g = c["g"]
    v1, h1, t1 = _burn(0.0, 0.0, 1000.0, 400.0, c["T1"], c["ve1"], g)
    v2, h2, t2 = _burn(v1, h1, 400.0 - c["dry1"], 100.0, c["T2"], c["ve2"], g)
    apogee = h2 + v2 ** 2 / (2 * g)
    assert sol.objective == pytest.approx(apogee, abs=0.5)
    assert apogee == pytest.approx(PRESETS["two-stage-ascent"]["optimum"], abs=0.01)
    s1, s2, coast = sol.phases
    assert s2["initial"]["m"] - s1["final"]["m"] == pytest.approx(-c["dry1"], abs=1e-9)    # the drop, exactly
    assert sol.verification["links"]["stage1_drop"]["value"] == pytest.approx(0.0, abs=1e-9)
    assert s1["tf"] == pytest.approx(t1, rel=1e-6) and s2["tf"] == pytest.approx(t1 + t2, rel=1e-6)
    assert s2["initial"]["v"] == pytest.approx(v1, rel=1e-6)
    assert coast["final"]["v"] == pytest.approx(0.0, abs=1e-3)


def test_lunar_lander_coasts_then_burns_as_meditch_found():
    sol = check("lunar-lander-coast-burn")
    c = PRESETS["lunar-lander-coast-burn"]["params"]["constants"]
    g, thrust, ve = c["g"], c["Tmax"], c["ve"]
    q = thrust / ve

    def miss(z):
        tc, tau = z
        v, h, _ = _burn(-50.0 - g * tc, 2000.0 - 50.0 * tc - 0.5 * g * tc ** 2, 1000.0, 1000.0 - q * tau,
                        thrust, ve, g)
        return [v, h]

    tc, tau = fsolve(miss, [15.0, 45.0], xtol=1e-14)
    assert sol.objective == pytest.approx(1000.0 - q * tau, abs=1e-3)
    coast, burn = sol.phases
    assert coast["tf"] == pytest.approx(tc, abs=1e-3) and burn["tf"] - burn["t0"] == pytest.approx(tau, abs=1e-3)
    assert np.min(burn["trajectory"]["T"]) > 0.999 * thrust       # full thrust throughout, the bang-bang answer


def test_a_warm_start_from_the_same_phases_converges_at_once():
    problem = parse_problem(PRESETS["lunar-lander-coast-burn"]["params"])
    cold = solve(problem)
    stored = {"phases": cold.phases, "parameters": cold.parameters}
    warm = solve(problem, initial_guess=stored)
    assert warm.status.outcome is Outcome.OPTIMAL
    assert warm.status.iterations < cold.status.iterations
    assert warm.objective == pytest.approx(cold.objective, abs=1e-6)
    check_warm_start(stored, problem, job_id="j", field="guess.from_job")       # fits: no failure
    other = copy.deepcopy(PRESETS["lunar-lander-coast-burn"]["params"])
    other["phases"][1]["name"] = "descent"
    other["objective"]["expr"] = 'final(m, "descent")'
    with pytest.raises(JobFailure, match="phase names must be the same"):
        check_warm_start(stored, parse_problem(other), job_id="j", field="guess.from_job")
    with pytest.raises(JobFailure, match="single phase cannot start"):
        check_warm_start(stored, parse_problem(PRESETS["brachistochrone"]["params"]), job_id="j",
                         field="guess.from_job")


@pytest.mark.slow
def test_every_phase_mesh_refined_to_the_accuracy():
    # from 4 intervals per phase: each phase's mesh is planned from its own interval errors
    # The states of the singular arc move by ~3e-4 of their scale between meshes (its junction times are
    # flat in the objective), so the answer's state error is not within 1e-7 and is said so (issue 35):
    # the objective's estimate and the re-flight are
    p = goddard(accuracy=1e-7, accuracy_required=False)
    for ph in p["phases"]:
        ph["transcription"]["intervals"] = 4
    sol = solve(parse_problem(p))
    assert sol.status.outcome is Outcome.OPTIMAL, sol.status.message
    rounds = sol.solver["refinement"]
    acc = sol.solver["accuracy"]
    assert acc["objective_error_estimate"] <= 1e-7 and len(rounds) >= 2
    assert acc["reached"] is (acc["state_error"] <= 1e-7) and "NOT reached" in sol.notes[0]
    assert rounds[0]["max_error"] > 1e-7 >= rounds[-1]["max_error"]
    answer = sum(ph["solver"]["intervals"] for ph in sol.phases)     # the best round's (not reached)
    assert answer in [r["intervals"] for r in rounds] and answer > 12
    assert sol.objective == pytest.approx(1.01283, abs=1e-4)
    assert sol.objective == pytest.approx(solve(parse_problem(GODDARD3)).objective, abs=2e-6)


def test_path_limits_held_between_the_nodes_in_every_phase():
    # Bryson-Denham (the bryson-denham preset's problem, J = 4) in two phases of 7 intervals: the limit
    # x <= 1/9 is exceeded between the nodes until the bound is tightened there and solved again
    def phase(name, tf, first):
        return {"name": name,
                "states": [{"name": "x", "scale": 0.1, **({"initial": 0.0} if first else {"final": 0.0})},
                           {"name": "v", **({"initial": 1.0} if first else {"final": -1.0})}],
                "controls": [{"name": "u", "scale": 10.0}],
                "time": {"final": tf, **({"initial": 0.0} if first else {})},
                "dynamics": {"x": "v", "v": "u"},
                "path": [{"name": "x_limit", "expr": "x", "upper": 1.0 / 9.0}],
                "transcription": {"method": "multiple_shooting", "intervals": 7, "control": "linear"}}
    sol = solve(parse_problem({"phases": [phase("a", 0.5, True), phase("b", 1.0, False)],
                               "objective": {"sense": "minimize", "integrand": "0.5*u**2"}}))
    assert sol.status.outcome is Outcome.OPTIMAL, sol.status.message
    assert len(sol.solver["limit_rounds"]) >= 1 and sol.verification["limits_held"]
    for p in sol.phases:
        assert p["verification"]["path"]["x_limit"]["held"]
    # a conservative bound on a coarse grid whose corners (t = 1/3, 2/3) fall between nodes: above 4
    assert 4.0 <= sol.objective <= 4.01


def test_a_parameter_shared_by_phases_on_mixed_transcriptions():
    # the brachistochrone split where x reaches a parameter xs (free): shooting above, LGL below; the
    # split is free, so the minimum time is the single phase's
    base = PRESETS["brachistochrone"]["params"]

    def phase(name, first, method, n):
        ends = {"x": 0.0, "y": 10.0, "v": 0.0} if first else {"x": 10.0, "y": 5.0}
        return {"name": name,
                "states": [{"name": s, **({"initial" if first else "final": ends[s]} if s in ends else {}),
                            "scale": 10.0, **({"lower": 0.0} if s == "v" else {})} for s in ("x", "y", "v")],
                "controls": [{"name": "theta", "lower": 0.0, "upper": math.pi}],
                "time": {"final_upper": 10.0, **({"initial": 0.0} if first else {})},
                "dynamics": base["dynamics"],
                "boundary": [{"expr": "final(x) - xs", "lower": 0.0, "upper": 0.0}] if first else [],
                "transcription": {"method": method, "intervals": n},
                "guess": {"tf": 1.0 if first else 1.8, "states": {"v": [0.0, 7.0] if first else [7.0, 9.9]},
                          "controls": {"theta": [0.1, 1.0] if first else [1.0, 1.75]}}}

    sol = solve(parse_problem({
        "constants": {"g": 9.80665}, "parameters": [{"name": "xs", "lower": 1.0, "upper": 9.0, "guess": 4.0}],
        "phases": [phase("upper", True, "multiple_shooting", 25), phase("lower", False, "lgl", 10)],
        "objective": {"sense": "minimize", "expr": 'tf("lower")'}}))
    assert sol.status.outcome is Outcome.OPTIMAL, sol.status.message
    assert sol.objective == pytest.approx(1.8016, abs=1e-4)
    assert sol.phases[0]["final"]["x"] == pytest.approx(sol.parameters["xs"], abs=1e-8)
    assert sol.phases[1]["solver"]["method"] == "lgl" and sol.verification["agrees"]
    # costates across the phases, each phase's by its own transcription (defect multipliers above, the LGL
    # mapping below): x's costate is one constant (-sin(theta)/v, Snell), H = -1 in both (time continuous,
    # Phi = tf of the last), every necessary condition held; 1e-4 is (h/T)^4 of LGL's 10 segments
    lx = np.concatenate([p["costates"]["x"] for p in sol.phases])
    assert np.ptp(lx) <= 1e-4 * abs(lx[0])
    for p in sol.phases:
        assert np.asarray(p["hamiltonian"]) == pytest.approx(-1.0, abs=1e-4)
        assert p["verification"]["optimality"]["held"], p["verification"]["optimality"]["message"]


def test_a_time_gap_link_and_an_integrand_of_one_phase():
    p = copy.deepcopy(PRESETS["lunar-lander-coast-burn"]["params"])
    p["links"] = [{"expr": 't0("burn") - tf("coast")', "lower": 2.0, "upper": 2.0}]    # a 2 s ignition delay
    p["objective"] = {"sense": "minimize", "integrand": {"burn": "T/ve"}}                 # the propellant burnt
    problem = parse_problem(p)
    assert problem.time_links == () and problem.named("coast").problem.objective.integrand is None
    sol = solve(problem)
    assert sol.status.outcome is Outcome.OPTIMAL, sol.status.message
    coast, burn = sol.phases
    assert burn["t0"] - coast["tf"] == pytest.approx(2.0, abs=1e-6)
    # the integral of the mass flow is the mass burnt: the objective and the final mass agree
    assert sol.objective == pytest.approx(1000.0 - burn["final"]["m"], rel=1e-6)
