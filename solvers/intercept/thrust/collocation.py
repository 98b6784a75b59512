"""The NLP of one round: integral/differential LGL collocation of the nondimensional Hill
dynamics over the arcs (CasADi, built once per structure and cached), its bounds, the
packing of states/controls/durations into the decision vector, and the costates read
back from the defect multipliers (Fahroo & Ross 2001, covector mapping)."""
from __future__ import annotations

import casadi as ca
import numpy as np

from solvers.intercept.thrust.layout import Layout
from solvers.intercept.thrust.problem import Scaled
from solvers.models import relative_motion as rm
from solvers.transcription.lgl import collocation_constraints, legendre, lgl_integration_matrix, lgl_nodes, lgl_weights
from solvers.transcription.nlp import NLPSolver

# ----------------------------------------------------------------------------- NLP

def hill_dynamics_function() -> ca.Function:
    """The nondimensional Hill dynamics ``f(x, u, [tmax, c])`` as a CasADi function."""
    x = ca.SX.sym("x", rm.NX)
    u = ca.SX.sym("u", rm.NU)
    p = ca.SX.sym("p", 2)  # tmax, c (nondimensional)
    return ca.Function("hill", [x, u, p], [rm.dynamics_casadi(x, u, p[0], p[1])])


def build_nlp(layout: Layout, max_iter: int) -> NLPSolver:
    """The collocation NLP of one layout (maximise final mass); cached by the caller per structure."""
    N, A, S = layout.nodes, len(layout.arcs), layout.segments
    K = S * N
    X = ca.SX.sym("X", rm.NX, K)
    Dv = ca.SX.sym("d", 3, layout.count("burn", "free"))
    Th = ca.SX.sym("u", 1, layout.count("free"))
    tf = ca.SX.sym("tf")
    sigma = ca.SX.sym("sigma", A)
    blocks, dur = [], []
    i_d = i_u = 0
    for a in layout.arc_of_segment:
        kind = layout.arcs[a].kind
        if kind == "coast":
            blocks.append(ca.SX.zeros(rm.NU, N))
        else:
            thr = ca.SX.ones(1, N) if kind == "burn" else Th[:, i_u:i_u + N]
            i_u += N if kind == "free" else 0
            blocks.append(ca.vertcat(thr, Dv[:, i_d:i_d + N]))
            i_d += N
        dur.append(tf * sigma[a] / layout.arcs[a].segments)
    U = ca.horzcat(*blocks)
    eng = ca.SX.sym("eng", 2)
    defects, cont = collocation_constraints(dynamics=hill_dynamics_function(), X=X, U=U, params=eng,
                                            seg_duration=ca.horzcat(*dur), nodes=N, segments=S,
                                            form=layout.form)
    g = [ca.vec(defects), ca.vec(cont), ca.vec(ca.sum1(Dv ** 2))]
    if layout.free_durations:   # with fixed arcs the sum is data, and a constant row would break LICQ
        g.append(ca.sum1(sigma))
    w = ca.vertcat(ca.vec(X), ca.vec(Dv), ca.vec(Th), tf, sigma)
    nlp = {"x": w, "f": -X[6, K - 1], "g": ca.vertcat(*g), "p": eng}
    ipopt = {"max_iter": max_iter, "tol": 1e-9, "acceptable_tol": 1e-7, "acceptable_iter": 10}
    kinds = "".join(arc.kind[0] for arc in layout.arcs)
    return NLPSolver(nlp, name=f"intercept_lgl_{kinds}_{S}x{N}", ipopt=ipopt)


def nlp_bounds(layout: Layout, s: Scaled, free_tf: bool):
    """``(lbx, ubx, lbg, ubg)`` of the NLP: fixed initial state, zero final relative position, tf and arc bounds."""
    K = layout.segments * layout.nodes
    big = 50.0
    lbX = np.tile(np.array([-big] * 6 + [s.m_dry])[:, None], (1, K))
    ubX = np.tile(np.array([big] * 6 + [1.0])[:, None], (1, K))
    lbX[:, 0] = ubX[:, 0] = s.x0
    lbX[:3, -1] = ubX[:3, -1] = 0.0
    nd, nt = layout.count("burn", "free"), layout.count("free")
    lo, hi = (s.tf_lo, s.tf_hi) if free_tf else (s.tf, s.tf)
    sig = np.asarray(layout.sigma, float)
    A = sig.size
    lbs, ubs = (np.zeros(A), np.ones(A)) if layout.free_durations else (sig, sig)
    lbx = np.concatenate([lbX.ravel(order="F"), -np.ones(3 * nd), np.zeros(nt), [lo], lbs])
    ubx = np.concatenate([ubX.ravel(order="F"), np.ones(3 * nd), np.ones(nt), [hi], ubs])
    ng = rm.NX * layout.segments * layout.defect_nodes + rm.NX * (layout.segments - 1)
    one = [1.0] if layout.free_durations else []
    lbg = np.concatenate([np.zeros(ng), np.full(nd, -np.inf), one])
    ubg = np.concatenate([np.zeros(ng), np.ones(nd), one])
    return lbx, ubx, lbg, ubg


def pack_variables(layout: Layout, X, U, tf, sigma) -> np.ndarray:
    """The NLP decision vector from states, controls, tf and arc fractions."""
    thr = layout.throttle()
    dmask = ~(thr == 0.0)
    fmask = np.isnan(thr)
    return np.concatenate([X.ravel(order="F"), U[1:, dmask].ravel(order="F"), U[0, fmask],
                           [tf], np.asarray(sigma, float)])


def unpack_variables(layout: Layout, w: np.ndarray):
    """``(X, U, tf, sigma, index of tf)`` from the NLP decision vector."""
    K = layout.segments * layout.nodes
    thr = layout.throttle()
    dmask = ~(thr == 0.0)
    fmask = np.isnan(thr)
    nd, nt = int(dmask.sum()), int(fmask.sum())
    X = w[: rm.NX * K].reshape((rm.NX, K), order="F")
    i = rm.NX * K
    U = np.zeros((rm.NU, K))
    U[1:, dmask] = w[i:i + 3 * nd].reshape((3, nd), order="F")
    i += 3 * nd
    U[0] = np.where(np.isnan(thr), 0.0, thr)
    U[0, fmask] = w[i:i + nt]
    i += nt
    return X, U, float(w[i]), w[i + 1:].copy(), i


def filter_costates(lam: np.ndarray, N: int) -> np.ndarray:
    """Remove the degree N-1 Legendre mode from each segment's costate estimates.

    ``D`` on N LGL nodes has a left null vector ``w_i P_{N-1}(tau_i)`` (an
    alternating sign pattern), so the multipliers' component along it is fixed
    only by the small ``h/2 f_x`` term and carries an odd-even oscillation
    (Garg et al., Automatica 46, 2010, on LPM costates).  The LGL rule is exact
    for degree 2N-3, so the mode is discretely orthogonal to all lower ones and
    can be projected out without touching them.
    """
    tau = lgl_nodes(N)
    w = lgl_weights(N)
    P = legendre(N - 1, tau)
    L = lam.reshape((lam.shape[0], -1, N))
    c = np.einsum("ksn,n->ks", L, w * P) / float(w @ P**2)
    return (L - c[..., None] * P).reshape(lam.shape)


def costates(layout: Layout, lam_g: np.ndarray) -> np.ndarray:
    """Costates (7, K) at the nodes from the collocation multipliers."""
    N, S = layout.nodes, layout.segments
    w = lgl_weights(N)
    nu = lam_g[: rm.NX * S * layout.defect_nodes].reshape((rm.NX, S * layout.defect_nodes), order="F")
    if layout.form == "differential":
        return filter_costates(-nu / np.tile(w, S)[None, :], N)
    A = lgl_integration_matrix(N)[1:]
    lam = -np.einsum("ksi,ij->ksj", nu.reshape((rm.NX, S, N - 1)), A) / w
    return lam.reshape((rm.NX, S * N))
