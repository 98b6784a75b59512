"""Compiles during the tutorials (issue 38 item 6): the tutorials' jobs on a fresh ``trajlab serve`` (an empty
data directory, so an empty JIT cache, its two worker pools), once with ``TRAJLAB_JIT=off`` (no compile: the
baseline of time to the answers) and once with the default ``background`` (the compile policy of
solvers/transcription/jit.py).

Run: ``python -m benchmarks.compiles`` (``--modes background`` for one; ``--abba``: each mode twice, off,
background, background, off, against a drifting load; ``--quick``: the robust tutorial with
2000 Monte Carlo samples, as its page suggests for a faster check).

The jobs are the tutorials' commands in page order, one at a time as a reader runs them (each waits for its
answer): reentry (the preset, then the 600 kW/m^2 limit warm-started from it), robust reentry (the preset, then
k_objective 2), midcourse (the preset, then 3 corrections), intercept (the preset, then a free final time),
ocp (the brachistochrone as the reader's own problem, the same as the preset, the lunar lander at accuracy
1e-6, the tutorial's failing fixed time 0.3 s) and the ocp tutorial's continuation study (7 points).

Compiles are measured by a ``cc`` on the service's ``PATH`` ahead of the system's: a shell shim that runs the
real compiler and logs its start, end and the CPU seconds of the compiler and everything it ran (cc1, as,
ld: bash's ``times`` of its waited-for children) to ``compiles.csv``; the largest number of compiles in flight
at once follows from the intervals.  Time to answer: submission to the stored final status, per job.
Figures go to ``benchmarks/results/latest.json`` under ``compiles``.
"""
from __future__ import annotations

import argparse
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import httpx

from benchmarks.results import write_results

ROOT = Path(__file__).resolve().parents[1]

SHIM = """#!/bin/bash
# benchmarks.compiles: the real compiler, timed (start, end, CPU s of it and its children)
start=$(date +%s.%N)
{real} "$@"
rc=$?
end=$(date +%s.%N)
t=$(mktemp)
times > "$t"      # in this shell (a pipeline's subshell would report its own children: none)
cpu=$(tail -1 "$t" | awk '{{ s = 0; for (i = 1; i <= NF; i++) {{ split($i, a, "m"); sub("s", "", a[2]); s += a[1] * 60 + a[2] }}; print s }}')
rm -f "$t"
echo "$start,$end,$cpu,$rc,$$" >> {log}
exit $rc
"""


def tutorial_jobs(quick: bool) -> list[tuple[str, dict]]:
    """``(name, submission)`` in page order; ``{ID_OF:name}`` in a value stands for that job's id."""
    brachistochrone = "brachistochrone"
    robust: dict = {"monte_carlo": {"samples": 2000}} if quick else {}
    return [
        ("reentry", {"kind": "reentry", "preset": "betts-max-crossrange-heat-limited"}),
        ("reentry-600kW", {"kind": "reentry", "preset": "betts-max-crossrange-heat-limited",
                           "params": {"path": {"max_heat_rate_w_m2": 600000},
                                      "initial_guess": {"from_job": "{ID_OF:reentry}"}}}),
        ("robust", {"kind": "robust_reentry", "preset": "robust-max-crossrange", "params": robust}),
        ("robust-k2", {"kind": "robust_reentry", "preset": "robust-max-crossrange",
                       "params": {**robust, "robust": {"k_objective": 2}}}),
        ("midcourse", {"kind": "midcourse", "preset": "upper-stage-two-corrections"}),
        ("midcourse-3", {"kind": "midcourse", "preset": "upper-stage-two-corrections", "params": {"corrections": 3}}),
        ("intercept", {"kind": "intercept", "preset": "long-range-intercept"}),
        ("intercept-free-tf", {"kind": "intercept", "preset": "long-range-intercept",
                               "params": {"free_final_time": True, "tf_bounds_s": [2000, 9000]}}),
        ("ocp-own", {"kind": "ocp", "params": "{PRESET_PARAMS:ocp:brachistochrone}"}),
        ("ocp-preset", {"kind": "ocp", "preset": brachistochrone}),
        ("ocp-lander", {"kind": "ocp", "preset": "lunar-lander-bang-bang", "params": {"accuracy": 1e-6}}),
        ("ocp-fixed-0.3s", {"kind": "ocp", "params": "{PRESET_PARAMS:ocp:brachistochrone}",
                            "set": {"time": {"final": 0.3, "final_lower": None, "final_upper": None,
                                             "final_guess": None}}}),
        ("ocp-study", {"study": {"kind": "ocp", "preset": brachistochrone, "mode": "continuation",
                                 "sweeps": [{"path": "states.1.final", "start": 2, "stop": 8, "count": 7}]}}),
    ]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _resolve(value, ids: dict, client: httpx.Client):
    if isinstance(value, dict):
        return {k: _resolve(v, ids, client) for k, v in value.items()}
    if isinstance(value, list):
        return [_resolve(v, ids, client) for v in value]
    if isinstance(value, str) and value.startswith("{ID_OF:"):
        return ids[value[len("{ID_OF:"):-1]]
    if isinstance(value, str) and value.startswith("{PRESET_PARAMS:"):
        kind, name = value[len("{PRESET_PARAMS:"):-1].split(":")
        presets = client.get("/v1/presets", params={"kind": kind}).json()
        items = presets["items"] if isinstance(presets, dict) else presets
        return next(p["params"] for p in items if p["name"] == name)
    return value


def _merge(base: dict, over: dict) -> dict:
    out = dict(base)
    for k, v in over.items():
        out[k] = _merge(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) else v
    return out


def run_tutorials(client: httpx.Client, jobs, *, timeout: float) -> list[dict]:
    ids: dict[str, str] = {}
    rows = []
    for name, spec in jobs:
        spec = _resolve(spec, ids, client)
        t0 = time.perf_counter()
        if "study" in spec:
            r = client.post("/v1/studies", json=spec["study"])
            path = "/v1/studies/{}"
        else:
            body = {k: v for k, v in spec.items() if k != "set"}
            if "set" in spec:
                body["params"] = _merge(body["params"], spec["set"])
            r = client.post("/v1/jobs", json=body)
            path = "/v1/jobs/{}"
        assert r.status_code in (200, 201, 202), f"{name}: {r.status_code} {r.text[:300]}"
        ids[name] = r.json()["id"]
        deadline = time.monotonic() + timeout
        while True:
            status = client.get(path.format(ids[name])).json()["status"]
            if status not in ("queued", "running", "pending"):
                break
            if time.monotonic() > deadline:
                status = "timeout"
                break
            time.sleep(0.25)
        rows.append({"job": name, "status": status, "seconds": round(time.perf_counter() - t0, 2)})
        print(f"  {name:<18} {status:<10} {rows[-1]['seconds']:8.1f} s", flush=True)
    return rows


def compile_figures(log: Path) -> dict:
    lines = [line.split(",") for line in log.read_text().splitlines()] if log.exists() else []
    spans = [(float(a), float(b), float(cpu), int(rc)) for a, b, cpu, rc, _ in lines]
    edges = sorted([(a, 1) for a, _, _, _ in spans] + [(b, -1) for _, b, _, _ in spans])
    most, now = 0, 0
    for _, step in edges:
        now += step
        most = max(most, now)
    return {"compiles": len(spans), "failed": sum(rc != 0 for *_, rc in spans),
            "cpu_s": round(sum(cpu for _, _, cpu, _ in spans), 1),
            "wall_s": round(sum(b - a for a, b, _, _ in spans), 1), "most_at_once": most}


def _compilers_in(directory: Path) -> list[int]:
    """Processes whose command line names ``directory`` (this run's compilers: cc, cc1, as, ld)."""
    out = []
    for entry in os.scandir("/proc"):
        if entry.name.isdigit():
            try:
                with open(f"/proc/{entry.name}/cmdline", "rb") as f:
                    if str(directory).encode() in f.read():
                        out.append(int(entry.name))
            except OSError:
                pass
    return [pid for pid in out if pid != os.getpid()]


def _compiling(records: Path) -> bool:
    """A compile started and not ended (others may wait for the lock behind it: they start when it ends)."""
    events = [line.split()[2] for line in records.read_text().splitlines()]
    return events.count("start") != events.count("end")


def run_mode(mode: str, *, quick: bool, timeout: float, compile_wait: float) -> dict:
    tmp = Path(tempfile.mkdtemp(prefix=f"trajlab-compiles-{mode}-"))
    data, bindir = tmp / "data", tmp / "bin"
    bindir.mkdir()
    real = shutil.which("cc") or shutil.which("gcc")
    log = tmp / "compiles.csv"
    (bindir / "cc").write_text(SHIM.format(real=real, log=log))
    (bindir / "cc").chmod(0o755)
    port = free_port()
    env = {k: v for k, v in os.environ.items() if not k.startswith("TRAJLAB_")}
    env.update({"TRAJLAB_DATA_DIR": str(data), "TRAJLAB_JIT": mode, "PATH": f"{bindir}:{env.get('PATH', '')}",
                "PYTHONPATH": str(ROOT)})
    serve = subprocess.Popen([sys.executable, "-m", "app.cli.commands", "serve", "--port", str(port)], cwd=ROOT,
                             env=env, stdout=open(tmp / "serve.log", "wb"), stderr=subprocess.STDOUT,
                             start_new_session=True)
    client = httpx.Client(base_url=f"http://127.0.0.1:{port}", timeout=30)
    try:
        t0 = time.monotonic()
        while True:
            try:
                if client.get("/healthz").status_code == 200:
                    break
            except httpx.HTTPError:
                pass
            if serve.poll() is not None or time.monotonic() - t0 > 120:
                raise RuntimeError(f"trajlab serve did not come up: {tmp / 'serve.log'}")
            time.sleep(0.5)
        time.sleep(5)                      # both pools ready before the first job
        print(f"TRAJLAB_JIT={mode} (service in {tmp})", flush=True)
        t_start = time.perf_counter()
        rows = run_tutorials(client, tutorial_jobs(quick), timeout=timeout)
        answers_s = time.perf_counter() - t_start
        # compiles the tutorials started and that outlive their jobs: let them end, and count them
        records = data / "jit" / "compiles.log"
        deadline = time.monotonic() + compile_wait
        while records.exists() and time.monotonic() < deadline and _compiling(records):
            time.sleep(1)
        total_s = time.perf_counter() - t_start
        unfinished = _compiling(records) if records.exists() else False
    finally:
        client.close()
        os.killpg(serve.pid, signal.SIGTERM)
        try:
            serve.wait(timeout=60)
        except subprocess.TimeoutExpired:
            os.killpg(serve.pid, signal.SIGKILL)
    # compilers run in sessions of their own (solvers.transcription.jit._low_priority): a compile still going
    # when the service stopped is ended here, before its directory is removed
    for pid in _compilers_in(tmp):
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    figures = compile_figures(log)
    figures.update({"answers_s": round(answers_s, 1), "until_compiles_done_s": round(total_s, 1),
                    "compile_cores": round(figures["cpu_s"] / total_s, 3), "jobs": rows,
                    "structures_seen": len(list((data / "jit").glob("nlp_*.seen"))),
                    "compiling_when_stopped": unfinished,
                    "libraries": len(list((data / "jit").glob("nlp_*.so")))})
    shutil.rmtree(tmp, ignore_errors=True)
    return figures


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--modes", default="off,background")
    ap.add_argument("--quick", action="store_true", help="the robust tutorial with 2000 Monte Carlo samples")
    ap.add_argument("--abba", action="store_true",
                    help="each mode twice, in the order off, background, background, off: on a machine whose "
                         "load drifts, each mode's mean then sees the same drift")
    ap.add_argument("--timeout", type=float, default=900, help="seconds per job")
    ap.add_argument("--compile-wait", type=float, default=300,
                    help="seconds to let compiles that outlive the tutorials finish before the service stops")
    args = ap.parse_args()
    modes = args.modes.split(",")
    runs: dict[str, list[dict]] = {m: [] for m in modes}
    for mode in modes + (modes[::-1] if args.abba else []):
        runs[mode].append(run_mode(mode, quick=args.quick, timeout=args.timeout, compile_wait=args.compile_wait))
    print(f"\n{'mode':<12}{'answers s':>10}{'compiles':>10}{'at once':>9}{'compile CPU s':>15}{'cores':>7}"
          f"{'libraries':>10}{'structures':>11}")
    for mode in modes:
        for f in runs[mode]:
            print(f"{mode:<12}{f['answers_s']:>10.1f}{f['compiles']:>10}{f['most_at_once']:>9}{f['cpu_s']:>15.1f}"
                  f"{f['compile_cores']:>7.3f}{f['libraries']:>10}{f['structures_seen']:>11}")
    out: dict = {"quick": args.quick, "abba": args.abba,
                 **{m: {"answers_s": round(sum(f["answers_s"] for f in r) / len(r), 1), "runs": r}
                    for m, r in runs.items()}}
    if "off" in runs and "background" in runs:
        print("\njob (mean of runs)       off s  background s   ratio")
        n_off, n_bg = len(runs["off"]), len(runs["background"])
        for i, row in enumerate(runs["off"][0]["jobs"]):
            a = sum(r["jobs"][i]["seconds"] for r in runs["off"]) / n_off
            b = sum(r["jobs"][i]["seconds"] for r in runs["background"]) / n_bg
            print(f"{row['job']:<20}{a:>9.1f}{b:>14.1f}{b / a:>8.2f}")
        out["answers_ratio"] = round(out["background"]["answers_s"] / out["off"]["answers_s"], 3)
        print(f"\nall answers: background / off = {out['answers_ratio']:.3f}")
    write_results("compiles", out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
