"""What a failed ``ocp`` solve left violated, named as the user wrote it (issue 35 item 4, issue 38 item 3).

IPOPT's "worst constraint violation 2.1e-02 (scaled)" is a row of the NLP; the user wrote path and
boundary entries with a ``name`` (or none: then the entry's field path, ``path[2]`` or
``phases[1].boundary[0]``).  :func:`violations` evaluates each entry on the last iterate, physical units,
at the nodes (path: the worst node's time) or at the phase's ends (boundary), and keeps those outside
their bounds; :func:`words` is the sentence the failure message carries.  Where the dynamics do not
join up (a final value that cannot be reached shows there, not in an entry), :func:`worst_defect` gives
the interval, from the per-interval re-flight the mesh refinement uses.  A NaN or Inf in the iterate is
a violation too: it names the entry that cannot be evaluated.
"""
from __future__ import annotations

import math

from dataclasses import dataclass

import numpy as np

from solvers.ocp.flown import RK4_STABILITY
from solvers.common import Outcome, SolveStatus
from solvers.ocp.phase import positive_scale

# An entry counts as violated beyond this share of its scale (IPOPT's default constr_viol_tol is 1e-4
# on the scaled rows; an entry at the bound to the solver's last digits is not what failed).
TOLERANCE = 1e-6
SHOWN = 3          # the failure message names the worst few; details keep them all


@dataclass
class Violation:
    """One entry outside its bounds on the last iterate."""

    name: str             # the entry's ``name``, else its field path (``path[2]``)
    phase: str            # the phase's name; "" for a problem posed as one phase
    where: str            # "path" | "boundary"
    value: float          # the entry's worst value (physical)
    lower: float | None
    upper: float | None
    t: float | None       # the time of the worst value (a boundary entry: None)
    excess_scaled: float  # distance outside the bounds over the entry's scale; inf when not finite

    def as_dict(self) -> dict:
        return {"name": self.name, "phase": self.phase or None, "where": self.where,
                "value": _finite(self.value), "lower": self.lower, "upper": self.upper,
                "t": _finite(self.t), "excess_scaled": _finite(self.excess_scaled)}

    def words(self) -> str:
        phase = f" in phase {self.phase}" if self.phase else ""
        bounds = " and ".join(b for b in (None if self.lower is None else f">= {self.lower:.6g}",
                                          None if self.upper is None else f"<= {self.upper:.6g}") if b)
        at = "" if self.t is None else f" at t = {self.t:.6g}"
        value = f"{self.value:.6g}" if np.isfinite(self.value) else "not a number (overflow or NaN)"
        return f"{self.where} constraint '{self.name}'{phase} is {value}{at}, asked {bounds}"


def _finite(v):
    return None if v is None or not np.isfinite(v) else float(v)


def _excess(values: np.ndarray, lo: float | None, hi: float | None, scale: float) -> np.ndarray:
    """Per value, how far outside [lo, hi] over ``scale``; inf where the value is not finite."""
    out = np.maximum(np.maximum((-np.inf if lo is None else lo) - values, values - (np.inf if hi is None else hi)),
                     0.0) / scale
    return np.where(np.isfinite(values), out, np.inf)


def _field(prefix: str, which: str, k: int, name: str) -> str:
    """The entry's own name; an unnamed one (the reader calls it ``path_2``) by its field path."""
    return f"{prefix}{which}[{k}]" if not name or name == f"{which}_{k}" else name


def violations(problem, nlp, checks, nums) -> list[Violation]:
    """Every path and boundary entry of every phase outside its bounds on the iterate the checks
    (:class:`solvers.ocp.check.PhaseCheck`) unpacked, the worst first.  ``nlp`` the
    :class:`solvers.ocp.trajectory.TrajectoryNLP`, ``nums`` each phase's :class:`solvers.ocp.scaling.Numbers`."""
    out: list[Violation] = []
    for i, (ph, b, chk, num) in enumerate(zip(problem.phases, nlp.blocks, checks, nums)):
        fns, grid, att = b.nlp.fns, b.nlp.grid, chk.attempt
        phase = "" if problem.single else ph.name
        prefix = "" if problem.single else f"phases[{i}]."
        c = num.p[:fns.nc]
        t0 = float(chk.report["t0"])
        t = t0 + (att.tf - t0) * grid.tau()
        X, U = att.X, b.nlp.node_controls(att.U)
        with np.errstate(all="ignore"):
            if b.problem.phase.path:
                G = np.asarray(fns.path.map(t.size)(t[None, :], X, U, att.theta, c, t0, att.tf), float)
                for k, cn in enumerate(b.problem.phase.path):
                    ex = _excess(G[k], cn.lower, cn.upper, positive_scale(cn.lower, cn.upper))
                    j = int(np.argmax(ex))
                    if ex[j] > TOLERANCE:
                        out.append(Violation(_field(prefix, "path", k, cn.name), phase, "path", float(G[k, j]),
                                             cn.lower, cn.upper, float(t[j]), float(ex[j])))
            if b.problem.phase.boundary:
                ev, _ = fns.events(t0, att.tf, X[:, 0], X[:, -1], U[:, 0], U[:, -1], att.theta, c)
                ev = np.asarray(ev, float).ravel()
                for k, cn in enumerate(b.problem.phase.boundary):
                    ex = _excess(ev[k:k + 1], cn.lower, cn.upper, positive_scale(cn.lower, cn.upper))
                    if ex[0] > TOLERANCE:
                        out.append(Violation(_field(prefix, "boundary", k, cn.name), phase, "boundary",
                                             float(ev[k]), cn.lower, cn.upper, None, float(ex[0])))
    return sorted(out, key=lambda v: -v.excess_scaled)


def worst_defect(problem, nlp, checks) -> str | None:
    """Where the dynamics join up worst on the last iterate (a per-interval re-flight from each
    interval's first node), in words; None when every interval joins up or none can be flown."""
    worst: tuple[float, str] | None = None
    for ph, b, chk in zip(problem.phases, nlp.blocks, checks):
        if not chk.ok:       # the whole re-flight failed its call cap: the per-interval one has none, skip it
            continue
        try:
            err = np.asarray(chk.errors["state"](), float)
        except (ValueError, ArithmeticError, RuntimeError):
            continue
        if not err.size or not np.isfinite(err).any():
            continue
        k = int(np.nanargmax(err))
        t0, tf = float(chk.report["t0"]), float(chk.report["tf"])
        t = t0 + (tf - t0) * np.asarray(b.nlp.grid.bounds(), float)    # the intervals' starts
        phase = "" if problem.single else f" of phase {ph.name}"
        if err[k] > TOLERANCE and (worst is None or err[k] > worst[0]):
            worst = (float(err[k]), f"the dynamics{phase} do not join up worst on the interval from "
                                    f"t = {float(t[k]):.6g} (scaled defect {err[k]:.3g})")
    return None if worst is None else worst[1]


def words(found: list[Violation], defect: str | None = None) -> str:
    """The sentence a failure message carries: the worst few entries by name, then the dynamics."""
    parts = [v.words() for v in found[:SHOWN]]
    if len(found) > SHOWN:
        parts.append(f"and {len(found) - SHOWN} more (details.violations)")
    if defect:
        parts.append(defect)
    return "; ".join(parts)


# The solver's words for an iterate it could not evaluate: an overflow or NaN in the user's expressions
# or in the transcription's integration of them (explicit RK4 steps on stiff dynamics overflow).
INVALID_NUMBER = "Invalid_Number_Detected"
_FAILED = (Outcome.INFEASIBLE, Outcome.NOT_CONVERGED, Outcome.FAILED)


def name_them(status: SolveStatus, problem, nlp, checks, nums) -> None:
    """A failed solve's message and ``details`` name what the last iterate left violated (module
    docstring) in place of the NLP's scaled row; an overflow says where it came from."""
    if status.outcome not in _FAILED:
        return
    found = violations(problem, nlp, checks, nums)
    status.details = {**status.details, "violations": [v.as_dict() for v in found]}
    if status.solver_status == INVALID_NUMBER:
        at = "the first guess" if status.iterations == 0 else f"iteration {status.iterations}"
        # the user's expressions (or their integration) overflowed: theirs to change, not the solver's fault
        status.outcome = Outcome.NUMERICAL_OVERFLOW
        status.message = (f"IPOPT: {INVALID_NUMBER}: the problem's expressions, or the transcription's "
                          f"integration of its dynamics, gave an overflow or NaN at {at}")
        status.message += recovery_words(status.details.get("guess_recovery"))
        if found:
            status.message += "; " + words(found)
        return
    text = words(found, worst_defect(problem, nlp, checks))
    if text:
        status.message = f"IPOPT: {status.solver_status}; violated: {text}"


def recovery_words(recovery: dict | None) -> str:
    """What the second first guess (:mod:`solvers.ocp.flown`) showed, for an overflow's message."""
    if not recovery:
        return ""
    out = ("; a guess flown from the dynamics (LSODA from the guessed initial state, controls clipped to "
           "their bounds") 
    stopped = recovery.get("flight_stopped") or []
    if stopped:
        where = ", ".join(f"t = {n['stopped_at_t']:.6g}" + (f" in phase {n['phase']}" if n["phase"] else "")
                          for n in stopped)
        out += f", stopped before blowing up at {where}"
    out += ") overflowed too"
    stiff = recovery.get("rk4_stiffness")
    if stiff and stiff["h_lambda"] > RK4_STABILITY:
        phase = f" in phase {stiff['phase']}" if stiff["phase"] else ""
        steps = int(math.ceil(stiff["h_lambda"] / RK4_STABILITY))
        out += (f": the multiple shooting's RK4 steps of {stiff['step']:.4g} s meet a rate |lambda| = "
                f"{stiff['rate']:.4g} 1/s of the dynamics at t = {stiff['t']:.6g}{phase} (h |lambda| = "
                f"{stiff['h_lambda']:.4g}, past RK4's stability limit {RK4_STABILITY}): steps at least "
                f"{steps} times shorter there (transcription.intervals, substeps) or LGL collocation")
    return out
