"""/v1/presets: the named cases of the reference papers."""
from __future__ import annotations

from fastapi import APIRouter, HTTPException

from app.kinds import KINDS, PRESETS
from app.service.params import resolve_params
from app.api.schemas import ErrorBody, PresetOut

router = APIRouter(prefix="/v1/presets", tags=["presets"])


def _out(name: str) -> dict:
    p = PRESETS[name]
    return {"name": p.name, "kind": p.kind, "description": p.description,
            "params": resolve_params(KINDS[p.kind], p.params, None)}


@router.get("", response_model=list[PresetOut])
def list_presets():
    return [_out(name) for name in PRESETS]


@router.get("/{name}", response_model=PresetOut, responses={404: {"model": ErrorBody, "description": "Unknown preset"}})
def get_preset(name: str):
    if name not in PRESETS:
        raise HTTPException(status_code=404, detail=f"preset {name} not found; known: {sorted(PRESETS)}")
    return _out(name)
