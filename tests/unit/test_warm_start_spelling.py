"""One spelling of a warm start (issue 34 item 5): ``initial_guess.from_job`` in every kind that takes one;
the old spellings (intercept ``finite_thrust.from_job``, ocp ``guess``) are still accepted, moved to the
new name before validation (stored parameters carry only the new one), and marked deprecated in OpenAPI."""
from __future__ import annotations

import warnings

import pytest

from app.api.main import create_app
from app.kinds import KINDS, PRESETS
from app.runtime.settings import Settings
from app.service.params import resolve_params
from app.service.summary import WARM_START_FIELD

JOB = "0123456789abcdef0123456789abcdef"
PRESET = {"reentry": "betts-max-crossrange", "robust_reentry": "robust-max-crossrange",
          "intercept": "long-range-intercept", "ocp": "brachistochrone"}


def _resolve(kind: str, overrides: dict) -> dict:
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)  # the kinds never read the deprecated fields
        return resolve_params(KINDS[kind], PRESETS[PRESET[kind]].params, overrides)


@pytest.mark.parametrize("kind", sorted(PRESET))
def test_every_warm_start_is_initial_guess_from_job(kind):
    assert WARM_START_FIELD[kind] == "initial_guess.from_job"
    assert _resolve(kind, {"initial_guess": {"from_job": JOB}})["initial_guess"]["from_job"] == JOB


@pytest.mark.parametrize(("kind", "old"), [("intercept", {"finite_thrust": {"from_job": JOB}}),
                                           ("ocp", {"guess": {"from_job": JOB}})])
def test_the_old_spellings_are_moved_to_the_new_one(kind, old):
    params = _resolve(kind, old)
    assert params["initial_guess"]["from_job"] == JOB
    assert "guess" not in params  # ocp: the whole group moved
    assert "from_job" not in params.get("finite_thrust", {})  # intercept: out of the method's group
    # what is stored validates again unchanged (a re-run from GET .../params)
    assert resolve_params(KINDS[kind], params, None) == params


def test_a_preset_in_the_old_spelling_merges_with_overrides_in_the_new_one():
    # the ocp presets write their straight-line guess under `guess`; the user's warm start joins it
    params = _resolve("ocp", {"initial_guess": {"from_job": JOB}})
    assert params["initial_guess"]["from_job"] == JOB
    assert params["initial_guess"]["states"] == PRESETS["brachistochrone"].params["guess"]["states"]


def test_the_old_spellings_are_deprecated_in_openapi():
    doc = create_app(Settings(database_url="sqlite://", broker_url="redis://127.0.0.1:1/0")).openapi()
    schemas = doc["components"]["schemas"]
    assert schemas["InterceptFiniteThrust"]["properties"]["from_job"]["deprecated"] is True
    assert schemas["OcpParams"]["properties"]["guess"]["deprecated"] is True
    for model in ("InterceptParams", "OcpParams", "ReentryParams", "RobustReentryParams"):
        assert "deprecated" not in schemas[model]["properties"]["initial_guess"], model
