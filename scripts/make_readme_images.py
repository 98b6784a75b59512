"""Make the README's pictures (docs/img/*.png): one plot per kind from a real solve of its preset.

Run from the repository root: ``python -m scripts.make_readme_images`` (about a minute; the robust case
dominates).
"""
from __future__ import annotations

from pathlib import Path

from app.kinds import KINDS, PRESETS
from app.api.params import resolve_params
from app.results import plots
from tests.support import RecordingContext

OUT = Path(__file__).resolve().parents[1] / "docs" / "img"
# (preset, overrides, plot): the picture that says most about each kind
CASES = [
    ("betts-max-crossrange-heat-limited", {}, "heating"),
    ("robust-max-crossrange", {"monte_carlo": {"samples": 2000}}, "envelopes"),
    ("upper-stage-two-corrections", {}, "pareto_front"),
    ("long-range-intercept", {"porkchop": {"enabled": True}}, "porkchop"),
]


def main() -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    for name, overrides, plot_name in CASES:
        preset = PRESETS[name]
        spec = KINDS[preset.kind]
        params = resolve_params(spec, preset.params, overrides)
        outcome = spec.run(spec.params_model.model_validate(params), RecordingContext())
        assert outcome.status == "succeeded", (name, outcome.error)
        plot = next(p for p in plots.plots_for(preset.kind, outcome.result) if p.name == plot_name)
        png = plots.render(plot, result=outcome.result, params=params, title=name, fmt="png", dpi=70)
        (OUT / f"{preset.kind}.png").write_bytes(png)
        print(f"docs/img/{preset.kind}.png: {plot.title} of {name} ({len(png) // 1024} kB)")


if __name__ == "__main__":
    main()
