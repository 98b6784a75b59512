"""The Monte Carlo of a robust ``ocp`` design as the result keeps it (``robust.monte_carlo``): the envelope
(mean and standard deviation over the draws, at the kept node times, of every state and of each named path
constraint's value) and the per-draw values of the objective and of each named boundary constraint (the
first :data:`solvers.uncertainty.montecarlo.MAX_TERMINAL_SAMPLES` draws), from the merged summary of
:func:`solvers.uncertainty.montecarlo.merge_chunks`.  The plots, the CSV tables and the study's Monte Carlo
columns read this block; CADET's figures stay in the rest of ``robust``."""
from __future__ import annotations

from app.kinds.base import json_value

STATE, PATH, BOUNDARY = "state:", "path:", "boundary:"   # the ocp Monte Carlo model's quantity prefixes


def monte_carlo_block(summary: dict) -> dict:
    """``{"envelope": {"t", "states": {name: {mean, std}}, "constraints": {name: {mean, std}}},
    "samples": {"objective": [...], "boundary": {name: [...]}}}`` (either part absent when the summary has
    none)."""
    out: dict = {}
    env = summary.get("envelope")
    if isinstance(env, dict) and env.get("t_s"):
        out["envelope"] = {
            "t": env["t_s"],
            "states": {q[len(STATE):]: v for q, v in env.items() if q.startswith(STATE)},
            "constraints": {q[len(PATH):]: v for q, v in env.items() if q.startswith(PATH)}}
    drawn = summary.get("terminal_samples") or {}
    if drawn.get("objective"):
        out["samples"] = {"objective": drawn["objective"],
                          "boundary": {q[len(BOUNDARY):]: v for q, v in drawn.items() if q.startswith(BOUNDARY)}}
    return json_value(out)
