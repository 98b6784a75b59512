"""The initial guess of one phase on its grid: a stored answer interpolated onto it, or straight lines
between the ends the problem fixes (or its guess, or the bounds' middle).

A stored answer is a result of this kind (a job's ``guess.from_job``) or the previous round of a
refinement; either way its phases are read by name (:func:`stored_phases`; a problem posed as one
phase has the one phase named "").
"""
from __future__ import annotations

import numpy as np

from solvers.ocp.problem import OcpProblem, PhaseProblem


def stored_phases(problem: OcpProblem, initial_guess: dict | None) -> dict[str, dict]:
    """A stored answer's phases by name, each ``{trajectory, tf?, t0?}`` (empty without one)."""
    if not initial_guess:
        return {}
    if problem.single and initial_guess.get("phases") is None:     # a stored single-phase result
        one = {"trajectory": initial_guess["trajectory"]}
        if "tf" in initial_guess:
            one["tf"] = initial_guess["tf"]
        return {"": one}
    return {p["name"]: p for p in initial_guess.get("phases") or [] if isinstance(p, dict) and "name" in p}


def _interp_rows(tau_new, tau_old, rows) -> np.ndarray:
    return np.vstack([np.interp(tau_new, tau_old, r) for r in rows]) if len(rows) else np.zeros((0, tau_new.size))


def guess_of(problem: PhaseProblem, grid, initial_guess: dict | None = None):
    """``(tf, theta, X (nx, N), U (nu, Nu))`` physical: a stored result interpolated onto the grid,
    else straight lines between the ends the problem fixes (or its guess, or the bounds' middle)."""
    ph = problem.phase
    tau = grid.tau()
    tau_u = tau if grid.n_controls == grid.n_nodes else tau[:-1]
    t0 = ph.time.initial
    if initial_guess:
        traj = initial_guess["trajectory"]
        t_old = np.asarray(traj["t"], float)
        tf = float(initial_guess.get("tf", t_old[-1])) if ph.time.final is None else ph.time.final
        s_old = (t_old - t_old[0]) / max(t_old[-1] - t_old[0], 1e-300)
        X = _interp_rows(tau, s_old, [np.asarray(traj[s.name], float) for s in ph.states])
        U = _interp_rows(tau_u, s_old, [np.asarray(traj[k.name], float) for k in ph.controls])
        stored = initial_guess.get("parameters") or {}
        theta = np.array([float(stored.get(q.name, _mid(q.lower, q.upper, q.guess))) for q in problem.parameters])
        return tf, theta, X, U
    gs = ph.guess
    if ph.time.final is not None:
        tf = ph.time.final
    elif gs.tf is not None:
        tf = gs.tf
    elif ph.time.final_guess is not None:
        tf = ph.time.final_guess
    else:
        lo, hi = ph.time.final_lower, ph.time.final_upper
        tf = 0.5 * (lo + hi) if lo is not None and hi is not None else (hi if hi is not None else t0 + 1.0)
    rows = []
    for s in ph.states:
        if s.name in gs.states:
            a, b = gs.states[s.name]
        else:
            mid = _mid(s.lower, s.upper, None)
            a = s.initial if s.initial is not None else (s.final if s.final is not None else mid)
            b = s.final if s.final is not None else a
        rows.append(a + (b - a) * tau)
    X = np.vstack(rows)
    urows = []
    for k in ph.controls:
        a, b = gs.controls.get(k.name, (_mid(k.lower, k.upper, None),) * 2)
        urows.append(a + (b - a) * tau_u)
    U = np.vstack(urows) if urows else np.zeros((0, tau_u.size))
    theta = np.array([_mid(q.lower, q.upper, q.guess) for q in problem.parameters])
    return tf, theta, X, U


def _mid(lo, hi, guess) -> float:
    if guess is not None:
        return guess
    if lo is not None and hi is not None:
        return 0.5 * (lo + hi)
    if lo is not None:
        return max(lo, 0.0) if lo <= 0 else lo
    if hi is not None:
        return min(hi, 0.0)
    return 0.0
