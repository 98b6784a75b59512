"""Terminal conditions that hold: the requested final values, met on the dense re-propagation.

The NLP pins the last node to the requested final state, but the last node is where the NLP's own
integrator (``substeps`` RK4 steps per interval) puts the flight; the dense re-propagation
(:func:`solvers.verification.propagate_dense`, 40 RK4 steps per interval) is where the controls
actually take it.  On coarse grids the two differ by more than guidance work tolerates: an
aero-table vehicle (Sutton-Graves, US 1976, rotating Earth) at 50 intervals and 2 substeps ended
9.1 m, 0.19 m/s and 0.062 deg away from its requested final altitude, speed and flight-path angle
(issue 25), while the verification said ``ok``.

The check and its remedy mirror the path limits' (:mod:`solvers.reentry.limits`):

1. each fixed terminal component is compared with the re-propagated final state, against a
   tolerance per quantity (:class:`TerminalTolerance`: 1 m, 0.01 m/s, 0.001 deg by default);
2. when a component misses, the NLP's integration error is what misses: RK4's global error
   falls as ``h^4``, so the substeps are raised by the factor the worst miss/tolerance ratio asks
   for (``(2 ratio)^(1/4)``, the 2 a safety factor), at least doubled, capped at
   :data:`MAX_SUBSTEPS`, and the problem is re-solved warm from the previous answer on the same
   grid (a new NLP structure, so one build per round);
3. after ``terminal_rounds`` rounds without success the solve fails as ``terminal_not_held``,
   the best answer (the smallest worst ratio) stored as the diagnostic, never ``ok``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from solvers.models.reentry_state import STATES

MAX_SUBSTEPS = 32


@dataclass(frozen=True)
class TerminalTolerance:
    """How far the re-propagated final state may be from a requested final value (SI)."""

    altitude_m: float = 1.0
    speed_mps: float = 0.01
    angle_rad: float = math.radians(1e-3)   # latitude, longitude, flight path, heading

    def of(self, component) -> float:
        if component.is_angle:
            return self.angle_rad
        return self.altitude_m if component.name == "altitude_m" else self.speed_mps


def terminal_checks(requested: np.ndarray, ver, tolerance: TerminalTolerance) -> dict[str, dict]:
    """Per fixed terminal component (solver name): requested and re-propagated final value, the
    miss, the tolerance, the verification's own error estimate there, and whether it held."""
    out = {}
    for i, c in enumerate(STATES):
        if np.isnan(requested[i]):
            continue
        reached = float(ver.x_final[i])
        miss = reached - float(requested[i])
        tol = tolerance.of(c)
        err = None if ver.error_estimate is None else float(ver.error_estimate[i])
        out[c.name] = {"requested": float(requested[i]), "reached": reached, "miss": miss,
                       "tolerance": tol, "error_estimate": err,
                       "held": bool(np.isfinite(miss) and abs(miss) <= tol)}
    return out


def worst_ratio(checks: dict[str, dict]) -> float:
    """The largest |miss| / tolerance over the components (0 when none is fixed)."""
    ratios = [abs(c["miss"]) / c["tolerance"] for c in checks.values()]
    return max(ratios, default=0.0) if all(map(math.isfinite, ratios)) else math.inf


def round_record(substeps: int, checks: dict[str, dict]) -> dict:
    """What ``details.terminal_rounds`` keeps of one solve: its substeps, each miss, the worst ratio."""
    return {"substeps": int(substeps), "miss": {n: c["miss"] for n, c in checks.items()},
            "worst_ratio": worst_ratio(checks)}


def next_substeps(substeps: int, ratio: float) -> int:
    """The substeps that should bring a miss of ``ratio`` tolerances inside it (RK4: error ~ h^4)."""
    factor = (2.0 * ratio) ** 0.25 if math.isfinite(ratio) else 2.0
    return min(MAX_SUBSTEPS, max(2 * substeps, math.ceil(substeps * factor)))


def summary(checks: dict[str, dict], rounds: list[dict]) -> str:
    """One sentence for the notes: held or not, each miss against its tolerance, the rounds."""
    held = all(c["held"] for c in checks.values())
    parts = []
    for name, c in checks.items():
        comp = next(s for s in STATES if s.name == name)
        f, unit = (180.0 / math.pi, "deg") if comp.is_angle else (1.0, comp.unit)
        parts.append(f"{comp.label} {c['miss'] * f:+.3g} {unit} (tolerance {c['tolerance'] * f:g})")
    n = len(rounds) - 1
    how = (f"after {n} refinement round{'s' if n != 1 else ''} (substeps "
           + " -> ".join(str(r["substeps"]) for r in rounds) + ")") if n else "with no refinement"
    verdict = "hold" if held else "do NOT hold"
    return (f"terminal conditions {verdict} on the dense re-propagation {how}; miss: "
            + ", ".join(parts))
