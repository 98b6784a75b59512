"""Trajectories of a midcourse transfer to export (a CCSDS OEM): the error-free nominal coast and the
corrected flight of one correction schedule, flown with the solver's own models.

What this module is for: a midcourse result stores schedules and objectives, not trajectories
(paper 002's front has up to a population of points).  Any one of them is re-flown here on demand:
the impulses are the solver's own (:meth:`solvers.midcourse.CorrectionEvaluator.evaluate_samples`
with ``keep_impulses``: the Lambert re-targeting on the branch closest to the current velocity), and
every coast is the same heyoka J2 propagation (:class:`solvers.astro.j2.J2Propagator`, tolerance
``problem.tol``) read through its Taylor dense output, so the final errors equal the front point's
objectives (a test checks it).  The initial error is the problem's fixed offset; with a dispersion
it is that offset, the per-axis 3-sigma, as one representative sample.

States are geocentric along the problem frame's axes; :func:`inertial_rotation` turns them into an
Earth-centred inertial frame with ``z`` along the Earth's spin axis and ``x`` in the launch
meridian at t0 (the launch-inertial frame of paper 002 is inertial and only translated by ``R0``).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from solvers.astro.j2 import LaunchFrame
from solvers.midcourse.problem import MidcourseProblem
from solvers.midcourse.solver import CorrectionEvaluator

__all__ = ["Arc", "TransferTrajectories", "inertial_rotation", "transfer_trajectories"]


@dataclass
class Arc:
    """One coast: times (n,) s and geocentric states (n, 6) in m and m/s along the frame's axes."""

    t_s: np.ndarray
    states: np.ndarray


@dataclass
class TransferTrajectories:
    nominal: Arc                    # error-free initial state, no correction, 0 to tf
    corrected: list[Arc]            # the erroneous flight, one arc per coast between corrections
    correction_times_s: np.ndarray  # (k,) s
    impulses_mps: np.ndarray        # (k, 3) m/s, frame axes
    objectives: np.ndarray          # (3,) total delta-v m/s, final position error m, velocity error m/s


def inertial_rotation(frame: LaunchFrame) -> np.ndarray:
    """``M`` (3, 3) with ``x_eci = M @ x_frame``: ``z`` the spin axis, ``x`` toward the equatorial
    projection of the frame's origin (the launch meridian at t0), ``y = z x x``.

    An Earth-centred frame (``r0 = 0``) with the spin axis along ``z`` is returned unchanged.
    """
    w = np.asarray(frame.spin_axis, float)
    w = w / np.linalg.norm(w)
    r0 = np.asarray(frame.r0, float)
    eq = r0 - (r0 @ w) * w
    if np.linalg.norm(eq) <= 1e-9 * max(float(np.linalg.norm(r0)), 1.0):
        eq = np.array([1.0, 0.0, 0.0]) - w[0] * w   # no launch point: keep the frame's own x
    x = eq / np.linalg.norm(eq)
    return np.vstack([x, np.cross(w, x), w])


def _grid(t0: float, t1: float, step_s: float) -> np.ndarray:
    inner = np.arange(t0, t1, step_s)
    return np.unique(np.concatenate([inner, [t1]])) if t1 > t0 else np.array([t0])


def transfer_trajectories(problem: MidcourseProblem, times_s, *, step_s: float = 60.0) -> TransferTrajectories:
    """The nominal coast and the flight corrected at ``times_s``, sampled every ``step_s`` and at
    each correction (the state just before the impulse ends one arc, the one after starts the next)."""
    fixed = dataclasses.replace(problem, dispersion=None)
    ev = CorrectionEvaluator(fixed)
    times = np.sort(np.asarray(times_s, float).reshape(-1))
    f, impulses = ev.evaluate_samples(times[None, :], keep_impulses=True)
    impulses = impulses[0, 0]
    tf = float(problem.tf_s)
    r0 = np.asarray(problem.r0, float) + problem.frame.r0
    start = np.concatenate([r0, np.asarray(problem.v0, float)])
    grid = _grid(0.0, tf, step_s)
    nominal = Arc(grid, ev.prop.dense(start, t0=0.0, t1=tf)(grid))

    arcs: list[Arc] = []
    state, t_prev = ev.initial[0].copy(), 0.0
    for j, t_next in enumerate([*times, tf]):
        if t_next > t_prev:
            g = _grid(t_prev, t_next, step_s)
            states = ev.prop.dense(state, t0=t_prev, t1=t_next)(g)
            arcs.append(Arc(g, states))
            state = states[-1].copy()
        if j < times.size:
            state[3:] += impulses[j]
        t_prev = t_next
    return TransferTrajectories(nominal=nominal, corrected=arcs, correction_times_s=times,
                                impulses_mps=impulses, objectives=f[0, 0])
