"""The numbers of one job on a built phase NLP: scales, bounds and the parameter vector, and the
decision vector packed and unpacked with them (:class:`Attempt`: one IPOPT answer in physical units).

Every phase of a problem gets its numbers here, whether it is the whole problem or one phase of
several (:mod:`solvers.ocp.solver` places them in the problem's vectors).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from solvers.ocp.phase import PhaseNLP, positive_scale
from solvers.ocp.problem import PhaseProblem

TF_MIN_FRACTION = 1e-6      # a free phase lasts at least this fraction of its time scale


@dataclass
class Numbers:
    """The numbers of one job on a built structure: parameter vector, bounds, scales."""

    p: np.ndarray
    lbz: np.ndarray
    ubz: np.ndarray
    lbg: np.ndarray
    ubg: np.ndarray
    x_scale: np.ndarray
    u_scale: np.ndarray
    t_scale: float
    theta_scale: np.ndarray
    path_scale: np.ndarray
    path_slices: slice | None


def state_scales(problem: PhaseProblem) -> np.ndarray:
    """Each state's ``scale``, or a typical magnitude from its bounds and ends."""
    return np.array([s.scale or positive_scale(s.lower, s.upper, s.initial, s.final) for s in problem.phase.states])


def control_scales(problem: PhaseProblem) -> np.ndarray:
    """Each control's ``scale``, or a typical magnitude from its bounds."""
    return np.array([k.scale or positive_scale(k.lower, k.upper) for k in problem.phase.controls])


def _scales(problem: PhaseProblem, tf_guess: float):
    ph = problem.phase
    xs, us = state_scales(problem), control_scales(problem)
    ts = positive_scale(ph.time.initial, tf_guess, ph.time.final_upper)
    ths = np.array([positive_scale(q.lower, q.upper, q.guess) for q in problem.parameters])
    return xs, us, ts, ths


def numbers_of(problem: PhaseProblem, nlp: PhaseNLP, tf_guess: float) -> Numbers:
    ph, g = problem.phase, nlp.grid
    N, Nu = g.n_nodes, g.n_controls
    xs, us, ts, ths = _scales(problem, tf_guess)
    t0 = ph.time.initial
    inf = np.inf

    def lo(v):
        return -inf if v is None else v

    def hi(v):
        return inf if v is None else v

    if ph.time.final is not None:
        tf_lb = tf_ub = ph.time.final
    else:
        tf_lb = max(lo(ph.time.final_lower), t0 + TF_MIN_FRACTION * ts)
        tf_ub = hi(ph.time.final_upper)
    x_lb = np.tile(np.array([lo(s.lower) for s in ph.states])[:, None], (1, N))
    x_ub = np.tile(np.array([hi(s.upper) for s in ph.states])[:, None], (1, N))
    for i, s in enumerate(ph.states):
        if s.initial is not None:
            x_lb[i, 0] = x_ub[i, 0] = s.initial
        if s.final is not None:
            x_lb[i, -1] = x_ub[i, -1] = s.final
    u_lb = np.tile(np.array([lo(k.lower) for k in ph.controls]).reshape(-1, 1), (1, Nu))
    u_ub = np.tile(np.array([hi(k.upper) for k in ph.controls]).reshape(-1, 1), (1, Nu))
    th_lb = np.array([lo(q.lower) for q in problem.parameters])
    th_ub = np.array([hi(q.upper) for q in problem.parameters])

    def pack(tf, th, x, u):
        return np.concatenate([[tf / ts], np.asarray(th, float) / ths,
                               (x / xs[:, None]).ravel(order="F"), (u / us[:, None]).ravel(order="F")])

    path_scale = np.array([positive_scale(c.lower, c.upper) for c in ph.path])
    bnd_scale = np.array([positive_scale(c.lower, c.upper) for c in ph.boundary])
    c = np.array([v for _, v in problem.constants])
    p = np.concatenate([c, [t0], xs, us, [ts], ths, path_scale, bnd_scale, [1.0]])
    lbg, ubg, path_slice, i = [], [], None, 0
    for name, n in nlp.layout:
        if name == "defects":
            lbg.append(np.zeros(n))
            ubg.append(np.zeros(n))
        elif name == "path":
            path_slice = slice(i, i + n)
            lbg.append(np.tile([lo(k.lower) / s for k, s in zip(ph.path, path_scale)], N))
            ubg.append(np.tile([hi(k.upper) / s for k, s in zip(ph.path, path_scale)], N))
        else:
            lbg.append(np.array([lo(k.lower) / s for k, s in zip(ph.boundary, bnd_scale)]))
            ubg.append(np.array([hi(k.upper) / s for k, s in zip(ph.boundary, bnd_scale)]))
        i += n
    nlp.pack = pack
    return Numbers(p=p, lbz=pack(tf_lb, th_lb, x_lb, u_lb), ubz=pack(tf_ub, th_ub, x_ub, u_ub),
                   lbg=np.concatenate(lbg), ubg=np.concatenate(ubg), x_scale=xs, u_scale=us,
                   t_scale=ts, theta_scale=ths, path_scale=path_scale, path_slices=path_slice)


class Attempt:
    """One phase of an IPOPT answer, unpacked into physical arrays: ``z`` the phase's own columns of
    the answer (:class:`solvers.ocp.phase.PhaseNLP`'s decision vector)."""

    def __init__(self, nlp: PhaseNLP, num: Numbers, z: np.ndarray):
        fns, g = nlp.fns, nlp.grid
        i = 1 + fns.ntheta
        j = i + fns.nx * g.n_nodes
        self.tf = float(z[0]) * num.t_scale
        self.theta = z[1:i] * num.theta_scale
        self.X = z[i:j].reshape((fns.nx, g.n_nodes), order="F") * num.x_scale[:, None]
        self.U = z[j:].reshape((fns.nu, g.n_controls), order="F") * num.u_scale[:, None]
