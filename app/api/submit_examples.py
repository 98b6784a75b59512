"""The request examples of ``POST /v1/jobs`` in the OpenAPI document (``/docs``'s example picker): one
per kind and preset, made from the registry so a new preset shows up without an edit here, plus a preset
with overrides, a warm start and a whole ocp problem."""
from __future__ import annotations

from app.kinds import KINDS, PRESETS


def job_examples() -> dict[str, dict]:
    out: dict[str, dict] = {}
    for kind, spec in KINDS.items():
        for preset in spec.presets:
            first_line = preset.description.split(". ")[0].rstrip(".")
            out[f"{kind}: {preset.name}"] = {
                "summary": f"{kind}: {preset.name}",
                "description": f"{first_line}. The preset's parameters are merged onto the kind's defaults; "
                               "`params` overrides any of them.",
                "value": {"kind": kind, "preset": preset.name}}
    out["override: fewer intervals"] = {
        "summary": "A preset with one parameter changed",
        "value": {"kind": "reentry", "preset": "betts-max-crossrange", "params": {"grid": {"intervals": 50}},
                  "label": "coarser grid"}}
    out["warm start"] = {
        "summary": "Warm start from a succeeded job of the same kind",
        "description": "`initial_guess.from_job` names a succeeded reentry job you may read (else a 422).",
        "value": {"kind": "reentry", "preset": "betts-max-crossrange-heat-limited",
                  "params": {"path": {"max_heat_rate_w_m2": 600000.0},
                             "initial_guess": {"from_job": "0123456789abcdef0123456789abcdef"}}}}
    if "brachistochrone" in PRESETS:
        out["ocp: a whole problem"] = {
            "summary": "Your own optimal-control problem, written out (the ocp tutorial in the guide)",
            "value": {"kind": "ocp", "params": PRESETS["brachistochrone"].params}}
    return out
