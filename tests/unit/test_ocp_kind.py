"""The ocp kind's API edge without a worker: every malformed problem is a 422 naming the field path
and the reason, fast and before anything is stored (hostile expressions included, and a fuzz that
never finds a 500); the limits name their setting; presets, overrides and study paths resolve;
warm starts fail cleanly; cost, queue, key numbers and plots of a result."""
from __future__ import annotations

import copy
from pathlib import Path

import pytest
from fastapi.testclient import TestClient
from hypothesis import HealthCheck, given
from hypothesis import settings as hsettings
from hypothesis import strategies as st

from app.api.main import create_app
from app.service.params import resolve_params
from app.kinds import KINDS, PRESETS
from app.kinds.ocp import SPEC, OcpParams, run
from app.kinds.ocp.kind import cost, key_numbers
from app.kinds.ocp.plots import plots
from app.runtime.migrate import upgrade
from app.runtime.settings import Settings, get_settings
from app.service import quota
from app.service.broker import QUEUE_HEAVY, QUEUE_JOBS
from app.service.studies import expand
from tests.support import RecordingContext

CANARY = Path("/tmp/trajlab-ocp-canary")

BRACHISTOCHRONE = {
    "title": "Brachistochrone",
    "constants": {"g": 9.80665},
    "states": [{"name": "x", "initial": 0.0, "final": 10.0, "unit": "m"},
               {"name": "y", "initial": 10.0, "final": 5.0, "unit": "m"},
               {"name": "v", "initial": 0.0, "unit": "m/s"}],
    "controls": [{"name": "theta", "lower": 0.01, "upper": 3.1, "unit": "rad"}],
    "time": {"initial": 0.0, "final": None, "final_lower": 0.5, "final_upper": 10.0, "final_guess": 2.0},
    "expressions": {"speed": "sqrt(2*g*(10 - y))"},
    "dynamics": {"x": "v*sin(theta)", "y": "-v*cos(theta)", "v": "g*cos(theta)"},
    "objective": {"sense": "minimize", "expr": "tf"},
    "plots": [["x", "y"]],
}


def body(**changes) -> dict:
    params = copy.deepcopy(BRACHISTOCHRONE)
    params.update(changes)
    return {"kind": "ocp", "params": params}


def with_dynamics(x: str) -> dict:
    b = body()
    b["params"]["dynamics"]["x"] = x
    return b


@pytest.fixture(scope="module")
def client(tmp_path_factory):
    url = f"sqlite:///{tmp_path_factory.mktemp('ocp') / 'ocp.db'}"
    upgrade(url)
    # the broker is never reached: a valid submission is stored unpublished (the recovery loop's job)
    with TestClient(create_app(Settings(database_url=url, broker_url="redis://127.0.0.1:1/0")),
                    raise_server_exceptions=False) as c:
        yield c


def stored(client) -> int:
    return client.get("/v1/jobs", params={"kind": "ocp", "limit": 1}).json()["total"]


def submit_422(client, payload: dict) -> dict:
    before = stored(client)
    r = client.post("/v1/jobs", json=payload)
    assert r.status_code == 422, r.text
    assert stored(client) == before, "a refused problem was stored"
    return r.json()


HOSTILE = [
    ("__import__('pathlib').Path('/tmp/trajlab-ocp-canary').touch()", "only calls of a function by its name"),
    ("__import__('os')", "unknown function '__import__'"),
    ("v.__class__.__mro__", "forbidden construct Attribute"),
    ("(lambda: v)()", "only calls of a function by its name"),
    ("(lambda q: q)(v)", "only calls of a function by its name"),
    ("v[0]", "forbidden construct Subscript"),
    ("[v for v in range(3)]", "forbidden construct ListComp"),
    ("sum(v for v in (1, 2))", "unknown function 'sum'"),
    ("'abc'", "only numbers are allowed"),
    ("v if v > 0 else 0", "forbidden construct IfExp"),
    ("v > 0", "forbidden construct Compare"),
    ("sin(x=v)", "keyword arguments are not allowed"),
    ("(" * 3000 + "v" + ")" * 3000, "max_expression_chars=2000 (setting TRAJLAB_OCP_MAX_EXPRESSION_CHARS)"),
    ("+".join(["v"] * 3000), "max_expression_chars=2000 (setting TRAJLAB_OCP_MAX_EXPRESSION_CHARS)"),
    ("+".join(["v"] * 300), "max_expression_nodes=400) (setting TRAJLAB_OCP_MAX_EXPRESSION_NODES)"),
    ("(" * 150 + "v" + ")" * 150, ""),   # deep but short: parsed or refused, never a 500
    ("vv*sin(theta)", "unknown name 'vv'; did you mean 'v'?"),
    ("final(v)", "final() is allowed only in boundary constraints and the objective"),
    ("v*sin(theta", "syntax error at column"),
    ("import os", "syntax error"),
]


@pytest.mark.parametrize("text, reason", HOSTILE)
def test_hostile_expressions_are_422_naming_field_and_reason_and_nothing_runs(client, text, reason):
    CANARY.unlink(missing_ok=True)
    r = client.post("/v1/jobs", json=with_dynamics(text))
    if not reason and r.status_code == 202:
        return   # 150 nested parentheses is a valid (silly) expression
    out = submit_422(client, with_dynamics(text))
    first = out["detail"][0]
    assert first["loc"] == ["body", "params", "dynamics", "x"]
    assert out["message"].startswith("params.dynamics.x: ")
    assert reason in first["msg"]
    assert not CANARY.exists()


@pytest.mark.parametrize("change, loc, reason", [
    ({"dynamics": {"x": "v*sin(theta)", "y": "-v*cos(theta)"}}, ["dynamics"], "state 'v' has no dynamics"),
    ({"dynamics": {"x": "1", "y": "1", "v": "1", "w": "1"}}, ["dynamics", "w"], "w"),
    ({"path": [{"expr": "final(x)", "upper": 1.0}]}, ["path", 0, "expr"], "final()"),
    ({"states": [{"name": "x"}, {"name": "x"}, {"name": "v"}]}, ["states", 1, "name"], "x"),
    ({"constants": {"t": 1.0, "g": 9.8}}, ["constants", "t"], "t"),
    ({"constants": {"sin": 1.0, "g": 9.8}}, ["constants", "sin"], "sin"),
    # a leading underscore is reserved (issue 36: __class__ was accepted as a state)
    ({"states": [{"name": "__class__"}, {"name": "y"}, {"name": "v"}]}, ["states", 0, "name"],
     "'__class__' is reserved: a name cannot begin with an underscore"),
    ({"constants": {"_g": 9.8}}, ["constants", "_g"], "cannot begin with an underscore"),
    ({"controls": [{"name": "theta", "lower": 2.0, "upper": 1.0}]}, ["controls", 0], "2"),
    ({"tables": {"rho": {"axes": [[0.0, 2.0, 1.0]], "values": [1.0, 2.0, 3.0]}}},
     ["tables", "rho", "axes", 0], "increasing"),
    ({"objective": None}, ["objective"], "objective is required"),
    ({"plots": [["x", "q"]]}, ["plots", 0, 1], "'q'"),
    ({"boundary": [{"expr": "final(vv)", "lower": 0.0}]}, ["boundary", 0, "expr"], "did you mean 'v'?"),
])
def test_problem_errors_name_the_path_and_the_reason(client, change, loc, reason):
    out = submit_422(client, body(**change))
    first = out["detail"][0]
    assert first["loc"][:2 + len(loc)] == ["body", "params", *loc], first
    assert reason in first["msg"], first["msg"]
    assert out["message"].startswith("params." + ".".join(map(str, loc)))


def test_limits_are_422_naming_the_limit_and_its_setting(client, monkeypatch):
    many = body(states=[{"name": f"s{i}", "initial": 0.0} for i in range(51)],
                dynamics={f"s{i}": "1" for i in range(51)})
    out = submit_422(client, many)
    assert "max_states=50" in out["message"] and "TRAJLAB_OCP_MAX_STATES" in out["message"]
    monkeypatch.setenv("TRAJLAB_OCP_MAX_STATES", "2")
    get_settings.cache_clear()
    try:
        out = submit_422(client, body())
        assert out["detail"][0]["loc"] == ["body", "params", "states"]
        assert "max_states=2" in out["message"] and "TRAJLAB_OCP_MAX_STATES" in out["message"]
    finally:
        monkeypatch.delenv("TRAJLAB_OCP_MAX_STATES")
        get_settings.cache_clear()
    b = body()
    b["params"]["transcription"] = {"intervals": 5000}
    out = submit_422(client, b)
    assert "TRAJLAB_OCP_MAX_INTERVALS" in out["message"]


def test_a_valid_problem_is_accepted_and_resolved(client):
    r = client.post("/v1/jobs", json=body())
    assert r.status_code == 202, r.text
    params = r.json()["params"]
    assert params["transcription"]["method"] == "multiple_shooting" and params["states"][2]["final"] is None
    assert OcpParams.model_validate(params).model_dump(mode="json") == params


@pytest.mark.skipif(not any(p.kind == "ocp" for p in PRESETS.values()), reason="no ocp presets yet")
def test_presets_partial_overrides_and_study_paths_resolve(client):
    ocp = [p for p in PRESETS.values() if p.kind == "ocp"]
    assert {"brachistochrone", "betts-shuttle-ocp"} <= {p.name for p in ocp}
    for p in ocp:
        assert len(p.description) > 40
        resolve_params(SPEC, p.params, None)
    # a partial override is checked once merged with the preset, not on its own
    r = client.post("/v1/jobs", json={"kind": "ocp", "preset": "brachistochrone",
                                      "params": {"transcription": {"intervals": 20}}})
    assert r.status_code == 202, r.text
    base = resolve_params(SPEC, PRESETS["brachistochrone"].params, None)
    const = next(iter(base["constants"]))
    points = expand(base, [{"path": f"constants.{const}", "values": [1.0, 2.0]},
                           {"path": "states.1.final", "values": [4.0, 5.0]}])
    for point in points:
        resolved = resolve_params(SPEC, point.params, None)
        assert resolved["states"][1]["final"] in (4.0, 5.0)
    # the Betts shuttle written as an ocp costs per solve what the reentry kind's Betts preset costs; the ocp
    # answer is that solve and its check on the mesh cut in 3 (linear multiple-shooting controls)
    betts = quota.estimate_cost("ocp", resolve_params(SPEC, PRESETS["betts-shuttle-ocp"].params, None))
    reentry = quota.estimate_cost("reentry", resolve_params(KINDS["reentry"], PRESETS["betts-max-crossrange"].params,
                                                            None))
    assert betts == pytest.approx((1 + 3) * reentry, rel=0.25)
    r = client.post("/v1/studies", json={"kind": "ocp", "preset": "brachistochrone", "mode": "independent",
                                         "sweeps": [{"path": "states.1.final", "values": [4.0, 6.0]}]})
    assert r.status_code == 202, r.text


# a small grammar of expressions, allowed and forbidden pieces mixed: the answer is 202 or 422, never 500
_atoms = st.sampled_from(["x", "y", "v", "theta", "g", "t", "tf", "pi", "1", "2.5", "1e308", "1e999", "0",
                          "vv", "__class__", "'s'", "None", "True", "...", "initial(x)", "final(v)"])
_exprs = st.recursive(_atoms, lambda inner: st.one_of(
    st.tuples(inner, st.sampled_from(["+", "-", "*", "/", "**", "%", "//", "@", "<", "and", "if"]), inner)
    .map(lambda t: f"{t[0]} {t[1]} {t[2]}"),
    st.tuples(st.sampled_from(["sin", "atan2", "min", "max", "hypot", "exp", "eval", "open", "rho", "x"]),
              st.lists(inner, max_size=3)).map(lambda t: f"{t[0]}({', '.join(t[1])})"),
    inner.map(lambda e: f"({e})"), inner.map(lambda e: f"-{e}"), inner.map(lambda e: f"{e}.real"),
    inner.map(lambda e: f"{e}[0]"), inner.map(lambda e: f"lambda: {e}"),
), max_leaves=20)


@hsettings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(text=st.one_of(_exprs, st.text(max_size=60)), where=st.sampled_from(["dynamics", "path", "objective"]))
@pytest.mark.slow
def test_fuzz_never_a_500(client, text, where):
    b = body()
    if where == "dynamics":
        b["params"]["dynamics"]["v"] = text
    elif where == "path":
        b["params"]["path"] = [{"expr": text, "upper": 1.0}]
    else:
        b["params"]["objective"] = {"sense": "maximize", "expr": text}
    r = client.post("/v1/jobs", json=b)
    assert r.status_code in (202, 422), r.text
    if r.status_code == 422:
        assert r.json()["message"]


def test_warm_start_from_an_unknown_or_unusable_job_is_a_clean_failure():
    from app.kinds.base import JobFailure

    params = OcpParams.model_validate({**BRACHISTOCHRONE, "initial_guess": {"from_job": "nope"}})
    with pytest.raises(JobFailure) as exc:
        run(params, RecordingContext())
    assert exc.value.code == "invalid_input" and "initial_guess.from_job" in exc.value.message
    params = OcpParams.model_validate({**BRACHISTOCHRONE, "initial_guess": {"from_job": "other"}})
    with pytest.raises(JobFailure) as exc:
        run(params, RecordingContext(stored={"other": {"pareto_front": []}}))
    assert exc.value.code == "invalid_input" and "no ocp trajectory" in exc.value.message


def test_cost_grows_with_the_problem_and_routes_heavy_problems_to_the_heavy_queue():
    small = OcpParams.model_validate(BRACHISTOCHRONE).model_dump(mode="json")
    big = copy.deepcopy(small)
    big["transcription"]["intervals"] = 1000
    big["states"] = [{"name": f"s{i}", "initial": 0.0} for i in range(50)]
    big["dynamics"] = {f"s{i}": " + ".join(f"sin(s{j})" for j in range(50)) for i in range(50)}
    settings = Settings(database_url="sqlite://")
    assert 0 < quota.estimate_cost("ocp", small) < cost(big) == quota.estimate_cost("ocp", big)
    assert quota.queue_for("ocp", quota.estimate_cost("ocp", small), settings) == QUEUE_JOBS
    assert quota.queue_for("ocp", quota.estimate_cost("ocp", big), settings) == QUEUE_HEAVY


def test_cost_and_memory_count_the_check_solve_on_the_finer_mesh():
    """Every answer is checked by a solve on its mesh with every interval cut in s parts (3 for linear
    multiple-shooting controls, 2 otherwise: solvers.ocp.estimate.parts_of), an NLP s times the answer's:
    the cost is (1 + s) solves of the answer's size, the memory that of the check's NLP, and a problem
    whose own solve is under the heavy threshold goes to the heavy queue once its check is counted."""
    from app.kinds.ocp.footprint import MEMORY
    from app.kinds.ocp.size import check_parts, phase_sizes
    from solvers.ocp.estimate import parts_of
    from solvers.ocp.problem import Transcription

    base = OcpParams.model_validate(BRACHISTOCHRONE).model_dump(mode="json")
    cases = {("multiple_shooting", "linear"): 3, ("multiple_shooting", "constant"): 2, ("lgl", "linear"): 2}
    one_solve = {}
    for (method, control), parts in cases.items():
        tr = {**base["transcription"], "method": method, "control": control}
        # the request's parts are the solver's
        assert check_parts(tr) == parts == parts_of(Transcription(method=method, control=control))
        p = {**base, "transcription": tr}
        one_solve[method, control] = cost(p) / (1 + parts)
        doubled = {**p, "transcription": {**tr, "intervals": 2 * tr["intervals"]}}
        assert cost(doubled) == pytest.approx(2 * cost(p))
    # the same mesh and integration: one solve costs the same whatever the control's parametrisation; the
    # memory is the check's NLP, 3 against 2 answers' worth
    assert one_solve["multiple_shooting", "linear"] == pytest.approx(one_solve["multiple_shooting", "constant"])
    ms = {**base, "transcription": {**base["transcription"], "method": "multiple_shooting"}}
    constant = {**ms, "transcription": {**ms["transcription"], "control": "constant"}}
    (lin,), (con,) = phase_sizes(ms), phase_sizes(constant)
    assert lin.grid == pytest.approx(1.5 * con.grid) and MEMORY.size(ms) > MEMORY.size(constant)
    settings = Settings(database_url="sqlite://")
    tr = base["transcription"]
    unit = cost(base) / (1 + 3) / tr["intervals"]                  # one solve's units per interval
    near = {**base, "transcription": {**tr, "intervals": int(0.6 * settings.heavy_cost / unit)}}
    assert cost(near) / 4 < settings.heavy_cost < cost(near)       # its own solve alone would be quick
    assert quota.queue_for("ocp", quota.estimate_cost("ocp", near), settings) == QUEUE_HEAVY
    # with accuracy, every round is an answer and its check
    rounds = {**base, "accuracy": 1e-6, "transcription": {**tr, "max_refinements": 2}}
    assert cost(rounds) == pytest.approx(3 * cost(base))


RESULT = {
    "objective": {"value": 1.8016, "sense": "minimize"}, "t0": 0.0, "tf": 1.8016,
    "initial": {"x": 0.0, "y": 10.0, "v": 0.0}, "final": {"x": 10.0, "y": 5.0, "v": 9.9},
    "parameters": {}, "units": {"x": "m", "y": "m"},
    "trajectory": {"t": [0.0, 0.9, 1.8016], "x": [0.0, 3.0, 10.0], "y": [10.0, 7.0, 5.0],
                   "v": [0.0, 6.0, None], "theta": [0.1, 1.0, 1.5], "speed": [0.0, 6.0, 9.9]},
    "verification": {"limits_held": True, "agrees": True, "agreement_tolerance": 1e-4},
    "solver": {"status": "Solve_Succeeded", "iterations": 12, "build_time_s": 0.1, "solve_time_s": 0.02,
               "max_constraint_violation": 1e-10},
    "plots": [["x", "y"]], "notes": [],
}


@pytest.mark.slow
def test_key_numbers_plots_and_the_result_model_of_a_result():
    from app.results.plots import plots_for, render

    assert key_numbers(RESULT) == {"objective": 1.8016, "sense": "minimize", "tf": 1.8016, "iterations": 12,
                                   "final.x": 10.0, "final.y": 5.0, "final.v": 9.9,
                                   "limits_held": True, "verification_agrees": True}
    names = [p.name for p in plots_for("ocp", RESULT)]
    assert names == ["t-x", "t-y", "t-v", "t-theta", "t-speed", "x-y"]
    assert [p.name for p in plots(RESULT)] == names
    png = render(plots_for("ocp", RESULT)[-1], result=RESULT, params=BRACHISTOCHRONE, title="ocp test", fmt="png")
    assert png.startswith(b"\x89PNG")
    svg = render(plots_for("ocp", RESULT)[0], result=RESULT, params=BRACHISTOCHRONE, title="ocp test", fmt="svg")
    assert b"<svg" in svg
    assert SPEC.result_model.model_validate(RESULT).objective.value == 1.8016


def test_openapi_documents_the_params_and_the_result(client):
    doc = client.get("/openapi.json").json()
    schemas = doc["components"]["schemas"]
    for name in ("OcpParams", "OcpState", "OcpControl", "OcpTranscription", "OcpResult", "OcpSubmission"):
        assert name in schemas, name
    for field, prop in schemas["OcpParams"]["properties"].items():
        assert prop.get("description"), field
    assert KINDS["ocp"] is SPEC
