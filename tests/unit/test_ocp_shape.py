"""The ``ocp`` params' shape is declared once (:mod:`solvers.ocp.shape`, which the parser refuses other
fields with); the request models that document it in ``/docs`` have exactly those fields, so neither
can grow a field the other lacks."""
from __future__ import annotations

import pytest

from app.kinds.ocp import params as models
from solvers.ocp import OcpInputError, parse_problem
from solvers.ocp.shape import FIELDS

MODELS = {
    "params": None,   # OcpParams holds both forms: checked below
    "phase": models.OcpPhase, "state": models.OcpState, "control": models.OcpControl,
    "parameter": models.OcpParameter, "table": models.OcpTable, "time": models.OcpTime,
    "phase.time": models.OcpPhaseTime, "constraint": models.OcpConstraint, "link": models.OcpLink,
    "objective": models.OcpObjective, "transcription": models.OcpTranscription, "guess": models.OcpGuess,
    "phase.guess": models.OcpPhaseGuess, "search": models.OcpSearch,
}


@pytest.mark.parametrize("section", [s for s, m in MODELS.items() if m is not None])
def test_each_request_model_has_the_declared_fields(section):
    assert set(MODELS[section].model_fields) == set(FIELDS[section])


def test_the_params_model_holds_both_forms_and_nothing_else():
    # the API names the top-level guess initial_guess (one warm-start spelling in every kind, issue 34
    # item 5); `guess` stays in the model as its deprecated name (app/kinds/ocp/params.py, PARSER_GUESS)
    assert set(models.OcpParams.model_fields) == set(FIELDS["params"]) | set(FIELDS["params.phases"]) | {
        "initial_guess"}
    assert set(FIELDS["params.phases.guess"]) <= set(FIELDS["guess"])


@pytest.mark.parametrize("section,path", [("transcription", ("transcription",)), ("time", ("time",)),
                                          ("objective", ("objective",))])
def test_the_parser_refuses_a_field_the_shape_lacks(section, path):
    from solvers.ocp import PRESETS

    params = {**PRESETS["brachistochrone"]["params"]}
    params[path[0]] = {**params[path[0]], "bogus": 1}
    with pytest.raises(OcpInputError) as exc:
        parse_problem(params)
    assert exc.value.path == f"params.{section}.bogus"
