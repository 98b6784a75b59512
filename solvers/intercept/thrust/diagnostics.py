"""Checks of a solution that do not trust the NLP: segment re-propagation defects (for
refinement), the inertial two-body re-propagation of the controls (verification), the
optimality evidence from the costates (Hamiltonian, switching function, primer), and
the arc and burn tables of the result."""
from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp

from solvers.intercept.thrust.layout import Layout
from solvers.intercept.thrust.problem import FiniteThrustProblem, Scaled
from solvers.models import relative_motion as rm
from solvers.transcription.lgl import Mesh, lagrange_matrix, lgl_nodes

# ----------------------------------------------------------------------------- analysis

def segment_defects(s: Scaled, *, mesh: Mesh, X, U, tf) -> np.ndarray:
    """Re-propagate every segment from its first node (all segments stacked in one
    ODE in the segment-normalised time) and return the end-state mismatch (7, S)."""
    S, N = mesh.segments, mesh.nodes
    h = mesh.fractions * tf
    Xs = X.reshape((rm.NX, S, N))
    Us = U.reshape((rm.NU, S, N))
    nodes = lgl_nodes(N)

    def rhs(tau, y):
        x = y.reshape((rm.NX, S))
        uu = Us @ lagrange_matrix(nodes, np.array([tau]))[0]      # (4, S)
        f = rm.dynamics_numpy(x, s.tmax * uu[0] * uu[1:], s.tmax * uu[0] / s.c)
        return (0.5 * h[None, :] * f).ravel()

    sol = solve_ivp(rhs, (-1.0, 1.0), Xs[:, :, 0].ravel(), method="DOP853", rtol=1e-10, atol=1e-12)
    return sol.y[:, -1].reshape((rm.NX, S)) - Xs[:, :, -1]


def verify_controls(problem: FiniteThrustProblem, *, s: Scaled, mesh: Mesh, X, U, tf) -> dict:
    """Inertial two-body re-propagation of both bodies under the interpolated controls."""
    L, Tm = s.sc.length_m, s.sc.time_s
    V = L / Tm
    r_i, v_i, r_t, v_t = problem.scenario.initial_states()
    r_i, v_i, r_t, v_t = r_i / L, v_i / V, r_t / L, v_t / V
    y = np.concatenate([r_i, v_i, [1.0], r_t, v_t])
    S, N = mesh.segments, mesh.nodes
    Us = U.reshape((rm.NU, S, N))
    nodes = lgl_nodes(N)
    b = np.asarray(mesh.boundaries) * tf

    def rhs_for(k):
        t0, t1 = b[k], b[k + 1]

        def rhs(t, y):
            tau = 2.0 * (t - t0) / (t1 - t0) - 1.0
            uu = Us[:, k, :] @ lagrange_matrix(nodes, np.array([tau]))[0]
            ri, vi, m, rt, vt = y[:3], y[3:6], y[6], y[7:10], y[10:13]
            thrust_i = rm.hill_axes(rt, vt).T @ (s.tmax * uu[0] * uu[1:])
            ai = -ri / np.linalg.norm(ri) ** 3 + thrust_i / m
            at = -rt / np.linalg.norm(rt) ** 3
            return np.concatenate([vi, ai, [-s.tmax * uu[0] / s.c], vt, at])
        return rhs

    nfev = 0
    r_min = float(np.linalg.norm(r_i))
    for k in range(S):
        if b[k + 1] - b[k] < 1e-9:
            continue
        sol = solve_ivp(rhs_for(k), (b[k], b[k + 1]), y, method="DOP853", rtol=1e-10, atol=1e-13,
                        dense_output=True)
        y = sol.y[:, -1]
        nfev += sol.nfev
        # the interceptor's distance from the Earth's centre, sampled densely (a segment is at most
        # ~1000 s: 64 samples resolve a periapsis passage to a few km)
        r_min = min(r_min, float(np.min(np.linalg.norm(sol.sol(np.linspace(b[k], b[k + 1], 64))[:3], axis=0))))
    dr = (y[:3] - y[7:10]) * L
    dv = (y[3:6] - y[10:13]) * V
    return {
        "miss_distance_m": float(np.linalg.norm(dr)),
        "relative_speed_mps": float(np.linalg.norm(dv)),
        "propellant_kg": float((1.0 - y[6]) * problem.scenario.mass_kg),
        "final_mass_kg": float(y[6] * problem.scenario.mass_kg),
        "collocation_propellant_kg": float((1.0 - X[6, -1]) * problem.scenario.mass_kg),
        "integrator": "DOP853 rtol 1e-10, inertial two-body, both bodies",
        "function_evaluations": int(nfev),
        "min_radius_m": r_min * L,
        "through_planet": bool(r_min * L < problem.scenario.body_radius_m),
    }


def optimality_evidence(s: Scaled, *, layout: Layout, mesh: Mesh, X, U, tf, lam: np.ndarray,
                        lam_tf: float, free_tf: bool) -> tuple[dict, dict]:
    """Hamiltonian constancy and value, switching-function agreement with the thrust and the
    thrust-primer alignment, from the costates ``lam`` (see the package docstring); and the
    Hamiltonian and switching function along the nodes."""
    S, N = mesh.segments, mesh.nodes
    thrust = s.tmax * U[0] * U[1:]
    terms = lam * rm.dynamics_numpy(X, thrust, s.tmax * U[0] / s.c)
    H = terms.sum(axis=0)
    # Segment-end nodes carry the boundary terms of the covector mapping (closure
    # conditions), and zero-length arcs carry no information: use the rest.
    interior = np.tile(np.r_[False, np.ones(N - 2, bool), False], S)
    interior &= np.repeat(mesh.fractions * tf > 1e-6, N)
    scale = float(np.max(np.abs(terms[:, interior]).sum(axis=0)))
    Hi = H[interior]
    lam_v = np.linalg.norm(lam[3:6], axis=0)
    sw = lam_v / X[6] + lam[6] / s.c
    on = U[0] > 0.5
    decided = interior & (np.abs(sw) > 1e-3 * max(float(np.max(np.abs(sw[interior]))), 1e-300))
    agree = (sw > 0) == on
    burning = on & interior & (lam_v > 0)
    cosang = -np.sum(U[1:] * lam[3:6], axis=0) / np.maximum(lam_v * np.linalg.norm(U[1:], axis=0), 1e-300)
    # H = -dJ/dtf, read off the multiplier of tf's bounds: zero for a free tf off its
    # bounds, the price of the bound where it is fixed or pinned at a bound
    expected = float(-lam_tf)
    out = {
        "hamiltonian_mean": float(np.mean(Hi)),
        "hamiltonian_std": float(np.std(Hi)),
        "hamiltonian_relative_variation": float((np.max(Hi) - np.min(Hi)) / scale),
        "hamiltonian_expected": expected,
        "hamiltonian_relative_error": float(abs(np.mean(Hi) - expected) / scale),
        "tf_free_and_off_bounds": bool(free_tf and abs(lam_tf) < 1e-9 * max(scale, 1.0)),
        "hamiltonian_scale": scale,
        "hamiltonian_units": "nondimensional (mass m0, time 1/n)",
        "costate_mass_final": float(lam[6, -1]),
        "switching_function_agreement": float(np.mean(agree[decided])) if decided.any() else 1.0,
        "switching_function_mismatches": int(np.sum(~agree & decided)),
        "switching_function_max_on_coasts": float(np.max(sw[interior & ~on], initial=-np.inf)
                                                  / max(float(np.max(np.abs(sw[interior]))), 1e-300)),
        "nodes_checked": int(decided.sum()),
        "thrust_primer_alignment_min_cos": float(np.min(cosang[burning])) if burning.any() else 1.0,
    }
    return out, {"t_s": mesh.node_fractions().ravel() * tf * s.sc.time_s, "hamiltonian": H,
                 "switching_function": sw, "interior": interior}


def arc_table(layout: Layout, mesh: Mesh, X, tf_s: float, problem: FiniteThrustProblem) -> list[dict]:
    """One row per arc: kind, start, end, duration, segments and the propellant it burns."""
    out, k = [], 0
    b = np.asarray(mesh.boundaries) * tf_s
    N = layout.nodes
    for arc in layout.arcs:
        k1 = k + arc.segments
        m0, m1 = X[6, k * N] * problem.scenario.mass_kg, X[6, k1 * N - 1] * problem.scenario.mass_kg
        out.append({"kind": arc.kind, "start_s": float(b[k]), "end_s": float(b[k1]),
                    "duration_s": float(b[k1] - b[k]), "segments": arc.segments, "propellant_kg": float(m0 - m1)})
        k = k1
    return out


def burns_from_throttle(t, u, mesh: Mesh, problem: FiniteThrustProblem) -> list[dict]:
    """Burns of a free-throttle solution: runs of nodes above half throttle."""
    on = u > 0.5
    out, k = [], 0
    while k < on.size:
        if on[k]:
            j = k
            while j + 1 < on.size and on[j + 1]:
                j += 1
            out.append({"kind": "burn", "start_s": float(t[k]), "end_s": float(t[j]),
                        "duration_s": float(t[j] - t[k])})
            k = j + 1
        else:
            k += 1
    return out
