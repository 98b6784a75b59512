"""POST /v1/jobs's OpenAPI examples: one per kind and preset, each a body the service accepts."""
from __future__ import annotations

from pydantic import TypeAdapter

from app.api.main import create_app
from app.service.params import resolve_params
from app.api.schemas import JobSubmission
from app.kinds import KINDS, PRESETS
from app.runtime.settings import Settings


def test_every_preset_has_an_example_and_every_example_resolves():
    doc = create_app(Settings(database_url="sqlite:///:memory:", broker_url="redis://127.0.0.1:1/0")).openapi()
    examples = doc["paths"]["/v1/jobs"]["post"]["requestBody"]["content"]["application/json"]["examples"]
    named = {(e["value"]["kind"], e["value"].get("preset")) for e in examples.values()}
    assert {(p.kind, name) for name, p in PRESETS.items()} <= named
    assert {kind for kind, _ in named} == set(KINDS)
    for example in examples.values():
        body = TypeAdapter(JobSubmission).validate_python(example["value"])
        spec = KINDS[body.kind]
        overrides = body.params.model_dump(exclude_unset=True) if body.params is not None else None
        resolve_params(spec, PRESETS[body.preset].params if body.preset else None, overrides)  # a 422 raises
