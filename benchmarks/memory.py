"""Peak memory (RSS) of each job kind, against a bare ``python -c "import numpy, casadi"`` in the same run.

Run: ``python -m benchmarks.memory`` (``--kinds reentry,intercept`` for a subset).

Each kind's default preset (its first, ``KindSpec.presets[0]``) runs in a fresh Python process, the
way a worker's pool child runs it: the parameters resolved as the API resolves them
(``app.service.params.resolve_params``), validated by the kind's model, then the kind's ``run`` with a minimal
in-process job context (Monte Carlo in this process, as a worker does below its fan-out threshold).
The figure is the child's peak resident set from the kernel (``ru_maxrss`` of ``os.wait4`` on that
child, cross-checked by its own ``VmHWM``), together with the resident set after the imports alone
and the solve's status.  The baseline is the floor every solver process pays: a bare process that
imports numpy and CasADi, measured the same way in the same run.  Figures go to
``benchmarks/results/latest.json`` under ``memory``.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

from benchmarks.results import write_results

ROOT = Path(__file__).resolve().parents[1]
BASELINE_CODE = "import numpy, casadi"
RESULT = "RESULT "          # the prefix of the child's one line of figures


def own_mb(field: str = "VmHWM") -> float:
    """This process's own ``field`` of ``/proc/self/status`` in MB (``VmHWM``: its high-water mark; not
    ``ru_maxrss``, which a child forked from a large parent inherits), -1 where there is none."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith(field + ":"):
            return int(line.split()[1]) / 1024
    return -1.0


def child(kind: str, params_json: str | None = None) -> int:
    """Run ``kind``'s default preset (or the body ``params_json``) here and print one line: ``RESULT`` and
    its figures as JSON (the parent measures this process too)."""
    from app.kinds import KINDS
    from app.kinds.base import InProcessContext
    from app.service.params import resolve_params

    spec = KINDS[kind]
    preset = spec.presets[0]
    body = preset.params if params_json is None else json.loads(params_json)
    params = spec.params_model.model_validate(resolve_params(spec, body, None))
    ctx = InProcessContext()
    # the kind's solver modules are imported inside run; import them first to split imports from the solve
    import numpy  # noqa: F401
    import casadi  # noqa: F401

    after_imports_mb = own_mb("VmRSS")
    t0 = time.perf_counter()
    outcome = spec.run(params, ctx)
    seconds = time.perf_counter() - t0
    print(RESULT + json.dumps({"kind": kind, "preset": preset.name if params_json is None else None,
                               "status": outcome.status, "error": (outcome.error or {}).get("code"),
                               "seconds": seconds, "rss_after_imports_mb": after_imports_mb,
                               "vmhwm_mb": own_mb("VmHWM")}), flush=True)
    return 0


def result_line(stdout: str) -> dict:
    """The figures a :func:`child` printed."""
    return json.loads(next(line for line in stdout.splitlines() if line.startswith(RESULT)).removeprefix(RESULT))


def measure(cmd: list[str], timeout_s: float) -> tuple[float, str]:
    """Peak RSS (MB) of the process running ``cmd`` (the kernel's ru_maxrss for that child), and its stdout."""
    proc = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "PYTHONPATH": str(ROOT)})
    deadline = time.monotonic() + timeout_s
    while True:
        pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
        if pid:
            break
        if time.monotonic() > deadline:
            proc.kill()
            raise RuntimeError(f"{' '.join(cmd)} took longer than {timeout_s:.0f} s")
        time.sleep(0.05)
    out, err = proc.stdout.read(), proc.stderr.read()
    code = os.waitstatus_to_exitcode(status)
    if code != 0:
        raise RuntimeError(f"{' '.join(cmd)} exited with {code}: {err[-2000:]}")
    return usage.ru_maxrss / 1024, out  # Linux: kilobytes


def main() -> int:
    from app.kinds import KINDS

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--kinds", default=",".join(KINDS), help="comma-separated kinds (default: all)")
    ap.add_argument("--timeout", type=float, default=1800, help="seconds per kind")
    ap.add_argument("--child", help=argparse.SUPPRESS)
    ap.add_argument("--params", help=argparse.SUPPRESS)       # with --child: this body, not the preset
    args = ap.parse_args()
    if args.child:
        return child(args.child, args.params)
    base_mb = min(measure([sys.executable, "-c", BASELINE_CODE], 120)[0] for _ in range(3))
    figures: dict = {"baseline": {"what": f'python -c "{BASELINE_CODE}"', "peak_rss_mb": base_mb}, "kinds": {}}
    print(f"\n{'kind':<16}{'preset':<30}{'status':<11}{'solve s':>9}{'after imports MB':>18}{'peak RSS MB':>13}"
          f"{'vs baseline':>13}")
    print(f"{'(baseline)':<16}{'import numpy, casadi':<30}{'':<11}{'':>9}{'':>18}{base_mb:>13.0f}{1.0:>13.2f}")
    for kind in args.kinds.split(","):
        peak_mb, out = measure([sys.executable, "-m", "benchmarks.memory", "--child", kind], args.timeout)
        r = result_line(out)
        r.update(peak_rss_mb=peak_mb, ratio_to_baseline=peak_mb / base_mb)
        figures["kinds"][kind] = r
        print(f"{kind:<16}{r['preset']:<30}{r['status']:<11}{r['seconds']:>9.2f}{r['rss_after_imports_mb']:>18.0f}"
              f"{peak_mb:>13.0f}{peak_mb / base_mb:>13.2f}", flush=True)
    write_results("memory", figures)
    return 0


if __name__ == "__main__":
    sys.exit(main())
