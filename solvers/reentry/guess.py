"""Initial guesses of the reentry problem: a glide simulated with constant controls, straight
lines, or another solution on any grid, interpolated onto the shooting grid.

Split from :mod:`solvers.reentry.solver` (the package re-exports these names) to keep that module on the
problem and the solve.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import TYPE_CHECKING

import casadi as ca
import numpy as np

from solvers.models import reentry_dynamics as dyn
from solvers.models import shuttle as sh
from solvers.models.reentry_state import ALTITUDE, LATITUDE, LONGITUDE, NU, NX, SPEED
from solvers.transcription.multiple_shooting import control_nodes

if TYPE_CHECKING:
    from solvers.reentry.problem import ReentryProblem


@dataclass
class InitialGuess:
    """A guess on any time grid: ``t`` (N,), ``x`` (NX, N), ``u`` (NU, N), physical units."""

    t: np.ndarray
    x: np.ndarray
    u: np.ndarray


def rhs_numpy(vehicle):
    """Fast scalar right-hand side for the adaptive integrator: one compiled CasADi call
    costs a few microseconds where the numpy expression of 6-vectors costs ~50."""
    xs, us = ca.SX.sym("x", NX), ca.SX.sym("u", NU)
    f = ca.Function("eom", [xs, us], [dyn.eom(xs, us, vehicle, ca)])

    def rhs(x, u):
        return f(x, u).full().ravel()
    return rhs


@functools.lru_cache(maxsize=8)    # vehicles are frozen dataclasses: the build (~50 ms) once per vehicle
def _glide_steps(vehicle, *, dt: float, steps: int) -> ca.Function:
    """``(x0, u) -> X (NX, steps)``: ``steps`` RK4 steps of ``dt`` with constant controls, in one
    CasADi call (the same arithmetic, in the same order, as a numpy loop over :func:`rhs_numpy`,
    without ~1,400 Python-level calls)."""
    xs, us = ca.SX.sym("x", NX), ca.SX.sym("u", NU)
    f = ca.Function("eom", [xs, us], [dyn.eom(xs, us, vehicle, ca)])
    k1 = f(xs, us)
    k2 = f(xs + 0.5 * dt * k1, us)
    k3 = f(xs + 0.5 * dt * k2, us)
    k4 = f(xs + dt * k3, us)
    step = ca.Function("glide_step", [xs, us], [xs + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)])
    return step.mapaccum("glide", steps)


def simulate_constant_controls(problem: ReentryProblem, *, alpha_rad: float, bank_rad: float,
                               t_max: float = 5000.0, dt: float = 5.0) -> InitialGuess:
    """Fixed-step RK4 glide with constant controls until the terminal altitude or speed is reached.

    The controls are clipped to the problem's bounds (a capsule's alpha range is far from the
    shuttle's 17 deg), so the guess is a trajectory the problem can fly."""
    u = np.array([np.clip(alpha_rad, *problem.alpha_bounds_rad), np.clip(bank_rad, *problem.bank_bounds_rad)])
    x0 = np.asarray(problem.initial_state, float)
    h_end = problem.terminal.altitude_m if problem.terminal.altitude_m is not None else 0.0
    v_end = problem.terminal.speed_mps if problem.terminal.speed_mps is not None else 0.0
    ts = [0.0]
    while ts[-1] < t_max:                 # the times a step-by-step loop would reach
        ts.append(ts[-1] + dt)
    X = np.hstack([x0[:, None], np.asarray(_glide_steps(problem.vehicle, dt=dt, steps=len(ts) - 1)(x0, u))])
    # Stop after the first state at or past the terminal altitude or speed (the loop's test).
    done = (X[ALTITUDE] <= h_end) | (X[SPEED] <= max(v_end, problem.min_speed_mps)) | ~np.isfinite(X).all(axis=0)
    n = int(np.argmax(done)) + 1 if done.any() else X.shape[1]
    X = X[:, :n]
    return InitialGuess(t=np.array(ts[:n]), x=X, u=np.tile(u[:, None], (1, n)))


def linear_guess(problem: ReentryProblem, *, tf: float = 2000.0,
                 alpha_rad: float = 17.0 * sh.DEG, bank_rad: float = -60.0 * sh.DEG) -> InitialGuess:
    """States on straight lines from the initial state to the terminal values (free components:
    a plausible end point), constant controls."""
    x0 = np.asarray(problem.initial_state, float)
    xf = problem.terminal.as_array()
    default_end = np.array([sh.BETTS_TERMINAL["altitude_m"], x0[LONGITUDE] + 1.2, x0[LATITUDE] + 0.5,
                            sh.BETTS_TERMINAL["speed_mps"], sh.BETTS_TERMINAL["flight_path_rad"], 0.0])
    xf = np.where(np.isnan(xf), default_end, xf)
    s = np.linspace(0.0, 1.0, 11)
    X = x0[:, None] + (xf - x0)[:, None] * s[None, :]
    alpha_rad, bank_rad = np.clip(alpha_rad, *problem.alpha_bounds_rad), np.clip(bank_rad, *problem.bank_bounds_rad)
    U = np.tile(np.array([[alpha_rad], [bank_rad]]), (1, s.size))
    return InitialGuess(t=s * tf, x=X, u=U)


def on_grid(guess: InitialGuess, m: int, control: str):
    """A guess interpolated onto ``m`` intervals of normalized time: ``(tf, x, u)`` as the NLP wants."""
    tf = float(guess.t[-1])
    tau = np.linspace(0.0, 1.0, m + 1)
    tg = np.asarray(guess.t, float) / tf
    x = np.vstack([np.interp(tau, tg, row) for row in np.asarray(guess.x, float)])
    nun = control_nodes(m, control)
    tu = tau if control == "linear" else 0.5 * (tau[:-1] + tau[1:])
    u = np.vstack([np.interp(tu, tg, row) for row in np.asarray(guess.u, float)])
    return tf, x, u[:, :nun]
