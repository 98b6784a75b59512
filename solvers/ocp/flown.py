"""A second first guess for a problem whose first one overflowed: the dynamics flown from the guessed
initial state with the guessed controls, and what the flight says about the transcription.

When IPOPT meets an overflow or NaN at the guess or in its first iterates (``Invalid_Number_Detected``),
the straight lines between the ends (:mod:`solvers.ocp.guess`) are often far from anything the dynamics
can do: a state interpolated through a region where an expression overflows, or node values from which
an explicit step blows up.  :func:`flown_guess` integrates each phase's dynamics from its guessed initial
state with its guessed controls clipped to their bounds, with an implicit, adaptive integrator (LSODA,
which follows stiff dynamics at any step), and stops the flight before it blows up (a state non-finite,
past ``ESCAPE`` times its scale from where it started, or more than a span outside its bounds): the
states hold their last good value from there.  The states are then clipped to their bounds (a fixed
final value stays fixed: it is a bound of the NLP).  The result has the form of a stored answer, so the
solver places it like a warm start (without the warm start's small barrier: it is not near an optimum).

:func:`rk4_stiffness` is the diagnostic the flight makes possible for multiple shooting: the largest
``h |lambda|`` along the flown guess, ``h`` the RK4 step and ``lambda`` the eigenvalues of the
dynamics' Jacobian; past RK4's stability limit on the negative real axis (about 2.785) an explicit
step amplifies, and on a long horizon overflows whatever the guess.
"""
from __future__ import annotations

import numpy as np

from solvers.ocp.growth import jacobian_function
from solvers.ocp.guess import guess_of, stored_phases
from solvers.ocp.problem import OcpProblem, PhaseProblem
from solvers.ocp.scaling import state_scales
from solvers.ocp.symbolic import functions_of

ESCAPE = 1e3                # a flight past this many scales from its start is blowing up
RK4_STABILITY = 2.785       # RK4's stability interval on the negative real axis (h lambda in [-2.785, 0])
MAX_STEPS = 20000           # LSODA steps per phase at most: a flight is a guess, not an answer


def clip(v, lo, hi):
    """``v`` within ``[lo, hi]`` (None: no bound that side)."""
    return np.clip(v, -np.inf if lo is None else lo, np.inf if hi is None else hi)


def within_bounds(states, X: np.ndarray) -> np.ndarray:
    """The state rows ``X`` clipped to their bounds, with the fixed ends put back: those are the NLP's
    bounds, a guess keeps them."""
    Xb = np.vstack([clip(X[i], s.lower, s.upper) for i, s in enumerate(states)]) if len(states) else X
    for i, s in enumerate(states):
        if s.initial is not None:
            Xb[i, 0] = s.initial
        if s.final is not None:
            Xb[i, -1] = s.final
    return Xb


def fly(problem: PhaseProblem, grid, *, t0: float, tf: float, theta, X: np.ndarray, U: np.ndarray):
    """``(t nodes, X, U at the nodes, stopped_at)``: the phase's dynamics flown on ``grid`` from ``X[:, 0]``
    with the controls ``U`` (on the grid's control nodes) clipped to their bounds (module docstring)."""
    from scipy.integrate import solve_ivp

    ph, fns = problem.phase, functions_of(problem)
    tau = grid.tau()
    tau_u = tau if grid.n_controls == grid.n_nodes else tau[:-1]
    t = t0 + (tf - t0) * tau
    t_u = t0 + (tf - t0) * tau_u
    U = np.vstack([clip(U[i], k.lower, k.upper) for i, k in enumerate(ph.controls)]) if ph.controls else U
    c = np.array([v for _, v in problem.constants], float)
    scale = state_scales(problem)
    x0 = np.asarray(X[:, 0], float).copy()

    def controls(ti: float) -> np.ndarray:
        return np.array([np.interp(ti, t_u, row) for row in U]) if len(U) else np.zeros(0)

    def rhs(ti, x):
        f = np.asarray(fns.rhs(ti, x, controls(ti), theta, c, t0, tf), float).ravel()[:fns.nx]
        return np.where(np.isfinite(f), f, 0.0)     # the escape event below ends such a flight

    def escape(ti, x):
        if not np.all(np.isfinite(x)):
            return -1.0
        far = np.abs(x - x0) / scale
        outside = [0.0]
        for s, xi, si in zip(ph.states, x, scale):
            span = (s.upper - s.lower) if s.lower is not None and s.upper is not None else si
            if s.lower is not None:
                outside.append((s.lower - xi) / span)
            if s.upper is not None:
                outside.append((xi - s.upper) / span)
        return 1.0 - max(far.max() / ESCAPE, max(outside))
    escape.terminal = True   # type: ignore[attr-defined]

    stopped = None
    try:
        sol = solve_ivp(rhs, (t0, tf), x0, method="LSODA", t_eval=t, events=escape, rtol=1e-6,
                        atol=1e-9 * scale, max_step=max(tf - t0, 1e-12))
        reached = sol.t.size
        if sol.t_events and len(sol.t_events[0]):
            stopped = float(sol.t_events[0][0])
        flown = sol.y if reached else x0[:, None]
    except (ValueError, RuntimeError, FloatingPointError):
        reached, flown, stopped = 1, x0[:, None], t0
    reached = max(reached, 1)
    if flown.shape[1] < t.size:            # stopped: hold the last good state
        flown = np.hstack([flown, np.repeat(flown[:, -1:], t.size - flown.shape[1], axis=1)])
        stopped = float(t[reached - 1]) if stopped is None else stopped
    Xf = within_bounds(ph.states, flown)
    Ux = np.vstack([np.interp(t, t_u, row) for row in U]) if len(U) else np.zeros((0, t.size))
    return t, Xf, Ux, stopped


def as_stored(problem: OcpProblem, phases: list[dict], theta) -> dict:
    """Phases ``{"name", "t0", "tf", "t", "X", "U"}`` in the form of a stored answer (what the solver places)."""
    out = []
    for ph, f in zip(problem.phases, phases):
        p = ph.problem.phase
        traj = {"t": np.asarray(f["t"]).tolist(), **{s.name: f["X"][i].tolist() for i, s in enumerate(p.states)},
                **{k.name: f["U"][i].tolist() for i, k in enumerate(p.controls)}}
        out.append({"name": ph.name, "t0": float(f["t0"]), "tf": float(f["tf"]), "trajectory": traj})
    params = {q.name: float(v) for q, v in zip(problem.parameters, np.asarray(theta, float))}
    if problem.single:
        return {"trajectory": out[0]["trajectory"], "tf": out[0]["tf"], "parameters": params}
    return {"phases": out, "parameters": params}


def phase_start(ph, initial_guess: dict | None, stored: dict, grid):
    """``(t0, tf, theta, X, U)`` of phase ``ph`` from the guess (a stored answer or the straight lines)."""
    old = stored.get(ph.name)
    warm = None if old is None else {**old, "parameters": (initial_guess or {}).get("parameters")}
    tf, theta, X, U = guess_of(ph.problem, grid, warm)
    time = ph.problem.phase.time
    t0 = float(old["t0"]) if old is not None and "t0" in old else (time.initial if time.initial is not None else 0.0)
    return t0, tf, theta, X, U


def flown_guess(problem: OcpProblem, nlp, initial_guess: dict | None) -> tuple[dict, list[dict]]:
    """The guess of the module docstring in the form of a stored answer, and per phase where its
    flight stopped (``{"phase", "stopped_at_t"}``; None: it flew to the end)."""
    stored = stored_phases(problem, initial_guess)
    flights, notes = [], []
    theta = np.zeros(len(problem.parameters))
    for ph, b in zip(problem.phases, nlp.blocks):
        t0, tf, theta, X, U = phase_start(ph, initial_guess, stored, b.nlp.grid)
        t, Xf, Uf, stopped = fly(ph.problem, b.nlp.grid, t0=t0, tf=tf, theta=theta, X=X, U=U)
        flights.append({"t0": t0, "tf": tf, "t": t, "X": Xf, "U": Uf})
        notes.append({"phase": ph.name, "stopped_at_t": stopped})
    return as_stored(problem, flights, theta), notes


def rk4_stiffness(problem: OcpProblem, nlp, guess: dict) -> dict | None:
    """The worst ``h |lambda|`` of a multiple-shooting phase along ``guess`` (a stored-answer form):
    ``{"phase", "t", "rate", "step", "h_lambda"}``, or None when no phase integrates with RK4 steps."""
    stored = stored_phases(problem, guess)
    worst: dict | None = None
    for ph, b in zip(problem.phases, nlp.blocks):
        grid, fns = b.nlp.grid, b.nlp.fns
        if grid.method != "multiple_shooting" or ph.name not in stored:
            continue
        traj = stored[ph.name]["trajectory"]
        t = np.asarray(traj["t"], float)
        t0, tf = t[0], float(stored[ph.name].get("tf", t[-1]))
        theta = np.array([float((guess.get("parameters") or {}).get(q.name, 0.0)) for q in b.problem.parameters])
        c = np.array([v for _, v in b.problem.constants], float)
        n, nx = t.size, fns.nx
        X = np.array([traj[s.name] for s in b.problem.phase.states], float).reshape(nx, n)
        U = np.array([traj[k.name] for k in b.problem.phase.controls], float).reshape(fns.nu, n)
        flat = np.asarray(jacobian_function(fns).map(n)(t[None, :], X, U, theta, c, t0, tf), float)
        steps = np.diff(grid.bounds()) * (tf - t0) / grid.substeps
        k_of = grid.node_interval()
        for j in range(n):
            J = flat[:, j * nx:(j + 1) * nx]
            if not np.all(np.isfinite(J)):
                continue
            rate = float(np.max(np.abs(np.linalg.eigvals(J)))) if J.size else 0.0
            h = float(steps[min(k_of[j], len(steps) - 1)])
            if worst is None or h * rate > float(worst["h_lambda"]):
                worst = {"phase": ph.name, "t": float(t[j]), "rate": rate, "step": h, "h_lambda": h * rate}
    return worst
