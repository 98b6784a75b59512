"""Robust reentry design with CADET covariance propagation (the ``robust_reentry`` job kind).

Problem: paper 001 (Liu Xu et al., reentry trajectory robust optimization based on the
covariance analysis describing function technique, 2020), eqs. (13)-(16): the Betts
heat-limited maximum-crossrange shuttle reentry (Betts, *Practical Methods for Optimal
Control*, 2nd ed., sec. 6.3) with uncertain aerodynamics ``CD = CD_N (1 + s1)``,
``CL = CL_N (1 + s2)``, ``s ~ N(mu_s, P_ss)`` constant over the flight, solved as

    max  mu(lat_f) - kJ sigma(lat_f)
    s.t. CADET mean/covariance dynamics (:mod:`solvers.uncertainty.cadet`)
         mu(q) + kC sigma(q) <= q_max         (at the nodes and every RK4 substep)
         mu(h_f, v_f, gamma_f) = required,   sigma(h_f, v_f, gamma_f) <= limits

on the deterministic problem's own multiple-shooting transcription
(:mod:`solvers.transcription.multiple_shooting`) with the 39-state augmented system
(6 means, 21 upper-triangle entries of P_xx, 12 of P_xs).  The robust heating limit is
written without a square root: ``q_max - mu >= 0`` and ``kC^2 var <= (q_max - mu)^2``.
The variance limits are plain bounds on the final node's variance entries.

Continuation (the single-stage solve is badly conditioned): the deterministic optimum (DO)
supplies the mean, CADET along its controls the covariance; stage 1 has ``kJ = kC = 0`` and
no sigma limits, stage 2 is the full problem.  Both stages share one built solver (the
weights are NLP parameters, the sigma limits bounds).

Monte Carlo validation of both designs: :mod:`solvers.robust_reentry.mc` (``monte_carlo_spec``
is on the package's face too).
"""
from __future__ import annotations

import dataclasses
import time

import casadi as ca
import numpy as np

from solvers import reentry as det
from solvers.common import ProgressFn, StopFn
from solvers.models import reentry_dynamics as dyn
from solvers.models import shuttle as sh
from solvers.models.reentry_state import LATITUDE, NU, NX, U_SCALE, X_SCALE
from solvers.robust_reentry.mc import TERMINAL_INDEX
from solvers.robust_reentry.problem import (NS, S_SCALE, SIGMA_NORM, SIGMA_SCALE, WARM_IPOPT, Prediction,
                                            RobustReentryProblem, RobustReentrySolution)
from solvers.transcription.multiple_shooting import PathConstraint, ShootingProblem, Transcription
from solvers.uncertainty.cadet import CadetSensitivity, CadetSystem

# --- the CADET system of the shuttle --------------------------------------------------------
def _heat_moments(cad: CadetSensitivity, vehicle: sh.Vehicle, q_max: float) -> ca.Function:
    x = ca.SX.sym("x", NX)
    u = ca.SX.sym("u", NU)
    s = ca.SX.sym("s", NS)
    c = ca.Function("qn", [x, u, s], [dyn.heat_rate(x, u, vehicle, ca) / q_max])
    return cad.output_moments(c, name="heat_moments")


def _sens(problem: "RobustReentryProblem") -> CadetSensitivity:
    x = ca.SX.sym("x", NX)
    u = ca.SX.sym("u", NU)
    s = ca.SX.sym("s", NS)
    v = problem.base.vehicle
    f = ca.Function("eom", [x, u, s], [dyn.eom(x, u, v, ca, cd_scale=1 + s[0], cl_scale=1 + s[1])])
    return CadetSensitivity(f, nx=NX, nu=NU, ns=NS, r0=problem.uncertainty.r0,
                            second_order=problem.robust.second_order)


def _robust_problem(problem: RobustReentryProblem, cad: CadetSensitivity, *, ipopt: dict | None = None) -> ShootingProblem:
    base, rob = problem.base, problem.robust
    vehicle = base.vehicle
    if base.max_heat_rate_w_m2 is None:
        raise ValueError("the robust problem needs a heat-rate limit (max_heat_rate_w_m2)")
    q_max = float(base.max_heat_rate_w_m2)
    nth = cad.n_theta
    hm = _heat_moments(cad, vehicle, q_max)
    margin = 1.0 - rob.heat_margin

    def dynamics(z, u, p):
        return cad.rhs(z, u, p[:nth])

    def heat(z, u, p):
        kc = p[nth + 1]
        mu, var = hm(z, u, p[:nth])
        slack = margin - mu
        # no sqrt: mu + kC sigma <= 1  <=>  1 - mu >= 0  and  kC^2 var <= (1 - mu)^2
        return ca.vertcat(mu - margin, kc ** 2 * ca.fmax(var, 0) - ca.fmax(slack, 0) ** 2)

    def mayer(zf, T, p):
        kj = p[nth]
        var = cad.variance_of_state(zf, p[:nth], LATITUDE)
        return -(zf[LATITUDE] - kj * ca.sqrt(ca.fmax(var, 0) + 1e-14))

    def terminal(zf, p):
        # variances of h_f, v_f, gamma_f over their limits squared: bounds (-inf, 1] in stage 2
        return ca.vertcat(*[cad.variance_of_state(zf, p[:nth], i) / SIGMA_NORM[n] ** 2
                            for n, i in TERMINAL_INDEX.items()])

    L = cad.layout
    w_scale = (1.0,) * cad.r0 + S_SCALE
    x_scale = L.scale_with_mean(X_SCALE, SIGMA_SCALE, w_scale)
    key = ("robust_reentry", vehicle, rob.second_order, cad.r0, float(q_max), float(rob.heat_margin))
    return ShootingProblem(
        key=key, nx=L.nz, nu=NU, n_params=nth + 2, dynamics=dynamics, x_scale=tuple(x_scale),
        u_scale=U_SCALE, t_scale=det.T_SCALE, intervals=base.intervals, control="linear",
        substeps=rob.substeps, mayer=mayer, terminal=terminal, n_terminal=len(TERMINAL_INDEX),
        path=(PathConstraint("robust_heat_rate", heat, size=2, where="substeps"),),
        # A warm start: IPOPT's adaptive barrier jumped to mu = 1e9 on the first step and
        # never recovered (the pitfall of the spec); a small monotone barrier converges.
        ipopt={"mu_strategy": "monotone", "mu_init": 1e-3, **base.ipopt, **(ipopt or {})},
        block_derivatives=True)


def _bounds(problem: RobustReentryProblem, cad: CadetSensitivity, *, sigma_limits: bool):
    base = problem.base
    m = base.intervals
    L = cad.layout
    x_lb6, x_ub6, u_lb, u_ub = det.state_bounds(base, m)  # the deterministic problem's own bounds
    big = 1e20
    x_lb = np.vstack([x_lb6, np.full((L.nz - NX, m + 1), -big)])
    x_ub = np.vstack([x_ub6, np.full((L.nz - NX, m + 1), big)])
    z0 = cad.initial(np.asarray(base.initial_state, float), problem.uncertainty.x0_cov)
    x_lb[:, 0] = z0
    x_ub[:, 0] = z0
    hi = np.full(len(TERMINAL_INDEX), np.inf)
    if sigma_limits:
        for k, name in enumerate(TERMINAL_INDEX):
            lim = problem.robust.sigma_limits.get(name)
            if lim is not None:
                hi[k] = (float(lim) / SIGMA_NORM[name]) ** 2
    return x_lb, x_ub, u_lb, u_ub, z0, (np.full(len(TERMINAL_INDEX), -np.inf), hi)


def predict(problem: RobustReentryProblem, *, t, u, second_order: bool | None = None,
            substeps: int | None = None) -> Prediction:
    """CADET means and sigmas along node controls ``u`` (2, m+1) at node times ``t``."""
    if second_order is not None and second_order != problem.robust.second_order:
        problem = dataclasses.replace(problem, robust=dataclasses.replace(problem.robust,
                                                                          second_order=second_order))
    cad = _sens(problem)
    unc = problem.uncertainty
    theta = CadetSystem.theta(unc.s_mean, unc.s_cov)
    z0 = cad.initial(np.asarray(problem.base.initial_state, float), unc.x0_cov)
    Z, _ = cad.propagate(z0=z0, controls=u, t_nodes=t, theta=theta,
                         substeps=substeps or problem.robust.substeps)
    return _prediction(problem, cad, t, Z, u, theta)


def _prediction(problem, cad, t, Z, u, theta) -> Prediction:
    m, Pxx, _ = cad.covariance(Z, theta)
    sig = np.sqrt(np.maximum(np.einsum("iik->ik", Pxx), 0.0))
    q_max = float(problem.base.max_heat_rate_w_m2)
    hm = _heat_moments(cad, problem.base.vehicle, q_max).map(Z.shape[1])
    mu, var = hm(Z, u, theta)
    return Prediction(t=np.asarray(t, float), mean=m, sigma=sig,
                      heat_mean=np.asarray(mu).ravel() * q_max,
                      heat_sigma=np.sqrt(np.maximum(np.asarray(var).ravel(), 0.0)) * q_max)


def solve(problem: RobustReentryProblem, *, initial_guess=None, on_progress: ProgressFn | None = None,
          should_stop: StopFn | None = None, seed=None) -> RobustReentrySolution:  # seed: deterministic
    """DO, then CADET along the DO controls, then the two robust stages."""
    progress = on_progress or (lambda f, msg: None)
    base = problem.base
    notes: list[str] = []

    def sub(lo, hi):
        return lambda f, msg: progress(lo + (hi - lo) * f, msg)

    # The DO is paper 001's comparison design and the RO's starting point: its heating limit at
    # the nodes, reported between them, as the paper's reference numbers were computed (the
    # reentry kind's default tightens it until it holds between the nodes: solvers.reentry.limits).
    do_base = dataclasses.replace(base, path_enforcement="nodes", limit_tolerance=None)
    do = det.solve(do_base, initial_guess=initial_guess, on_progress=sub(0.0, 0.3), should_stop=should_stop)
    stages = [{"stage": "deterministic", **{k: v for k, v in s.items() if k != "stage"},
               "sub_stage": s["stage"]} for s in do.stages]
    if not do.status.ok:
        status = dataclasses.replace(do.status, message=f"deterministic stage: {do.status.message}")
        return RobustReentrySolution(status=status, deterministic=do, tf_s=do.tf_s, t=do.t, x=do.x, u=do.u,
                                     objective_value=float("nan"), heat_rate=do.heat_rate,
                                     robust_prediction=None, deterministic_prediction=None,
                                     verification=None, stages=stages, notes=notes)

    t_build = time.perf_counter()
    cad = _sens(problem)
    rob = problem.robust
    if rob.continuation not in ("two_stage", "direct"):
        raise ValueError("continuation must be 'two_stage' or 'direct'")
    tr1 = None
    if rob.continuation == "two_stage":
        # Its own (cheap, 18-state) build: the loose tolerance is part of the solver options.
        tr1 = Transcription(_robust_problem(problem, cad, ipopt={"tol": rob.stage1_tol,
                                                                  "acceptable_tol": 10 * rob.stage1_tol,
                                                                  "mu_init": rob.stage1_mu_init}))
        # Stage 2 starts from stage 1's primal AND dual point (WARM_IPOPT): 18 iterations
        # instead of 40, same optimum (tf within 1e-5 s).
        tr = Transcription(_robust_problem(problem, cad, ipopt=WARM_IPOPT))
    else:
        tr = Transcription(_robust_problem(problem, cad))
    build_time = 0.0 if tr.was_cached else time.perf_counter() - t_build
    unc = problem.uncertainty
    theta = CadetSystem.theta(unc.s_mean, unc.s_cov)
    u_do = do.u_nodes_at_t
    Zdo, _ = cad.propagate(z0=_bounds(problem, cad, sigma_limits=False)[4], controls=u_do,
                           t_nodes=do.t, theta=theta, substeps=problem.robust.substeps)
    do_pred = _prediction(problem, cad, do.t, Zdo, u_do, theta)
    # The whole guess is the CADET propagation along the DO controls (mean with s = mu_s):
    # consistent with the matching conditions, only the terminal mean is off.  The DO nodes as
    # mean with this covariance leave O(1) covariance defects late in the flight, from which
    # IPOPT diverged.
    guess = (do.tf_s, Zdo, u_do)
    if tr1 is None:
        weights = [(tr, rob.k_objective, rob.k_constraint, True, (0.3, 0.97), "robust (full problem, direct)")]
    else:
        weights = [(tr1, 0.0, 0.0, False, (0.3, 0.6), "robust stage 1 (kJ = kC = 0, no sigma limits)"),
                   (tr, rob.k_objective, rob.k_constraint, True, (0.6, 0.97), "robust stage 2 (full problem)")]
    res = warm = None
    for trs, kj, kc, limits, span, label in weights:
        x_lb, x_ub, u_lb, u_ub, _, term = _bounds(problem, cad, sigma_limits=limits)
        p = np.concatenate([theta, [kj, kc]])
        res = trs.solve(p=p, x_lb=x_lb, x_ub=x_ub, u_lb=u_lb, u_ub=u_ub, tf_bounds=base.tf_bounds_s,
                       guess=guess, terminal_bounds=term, on_progress=sub(*span), should_stop=should_stop,
                       expected_iterations=60, warm=warm if trs is tr else None)
        stages.append({"stage": label, "status": res.status.solver_status,
                       "iterations": res.status.iterations, "solve_time_s": res.status.solve_time_s})
        if not res.status.ok:
            break
        guess = (res.tf, res.x, res.u)
        warm = res

    return _finish(problem, cad, do=do, res=res, stages=stages, build_time=build_time,
                   was_cached=tr.was_cached, do_pred=do_pred, notes=notes)


def resolve(problem: RobustReentryProblem, previous: RobustReentrySolution, *,
            on_progress: ProgressFn | None = None, should_stop: StopFn | None = None) -> RobustReentrySolution:
    """The full robust problem (stage 2) again for corrected settings of ``problem`` (its kC, sigma
    limits or heating margin), warm-started from ``previous``'s design: the Monte Carlo loop's
    re-solve.  kC is an NLP parameter and the limits are bounds, so the built solver is reused."""
    progress = on_progress or (lambda f, msg: None)
    base, rob = problem.base, problem.robust
    t_build = time.perf_counter()
    cad = _sens(problem)
    warm = previous.shooting
    tr = Transcription(_robust_problem(problem, cad, ipopt=WARM_IPOPT if warm is not None else None))
    build_time = 0.0 if tr.was_cached else time.perf_counter() - t_build
    unc = problem.uncertainty
    theta = CadetSystem.theta(unc.s_mean, unc.s_cov)
    guess = (previous.tf_s, previous.augmented, previous.u)
    x_lb, x_ub, u_lb, u_ub, _, term = _bounds(problem, cad, sigma_limits=True)
    res = tr.solve(p=np.concatenate([theta, [rob.k_objective, rob.k_constraint]]), x_lb=x_lb, x_ub=x_ub,
                   u_lb=u_lb, u_ub=u_ub, tf_bounds=base.tf_bounds_s, guess=guess, terminal_bounds=term,
                   on_progress=progress, should_stop=should_stop, expected_iterations=30, warm=warm)
    stages = [s for s in previous.stages if s["stage"] == "deterministic"]
    stages.append({"stage": f"robust re-solve (kC = {rob.k_constraint:.3f}, warm start)",
                   "status": res.status.solver_status, "iterations": res.status.iterations,
                   "solve_time_s": res.status.solve_time_s})
    return _finish(problem, cad, do=previous.deterministic, res=res, stages=stages, build_time=build_time,
                   was_cached=tr.was_cached, do_pred=previous.deterministic_prediction, notes=[])


def _finish(problem, cad, *, do, res, stages, build_time, was_cached, do_pred, notes) -> RobustReentrySolution:
    """Status over the robust stages, CADET prediction, objective and verification of a robust NLP result."""
    base, rob, unc = problem.base, problem.robust, problem.uncertainty
    theta = CadetSystem.theta(unc.s_mean, unc.s_cov)
    st = res.status
    status = dataclasses.replace(
        st, iterations=sum(s["iterations"] for s in stages if s["stage"].startswith("robust")),
        solve_time_s=sum(s["solve_time_s"] for s in stages if s["stage"].startswith("robust")),
        build_time_s=build_time,
        details={**st.details, "stages": stages, "solver_cached": was_cached,
                 "deterministic_solve_time_s": do.status.solve_time_s,
                 "deterministic_iterations": do.status.iterations})
    if not st.ok:
        status.message = f"{stages[-1]['stage']}: {st.message}"
    mean = res.x[:NX]
    pred = _prediction(problem, cad, res.t, res.x, res.u, theta)
    obj = float(mean[LATITUDE, -1] - rob.k_objective * pred.sigma[LATITUDE, -1])
    sol = RobustReentrySolution(
        status=status, deterministic=do, tf_s=res.tf, t=res.t, x=mean, u=res.u, objective_value=obj,
        heat_rate=pred.heat_mean, robust_prediction=pred, deterministic_prediction=do_pred,
        verification=None, stages=stages, notes=notes, augmented=np.array(res.x), shooting=res)
    return verify(problem, sol) if st.ok and base.verify else sol


def verify(problem: RobustReentryProblem, sol: RobustReentrySolution) -> RobustReentrySolution:
    """``sol`` with its independent check: the robust controls re-propagated with s = mu_s.
    :func:`solve` and :func:`resolve` call it when ``problem.base.verify``; the job's
    confirmation loop solves without it and verifies only the design it reports."""
    base, unc = problem.base, problem.uncertainty
    nominal = dataclasses.replace(base.vehicle, cd_scale=base.vehicle.cd_scale * (1 + unc.s_mean[0]),
                                  cl_scale=base.vehicle.cl_scale * (1 + unc.s_mean[1]))
    from solvers.verification import repropagate
    ver = repropagate(rhs=lambda x, u: dyn.eom(x, u, nominal, np), x0=base.initial_state,
                      t_nodes=sol.t, x_nodes=sol.x, u_nodes=sol.u, control="linear",
                      path=det.path_quantities(nominal))
    note = ("verification re-propagates the robust controls with s = mu_s (the mean "
            "aerodynamics); the difference to the CADET mean is the nonlinearity the "
            "second-order term does not capture")
    return dataclasses.replace(sol, verification=ver, notes=[*sol.notes, note])
