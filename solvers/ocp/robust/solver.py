"""Robust design of an ``ocp`` problem: the deterministic twin, the robust NLP, the mean re-flown, CADET's
prediction and the Monte Carlo's verdict.

:func:`solve_robust` solves the deterministic twin (:func:`solvers.ocp.solver.solve`: the same problem with
every constant at its declared value, which is its mean unless the uncertainty gives one; its answer
warm-starts the robust NLP and prices robustness), then the robust NLP
(:class:`solvers.ocp.robust.nlp.RobustNLP`), and checks the design's mean trajectory exactly as a
deterministic answer is checked (:func:`solvers.ocp.check.check_phase`: the DOP853 re-flight at the means, the limits
between the nodes).  CADET's prediction is evaluated at the nodes and between them (``DENSE`` RK4 steps of
the augmented system between neighbouring nodes, the control the transcription's own: on LGL the segment's
polynomial): the objective's mean and sigma and, per named constraint, the worst
``mu +- k sigma`` against its bounds.  :func:`confirm` folds a Monte Carlo summary of the design
(:mod:`solvers.ocp.robust.montecarlo`, run by the caller: in process or fanned across workers) into the
result's ``robust`` block (``shared/specs/ocp.md``, "Robust design") and decides ``confirmed``.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from types import SimpleNamespace

import numpy as np

from solvers.common import Outcome, ProgressFn, StopFn
from solvers.progress import Progress
from solvers.ocp.check import AGREEMENT_TOLERANCE, check_phase
from solvers.ocp.phase import positive_scale
from solvers.ocp.robust.cadet import path_bands, state_bands
from solvers.ocp.robust.montecarlo import monte_carlo_spec
from solvers.ocp.robust.nlp import Design, RobustNLP
from solvers.ocp.solution import OcpSolution, solution_of
from solvers.ocp.solver import Placed
from solvers.ocp.solver import solve as solve_deterministic
from solvers.ocp.stages import ROBUST_DESIGN_PLAN, ROBUST_PLAN, ROBUST_ROUND_PLAN
from solvers.ocp.trajectory import TrajectoryNLP
from solvers.ocp.verify import control_function
from solvers.uncertainty.confirm import clipped_quantile, kept_enough, normal_share, raised_k, sampling_tolerance

DENSE = 10               # RK4 steps between neighbouring nodes in CADET's check
MAX_ROUNDS = 4           # tighten-and-re-solve rounds for the robust path limits between the nodes
MARGIN_GROWTH = 1.5      # a round tightens by this times the excess (the excess moves as the answer does)
HELD = 1e-4              # a scaled excess below this counts as held (the re-flight's tolerance is 1e-3)


@dataclass
class RobustSolution:
    """The design (``solution``: the mean trajectory as an ``ocp`` answer), its twin, CADET's prediction
    and the Monte Carlo spec that confirms it."""

    solution: OcpSolution
    deterministic: OcpSolution
    prediction: dict = field(default_factory=dict)
    monte_carlo_spec: dict | None = None
    timing: dict = field(default_factory=dict)
    design: Design | None = None
    built: Built | None = None            # the NLPs, for a confirmation round


class Built:
    """What a job builds once and every confirmation round reuses: the robust NLP (a round that raises the
    constraints' k changes a parameter) and the deterministic NLP's layout and numbers on which the
    design's mean is checked (no solver: it is only re-flown)."""

    def __init__(self, problem, rob):
        self.R = RobustNLP(problem, rob)
        self.mean_problem = at_mean(problem)
        self.check_nlp = TrajectoryNLP(self.mean_problem, build=False)
        self.check_placed = Placed(self.mean_problem, self.check_nlp, None)


def at_mean(problem):
    """``problem`` with every uncertain constant at its mean, the constants the design's mean flies (they
    differ from the declared ones, which the twin flies, where the uncertainty gives a ``mean``: paper 001's
    biased aerodynamic errors)."""
    means = {p.name: p.mean for p in problem.robust.parameters}
    c = tuple((n, means.get(n, v)) for n, v in problem.constants)
    return replace(problem, constants=c).on_phases([replace(ph.problem, constants=c) for ph in problem.phases])


def solve_robust(problem, *, params: dict, initial_guess: dict | None = None,
                 on_progress: ProgressFn | Progress | None = None, should_stop: StopFn | None = None,
                 k_constraints: float | None = None, deterministic: OcpSolution | None = None,
                 built: Built | None = None) -> RobustSolution:
    """The robust design of ``problem`` (its ``robust`` spec; ``params``: the problem as data, which the
    Monte Carlo's workers parse again); ``k_constraints``: the constraints' k when a confirmation round
    raised it (default the spec's ``k``); ``deterministic``: the twin's answer when already solved;
    ``built``: the NLPs when already built (a confirmation round).
    ``on_progress``: a callback (the design's own stages, :data:`ROBUST_DESIGN_PLAN`) or the
    :class:`Progress` of a plan with the stages ``robust build``, ``robust solve`` and ``limit`` (and
    ``deterministic twin`` when ``deterministic`` is None), as :func:`design_and_confirm` passes."""
    own = not isinstance(on_progress, Progress)
    progress = on_progress if isinstance(on_progress, Progress) else Progress(on_progress, ROBUST_DESIGN_PLAN)
    rob = problem.robust
    k_c = rob.k if k_constraints is None else k_constraints
    t_start = time.perf_counter()
    det = deterministic
    if det is None:
        det = solve_deterministic(problem, initial_guess=initial_guess, should_stop=should_stop,
                                  on_progress=progress.stage("deterministic twin"))
    t_det = time.perf_counter() - t_start
    if not det.status.ok:
        det.notes.append("the deterministic twin failed: no robust design was attempted")
        return RobustSolution(solution=det, deterministic=det, timing={"deterministic_s": t_det})
    t1 = time.perf_counter()
    progress.stage("robust build", message=f"the robust NLP (CADET, k = {k_c:.3g} on the constraints)")
    built = built or Built(problem, rob)
    R = built.R
    assert R.nlp.solver is not None   # built with its solver
    placed = R.place(det=det, k=rob.k, k_c=k_c)
    res = R.nlp.solver.solve(x0=placed["z0"], lbx=placed["lbz"], ubx=placed["ubz"], lbg=placed["lbg"],
                             ubg=placed["ubg"], p=placed["p"], should_stop=should_stop,
                             on_progress=progress.stage("robust solve"), label="robust IPOPT")
    design = R.design(res.x, placed)
    prediction = predict(R, design, rob, k_c, z=res.x, p=placed["p"])
    res, design, prediction, rounds = _hold_between_nodes(R, placed, res, design, prediction, rob, k_c, should_stop,
                                                           progress=progress)
    t_rob = time.perf_counter() - t1
    sol = _mean_solution(problem, built, design, res)
    if rounds:
        sol.notes.append(f"robust path limits tightened where CADET's mean +- k sigma exceeded them between the "
                         f"nodes: {len(rounds)} round(s)")
    prediction.pop("per_interval", None)
    sol.notes.insert(0, f"robust design (CADET, k = {rob.k:g}, objective {rob.objective}): the trajectory is the "
                        f"mean; the deterministic twin's objective is {det.objective:.6g}")
    spec = monte_carlo_spec(params, problem=problem, rob=rob, design=design) if res.status.ok else None
    if own:
        progress.stage("answer")
        progress.done("robust design solved")
    return RobustSolution(solution=sol, deterministic=det, prediction=prediction, monte_carlo_spec=spec,
                          timing={"deterministic_s": t_det, "robust_s": t_rob, "limit_rounds": len(rounds),
                                  "robust_iterations": res.status.iterations,
                                  "deterministic_iterations": det.status.iterations}, design=design,
                          built=built)


def _hold_between_nodes(R: RobustNLP, placed: dict, res, design: Design, prediction: dict, rob, k_c: float,
                        should_stop, *, progress: Progress):
    """Tighten-and-re-solve rounds (as :mod:`solvers.ocp.limits` for a deterministic answer): where CADET's
    ``mu +- k sigma`` of a named path constraint exceeds its bound between the nodes of an interval, that
    bound is tightened at the interval's two nodes by the excess (times ``MARGIN_GROWTH``) and the NLP
    re-solved from its answer; at most ``MAX_ROUNDS``."""
    assert R.nlp.solver is not None
    starts = R.path_starts()
    lbg, ubg = placed["lbg"].copy(), placed["ubg"].copy()
    rounds: list[dict] = []
    for _ in range(MAX_ROUNDS):
        per = prediction.get("per_interval") or {}
        if not per or all(max(np.max(a), np.max(b)) <= HELD for a, b in per.values()):
            break
        if should_stop is not None and should_stop():
            break
        for (ip, j), (e_hi, e_lo) in per.items():
            start, n_rows, row = starts[ip], R.phases[ip].rf.n_path, _path_rows(R.phases[ip].lay)[j]
            assert start is not None
            for i in np.flatnonzero(e_hi > HELD):
                for node in (i, i + 1):
                    ubg[start + node * n_rows + row] -= MARGIN_GROWTH * e_hi[i]
            for i in np.flatnonzero(e_lo > HELD):
                for node in (i, i + 1):
                    lbg[start + node * n_rows + row + 1] += MARGIN_GROWTH * e_lo[i]
        r = R.nlp.solver.solve(x0=res.x, lbx=placed["lbz"], ubx=placed["ubz"], lbg=lbg, ubg=ubg, p=placed["p"],
                               lam_x0=res.lam_x, lam_g0=res.lam_g, should_stop=should_stop, expected_iterations=15,
                               label="robust limit round",
                               on_progress=progress.stage("limit", round=len(rounds) + 1))
        rounds.append({"status": r.status.solver_status, "iterations": r.status.iterations})
        if not r.status.ok:
            break
        res = r
        design = R.design(res.x, placed)
        prediction = predict(R, design, rob, k_c, z=res.x, p=placed["p"])
    return res, design, prediction, rounds


def _mean_solution(problem, built: Built, design: Design, res) -> OcpSolution:
    """The design's mean as an ``ocp`` answer: every phase checked and reported as a deterministic one (no
    costates: the deterministic optimality conditions do not apply to a robust design), re-flown with the
    uncertain constants at their means."""
    problem, nlp, placed = built.mean_problem, built.check_nlp, built.check_placed
    checks = []
    for b, num, P, d in zip(nlp.blocks, placed.nums, built.R.phases, design.phases):
        nx = P.rf.base.nx
        z = b.nlp.pack(d.tf, d.theta, d.Z[:nx], d.U)
        checks.append(check_phase(b, num, z, t0=d.t0, agreement=problem.accuracy or AGREEMENT_TOLERANCE,
                                  single=problem.single, mult=None))
    status = res.status
    if status.ok and not all(c.ok for c in checks):
        status.outcome = Outcome.FAILED
        status.message += "; " + "; ".join(c.label + c.verification.message for c in checks if not c.ok)
    return solution_of(problem, nlp=nlp, res=SimpleNamespace(f=float(res.f)), status=status,
                       checks=checks, rounds=[])


def predict(R: RobustNLP, design: Design, rob, k_c: float, *, z=None, p=None) -> dict:
    """CADET's objective mean and sigma, and per named constraint the worst ``mu +- k sigma`` at the nodes
    and between them (``DENSE`` steps per interval) against its bounds (scaled excess, <= 0 held), over
    every phase that has it."""
    if R.problem.single:
        P, d = R.phases[0], design.phases[0]
        c_aug = R.constants(rob.k, k_c, R.eps_default(0) * 0.0)
        Un = P.det.node_controls(d.U)
        mu, var = P.rf.objective_moments(d.t0, d.tf, d.Z[:, 0], d.Z[:, -1], Un[:, 0], Un[:, -1], d.theta, c_aug)
    else:
        cols, _ = R.nlp.event_columns()
        assert R.objective_moments is not None
        mu, var = R.objective_moments(np.asarray(z)[cols], p)
    out: dict = {"objective": {"mean": float(mu), "std": float(np.sqrt(max(float(var), 0.0)))}, "constraints": {}}
    per_interval: dict[tuple, tuple] = {}
    out["per_interval"] = per_interval
    for ip, (P, d) in enumerate(zip(R.phases, design.phases)):
        _predict_phase(R, ip, P, d, rob, k_c, out["constraints"], per_interval)
    return out


def _worse(old: dict | None, new: dict, key: str) -> dict:
    return new if old is None or new[key] > old[key] else old


def _predict_phase(R: RobustNLP, ip: int, P, d, rob, k_c: float, cons: dict, per_interval: dict) -> None:
    rf, g = P.rf, P.grid
    ph = P.php.phase
    c_aug = R.constants(rob.k, k_c, R.eps_default(ip) * 0.0)
    t0, Z, tf, th = d.t0, d.Z, d.tf, d.theta
    Un = P.det.node_controls(d.U)
    phase = {} if R.problem.single else {"phase": P.name}
    bm, bv = rf.boundary_moments(t0, tf, Z[:, 0], Z[:, -1], Un[:, 0], Un[:, -1], th, c_aug)
    bm, bv = np.asarray(bm, float).ravel(), np.asarray(bv, float).ravel()
    for j, cn in enumerate(ph.boundary):
        if cn.name in rob.constraints:
            sd = float(np.sqrt(max(bv[j], 0.0)))
            cons[cn.name] = _worse(cons.get(cn.name), {"kind": "boundary", "mean": float(bm[j]), "std": sd,
                                                       "excess_scaled": _excess(bm[j] + k_c * sd, bm[j] - k_c * sd,
                                                                                cn), **phase}, "excess_scaled")
    named = [(j, cn) for j, cn in enumerate(ph.path) if cn.name in rob.constraints]
    if not named:
        return
    F = P.interval(1)
    rows = _path_rows(P.lay)
    # between each pair of neighbouring nodes (a shooting interval, or two nodes of an LGL segment), the
    # transcription's own control: linear or constant, or the segment's interpolating polynomial
    u_of = control_function(g, d.t_nodes, d.U)
    segment = np.searchsorted(g.offsets(), np.arange(g.n_nodes - 1), side="right") - 1
    ts, zs, us = [], [], []
    for i in range(g.n_nodes - 1):
        ta, tb = d.t_nodes[i], d.t_nodes[i + 1]
        tj = ta + np.linspace(0.0, 1.0, DENSE + 1) * (tb - ta)
        uj = u_of(tj, int(segment[i]))
        z = Z[:, i]
        for j in range(DENSE + 1):
            ts.append(tj[j])
            zs.append(z)
            us.append(uj[:, j])
            if j < DENSE:
                z = np.asarray(F(z, uj[:, j], uj[:, j + 1], tj[j], tj[j + 1] - tj[j], th, c_aug, t0, tf)[0],
                               float).ravel()
    T, Zd, Ud = np.array(ts), np.array(zs).T, np.array(us).T
    Pv = np.asarray(rf.fns.path.map(T.size)(T[None, :], Zd, Ud, th, c_aug, t0, tf), float)
    is_node = np.zeros(T.size, bool)
    is_node[::DENSE + 1] = True
    is_node[DENSE::DENSE + 1] = True
    for j, cn in named:
        hi, lo = Pv[rows[j]], Pv[rows[j] + 1]
        e_hi, e_lo = _excess_v(hi, None, cn), _excess_v(None, lo, cn)
        e = np.maximum(e_hi, e_lo)
        per_interval[(ip, j)] = (e_hi.reshape(g.n_nodes - 1, DENSE + 1).max(axis=1),
                                 e_lo.reshape(g.n_nodes - 1, DENSE + 1).max(axis=1))
        dense = float(np.max(e))
        cons[cn.name] = _worse(cons.get(cn.name), {"kind": "path", "excess_scaled_nodes": float(np.max(e[is_node])),
                                                   "excess_scaled_dense": dense,
                                                   "held_between_nodes": bool(dense <= 1e-3), **phase},
                               "excess_scaled_dense")


def _path_rows(lay) -> dict[int, int]:
    """The first row of each path constraint in the augmented path function."""
    rows, r = {}, 0
    for j, robust in enumerate(lay.robust_path):
        rows[j] = r
        r += 2 if robust else 1
    return rows


def _excess_v(hi, lo, cn) -> np.ndarray:
    """Scaled excess of the upper row over ``upper`` (or of ``lower`` over the lower row); -inf if unbounded."""
    if hi is not None:
        return (np.asarray(hi) - cn.upper) / positive_scale(cn.lower, cn.upper) if cn.upper is not None else np.full(np.shape(hi), -np.inf)
    return (cn.lower - np.asarray(lo)) / positive_scale(cn.lower, cn.upper) if cn.lower is not None else np.full(np.shape(lo), -np.inf)


def _excess(hi: float, lo: float, cn) -> float:
    return float(max(_excess_v(np.array([hi]), None, cn)[0], _excess_v(None, np.array([lo]), cn)[0]))


def confirm(rs: RobustSolution, summary: dict, rob) -> dict:
    """The result's ``robust`` block from the Monte Carlo ``summary`` (:func:`solvers.uncertainty.montecarlo.merge_chunks`)."""
    n = int(summary["samples"])
    ok_share = 1.0 - summary.get("failed_samples", 0) / max(n, 1)
    required = normal_share(rob.k)
    obj = summary["terminal"].get("objective", {"mean": float("nan"), "std": float("nan")})
    cons, confirmed = {}, True
    for name in rob.constraints:
        if name in summary.get("path", {}):
            kept = float(summary["path"][name]["kept_fraction"])
        else:
            kept = float(summary["terminal"][f"kept:{name}"]["mean"]) * ok_share
        held = kept_enough(kept, required, n)
        confirmed &= held
        cons[name] = {"kept_fraction": kept, "required_fraction": required, "kept": held,
                      "sampling_tolerance": sampling_tolerance(required, n),
                      "cadet": rs.prediction.get("constraints", {}).get(name)}
    det = rs.deterministic.objective
    return {"k": rob.k, "statistic": rob.objective, "samples": n, "failed_samples": summary.get("failed_samples", 0),
            "objective": {"mean": obj["mean"], "std": obj["std"],
                          "cadet_mean": rs.prediction["objective"]["mean"],
                          "cadet_std": rs.prediction["objective"]["std"]},
            "constraints": cons, "confirmed": bool(confirmed),
            "deterministic_objective": det, "robust_objective": rs.solution.objective,
            "cost_of_robustness": rs.solution.objective - det,
            "cadet_envelope": {**state_bands(rs.built.R.problem, rs.design, rs.built.R.sigma_s),
                               "constraints": path_bands(rs.built.R, rs.design)} if rs.built else None,
            "timing": rs.timing}


def design_and_confirm(problem, *, params: dict, run_monte_carlo, seed: int = 0, initial_guess: dict | None = None,
                       on_progress: ProgressFn | Progress | None = None, should_stop: StopFn | None = None):
    """The robust design confirmed by its Monte Carlo: ``(RobustSolution, robust block, Monte Carlo summary)``.

    ``run_monte_carlo(spec, samples, seed)`` runs the draws (in process, or fanned across workers by the
    service).  Where a named constraint is kept less than promised (the per-instant bound promises more
    than a whole flight keeps, and a linearisation can under-predict a spread), the constraints' k is
    raised by the gap in normal quantiles plus ``K_OVERSHOOT`` and the design re-solved and re-flown, at
    most ``robust.monte_carlo.rounds`` times; the objective keeps the user's k.  The block of the last
    round is the answer, the rounds listed in it.
    """
    rob = problem.robust
    progress = on_progress if isinstance(on_progress, Progress) else Progress(on_progress, ROBUST_PLAN)
    k_c, det, history = rob.k, None, []
    rs = block = summary = built = None
    for r in range(rob.rounds + 1):
        # round 0 is the plan's own stages; a confirmation round (k raised) runs them again inside its share
        stages = progress if r == 0 else progress.within("confirmation", ROBUST_ROUND_PLAN, round=r)
        rs = solve_robust(problem, params=params, initial_guess=initial_guess, on_progress=stages,
                          should_stop=should_stop, k_constraints=k_c, deterministic=det, built=built)
        det, built = rs.deterministic, rs.built       # every later round reuses both
        if rs.monte_carlo_spec is None:
            progress.stage("answer")
            progress.done(rs.solution.status.outcome.value)
            return rs, None, None
        spec = scaled_spec(rs.monte_carlo_spec, rob.sigma_factor)
        t = time.perf_counter()
        stages.stage("monte carlo", message=f"{rob.samples} samples of the design")
        summary = run_monte_carlo(spec, rob.samples, seed)
        block = confirm(rs, summary, rob)
        block["timing"]["monte_carlo_s"] = time.perf_counter() - t
        block["k_constraints"] = k_c
        history.append({"round": r, "k_constraints": k_c, "objective": rs.solution.objective,
                        "kept_fractions": {n: c["kept_fraction"] for n, c in block["constraints"].items()},
                        "confirmed": block["confirmed"]})
        short = [c for c in block["constraints"].values() if not c["kept"]]
        if block["confirmed"] or not short or (should_stop is not None and should_stop()):
            break
        if r < rob.rounds:
            k_c = raised_k(k_c, max(clipped_quantile(c["required_fraction"]) - clipped_quantile(c["kept_fraction"])
                                    for c in short))
    progress.stage("answer")
    progress.done("confirmed" if block is not None and block["confirmed"] else "not confirmed")
    assert block is not None
    block["rounds"] = history
    block["sigma_factor"] = rob.sigma_factor
    return rs, block, summary


def scaled_spec(spec: dict, factor: float) -> dict:
    """The Monte Carlo spec with every sigma times ``factor`` (uniform laws widened about their means)."""
    if factor == 1.0:
        return spec
    out = dict(spec)
    out["s_cov"] = (np.asarray(spec["s_cov"], float) * factor ** 2).tolist()
    if spec.get("x0_cov") is not None:
        out["x0_cov"] = (np.asarray(spec["x0_cov"], float) * factor ** 2).tolist()
    out["s_uniform"] = [None if b is None else [0.5 * (b[0] + b[1]) - 0.5 * factor * (b[1] - b[0]),
                                                0.5 * (b[0] + b[1]) + 0.5 * factor * (b[1] - b[0])]
                        for b in spec.get("s_uniform") or []]
    return out
