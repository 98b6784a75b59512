"""Where a job's wall time goes, stage by stage: the measurement behind the progress weights
(``solvers/<kind>/stages.py``; issue 38 item 4).

Runs presets through their kind's ``run`` (as a worker does, in this process), records the wall time
from each stage's announcement (:class:`solvers.progress.ProgressMessage`) to the next, and prints
each stage's share of the total, summed over the presets (a refinement or limit round counted under
its stage's name, whatever its number).  Usage::

    python -m benchmarks.progress_stages ocp       # or ocp-refined, ocp-robust, ocp-search, reentry
"""
from __future__ import annotations

import sys
import time
from collections import defaultdict

from app.kinds import KINDS, PRESETS
from app.kinds.base import InProcessContext
from app.service.params import resolve_params

# The presets measured, with the options that make them take the stages users meet: refinement to an
# accuracy from a coarse grid (ocp, as benchmarks/ocp_refine.py), the heating-limited reentry whose limit
# rounds run.
CASES = {
    "ocp": [("bryson-denham", {}), ("goddard-rocket", {}), ("hang-glider", {}), ("van-der-pol-state-limit", {})],
    "ocp-refined": [("brachistochrone", {"accuracy": 1e-6, "transcription": {"intervals": 4}}),
                    ("brachistochrone", {"accuracy": 1e-6, "transcription": {"method": "lgl", "intervals": 4}}),
                    ("betts-shuttle-ocp", {"accuracy": 1e-6, "transcription": {"intervals": 50}})],
    "ocp-robust": [("rocket-ascent-q-limit-robust", {}), ("orbit-raising-uncertain-thrust-robust", {})],
    "ocp-search": [("brachistochrone", {"search": {"starts": 4}}), ("hang-glider", {"search": {"starts": 3}})],
    "reentry": [("betts-max-crossrange", {}), ("betts-max-crossrange-heat-limited", {}),
                ("betts-max-crossrange", {"accuracy": 1e-4})],
}


class TimedContext(InProcessContext):
    """Records (time, stage) at every change of stage."""

    def __init__(self):
        super().__init__()
        self.marks: list[tuple[float, str]] = []

    def progress(self, fraction: float, message: str) -> None:
        super().progress(fraction, message)
        stage = getattr(message, "stage", None)
        if stage is not None and (not self.marks or self.marks[-1][1] != stage):
            self.marks.append((time.perf_counter(), stage))


def stage_key(stage: str) -> str:
    """The declared stage a reported one counts under: the innermost name, its round number dropped
    ("refinement round 2 / solve" -> "refinement")."""
    outer = stage.split(" / ")[0]
    return outer.split(" round ")[0]


def measure(case: str) -> dict[str, float]:
    spent: dict[str, float] = defaultdict(float)
    kind = case.split("-")[0]
    for name, overrides in CASES[case]:
        spec = KINDS[kind]
        params = resolve_params(spec, PRESETS[name].params, overrides or None)
        ctx = TimedContext()
        t0 = time.perf_counter()
        out = spec.run(spec.params_model.model_validate(params), ctx)
        end = time.perf_counter()
        marks = ctx.marks + [(end, "")]
        own: dict[str, float] = defaultdict(float)
        for (t, stage), (t_next, _) in zip(marks, marks[1:]):
            own[stage_key(stage)] += t_next - t
            spent[stage_key(stage)] += t_next - t
        print(f"{name} {overrides or ''}: {out.status}, {end - t0:.2f} s, stages "
              + ", ".join(f"{k} {v:.2f} s" for k, v in own.items()), flush=True)
    return spent


def main(kind: str) -> None:
    spent = measure(kind)
    total = sum(spent.values())
    print(f"\n{kind}: share of wall time per stage over {len(CASES[kind])} presets ({total:.1f} s)")
    for stage, s in spent.items():
        print(f"  {stage:<14} {s:8.2f} s  {100 * s / total:6.2f} %")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "ocp")
