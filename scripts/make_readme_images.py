"""Make the README's pictures (docs/img/*.png): one plot per kind from a real solve of its preset.

Run from anywhere: ``.venv/bin/python scripts/make_readme_images.py`` (about a minute; the robust case
dominates; ``--only reentry`` for one kind, ``--out DIR`` to write elsewhere, ``--help`` solves nothing).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:  # run as a file (python scripts/...), sys.path[0] is scripts/, not the repository
    sys.path.insert(0, str(ROOT))

OUT = ROOT / "docs" / "img"
# (kind, preset, overrides, plot): the picture that says most about each kind
CASES = [
    ("reentry", "betts-max-crossrange-heat-limited", {}, "heating"),
    ("robust_reentry", "robust-max-crossrange", {"monte_carlo": {"samples": 2000}}, "envelopes"),
    ("midcourse", "upper-stage-two-corrections", {}, "pareto_front"),
    ("intercept", "long-range-intercept", {"porkchop": {"enabled": True}}, "porkchop"),
]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=OUT, help=f"where the PNGs go (default {OUT.relative_to(ROOT)})")
    parser.add_argument("--only", action="append", metavar="KIND", choices=[c[0] for c in CASES],
                        help="make this kind's picture only (repeatable)")
    args = parser.parse_args(argv)
    # imported after the arguments are read: --help loads no solver and writes nothing
    from app.kinds import KINDS, PRESETS
    from app.service.params import resolve_params
    from app.results import plots
    from tests.support import RecordingContext

    args.out.mkdir(parents=True, exist_ok=True)
    for kind, name, overrides, plot_name in CASES:
        if args.only and kind not in args.only:
            continue
        preset = PRESETS[name]
        spec = KINDS[preset.kind]
        params = resolve_params(spec, preset.params, overrides)
        outcome = spec.run(spec.params_model.model_validate(params), RecordingContext())
        if outcome.status != "succeeded":
            print(f"{name}: {outcome.status} {outcome.error}", file=sys.stderr)
            return 1
        plot = next(p for p in plots.plots_for(preset.kind, outcome.result) if p.name == plot_name)
        png = plots.render(plot, result=outcome.result, params=params, title=name, fmt="png", dpi=70)
        (args.out / f"{preset.kind}.png").write_bytes(png)
        print(f"{args.out / preset.kind}.png: {plot.title} of {name} ({len(png) // 1024} kB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
