"""Does the Monte Carlo confirm a robust design?  Targets, the comparison, and the correction.

The robust design (:mod:`solvers.robust_reentry`) promises what first-order CADET predicts:
``mu(q) + kC sigma(q) <= q_max`` at every RK4 point, and terminal sigmas below their limits.
Its Monte Carlo (:mod:`solvers.uncertainty.montecarlo`) measures what the open-loop controls
really give.  This module turns one Monte Carlo summary into a round record (promised vs
measured for each constraint and the objective), decides whether the Monte Carlo agrees, and
if not, how the next solve is corrected:

* **Heating limit**: target ``P(q(t) <= q_max over the whole flight)``; default ``Phi(kC)``
  (one-sided normal share of kC sigma: 99.865% at kC = 3).  Judged on the Monte Carlo's fine grid
  (every RK4 step, ``kept_fraction``), not at the nodes: a sample that crosses the limit between
  nodes has not kept it.  A per-instant bound ``mu + kC sigma <= q_max`` promises ``Phi(kC)`` at
  each instant, which is more than the whole flight keeps (the union over time is larger), so the
  measured share can fall short.  Sampling tolerance: with ``n`` samples the kept share of a design
  whose true share is the target has standard error ``sqrt(p (1 - p) / n)`` (binomial); the
  Monte Carlo disagrees when the share is below ``target - z sqrt(p (1 - p) / n)`` with
  ``z = Phi^-1(confidence)`` (99%: z = 2.326; at n = 10,000 and 99.865% that is 0.085 points), i.e.
  when the shortfall is significant at that confidence.  Correction: kC is raised by the gap in
  normal quantiles ``Phi^-1(target) - Phi^-1(measured)`` plus ``K_OVERSHOOT`` (so the next round
  does not land on the edge of the tolerance).
* **Terminal sigma limits** (h_f, v_f, gamma_f): the Monte Carlo's standard deviation against the
  limit, no tolerance (its standard error, ``1/sqrt(2 (n - 1))`` relative, 0.7% at 10,000, is
  reported).  Correction: the limit the NLP sees becomes ``limit * sigma_CADET / sigma_MC`` (times
  ``SIGMA_SAFETY``), i.e. tightened by the ratio by which CADET underestimates the spread; when
  that ratio exceeds ``MAX_SIGMA_RATIO`` the loop stops (the linearization does not hold there).
* **Objective** ``mu(lat_f) - kJ sigma(lat_f)``: promised (first-order CADET) and measured are
  reported side by side; it is not a constraint and does not decide the round.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from solvers.robust_reentry.mc import TERMINAL_INDEX
from solvers.uncertainty.confirm import K_OVERSHOOT as K_OVERSHOOT   # the rule (its tests read it here)
from solvers.uncertainty.confirm import kept_enough, normal_share, quantile, raised_k, sampling_tolerance

SIGMA_SAFETY = 0.99      # tightened sigma limits aim 1% below the limit
MAX_SIGMA_RATIO = 3.0    # Monte Carlo sigma over CADET's beyond which the linearization is not trusted


@dataclass
class LoopSettings:
    max_rounds: int = 3
    confidence: float = 0.99
    heat_target: float | None = None        # None: Phi(kC) of the user's kC
    sigma_names: tuple = tuple(TERMINAL_INDEX)


@dataclass
class Correction:
    """What the next round's NLP uses."""

    k_constraint: float
    sigma_limits: dict = field(default_factory=dict)   # SI limits the NLP sees


def assess(*, summary: dict, prediction, objective_promised: float, k_objective: float,
           k_constraint_user: float, correction: Correction, sigma_limits_user: dict,
           settings: LoopSettings) -> dict:
    """A round record (SI, radians) and whether the Monte Carlo agrees (``record["agrees"]``)."""
    n = int(summary["samples"])
    constraints: dict = {}
    heat = summary["path"].get("heat_rate")
    if heat is not None:
        target = settings.heat_target if settings.heat_target is not None else normal_share(k_constraint_user)
        tol = sampling_tolerance(target, n, settings.confidence)
        k_eff = min((heat["limit"] - mu) / sd if sd > 0 else math.inf
                    for mu, sd in zip(prediction.heat_mean, prediction.heat_sigma))
        kept = float(heat["kept_fraction"])
        constraints["heat_rate"] = {
            "target": target, "acceptance": target - tol, "tolerance": tol,
            "promised": normal_share(k_eff) if math.isfinite(k_eff) else 1.0,
            "monte_carlo": kept, "monte_carlo_nodes": float(heat["kept_fraction_nodes"]),
            "k_constraint": correction.k_constraint,
            "agrees": kept_enough(kept, target, n, settings.confidence)}
    se = 1.0 / math.sqrt(2.0 * max(n - 1, 1))
    for name in settings.sigma_names:
        lim = sigma_limits_user.get(name)
        if lim is None:
            continue
        i = TERMINAL_INDEX[name]
        mc_sd = float(summary["terminal"][name]["std"])
        constraints[f"sigma_{name}"] = {
            "limit": float(lim), "limit_in_nlp": float(correction.sigma_limits.get(name, lim)),
            "promised": float(prediction.sigma[i, -1]), "monte_carlo": mc_sd,
            "monte_carlo_relative_standard_error": se, "agrees": mc_sd <= float(lim)}
    lat = summary["terminal"]["latitude_rad"]
    objective = {"promised": float(objective_promised),
                 "monte_carlo": float(lat["mean"] - k_objective * lat["std"])}
    return {"constraints": constraints, "objective": objective,
            "agrees": all(c["agrees"] for c in constraints.values())}


def shortfall(record: dict) -> float:
    """How far a round is from agreeing (<= 0: it agrees): the worst of the heating share's gap in
    normal quantiles and the sigma limits' relative excess.  Picks the best design of failed loops."""
    worst = -math.inf
    for name, c in record["constraints"].items():
        if name == "heat_rate":
            worst = max(worst, quantile(c["acceptance"]) - quantile(_clip(c["monte_carlo"])))
        else:
            worst = max(worst, c["monte_carlo"] / c["limit"] - 1.0)
    return worst


def _clip(p: float) -> float:
    return min(max(p, 1e-9), 1.0 - 1e-9)


def correct(record: dict, correction: Correction, *, samples: int) -> Correction | None:
    """The next round's kC and NLP sigma limits from a round that did not agree; None when a
    failing sigma is more than ``MAX_SIGMA_RATIO`` times CADET's: the design is outside the regime
    where the first-order covariance means anything, and scaling the limit by that ratio would only
    ask the NLP for a spread it cannot predict (seen with sigma(gamma_f) 30x CADET's)."""
    k = correction.k_constraint
    limits = dict(correction.sigma_limits)
    for name, c in record["constraints"].items():
        if c["agrees"]:
            continue
        if name == "heat_rate":
            kept = min(max(c["monte_carlo"], 0.5 / samples), 1.0 - 0.5 / samples)
            k = raised_k(k, quantile(c["target"]) - quantile(kept))
        else:
            q = name[len("sigma_"):]
            if not c["monte_carlo"] <= MAX_SIGMA_RATIO * c["promised"]:
                return None
            ratio = c["promised"] / c["monte_carlo"] if c["monte_carlo"] > 0 else 1.0
            limits[q] = min(c["limit_in_nlp"], c["limit"] * ratio * SIGMA_SAFETY)
    return Correction(k_constraint=k, sigma_limits=limits)


def failure_message(record: dict, *, display=None) -> str:
    """Names the constraints the Monte Carlo did not confirm, with the shares.  ``display(name)``
    may give ``(label, to_unit)`` for a sigma constraint's quantity (the API edge's names and units)."""
    parts = []
    for name, c in record["constraints"].items():
        if c["agrees"]:
            continue
        if name == "heat_rate":
            parts.append(f"heating limit kept over the flight by {100 * c['monte_carlo']:.2f}% of the samples "
                         f"(fine grid), target {100 * c['target']:.3f}% (accepted down to "
                         f"{100 * c['acceptance']:.3f}%), CADET promised {100 * c['promised']:.3f}%")
        else:
            q = name[len("sigma_"):]
            label, unit = display(q) if display else (q, lambda v: v)
            parts.append(f"sigma of the final {label}: Monte Carlo {unit(c['monte_carlo']):.4g} above the limit "
                         f"{unit(c['limit']):.4g} (CADET promised {unit(c['promised']):.4g})")
    return "; ".join(parts)
