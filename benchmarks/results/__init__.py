"""Benchmark figures as JSON (``benchmarks/results/latest.json``), so the next change can be compared with this one."""
from __future__ import annotations

import json
import platform
import time
from pathlib import Path

LATEST = Path(__file__).resolve().parent / "latest.json"


def write_results(name: str, figures: dict) -> None:
    """Merge one benchmark's figures into latest.json under ``name`` (other benchmarks' entries are kept)."""
    data = json.loads(LATEST.read_text()) if LATEST.exists() else {}
    data[name] = {"when": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()), "machine": platform.machine(),
                  "python": platform.python_version(), "figures": figures}
    LATEST.write_text(json.dumps(data, indent=1, sort_keys=True) + "\n")
