"""``make bench``: every benchmark, one after another, each in its own process; a failure does not stop the rest.

Run: ``python -m benchmarks.run_all`` (``--only lambert,memory`` for a subset, ``--timeout`` per benchmark).

Each benchmark writes its own entry of ``benchmarks/results/latest.json`` (``write_results`` merges by
name), so one that fails or hangs (killed at ``--timeout``) leaves the others' fresh figures in place.
Its own entry is then the previous run's: the closing table says, for every benchmark, its exit status,
its time and which entries of latest.json it wrote in this run, and the exit status is non-zero if any
failed, naming them.  Last, the docs' tables of figures are rendered from the new latest.json
(:mod:`benchmarks.results.tables`, as ``scripts/docs_numbers.py --tables`` does).
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

from benchmarks.results import LATEST
from benchmarks.results.tables import write_tables

ROOT = Path(__file__).resolve().parents[1]
# the order: quick ones first; the service benchmarks (their own servers and workers) last
BENCHMARKS = ("lambert", "reentry", "midcourse", "intercept", "robust", "ocp", "ocp_robust", "memory",
              "api_load", "studies")


def _stamps() -> dict[str, str]:
    try:
        return {name: entry.get("when", "") for name, entry in json.loads(LATEST.read_text()).items()}
    except (OSError, ValueError):
        return {}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--only", help="comma-separated benchmark modules (default: all)")
    ap.add_argument("--timeout", type=float, default=3600, help="seconds per benchmark before it is killed")
    args = ap.parse_args()
    names = args.only.split(",") if args.only else list(BENCHMARKS)
    rows = []
    for name in names:
        print(f"\n==== benchmarks.{name}", flush=True)
        before = _stamps()
        t0 = time.monotonic()
        try:
            code = subprocess.run([sys.executable, "-m", f"benchmarks.{name}"], cwd=ROOT, timeout=args.timeout).returncode
        except subprocess.TimeoutExpired:
            code = "timeout"
        after = _stamps()
        wrote = sorted(k for k, v in after.items() if before.get(k) != v)
        rows.append((name, code, time.monotonic() - t0, wrote))
    print(f"\n{'benchmark':<12}{'exit':>8}{'seconds':>10}  entries written to {LATEST.name}")
    for name, code, seconds, wrote in rows:
        print(f"{name:<12}{code!s:>8}{seconds:>10.0f}  {', '.join(wrote) or '(none: its entry, if any, is older)'}")
    for page in write_tables():
        print(f"{page}: tables rewritten from {LATEST.name}")
    failed = [name for name, code, _, _ in rows if code != 0]
    if failed:
        print(f"\nmake bench: {len(failed)} failed: {', '.join(failed)}; the others' figures are fresh", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
