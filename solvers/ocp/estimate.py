"""How far an ``ocp`` answer is from the continuous problem's optimum: the objective's and the states'
discretization error, estimated against a check solve on a finer nested mesh, and where on the mesh it lies.

Why a second solve: the re-flight of the returned controls (:mod:`solvers.ocp.verify`) measures how well
the transcription integrates *those* controls.  With multiple shooting it agrees with the nodes almost by
construction, while what limits the objective is the control parametrisation itself (a bang-bang switch
or a kink inside an interval, a control that is not linear between the nodes), which no re-flight of the
returned controls can see.  The error against the continuous optimum is measured the way Richardson
extrapolation does: the same problem solved on the *nested* mesh with every interval cut in parts (LGL: the same
degree on each half), warm-started from the answer, is closer to the optimum; its feasible controls
contain the coarse ones, so its objective is at least as good, and

    objective_error_estimate = s/(s-1) * |J(M) - J(M/s)| / max(|J(M)|, |J(M/s)|)       (relative)

with ``M/s`` the mesh with every interval cut in ``s`` parts (:func:`parts_of`: 2, or 3 for linear
multiple-shooting controls) is the coarse answer's error exactly when cutting the intervals in ``s`` cuts
the error by ``s`` (order 1, the worst case: a switch inside an interval), and overestimates it by at
most ``s/(s-1)`` when the error falls faster (order p: the true error is ``s^p / (s^p - 1)`` times the
change).  The states' error is estimated
the same way at the coarse mesh's interval boundaries (nodes of both meshes), each state scaled by its
``scale``, and the answer's ``state_error`` is the larger of that and its re-flight's own difference.

Where: the estimated error is shared among the coarse intervals in proportion to
``integral over interval k of sum_j ((u_j(M/s) - u_j(M)) / scale_j)^2 dt`` (the controls move where the
parametrisation is wrong: the objective of a near-optimal control departs from the optimum by a
quadratic form of the control's error, Bryson & Ho, *Applied Optimal Control*, sec. 6.1), or, where no
control moves, to the growth of the scaled state difference across interval k, so the refinement
(:mod:`solvers.ocp.refine`) splits the intervals that hold the switch or the kink.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from solvers.ocp.grid import grid_of
from solvers.ocp.scaling import control_scales, state_scales
from solvers.ocp.verify import control_function
from solvers.transcription import refine as rf

OBJECTIVE_ORDER = 2     # how fast an interval's share of the objective error falls with its length
SAMPLES = 8             # control samples per coarse interval for the indicator
METHOD = ("objective and states against a check solve on the nested mesh with every interval cut in s parts "
          "(2; 3 for linear multiple-shooting controls), warm-started: s/(s-1) x the change (the error when "
          "cutting the intervals in s cuts it by s, the worst case of a switch inside an interval)")


def parts_of(transcription) -> int:
    """Parts each interval is cut into for the check: three for multiple shooting's linear controls, two
    otherwise.  A piecewise-linear control cannot jump: halved, a switch in the middle of an interval
    falls on the new node and the best continuous ramp over the two halves is the coarse ramp itself, so
    the objective would not move however wrong it is (the double integrator on 9 intervals: 2e-3 off,
    unchanged on 18); cut in three, two parts are narrower than the interval and the ramp steepens."""
    return 3 if transcription.method == "multiple_shooting" and transcription.control == "linear" else 2


def halved(mesh: rf.Mesh, parts: int = 2) -> rf.Mesh:
    """``mesh`` with every interval cut in ``parts`` equal parts (LGL: each keeps the interval's nodes)."""
    b = rf.subdivide(mesh.boundaries, [parts] * mesh.intervals)
    return rf.Mesh(b, None if mesh.nodes is None else tuple(n for n in mesh.nodes for _ in range(parts)))


def relative_change(a: float, b: float) -> float:
    den = max(abs(a), abs(b))
    if not (math.isfinite(a) and math.isfinite(b)):
        return math.inf
    return abs(a - b) / den if den > 0.0 else 0.0


@dataclass
class Estimate:
    """The error of one answer against its check (module docstring)."""

    objective_ref: float                       # the check's objective
    objective_error: float                     # relative, s/(s-1) x the change
    state_change: float                        # s/(s-1) x the worst scaled change at the shared nodes
    # per phase, each interval's share of the error (all phases' shares sum to 1)
    shares: list[np.ndarray] = field(default_factory=list)
    check_intervals: int = 0
    check_iterations: int = 0
    check_time_s: float = 0.0

    def words(self) -> dict:
        return {"check_intervals": self.check_intervals, "check_objective": self.objective_ref,
                "check_iterations": self.check_iterations}


def _phase_arrays(problem, report):
    traj, ph = report["trajectory"], problem.phase
    t = np.asarray(traj["t"], float)
    X = np.array([np.asarray(traj[s.name], float) for s in ph.states]).reshape(len(ph.states), t.size)
    U = np.array([np.asarray(traj[k.name], float) for k in ph.controls]).reshape(len(ph.controls), t.size)
    return t, X, U


def _controls_on(problem, report, tau):
    """The phase's controls as transcribed, at normalized times ``tau``."""
    grid = grid_of(problem)
    t, _, U = _phase_arrays(problem, report)
    uf = control_function(grid, t, U)
    b = grid.bounds()
    k = np.minimum(np.searchsorted(b, tau, side="right") - 1, grid.intervals - 1)
    out = np.zeros((U.shape[0], tau.size))
    for j in np.unique(k):
        sel = k == j
        out[:, sel] = uf(t[0] + (t[-1] - t[0]) * tau[sel], int(j))
    return out


def _at_bounds(problem, report):
    """The phase's times, states and state rates (differences over the nodes) at its mesh's interval
    boundaries (nodes of every transcription)."""
    grid = grid_of(problem)
    t, X, _ = _phase_arrays(problem, report)
    rate = np.gradient(X, t, axis=1) if t.size > 2 and X.size else np.zeros_like(X)
    k = grid.offsets()
    return t[k], X[:, k], rate[:, k]


def _normalized(arrays: list[np.ndarray]) -> list[np.ndarray] | None:
    total = float(sum(a.sum() for a in arrays))
    return None if not total > 0.0 else [a / total for a in arrays]


def estimate(coarse, fine) -> Estimate:
    """The error of the answer ``coarse`` (a :class:`solvers.ocp.refine.Trial`) against ``fine``, the same
    problem solved on its check mesh (module docstring)."""
    factor = max(parts / (parts - 1.0) for parts in (parts_of(ph.problem.transcription) for ph in coarse.problem.phases))
    err = factor * relative_change(coarse.objective, fine.objective)
    state, controls, states, widths = 0.0, [], [], []
    for cph, fph, crep, frep in zip(coarse.problem.phases, fine.problem.phases, coarse.sol.phases, fine.sol.phases):
        cp, fp = cph.problem, fph.problem
        xs = state_scales(cp)
        tc, xc, _ = _at_bounds(cp, crep)
        tf_, xf, rf_ = (a[..., ::parts_of(cp.transcription)] for a in _at_bounds(fp, frep))
        # compared at the coarse answer's times: a free phase end moves the same normalized time (the
        # junction times of a singular arc are flat in the objective and move by far more than the states)
        d = (xc - xf - rf_ * (tc - tf_)[None, :]) / xs[:, None] if xc.size else np.zeros((0, 0))
        if d.size:
            state = max(state, float(np.abs(d).max()))
        b = grid_of(cp).bounds()
        w = np.diff(b)
        # what each interval adds to the states' difference (the difference carried in from before is not its own)
        states.append(np.abs(np.diff(d, axis=1)).max(axis=0) if d.size else np.zeros(w.size))
        if cp.phase.controls:
            us = control_scales(cp)
            s = (np.arange(SAMPLES) + 0.5) / SAMPLES
            tau = (b[:-1, None] + w[:, None] * s[None, :]).ravel()
            du = (_controls_on(fp, frep, tau) - _controls_on(cp, crep, tau)) / us[:, None]
            controls.append((du**2).sum(axis=0).reshape(w.size, SAMPLES).mean(axis=1) * w)
        else:
            controls.append(np.zeros(w.size))
        widths.append(w)
    # where the controls move; else where the states' difference grows; else by length.  An error the
    # controls do not show (an integration error spread over the horizon) is found by the loop's rule for
    # a round that did not halve the error: refine everywhere (solvers.ocp.refine)
    shares = _normalized(controls) or _normalized(states) or [w / sum(v.sum() for v in widths) for w in widths]
    return Estimate(objective_ref=float(fine.objective), objective_error=err, state_change=factor * state,
                    shares=shares, check_intervals=int(fine.intervals),
                    check_iterations=int(fine.iterations))


def plan_estimate(tr, mesh: rf.Mesh, errors, target: float, *, n_max: int) -> rf.Mesh | None:
    """The next mesh of one phase from the errors its intervals hold against the check (relative, the
    estimate's shares): multiple shooting splits where they miss (the objective falls as ``h^2`` with
    a switch or a kink inside: OBJECTIVE_ORDER), LGL raises the degree or splits (ph)."""
    e = np.asarray(errors, float)
    if tr.method == "multiple_shooting":
        n = rf.split_counts(e, mesh.widths, target, order=OBJECTIVE_ORDER)
        return None if np.all(n == 1) else rf.Mesh(rf.subdivide(mesh.boundaries, n))
    return rf.refine_lgl(mesh, e, target, n_min=tr.nodes, n_max=n_max)


def same_mesh(a: rf.Mesh, b: rf.Mesh) -> bool:
    return a.intervals == b.intervals and a.nodes == b.nodes and \
        bool(np.allclose(a.boundaries, b.boundaries, rtol=0.0, atol=1e-12))


def union(a: rf.Mesh | None, b: rf.Mesh | None) -> rf.Mesh | None:
    """Every boundary of both meshes; LGL: each interval the larger node count of the two it lies in."""
    if a is None or b is None:
        return a or b
    cuts = np.unique(np.concatenate([a.boundaries, b.boundaries]))
    cuts = cuts[np.concatenate([[True], np.diff(cuts) > 1e-12])]
    cuts[-1] = 1.0
    nodes = None
    if a.nodes is not None and b.nodes is not None:
        mid = 0.5 * (cuts[:-1] + cuts[1:])

        def at(m: rf.Mesh):
            return np.asarray(m.node_counts)[np.searchsorted(m.boundaries, mid, side="right") - 1]
        nodes = tuple(int(v) for v in np.maximum(at(a), at(b)))
    return rf.Mesh(tuple(float(v) for v in cuts), nodes)


def accuracy_block(trial, requested: float | None, reached: bool | None) -> dict:
    """``solver.accuracy`` of the answer ``trial`` (a :class:`solvers.ocp.refine.Trial`)."""
    obj = trial.objective_error_estimate
    block = {"requested": requested,
             "state_error": trial.state_error if math.isfinite(trial.state_error) else None,
             "objective_error_estimate": obj if obj is not None and math.isfinite(obj) else None,
             "reached": reached, "estimated_by": METHOD,
             "reflight_state_error": trial.max_error if math.isfinite(trial.max_error) else None}
    if trial.estimate is not None:
        block.update(trial.estimate.words(), check_time_s=trial.estimate.check_time_s)
    else:
        block["check_failure"] = trial.check_failure
    return block
