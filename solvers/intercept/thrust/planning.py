"""Warm starts: a control plan from a single impulse or from a stored trajectory, the
propagation of the Hill dynamics under a plan (the initial states), and resampling a
solution onto a refined layout."""
from __future__ import annotations


import numpy as np
from scipy.integrate import solve_ivp

from solvers.intercept.thrust.layout import Layout, control_times
from solvers.intercept.thrust.problem import FiniteThrustProblem, ImpulsiveGuess, Plan, Scaled, TrajectoryGuess
from solvers.models import relative_motion as rm

# ----------------------------------------------------------------------------- warm starts

def plan_impulsive(guess: ImpulsiveGuess, *, problem: FiniteThrustProblem, s: Scaled, tf: float) -> Plan:
    """One full-thrust burn spending the impulse's propellant, centred on its time, along its direction."""
    dv = np.asarray(guess.delta_v_mps, float)
    dvn = float(np.linalg.norm(dv))
    fuel = problem.scenario.mass_kg * (1.0 - np.exp(-dvn / problem.scenario.exhaust_speed_mps))
    duration = fuel * problem.scenario.exhaust_speed_mps / problem.scenario.max_thrust_n / s.sc.time_s
    tc = guess.t_man_s / s.sc.time_s
    t_on, t_off = max(tc - duration / 2, 0.0), min(tc + duration / 2, tf)
    e_dir = dv / max(dvn, 1e-12)
    _, _, r_t0, v_t0 = problem.scenario.initial_states()

    def direction(t):
        rt, vt = rm.circular_state(r0=r_t0, v0=v_t0, mu=problem.scenario.mu_m3_s2, t=np.atleast_1d(t) * s.sc.time_s)
        return np.einsum("kij,j->ik", rm.hill_axes(rt, vt), e_dir)

    # One burn, like the impulse; a further burn (here: a short one at t=0)
    # comes from the switching function after the first solve.
    windows = [(t_on, t_off)]
    return Plan(windows, direction, tf)


def plan_trajectory(guess: TrajectoryGuess, problem: FiniteThrustProblem, s: Scaled) -> Plan:
    """A stored trajectory's burns (thrust above half the maximum), directions and states."""
    t, idx = np.unique(np.asarray(guess.t_s, float) / s.sc.time_s, return_index=True)
    scale = np.array([s.sc.length_m] * 3 + [s.sc.speed_mps] * 3 + [problem.scenario.mass_kg])[:, None]
    st = np.asarray(guess.states, float)[:, idx] / scale
    thr = np.asarray(guess.thrust_n, float)[:, idx]
    mag = np.linalg.norm(thr, axis=0)
    on = mag > 0.5 * problem.scenario.max_thrust_n
    edges = np.flatnonzero(np.diff(on.astype(int)))
    cuts = [0.5 * (t[i] + t[i + 1]) for i in edges]
    bounds = [t[0]] + cuts + [t[-1]]
    # a window's first sample tells whether it burns (cuts lie between samples; its midpoint may
    # fall in a gap between nodes and pick the next window's sample, which lost a burn at t=0)
    windows = [(bounds[j], bounds[j + 1]) for j in range(len(bounds) - 1)
               if on[min(np.searchsorted(t, bounds[j]), t.size - 1)]]
    unit = np.where(mag > 1e-9, thr / np.maximum(mag, 1e-300), 0.0)
    unit[:, ~on] = np.nan

    def direction(tq):
        # nearest burning sample: directions are only meaningful where the engine was on
        ok = ~np.isnan(unit[0])
        if not ok.any():
            return np.tile([[0.0], [1.0], [0.0]], (1, np.size(tq)))
        d = np.stack([np.interp(tq, t[ok], row[ok]) for row in unit])
        return d / np.maximum(np.linalg.norm(d, axis=0), 1e-12)

    return Plan(windows, direction, float(t[-1]), lambda tq: np.stack([np.interp(tq, t, row) for row in st]))


def propagate_hill(s: Scaled, t_eval: np.ndarray, control, *, breaks=()) -> np.ndarray:
    """Integrate the nondim Hill dynamics under ``control(t) -> (u, d)``; states at
    ``t_eval``.  ``breaks``: control switch times, where the integration restarts
    so no step straddles a discontinuity."""
    def rhs(t, x):
        u, d = control(t)
        return rm.dynamics_numpy(x[:, None], (s.tmax * u * d)[:, None], np.array([s.tmax * u / s.c]))[:, 0]
    t_end = float(np.max(t_eval))
    uniq, inv = np.unique(t_eval, return_inverse=True)
    edges = np.unique(np.clip(np.r_[0.0, list(breaks), t_end], 0.0, t_end))
    out = np.tile(s.x0[:, None], (1, uniq.size))
    x = s.x0.copy()
    for a, b in zip(edges[:-1], edges[1:]):
        sel = (uniq >= a) & (uniq < b)
        sol = solve_ivp(rhs, (a, b), x, method="DOP853", t_eval=np.r_[uniq[sel], b], rtol=1e-8, atol=1e-10)
        out[:, sel] = sol.y[:, :-1]
        x = sol.y[:, -1]
    out[:, uniq >= t_end] = x[:, None]
    out[6] = np.maximum(out[6], s.m_dry)
    return out[:, inv]


def initial_values(plan: Plan, layout: Layout, s: Scaled):
    """``(X, U, sigma, tf)`` on the layout's nodes: the plan's controls and its (given or propagated) states."""
    tf = plan.tf
    mesh = layout.mesh()
    t = mesh.node_fractions().ravel() * tf
    tc = control_times(mesh, tf)
    U = np.zeros((rm.NU, t.size))
    thr = layout.throttle()
    U[0] = np.where(np.isnan(thr), plan.on(tc).astype(float), thr)
    U[1:] = plan.direction(tc)
    if plan.states is not None:
        X = plan.states(t)
    else:
        def control(tt):
            return (1.0 if plan.on(tt)[0] else 0.0), plan.direction(np.array([tt]))[:, 0]
        X = propagate_hill(s, t, control, breaks=[e for w in plan.windows for e in w])
    return X, U, np.asarray(layout.sigma, float), tf


def resample(old: Layout, sigma_old, X, U, tf, new: Layout, direction=None):
    """Interpolate a solution onto another layout (same tf).  ``direction(t)``
    supplies the thrust direction where the old solution coasted."""
    mesh_old, mesh_new = old.mesh(sigma_old), new.mesh()
    vals = np.concatenate([X, U]).reshape((rm.NX + rm.NU, mesh_old.segments, mesh_old.nodes))
    tc = control_times(mesh_new, 1.0)
    Xn = mesh_old.interpolate(vals[: rm.NX], mesh_new.node_fractions().ravel())
    Un = mesh_old.interpolate(vals[rm.NX:], tc)
    thr = new.throttle()
    Un[0] = np.where(np.isnan(thr), np.clip(Un[0], 0.0, 1.0), thr)
    nrm = np.linalg.norm(Un[1:], axis=0)
    weak = nrm < 0.5
    if direction is not None and weak.any():
        Un[1:, weak] = direction(tc[weak] * tf)
    nrm = np.linalg.norm(Un[1:], axis=0)
    Un[1:] = np.where(nrm > 1e-9, Un[1:] / np.maximum(nrm, 1e-300), np.array([[0.0], [1.0], [0.0]]))
    return Xn, Un
