"""The ocp expression language and problem parser against hostile and malformed input.

Every bad problem must raise OcpInputError naming the field path and the reason, quickly, and
nothing in it may run: the parser is an allow-list over Python's ast, never eval.
"""
from __future__ import annotations

import copy
import subprocess
import sys

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from solvers.ocp.cases import PRESETS
from solvers.ocp.expressions import OcpInputError as ExprError
from solvers.ocp.spec import OcpInputError, OcpLimits, parse_problem

BASE = {
    "constants": {"g": 9.80665, "k": 0.5},
    "tables": {"cd_tab": {"axes": [[0.0, 1.0, 2.0, 3.0]], "values": [1.0, 2.0, 3.0, 5.0]}},
    "states": [{"name": "x", "initial": 0.0, "final": 10.0},
               {"name": "y", "initial": 10.0, "final": 5.0},
               {"name": "v", "initial": 0.0, "lower": 0.0}],
    "controls": [{"name": "theta", "lower": 0.0, "upper": 3.14}],
    "parameters": [{"name": "p1", "lower": 0.0, "upper": 1.0}],
    "time": {"initial": 0.0, "final": None, "final_lower": 0.1, "final_upper": 10.0},
    "expressions": {"drag": "k*v**2*cd_tab(v)"},
    "dynamics": {"x": "v*sin(theta)", "y": "-v*cos(theta)", "v": "g*cos(theta) - drag"},
    "path": [{"expr": "v", "upper": 20.0}],
    "boundary": [{"expr": "final(v) + tf", "lower": 0.0}],
    "objective": {"sense": "minimize", "expr": "tf"},
}


def with_dynamics(expr: str, state: str = "v") -> dict:
    body = copy.deepcopy(BASE)
    body["dynamics"][state] = expr
    return body


def rejected(body: dict, path: str, *words: str) -> OcpInputError:
    with pytest.raises(OcpInputError) as info:
        parse_problem(body)
    err = info.value
    assert err.path == path, (err.path, err.reason)
    assert str(err) == f"{err.path}: {err.reason}"
    for w in words:
        assert w in err.reason, (w, err.reason)
    return err


def test_base_problem_and_every_preset_parse():
    p = parse_problem(BASE)
    assert [s.name for s in p.states] == ["x", "y", "v"]
    assert p.single and p.transcription.method == "multiple_shooting"
    for preset in PRESETS.values():
        parse_problem(preset["params"])


def test_error_class_is_one():
    assert ExprError is OcpInputError
    assert issubclass(OcpInputError, ValueError)


HOSTILE = [
    ("__import__('os').system('touch /tmp/ocp_pwned')", "only calls of a function by its name"),
    ("__import__('os')", "unknown function '__import__'"),
    ("sin('os')", "only numbers"),
    ("().__class__", "forbidden construct"),
    ("v.__class__", "forbidden construct Attribute"),
    ("(lambda: 1)()", "only calls of a function by its name"),
    ("lambda v: v", "forbidden construct Lambda"),
    ("[1, 2][0]", "forbidden construct Subscript"),
    ("v[0]", "forbidden construct Subscript"),
    ("[v for v in (1, 2)]", "forbidden construct ListComp"),
    ("sin(v for v in (1, 2))", "forbidden construct GeneratorExp"),
    ("'abc'", "only numbers"),
    ("v < 1", "forbidden construct Compare"),
    ("v if v else 1", "forbidden construct IfExp"),
    ("v and 1", "forbidden construct BoolOp"),
    ("max(v, key=1)", "keyword arguments"),
    ("sin(*v)", "starred"),
    ("v % 2", "forbidden operator Mod"),
    ("v // 2", "forbidden operator FloorDiv"),
    ("v @ v", "forbidden operator MatMult"),
    ("~v", "forbidden operator Invert"),
    ("True", "only numbers"),
    ("1j", "only numbers"),
    ("1e999", "not finite"),
    ("(v := 2)", "forbidden construct NamedExpr"),
    ("{'a': 1}", "forbidden construct Dict"),
    ("f'{v}'", "forbidden construct JoinedStr"),
    ("eval('1')", "unknown function 'eval'"),
    ("exec", "unknown name"),
    ("open(1)", "unknown function"),
    ("sin(1, 2)", "sin() takes 1 argument"),
    ("atan2(1)", "atan2() takes 2 arguments"),
    ("cd_tab(1, 2)", "1-D"),
    ("sin", "used as a value"),
    ("final(v)", "only in boundary"),
    ("initial(x) + v", "only in boundary"),
]


@pytest.mark.parametrize("expr,reason", HOSTILE)
def test_hostile_expressions_are_refused(expr, reason, tmp_path):
    rejected(with_dynamics(expr), "params.dynamics.v", reason)


def test_nothing_is_executed(tmp_path):
    marker = tmp_path / "pwned"
    expr = f"__import__('pathlib').Path('{marker}').touch()"
    rejected(with_dynamics(expr), "params.dynamics.v", "only calls of a function by its name")
    assert not marker.exists()


def test_syntax_error_names_column():
    err = rejected(with_dynamics("v * (1 + "), "params.dynamics.v", "syntax error at column")
    assert any(ch.isdigit() for ch in err.reason)
    rejected(with_dynamics("v ** * 2"), "params.dynamics.v", "syntax error at column")
    rejected(with_dynamics("x = 1"), "params.dynamics.v", "syntax error")
    rejected(with_dynamics("import os"), "params.dynamics.v", "syntax error")


def test_size_guards():
    rejected(with_dynamics("(" * 3000 + "v" + ")" * 3000), "params.dynamics.v", "max_expression_chars=2000")
    rejected(with_dynamics("+".join(["v"] * 3000)), "params.dynamics.v", "max_expression_chars")
    # within the character limit, past the node limit
    rejected(with_dynamics("+".join(["v"] * 600)), "params.dynamics.v", "max_expression_nodes=400")
    rejected(with_dynamics("-" * 1990 + "v"), "params.dynamics.v")
    rejected(with_dynamics("(" * 990 + "v" + ")" * 990), "params.dynamics.v")
    small = OcpLimits(max_expression_chars=10)
    with pytest.raises(OcpInputError, match="max_expression_chars=10"):
        parse_problem(with_dynamics("v + v + v + v"), small)


def test_unknown_name_suggests_the_closest():
    err = rejected(with_dynamics("g*cos(thetta)"), "params.dynamics.v", "unknown name 'thetta'")
    assert "did you mean 'theta'" in err.reason
    rejected(with_dynamics("sine(theta)"), "params.dynamics.v", "unknown function 'sine'", "did you mean 'sin'")


def test_dynamics_coverage():
    body = copy.deepcopy(BASE)
    del body["dynamics"]["y"]
    rejected(body, "params.dynamics", "state 'y' has no dynamics")
    body = copy.deepcopy(BASE)
    body["dynamics"]["w"] = "1"
    rejected(body, "params.dynamics.w", "not a declared state")


def test_boundary_functions_where_allowed():
    body = copy.deepcopy(BASE)
    body["path"] = [{"expr": "final(v)", "upper": 1.0}]
    rejected(body, "params.path.0.expr", "only in boundary")
    body = copy.deepcopy(BASE)
    body["boundary"] = [{"expr": "v", "upper": 1.0}]
    rejected(body, "params.boundary.0.expr", "initial(v) or final(v)")
    body = copy.deepcopy(BASE)
    body["boundary"] = [{"expr": "final(vv)", "upper": 1.0}]
    rejected(body, "params.boundary.0.expr", "did you mean 'v'")
    body = copy.deepcopy(BASE)
    body["objective"] = {"sense": "maximize", "expr": "final(x) - initial(y) + p1 + tf - t0"}
    parse_problem(body)
    body["objective"] = {"sense": "maximize", "integrand": "final(x)"}
    rejected(body, "params.objective.integrand", "only in boundary")
    body["objective"] = {"sense": "maximize", "expr": "t"}
    rejected(body, "params.objective.expr", "unknown name 't'")


@pytest.mark.parametrize("name,reason", [("sin", "shadows the function"), ("t", "reserved"),
                                         ("tf", "reserved"), ("pi", "reserved"), ("final", "reserved"),
                                         ("initial", "reserved"), ("x", "duplicated name 'x'"),
                                         ("g", "duplicated name 'g'"), ("cd_tab", "duplicated"),
                                         ("lambda", "keyword"), ("1x", "not a valid name"),
                                         ("__class__.x", "not a valid name"),
                                         ("__class__", "cannot begin with an underscore"),
                                         ("_u", "cannot begin with an underscore")])
def test_bad_names(name, reason):
    body = copy.deepcopy(BASE)
    body["controls"].append({"name": name})
    rejected(body, "params.controls.1.name", reason)


def test_duplicated_expression_name():
    body = copy.deepcopy(BASE)
    body["constants"]["drag"] = 1.0
    rejected(body, "params.expressions.drag", "duplicated name 'drag'")


def test_bounds_and_tables():
    body = copy.deepcopy(BASE)
    body["states"][2]["lower"], body["states"][2]["upper"] = 5.0, 1.0
    rejected(body, "params.states.2.lower", "lower 5 > upper 1")
    body = copy.deepcopy(BASE)
    body["path"][0]["lower"] = 30.0
    rejected(body, "params.path.0.lower", "lower 30 > upper 20")
    body = copy.deepcopy(BASE)
    body["tables"]["cd_tab"]["axes"] = [[0.0, 2.0, 1.0, 3.0]]
    rejected(body, "params.tables.cd_tab.axes.0.2", "not strictly increasing")
    body = copy.deepcopy(BASE)
    body["tables"]["cd_tab"]["values"] = [1.0, 2.0]
    rejected(body, "params.tables.cd_tab.values", "2 values", "4")
    body = copy.deepcopy(BASE)
    body["tables"]["t2"] = {"axes": [[0, 1], [0, 1, 2]], "values": [1, 2, 3, 4, 5, 6]}
    body["dynamics"]["x"] = "t2(v, theta)"
    parse_problem(body)


def test_limits_name_the_limit():
    body = copy.deepcopy(BASE)
    body["states"] = [{"name": f"s{i}"} for i in range(51)]
    body["dynamics"] = {f"s{i}": "1" for i in range(51)}
    rejected(body, "params.states", "max_states=50")
    body = copy.deepcopy(BASE)
    body["tables"]["big"] = {"axes": [list(range(400)), list(range(300))], "values": [0.0] * 120000}
    rejected(body, "params.tables.big.values", "max_table_values=100000")


def test_other_field_errors():
    body = copy.deepcopy(BASE)
    body["objective"] = {"sense": "minimise", "expr": "tf"}
    rejected(body, "params.objective.sense", "minimize")
    body = copy.deepcopy(BASE)
    body["dynamics"]["x"] = 3
    parse_problem(body)                      # a number is an expression too
    body["dynamics"]["x"] = ["v"]
    rejected(body, "params.dynamics.x", "must be a string")
    body = copy.deepcopy(BASE)
    body["statse"] = []
    rejected(body, "params.statse", "unknown field", "did you mean 'states'")
    body = copy.deepcopy(BASE)
    body["transcription"] = {"method": "lgl", "intervals": 100000}
    rejected(body, "params.transcription.intervals", "max_intervals")


def test_spec_loads_no_numpy_or_casadi():
    code = ("import sys; import solvers.ocp.spec, solvers.ocp.cases, solvers.ocp; "
            "from solvers.ocp import parse_problem, PRESETS; "
            "assert not {'numpy', 'casadi', 'scipy'} & set(sys.modules), sorted(sys.modules)")
    subprocess.run([sys.executable, "-c", code], check=True, cwd=str(__import__('pathlib').Path(__file__).parents[2]))


# --- fuzz: random text and random trees only ever parse or raise OcpInputError ------------------
ATOMS = st.sampled_from(["v", "x", "theta", "g", "p1", "t", "tf", "pi", "1", "2.5", "1e3", "0",
                         "drag", "unknown", "__class__", "'s'", "True", "None", "()", "[]"])
FUNCS = st.sampled_from(["sin", "atan2", "min", "max", "cd_tab", "final", "initial", "eval", "hypot",
                         "sign", "x", "lambda"])
OPS = st.sampled_from(["+", "-", "*", "/", "**", "%", "<", " and ", ".", "@", "//", ","])


def trees(depth=0):
    leaf = ATOMS
    if depth > 4:
        return leaf
    sub = st.deferred(lambda: trees(depth + 1))
    return st.one_of(
        leaf,
        st.tuples(sub, OPS, sub).map(lambda a: f"{a[0]}{a[1]}{a[2]}"),
        st.tuples(FUNCS, st.lists(sub, max_size=3)).map(lambda a: f"{a[0]}({', '.join(a[1])})"),
        sub.map(lambda s: f"-({s})"),
        sub.map(lambda s: f"{s}[0]"),
    )


def _parse_or_refuse(expr: str):
    body = with_dynamics(expr)
    try:
        parse_problem(body)
    except OcpInputError as e:
        assert e.path.startswith("params.") and e.reason


@settings(max_examples=300, deadline=1000)
@given(trees())
def test_fuzz_trees(expr):
    _parse_or_refuse(expr)


@settings(max_examples=300, deadline=1000)
@given(st.text(alphabet=st.characters(codec="utf-8"), max_size=60))
@pytest.mark.slow
def test_fuzz_text(expr):
    _parse_or_refuse(expr)


@settings(max_examples=100, deadline=2000)
@given(st.recursive(st.one_of(st.none(), st.booleans(), st.integers(), st.floats(), st.text(max_size=5)),
                    lambda c: st.lists(c, max_size=3) | st.dictionaries(st.text(max_size=8), c, max_size=3),
                    max_leaves=8),
       st.sampled_from(["states", "controls", "time", "tables", "path", "boundary", "objective",
                        "transcription", "guess", "constants", "expressions", "parameters"]))
def test_fuzz_field_shapes(value, field):
    body = copy.deepcopy(BASE)
    body[field] = value
    try:
        parse_problem(body)
    except OcpInputError as e:
        assert e.path.startswith("params")


@settings(max_examples=150, deadline=None)
@given(trees())
def test_fuzz_parsed_trees_map_onto_casadi(expr):
    """Whatever parses also builds: the CasADi mapping never raises on a validated tree."""
    import numpy as np

    from solvers.ocp.symbolic import phase_functions
    try:
        problem = parse_problem(with_dynamics(expr))
    except OcpInputError:
        return
    fns = phase_functions(problem.phases[0].problem)
    out = fns.rhs(0.5, np.array([1.0, 2.0, 3.0]), np.array([0.3]), np.array([0.5]),
                  np.array([9.80665, 0.5]), 0.0, 2.0)
    assert out.shape == (3, 1)
