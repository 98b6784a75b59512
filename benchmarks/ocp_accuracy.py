"""``accuracy`` against uniform grids, measured against the published optimum (issue 35, "Done when").

For each preset with a published optimum (:data:`solvers.ocp.PRESETS`: ``optimum``) and each accuracy in
:data:`ACCURACIES`:

* **accuracy**: :func:`solvers.ocp.solve` on the preset as posed with ``accuracy`` set, cold (solver cache
  and symbolic functions cleared), everything counted: every round's build, IPOPT and re-flight and every
  round's check solve on the finer nested mesh.  Its objective error is ``|J - J*| / max(|J*|, 1)`` against
  the published ``J*``, floored at the optimum's own precision (half a unit of its last printed digit: a
  figure below that cannot be told from zero; :data:`ANALYTIC` optima are exact);
* **uniform**: the fewest equal intervals whose plain answer (no ``accuracy``) is within that same objective
  error (doubling from the preset's grid up to :data:`CAP`, then bisection; the probes are not timed), then
  that grid solved cold as a user who knew it would: build, IPOPT, re-flight and the check solve every
  answer gets now.  A bang-bang problem's error does not fall monotonically with N (where the switch falls
  inside an interval matters), so the bisection finds *a* small grid, not always the smallest.
The cold solve and the grid search are :mod:`benchmarks.ocp_refine`'s (:func:`~benchmarks.ocp_refine.cold`,
:func:`~benchmarks.ocp_refine.smallest_grid`).

Run ``python -m benchmarks.ocp_accuracy`` (``--only lunar-lander-bang-bang,bryson-denham``); the machine's
load average is printed beside the times (2 shared cores: compare the ratios, not the seconds).
"""
from __future__ import annotations

import argparse
import copy
import math
import os

from benchmarks.ocp_refine import cold, smallest_grid, solve_as_given
from solvers.ocp import PRESETS

ACCURACIES = (1e-4, 1e-6)
CAP = 960                       # uniform grids searched up to this many intervals
# bang-bang, smooth, state-constrained: the representative set run by default
# optima known in closed form whose printed value is exact (Bryson-Denham: 4 / (9 l), l = 1/9)
ANALYTIC = frozenset({"bryson-denham", "double-integrator-min-time"})
DEFAULT = ("lunar-lander-bang-bang", "scalar-lq-riccati", "bryson-denham")


def _params(name: str, intervals: int | None = None, accuracy: float | None = None) -> dict:
    params = copy.deepcopy(PRESETS[name]["params"])
    if intervals is not None:
        params["transcription"]["intervals"] = intervals
    if accuracy is not None:
        params["accuracy"] = accuracy
    return params


def precision(optimum: float, name: str = "") -> float:
    """Half a unit of the published optimum's last printed digit, relative to it (an analytic optimum
    printed short, such as Bryson-Denham's 4: double precision's)."""
    if name in ANALYTIC:
        return 1e-15
    text = repr(float(optimum))
    decimals = len(text.split(".")[1]) if "." in text and "e" not in text else 0
    return 0.5 * 10.0 ** -decimals / max(abs(optimum), 1.0)


def objective_error(name: str, value: float) -> float:
    optimum = float(PRESETS[name]["optimum"])
    return max(abs(value - optimum) / max(abs(optimum), 1.0), precision(optimum, name))


def smallest_uniform(name: str, target: float) -> tuple[int | None, int]:
    """``(N, probes)``: the fewest equal intervals found whose answer is within ``target`` (None past CAP)."""
    def ok(n: int) -> bool:
        sol = solve_as_given(_params(name, n))
        return sol.status.ok and objective_error(name, sol.objective) <= target

    return smallest_grid(ok, int(PRESETS[name]["params"]["transcription"].get("intervals", 50)), cap=CAP)


def rows(names=DEFAULT) -> dict:
    print(f"\nocp accuracy against the published optimum and the smallest uniform grid reaching the same "
          f"objective error; load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores (shared: compare "
          f"ratios)")
    print(f"{'preset':<24}{'accuracy':>9}{'form':>9}{'intervals':>10}{'obj error':>11}{'estimate':>10}"
          f"{'reached':>8}{'time s':>8}  mesh / search")
    figures: dict = {}
    for name in names:
        for acc in ACCURACIES:
            sol, t_acc = cold(_params(name, accuracy=acc))
            accuracy = sol.solver.get("accuracy") or {}
            err = objective_error(name, sol.objective)
            path = "->".join(str(r["intervals"]) for r in sol.solver.get("refinement") or [])
            print(f"{name:<24}{acc:>9.0e}{'accuracy':>9}{sol.solver['intervals']:>10}{err:>11.2e}"
                  f"{accuracy.get('objective_error_estimate') or float('nan'):>10.1e}"
                  f"{str(accuracy.get('reached')):>8}{t_acc:>8.2f}  {path}; J = {sol.objective:.10g}")
            n_uni, probes = smallest_uniform(name, err)
            row = {"accuracy": acc, "objective": sol.objective, "objective_error": err, "intervals": sol.solver["intervals"],
                   "time_s": t_acc, "reached": accuracy.get("reached"),
                   "objective_error_estimate": accuracy.get("objective_error_estimate"), "rounds": path,
                   "uniform": None}
            if n_uni is None:
                print(f"{'':<33}{'uniform':>9}{'>' + str(CAP):>10}{'':>11}{'':>10}{'':>8}{'':>8}  "
                      f"not within {err:.1e} up to {CAP} intervals ({probes} probes)")
            else:
                usol, t_uni = cold(_params(name, n_uni))
                uerr = objective_error(name, usol.objective)
                print(f"{'':<33}{'uniform':>9}{n_uni:>10}{uerr:>11.2e}{'':>10}{'':>8}{t_uni:>8.2f}  "
                      f"{probes} probes; accuracy / uniform time {t_acc / t_uni:.2f}x")
                row["uniform"] = {"intervals": n_uni, "objective_error": uerr, "time_s": t_uni, "probes": probes}
            figures[f"{name} {acc:g}"] = row
    return figures


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", default=",".join(DEFAULT), help="comma-separated preset names")
    args = ap.parse_args()
    names = [n for n in args.only.split(",") if n]
    unknown = [n for n in names if n not in PRESETS or not math.isfinite(float(PRESETS[n].get("optimum") or "nan"))]
    if unknown:
        raise SystemExit(f"no preset with a published optimum: {', '.join(unknown)}")
    rows(names)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
