"""Peak memory of ``ocp`` jobs against their estimate (issue 36 item 1): wide, long and multi-phase
problems, each run in a fresh process the way a worker's pool child runs it.

Run: ``python -m benchmarks.ocp_memory`` (``--cases wide,three-phase`` for a subset).

Each case is a linear-quadratic problem of the width and length asked (``n`` states, ``m`` controls,
``x_i' = -x_i/2 + u_(i mod m)``, ``integral of sum x^2 + sum u^2`` on a fixed horizon): IPOPT solves it in a
few iterations, so the figure is what the job builds (the NLP, its derivatives, the solver's factors,
the check solve on the finer mesh), not how long it searches.  The peak is the child's own high-water
mark (``VmHWM``, measured by :mod:`benchmarks.memory`'s child as every kind's is); the estimate is :func:`app.service.job_memory.measured_mb` (without the margin).
Figures go to ``benchmarks/results/latest.json`` under ``ocp_memory``, and their table to README.md
between ``<!-- bench: ocp_memory -->`` and ``<!-- /bench -->`` (rendered by
:func:`benchmarks.results.tables.ocp_memory`; ``--readme-only``, or ``scripts/docs_numbers.py --tables``,
rewrites it from latest.json without measuring).
"""
from __future__ import annotations

import argparse
import sys

from benchmarks.job_memory import ROOT, child_figures


def lq_phase(n: int, m: int, intervals: int, *, name: str | None = None, method: str = "multiple_shooting",
             nodes: int = 4) -> dict:
    """One phase (or a whole single-phase problem) of ``n`` states and ``m`` controls."""
    states = [{"name": f"x{i}", "initial": 1.0} for i in range(n)]
    controls = [{"name": f"u{j}", "lower": -10.0, "upper": 10.0} for j in range(m)]
    tr: dict = {"method": method, "intervals": intervals}
    if method == "lgl":
        tr["nodes"] = nodes
    out = {"states": states, "controls": controls, "time": {"initial": 0.0, "final": 1.0},
           "dynamics": {f"x{i}": f"-0.5*x{i} + u{i % m}" for i in range(n)}, "transcription": tr}
    if name:
        out["name"] = name
    return out


def _integrand(n: int, m: int) -> str:
    return " + ".join([f"x{i}**2" for i in range(n)] + [f"u{j}**2" for j in range(m)])


def single(n: int, m: int, intervals: int, **kw) -> dict:
    return {**lq_phase(n, m, intervals, **kw), "objective": {"sense": "minimize", "integrand": _integrand(n, m)}}


def phased(k: int, n: int, m: int, intervals: int) -> dict:
    """``k`` phases one after the other, each ``lq_phase`` on [i, i+1], states continuous across them."""
    phases = []
    for i in range(k):
        ph = lq_phase(n, m, intervals, name=f"p{i}")
        ph["time"] = {"initial": float(i), "final": float(i + 1)}
        if i:
            ph["states"] = [{"name": s["name"]} for s in ph["states"]]
        phases.append(ph)
    return {"phases": phases, "objective": {"sense": "minimize", "integrand": _integrand(n, m)}}


def robust_two_phase(intervals: int) -> dict:
    """A robust design of two phases (tests/unit/test_ocp_robust_phases.py's twin pair on ``intervals``
    per phase): x'' = u + w, y' = -y + b, w and b uncertain and x(0), v(0) too (4 uncertain quantities), the speed limit
    held at mean + 2 sigma, 2000 Monte Carlo draws."""
    dyn = {"x": "v", "v": "u + w", "y": "-y + b"}
    u = {"name": "u", "lower": -20.0, "upper": 20.0}
    v_max = {"name": "v_max", "expr": "v", "upper": 1.6}
    tr = {"method": "multiple_shooting", "intervals": intervals, "control": "constant", "substeps": 2}
    first = [{"name": "x", "initial": 0.0, "scale": 1.0}, {"name": "v", "initial": 0.0, "scale": 1.0},
             {"name": "y", "initial": 0.0, "scale": 1.0}]
    last = [{"name": "x", "final": 1.0, "scale": 1.0}, {"name": "v", "final": 0.0, "scale": 1.0},
            {"name": "y", "scale": 1.0}]
    return {"constants": {"b": 1.0, "w": 0.0},
            "phases": [{"name": name, "states": states, "controls": [u], "time": {"initial": t0, "final": t0 + 0.5},
                        "dynamics": dyn, "path": [v_max], "transcription": dict(tr)}
                       for name, states, t0 in (("a", first, 0.0), ("b", last, 0.5))],
            "objective": {"sense": "minimize", "expr": 'final(y, "b")', "integrand": "u**2"},
            "uncertainty": {"parameters": {"w": {"distribution": "normal", "sigma": 0.2},
                                           "b": {"distribution": "normal", "sigma": 0.2}},
                            "initial": {"x": {"sigma": 0.1}, "v": {"sigma": 0.05}}},
            "robust": {"k": 2.0, "constraints": ["v_max"], "monte_carlo": {"samples": 2000, "rounds": 2}}}


def preset(name: str) -> dict:
    from app.kinds import PRESETS
    return PRESETS[name].params


def on_intervals(body: dict, intervals: int) -> dict:
    """``body`` (one phase) on ``intervals`` intervals."""
    return {**body, "transcription": {**body["transcription"], "intervals": intervals}}


def lgl(body: dict, *, nodes: int) -> dict:
    """Every phase of ``body`` on LGL collocation of ``nodes`` nodes per interval."""
    return {**body, "phases": [{**ph, "transcription": {"method": "lgl", "intervals": ph["transcription"]["intervals"],
                                                        "nodes": nodes}} for ph in body["phases"]]}


# What each case is, for the README's table.
SIZES = {
    "narrow-long": "4 states, 2 controls, 1,000 intervals",
    "wide": "30 states, 10 controls, 200 intervals",
    "wider": "50 states, 20 controls, 150 intervals",
    "wide-lgl": "20 states, 8 controls, 150 LGL intervals of 5 nodes",
    "three-phase": "3 phases of 6 states, 2 controls, 400 intervals",
    "three-phase-wide": "3 phases of 20 states, 8 controls, 100 intervals",
    "piecewise-long": "the tumor-antiangiogenesis preset (3 states, 1 piecewise-constant control) on 800 intervals",
    "two-phase-lgl": "2 phases of 10 states, 3 controls, 100 LGL intervals of 4 nodes",
    "robust-shuttle": "the betts-shuttle-robust-ocp preset (6 states, 2 controls, 2 uncertain quantities, 100 intervals, 10,000 Monte Carlo draws)",
    "robust-two-phase": "robust, 2 phases of 3 states, 1 control, 4 uncertain quantities, 100 intervals each",
}

CASES = {
    "narrow-long": lambda: single(4, 2, 1000),
    "wide": lambda: single(30, 10, 200),
    "wider": lambda: single(50, 20, 150),
    "wide-lgl": lambda: single(20, 8, 150, method="lgl", nodes=5),
    "three-phase": lambda: phased(3, 6, 2, 400),
    "three-phase-wide": lambda: phased(3, 20, 8, 100),
    "piecewise-long": lambda: on_intervals(preset("tumor-antiangiogenesis"), 800),
    "two-phase-lgl": lambda: lgl(phased(2, 10, 3, 100), nodes=4),
    "robust-shuttle": lambda: preset("betts-shuttle-robust-ocp"),
    "robust-two-phase": lambda: robust_two_phase(100),
}


def measure(params: dict, timeout_s: float = 900) -> dict:
    """Run the ``ocp`` body ``params`` in a fresh process, as a pool child would: ``{status, error, peak_mb}``
    (:func:`benchmarks.job_memory.child_figures`: its own high-water mark)."""
    # the widest integrands (70 squares) pass the default 400 parse-tree nodes
    r = child_figures("ocp", params, timeout_s, env={"TRAJLAB_OCP_MAX_EXPRESSION_NODES": "2000"})
    return {"status": r["status"], "error": r["error"], "peak_mb": r["vmhwm_mb"]}


README = ROOT / "README.md"


def write_readme() -> None:
    """README's table from latest.json (its renderer reads ``SIZES`` above for each case's problem)."""
    from benchmarks.results.tables import write_tables
    write_tables([README])


def reestimate(name: str, bodies: dict[str, dict]) -> None:
    """latest.json's entry ``name``: each recorded peak against the memory model as it is now (the peaks and
    their date kept, ``estimated`` the date of the new estimates), after a change of the model alone."""
    import json
    import time

    from app.service.job_memory import measured_mb
    from benchmarks.results import LATEST
    data = json.loads(LATEST.read_text())
    for case, f in data[name]["figures"].items():
        if case in bodies:
            f["estimate_mb"] = measured_mb("ocp", bodies[case]) or 0.0
            f["ratio"] = f["estimate_mb"] / f["peak_mb"]
    data[name]["estimated"] = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
    LATEST.write_text(json.dumps(data, indent=1, sort_keys=True) + "\n")


def measure_all(bodies: dict[str, dict], label: str, width: int) -> dict[str, dict]:
    """Each body's peak (:func:`measure`, one fresh process each, one after another) beside its estimate,
    printed as it comes: ``{name: {status, error, peak_mb, estimate_mb, ratio}}``."""
    from app.service.job_memory import measured_mb

    figures = {}
    print(f"{label:<{width}}{'status':<11}{'estimate MB':>13}{'peak MB':>10}{'ratio':>8}")
    for name, params in bodies.items():
        est = measured_mb("ocp", params) or 0.0
        r = measure(params)
        r.update(estimate_mb=est, ratio=est / r["peak_mb"])
        figures[name] = r
        print(f"{name:<{width}}{r['status']:<11}{est:>13.0f}{r['peak_mb']:>10.0f}{r['ratio']:>8.2f}", flush=True)
    return figures


def command(entry: str, bodies: dict[str, dict], label: str, width: int, doc: str) -> int:
    """The command line of both ocp memory benchmarks: measure the ``--<label>s`` named (default: every one of
    ``bodies``) into latest.json's ``entry``, or only recompute its estimates (``--estimates-only``), then
    rewrite the README's tables (all that ``--readme-only`` does)."""
    ap = argparse.ArgumentParser(description=doc.split("\n")[0])
    ap.add_argument(f"--{label}s", default="", help=f"comma-separated names (default: every {label})")
    ap.add_argument("--readme-only", action="store_true", help="rewrite README's table from latest.json only")
    ap.add_argument("--estimates-only", action="store_true",
                    help="recompute the estimates of latest.json's peaks with the model as it is now, no measuring")
    args = ap.parse_args()
    if args.estimates_only:
        reestimate(entry, bodies)
    elif not args.readme_only:
        from benchmarks.results import write_results
        picked = getattr(args, f"{label}s")
        names = picked.split(",") if picked else list(bodies)
        write_results(entry, measure_all({name: bodies[name] for name in names}, label, width))
    write_readme()
    return 0


def main() -> int:
    return command("ocp_memory", {name: make() for name, make in CASES.items()}, "case", 20, __doc__ or "")


if __name__ == "__main__":
    sys.exit(main())
