"""Peak memory and cold wall time of one job kind's default preset in a fresh process, for the
intercept and midcourse benchmark tables.

The figure is the child's own high-water mark (``VmHWM`` from ``/proc/self/status``, printed by
``python -m benchmarks.memory --child KIND``), and the baseline the same mark of a bare
``python -c "import numpy, casadi"``.  Not the kernel's ``ru_maxrss`` of the child: for a child
forked from a large parent (a benchmark that has already built its solvers) it counts the
parent's pages before the exec, so a bare import measured from a 270 MB parent read 270 MB
(its own high-water mark is about 37 MB).
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

from benchmarks.memory import BASELINE_CODE, result_line

ROOT = Path(__file__).resolve().parents[1]
_HWM = "; print([l for l in open('/proc/self/status') if l.startswith('VmHWM')][0].split()[1])"


def _run(cmd: list[str], timeout_s: float, env: dict | None = None) -> str:
    out = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=timeout_s, check=True,
                         env={**os.environ, "PYTHONPATH": str(ROOT), **(env or {})})
    return out.stdout


def child_figures(kind: str, params: dict | None = None, timeout_s: float = 1800, *, env: dict | None = None) -> dict:
    """The figures of :func:`benchmarks.memory.child` run in a fresh process (``env`` added to its
    environment): ``kind``'s default preset, or the body ``params`` (``status``, ``error``, ``seconds``,
    ``vmhwm_mb``, ...)."""
    extra = [] if params is None else ["--params", json.dumps(params)]
    return result_line(_run([sys.executable, "-m", "benchmarks.memory", "--child", kind, *extra], timeout_s, env))


def job_figures(kind: str, timeout_s: float = 1800) -> dict:
    """``job_cold_s``, ``job_peak_rss_mb`` (VmHWM) of ``kind``'s default preset in a fresh process,
    ``baseline_peak_rss_mb`` of a bare import (best of 3), their ratio and the job's status."""
    base_mb = min(int(_run([sys.executable, "-c", BASELINE_CODE + _HWM], 120).split()[-1]) for _ in range(3)) / 1024
    r = child_figures(kind, timeout_s=timeout_s)
    return {"job_preset": r["preset"], "job_status": r["status"], "job_cold_s": r["seconds"],
            "job_peak_rss_mb": r["vmhwm_mb"], "baseline": BASELINE_CODE, "baseline_peak_rss_mb": base_mb,
            "job_rss_ratio": r["vmhwm_mb"] / base_mb, "rss_measure": "VmHWM of the process itself"}
