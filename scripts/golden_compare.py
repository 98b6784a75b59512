"""Golden check for refactors that must not change results: record every preset of some kinds, compare later.

``record`` runs each preset's ``run`` in this process (``tests.support.RecordingContext``, parameters
resolved as the API does) and stores ``{status, result, error}`` as ``<dir>/<kind>__<preset>.json``;
``compare`` runs them again and compares with the stored files: numbers equal to ``--rtol`` (relative),
strings and structure exactly, except that a stored ``0.0`` may now be ``null`` (the old NaN policy) and
keys that are new are reported as additions, not differences.  Timing fields vary run to run and are
skipped.  Results of earlier presets of a kind are kept in the context's store under the preset name, so
a later preset (or an ``EXTRA`` case) can warm-start ``from_job`` an earlier one.

    python scripts/golden_compare.py record  --kinds reentry robust_reentry --dir /tmp/golden_before
    python scripts/golden_compare.py compare --kinds reentry robust_reentry --dir /tmp/golden_before
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

# Keys whose values are wall-clock measurements or cache state, not results.
SKIPPED_KEYS = {"solve_time_s", "build_time_s", "time_s", "verification_time_s", "cached_build",
                "solver_cached", "wall_time_s", "elapsed_s", "check_time_s"}

# Extra cases per kind: (case name, preset to start from, overrides). Warm starts name an earlier case.
EXTRA = {
    "reentry": [("heat-limited-warm-start", "betts-max-crossrange-heat-limited",
                 {"initial_guess": {"from_job": "betts-max-crossrange"}})],
    # The ocp phase model (issue 34 item 2): refinement, LGL, warm starts and limit rounds, one and several phases.
    "ocp": [("brachistochrone-lgl-accuracy", "brachistochrone",
             {"transcription": {"method": "lgl", "intervals": 8, "nodes": 4}, "accuracy": 1e-6}),
            ("brachistochrone-ms-accuracy", "brachistochrone", {"transcription": {"intervals": 10}, "accuracy": 1e-7}),
            ("brachistochrone-warm", "brachistochrone",
             {"transcription": {"intervals": 80}, "guess": {"from_job": "brachistochrone"}}),
            ("bryson-denham-lgl", "bryson-denham",
             {"transcription": {"method": "lgl", "intervals": 20, "nodes": 5}}),
            ("lander-accuracy", "lunar-lander-coast-burn", {"accuracy": 1e-6}),
            ("goddard-three-phases-accuracy", "goddard-three-phases", {"accuracy": 1e-9, "accuracy_required": False}),
            ("two-stage-warm", "two-stage-ascent", {"guess": {"from_job": "two-stage-ascent"}})],
}


def _cases(kind: str):
    from app.kinds import KINDS

    spec = KINDS[kind]
    presets = {p.name: p.params for p in spec.presets}
    for name, params in presets.items():
        yield spec, name, params, None
    for name, base, overrides in EXTRA.get(kind, []):
        yield spec, name, presets[base], overrides


def _run_case(spec, params: dict, overrides: dict | None, ctx) -> dict:
    from app.kinds.base import JobFailure
    from app.service.params import resolve_params

    resolved = resolve_params(spec, params, overrides)
    try:
        out = spec.run(spec.params_model.model_validate(resolved), ctx)
    except JobFailure as exc:
        return {"status": "failed", "result": None, "error": {"code": exc.code, "message": exc.message}}
    return record_of(out)


def record_of(out) -> dict:
    """The record of a run's outcome: the stored JSON, as the service would store it."""
    return json.loads(json.dumps({"status": out.status, "result": out.result, "error": out.error},
                                 default=float))


def _run_kind(kind: str, only: set[str] | None):
    from tests.support import RecordingContext

    ctx = RecordingContext()
    for spec, name, params, overrides in _cases(kind):
        if only and name not in only:
            continue
        t0 = time.perf_counter()
        record = _run_case(spec, params, overrides, ctx)
        if record["status"] == "succeeded":
            ctx.stored[name] = record["result"]
        print(f"{kind}/{name}: {record['status']} in {time.perf_counter() - t0:.1f} s", flush=True)
        yield name, record


def _compare(old, new, path: str, out: dict) -> None:
    """Walk both values; count numbers, note the largest relative difference, list the rest."""
    if isinstance(old, dict) and isinstance(new, dict):
        for key in old:
            if key in SKIPPED_KEYS:
                continue
            if key not in new:
                out["missing"].append(f"{path}.{key}")
            else:
                _compare(old[key], new[key], f"{path}.{key}", out)
        out["added"].extend(f"{path}.{k}" for k in new if k not in old)
        return
    if isinstance(old, list) and isinstance(new, list):
        if len(old) != len(new):
            out["differences"].append(f"{path}: length {len(old)} -> {len(new)}")
            return
        for i, (a, b) in enumerate(zip(old, new)):
            _compare(a, b, f"{path}[{i}]", out)
        return
    numeric = (int, float)
    if isinstance(old, numeric) and not isinstance(old, bool) and new is None:
        (out["nan_to_null"] if old == 0.0 else out["differences"]).append(f"{path}: {old} -> null")
        return
    if (isinstance(old, numeric) and isinstance(new, numeric)
            and not isinstance(old, bool) and not isinstance(new, bool)):
        out["numbers"] += 1
        rel = abs(old - new) / max(abs(old), abs(new)) if old != new else 0.0
        if rel > out["max_rel"]:
            out["max_rel"], out["max_rel_at"] = rel, path
        if not rel <= out["rtol"] and not (math.isnan(old) and math.isnan(new)):
            out["differences"].append(f"{path}: {old!r} -> {new!r} (rel {rel:.3g})")
        return
    if old != new:
        out["differences"].append(f"{path}: {old!r} -> {new!r}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("mode", choices=("record", "compare"))
    ap.add_argument("--kinds", nargs="+", required=True)
    ap.add_argument("--dir", type=Path, required=True)
    ap.add_argument("--only", nargs="*", help="case names to run (default: all)")
    ap.add_argument("--rtol", type=float, default=1e-9)
    args = ap.parse_args(argv)
    args.dir.mkdir(parents=True, exist_ok=True)
    only = set(args.only) if args.only else None
    failed = False
    for kind in args.kinds:
        for name, record in _run_kind(kind, only):
            path = args.dir / f"{kind}__{name}.json"
            if args.mode == "record":
                path.write_text(json.dumps(record, indent=1))
                continue
            out = {"numbers": 0, "max_rel": 0.0, "max_rel_at": "", "rtol": args.rtol, "differences": [],
                   "missing": [], "added": [], "nan_to_null": []}
            _compare(json.loads(path.read_text()), record, "", out)
            bad = out["differences"] or out["missing"]
            failed |= bool(bad)
            print(f"  {'DIFFERENT' if bad else 'equal'}: {out['numbers']} numbers, max rel diff "
                  f"{out['max_rel']:.3g} at {out['max_rel_at'] or '-'}; {len(out['nan_to_null'])} 0.0 -> null; "
                  f"added {sorted(set(a.split('[')[0] for a in out['added']))}")
            for line in (out["differences"] + [f"missing {m}" for m in out["missing"]])[:20]:
                print("   ", line)
            for line in out["nan_to_null"][:5]:
                print("    null:", line)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
