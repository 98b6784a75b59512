"""The ``ocp`` kind against the same problems written by hand in CasADi ``Opti``, same process, same grid.

Run ``python -m benchmarks.ocp`` (``--only brachistochrone,goddard-rocket``, ``--reps 3``,
``--no-save`` to keep them out of ``benchmarks/results/latest.json``).

Issue 24 item 7: at these sizes building the NLP costs more than solving it, so the target is on
build + solve: trajlab within 1.2x of the faster hand-written form on the same grid.

* **trajlab**: :func:`solvers.ocp.solve` on the preset as posed (its transcription and grid), each
  repetition cold (solver cache and symbolic functions cleared): parse, SX functions, NLP build,
  IPOPT.  ``build`` and ``ipopt`` as the solver reports them; ``verify`` (DOP853 re-flight) is
  printed apart, since the baselines do not verify anything.
* **Opti MS**: the preset's dynamics written by hand in CasADi, direct multiple shooting with the
  same RK4 substeps and the same control parametrisation (linear or constant), free final time
  by time scaling, ``Opti`` + IPOPT with ``expand=True``, the same bounds, scaling by the same
  scales and the same straight-line guess.
* **Opti HS**: Hermite-Simpson collocation (separated form: states and controls at the nodes and
  midpoints) on the same number of intervals, ``expand=True``.

IPOPT as in :data:`solvers.transcription.nlp.DEFAULT_IPOPT` (tol 1e-8, MUMPS) for all.  Times are
best of ``--reps``; this machine's 2 shared cores make single runs noisy.

* **rockit** 0.6.7 (when installed, ``--skip-rockit`` to leave it out): ``MultipleShooting`` with the
  same substeps but rockit's piecewise-constant controls; total time only.
* **reentry kind** (betts-shuttle-ocp only): the ``reentry`` kind's own solve of the same problem
  against the ocp kind's whole solve (both with their verification; target within 2x).

* **refinement** (``--no-refinement`` to leave it out; :mod:`benchmarks.ocp_refine`): the
  brachistochrone and the Betts shuttle refined to 1e-6 from a coarse grid against the smallest
  uniform grid that reaches 1e-6: rounds, intervals, error, iterations, time.

* **accuracy** (``--accuracy PRESETS``, off by default; :mod:`benchmarks.ocp_accuracy`): per preset with a
  published optimum, the objective error against it and the wall time of ``accuracy`` 1e-4 and 1e-6 (every
  round's check solve counted) against the smallest uniform grid reaching the same objective error.

* **Dymos** 1.15.1 (``--dymos gl,radau``, off by default: on this machine Radau takes minutes on
  Goddard): Gauss-Lobatto and Radau on the same number of segments, IPOPT through cyipopt in
  place of SLSQP (``benchmarks.ocp_dymos``; pyOptSparse has no wheel here; cyipopt builds against
  Debian's IPOPT: ``apt-get install coinor-libipopt-dev liblapack-dev``, ``pip install cyipopt==1.7.0``).  Presets with a
  Mayer term on tf or one final state, or bryson-denham's integral.
"""
from __future__ import annotations

import argparse
import math
import time

import casadi as ca
import numpy as np

from solvers.ocp import PRESETS, parse_problem, solve
from solvers.ocp.grid import grid_of
from solvers.ocp.guess import guess_of
from solvers.ocp.symbolic import reset_caches
from solvers.transcription.nlp import DEFAULT_IPOPT, clear_cache

IPOPT = {k: v for k, v in DEFAULT_IPOPT.items()}


# --- the dynamics by hand ------------------------------------------------------------------------
def brachistochrone(x, u):
    g = 9.80665
    return ca.vertcat(x[2] * ca.sin(u[0]), -x[2] * ca.cos(u[0]), g * ca.cos(u[0])), 0


def bryson_denham(x, u):
    return ca.vertcat(x[1], u[0]), 0.5 * u[0] ** 2


def goddard(x, u):
    h, v, m = x[0], x[1], x[2]
    drag = 310.0 * v ** 2 * ca.exp(-500.0 * (h - 1.0))
    return ca.vertcat(v, (u[0] - drag) / m - 1.0 / h ** 2, -u[0] / 0.5), 0


def shuttle(x, u):
    h, _lon, lat, v, gam, psi = (x[i] for i in range(6))
    alpha, beta = u[0], u[1]
    mu, Re, S, mass = 0.14076539e17, 20902900.0, 2690.0, 203000.0 / 32.174
    r = Re + h
    rho = 0.002378 * ca.exp(-h / 23800.0)
    a = alpha * 180 / math.pi
    CL = -0.20704 + 0.029244 * a
    CD = 0.07854 - 0.61592e-2 * a + 0.621408e-3 * a ** 2
    q = 0.5 * rho * v ** 2
    L, D = q * S * CL, q * S * CD
    g = mu / r ** 2
    return ca.vertcat(
        v * ca.sin(gam),
        v * ca.cos(gam) * ca.sin(psi) / (r * ca.cos(lat)),
        v * ca.cos(gam) * ca.cos(psi) / r,
        -D / mass - g * ca.sin(gam),
        L * ca.cos(beta) / (mass * v) + ca.cos(gam) * (v / r - g / v),
        L * ca.sin(beta) / (mass * v * ca.cos(gam)) + v * ca.cos(gam) * ca.sin(psi) * ca.sin(lat) / (r * ca.cos(lat)),
    ), 0


def hang_glider(x, u):
    X = (x[0] / 100.0 - 2.5) ** 2
    ua = 2.5 * (1 - X) * ca.exp(-X)
    Vy = x[3] - ua
    vr = ca.sqrt(x[2] ** 2 + Vy ** 2)
    CD = 0.034 + 0.069662 * u[0] ** 2
    D = 0.5 * CD * 1.13 * 14.0 * vr ** 2
    L = 0.5 * u[0] * 1.13 * 14.0 * vr ** 2
    return ca.vertcat(x[2], x[3], (-L * Vy / vr - D * x[2] / vr) / 100.0,
                      (L * x[2] / vr - D * Vy / vr - 100.0 * 9.81) / 100.0), 0


# name -> (dynamics, Mayer term of (xf, tf), sign)
HAND = {
    "brachistochrone": (brachistochrone, lambda xf, tf: tf, 1.0),
    "bryson-denham": (bryson_denham, lambda xf, tf: 0, 1.0),
    "goddard-rocket": (goddard, lambda xf, tf: xf[0], -1.0),
    "hang-glider": (hang_glider, lambda xf, tf: xf[0], -1.0),
    "betts-shuttle-ocp": (shuttle, lambda xf, tf: xf[2] * 180 / math.pi, -1.0),
}


def _setup(name: str):
    """What both hand-written forms take from the preset: the problem, its phase and grid, the
    dynamics by hand, the scales, the bounds and trajlab's straight-line guess."""
    problem = parse_problem(PRESETS[name]["params"]).phases[0].problem     # the preset's one phase
    ph, grid = problem.phase, grid_of(problem)
    xs = np.array([s.scale or max([abs(a) for a in (s.lower, s.upper, s.initial, s.final) if a not in (None, 0)] or [1])
                   for s in ph.states])
    us = np.array([k.scale or max([abs(a) for a in (k.lower, k.upper) if a not in (None, 0)] or [1]) for k in ph.controls])
    tf_g, _, X_g, U_g = guess_of(problem, grid)
    return ph, grid, HAND[name], xs, us, _bounds(problem), (tf_g, X_g, U_g)


def _bounds(problem):
    ph = problem.phase
    big = np.inf

    def v(a, d):
        return d if a is None else a
    return ([v(s.lower, -big) for s in ph.states], [v(s.upper, big) for s in ph.states],
            [v(k.lower, -big) for k in ph.controls], [v(k.upper, big) for k in ph.controls])


def opti_baseline(name: str, method: str) -> dict:
    """The preset by hand in Opti: ``method`` "ms" (RK4, the preset's substeps and controls) or "hs"."""
    t_start = time.perf_counter()
    ph, grid, (dyn, mayer, sign), xs, us, (xl, xu, ul, uu), (tf_g, X_g, U_g) = _setup(name)
    nx, nu, m = len(ph.states), len(ph.controls), grid.intervals
    xs_s, us_s = ca.SX.sym("x", nx), ca.SX.sym("u", nu)
    fx, fq = dyn(xs_s, us_s)
    f = ca.Function("f", [xs_s, us_s], [fx, fq])
    opti = ca.Opti()
    fixed_tf = ph.time.final is not None
    T = ph.time.final if fixed_tf else opti.variable()
    constant = grid.control == "constant" and method == "ms"
    nun = m if constant else m + 1
    Xz = opti.variable(nx, m + 1)
    Uz = opti.variable(nu, nun)
    X = ca.repmat(ca.DM(xs), 1, m + 1) * Xz
    U = ca.repmat(ca.DM(us), 1, nun) * Uz
    h = T / m
    J = 0
    if method == "ms":
        # one RK4 interval as an SX Function, called on every interval (the CasADi examples' form)
        k = grid.substeps
        xa, ua_, ub_, hh = ca.SX.sym("xa", nx), ca.SX.sym("ua", nu), ca.SX.sym("ub", nu), ca.SX.sym("h")
        x, q, dt = xa, 0, hh / k
        for j in range(k):
            u0, um, u1 = (ua_ + (ub_ - ua_) * (j + a) / k for a in (0.0, 0.5, 1.0))
            k1, q1 = f(x, u0)
            k2, q2 = f(x + dt / 2 * k1, um)
            k3, q3 = f(x + dt / 2 * k2, um)
            k4, q4 = f(x + dt * k3, u1)
            x = x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
            q = q + dt / 6 * (q1 + 2 * q2 + 2 * q3 + q4)
        F = ca.Function("F", [xa, ua_, ub_, hh], [x, q])
        for i in range(m):
            xe, qe = F(X[:, i], U[:, i], U[:, i] if constant else U[:, i + 1], h)
            opti.subject_to((xe - X[:, i + 1]) / xs == 0)
            J = J + qe
    else:
        # one Hermite-Simpson interval as an SX Function: (xa, xm, xb, ua, um, ub, h) -> defects, quadrature
        Xmz = opti.variable(nx, m)
        Umz = opti.variable(nu, m)
        Xm = ca.repmat(ca.DM(xs), 1, m) * Xmz
        Um = ca.repmat(ca.DM(us), 1, m) * Umz
        xa, xm, xb = (ca.SX.sym(n, nx) for n in ("xa", "xm", "xb"))
        ua_, um_, ub_ = (ca.SX.sym(n, nu) for n in ("ua", "um", "ub"))
        hh = ca.SX.sym("h")
        (fa, qa), (fm, qm), (fb, qb) = f(xa, ua_), f(xm, um_), f(xb, ub_)
        H = ca.Function("H", [xa, xm, xb, ua_, um_, ub_, hh],
                        [(xm - (xa + xb) / 2 - hh / 8 * (fa - fb)) / xs, (xb - xa - hh / 6 * (fa + 4 * fm + fb)) / xs,
                         hh / 6 * (qa + 4 * qm + qb)])
        for i in range(m):
            d1, d2, qe = H(X[:, i], Xm[:, i], X[:, i + 1], U[:, i], Um[:, i], U[:, i + 1], h)
            opti.subject_to(d1 == 0)
            opti.subject_to(d2 == 0)
            J = J + qe
        opti.subject_to(opti.bounded(np.array(ul) / us, Umz, np.array(uu) / us))
        opti.set_initial(Xmz, (0.5 * (X_g[:, :-1] + X_g[:, 1:])) / xs[:, None])
        opti.set_initial(Umz, (0.5 * (U_g[:, :-1] + U_g[:, 1:]) if U_g.shape[1] > m else U_g[:, :m]) / us[:, None])
    for i in range(nx):
        lo, hi = xl[i] / xs[i], xu[i] / xs[i]
        if np.isfinite(lo) or np.isfinite(hi):
            opti.subject_to(opti.bounded(lo, Xz[i, :], hi))
        s = ph.states[i]
        if s.initial is not None:
            opti.subject_to(Xz[i, 0] == s.initial / xs[i])
        if s.final is not None:
            opti.subject_to(Xz[i, m] == s.final / xs[i])
    for i in range(nu):
        if np.isfinite(ul[i]) or np.isfinite(uu[i]):
            opti.subject_to(opti.bounded(ul[i] / us[i], Uz[i, :], uu[i] / us[i]))
    for c in ph.path:                 # the one preset with a path limit bounds a state: x <= l
        i = ph.state_names.index(c.text)
        opti.subject_to(Xz[i, :] <= c.upper / xs[i])
    if not fixed_tf:
        opti.subject_to(opti.bounded(ph.time.final_lower, T, ph.time.final_upper))
        opti.set_initial(T, tf_g)
    opti.minimize(sign * (mayer(X[:, m], T) + J))
    opti.set_initial(Xz, X_g / xs[:, None])
    Ug = U_g if U_g.shape[1] == nun else np.hstack([U_g, U_g[:, -1:]])[:, :nun]
    opti.set_initial(Uz, Ug / us[:, None])
    opti.solver("ipopt", {"expand": True, "print_time": False}, IPOPT)
    first = []
    opti.callback(lambda i: first.append(time.perf_counter()) if not first else None)
    sol = opti.solve_limited()
    total = time.perf_counter() - t_start
    stats = opti.stats()
    # IPOPT's first iteration callback ends the build (expand, derivatives, nlpsol)
    ipopt_s = total - (first[0] - t_start) if first else float("nan")
    Jv = sign * float(sol.value(opti.f))
    return {"total_s": total, "build_s": total - ipopt_s, "ipopt_s": ipopt_s,
            "iterations": int(stats.get("iter_count", -1)), "objective": Jv,
            "status": str(stats.get("return_status"))}


def rockit_baseline(name: str) -> dict | None:
    """The preset in rockit 0.6.7 (``pip install -e .[bench]``): ``MultipleShooting`` with the
    preset's RK4 substeps, rockit's piecewise-constant controls, the states scaled by hand as in
    the Opti forms, the same straight-line guess as functions of ``ocp.t``, ``expand=True``."""
    try:
        from rockit import FreeTime, MultipleShooting, Ocp
    except ImportError:
        return None
    t_start = time.perf_counter()
    ph, grid, (dyn, mayer, sign), xs, us, (xl, xu, ul, uu), (tf_g, X_g, U_g) = _setup(name)
    nx, nu, m = len(ph.states), len(ph.controls), grid.intervals
    fixed_tf = ph.time.final is not None
    ocp = Ocp(T=ph.time.final if fixed_tf else FreeTime(tf_g))
    zs = [ocp.state() for _ in range(nx)]         # one primitive each: rockit's set_initial wants those
    vs = [ocp.control() for _ in range(nu)]
    z, v = ca.vertcat(*zs), ca.vertcat(*vs)
    x, u = z * ca.DM(xs), v * ca.DM(us)
    fx, fq = dyn(x, u)
    for i in range(nx):
        ocp.set_der(zs[i], fx[i] / xs[i])
    J = sign * (ocp.at_tf(mayer(ocp.at_tf(x), ocp.T)) if name != "bryson-denham" else 0)
    if name == "bryson-denham":
        J = ocp.integral(fq)
    for i, st in enumerate(ph.states):
        if st.initial is not None:
            ocp.subject_to(ocp.at_t0(z[i]) == st.initial / xs[i])
        if st.final is not None:
            ocp.subject_to(ocp.at_tf(z[i]) == st.final / xs[i])
        if np.isfinite(xl[i]):
            ocp.subject_to(xl[i] / xs[i] <= zs[i])
        if np.isfinite(xu[i]):
            ocp.subject_to(zs[i] <= xu[i] / xs[i])
        ocp.set_initial(zs[i], (X_g[i, 0] + (X_g[i, -1] - X_g[i, 0]) * ocp.t / tf_g) / xs[i])
    for i in range(nu):
        if np.isfinite(ul[i]) or np.isfinite(uu[i]):
            ocp.subject_to(ul[i] / us[i] <= (vs[i] <= uu[i] / us[i]))
        ocp.set_initial(vs[i], U_g[i, 0] / us[i])
    for c in ph.path:
        i = ph.state_names.index(c.text)
        ocp.subject_to(zs[i] <= c.upper / xs[i])
    if not fixed_tf:
        ocp.subject_to(ph.time.final_lower <= (ocp.T <= ph.time.final_upper))
    ocp.add_objective(J)
    ocp.solver("ipopt", {"expand": True, "print_time": False, "ipopt": IPOPT})
    ocp.method(MultipleShooting(N=m, M=grid.substeps, intg="rk"))
    try:
        sol = ocp.solve()
        stats = sol.stats
        objective = sign * float(sol.value(J))
    except RuntimeError as e:              # rockit raises on IPOPT failure
        return {"total_s": time.perf_counter() - t_start, "build_s": float("nan"), "ipopt_s": float("nan"),
                "iterations": -1, "objective": float("nan"), "status": str(e)[:40]}
    total = time.perf_counter() - t_start
    return {"total_s": total, "build_s": float("nan"), "ipopt_s": float("nan"),
            "iterations": int(stats.get("iter_count", -1)), "objective": objective,
            "status": str(stats.get("return_status"))}


def trajlab(name: str) -> dict:
    reset_caches()
    clear_cache()
    t = time.perf_counter()
    problem = parse_problem(PRESETS[name]["params"])
    s = solve(problem)
    total = time.perf_counter() - t
    return {"total_s": total, "build_s": s.solver["build_time_s"], "ipopt_s": s.solver["solve_time_s"],
            "iterations": s.solver["iterations"], "objective": s.objective, "status": s.status.solver_status,
            "verify_s": total - s.solver["build_time_s"] - s.solver["solve_time_s"]}


def reentry_kind_ratio(ours: dict, reps: int) -> dict | None:
    """The ``reentry`` kind's own solve of the same problem (betts-max-crossrange: build, IPOPT and its
    verification), cold, best of ``reps``, against trajlab's whole ocp solve (issue 24: within 2x)."""
    try:
        from solvers.reentry import ReentryProblem
        from solvers.reentry import solve as reentry_solve
    except ImportError:
        return None

    def once():
        clear_cache()
        t = time.perf_counter()
        s = reentry_solve(ReentryProblem())
        return {"total_s": time.perf_counter() - t, "status": s.status.solver_status}
    theirs = min((once() for _ in range(reps)), key=lambda r: r["total_s"])
    ratio = ours["total_s"] / theirs["total_s"]
    print(f"{'':<19}whole solve with verification: ocp {ours['total_s']:.3f} s, reentry kind "
          f"{theirs['total_s']:.3f} s: {ratio:.2f}x (target <= 2x: {'met' if ratio <= 2 else 'MISSED'})")
    return {"reentry_total_s": theirs["total_s"], "ocp_total_s": ours["total_s"], "ratio": ratio}


def best(fn, reps: int) -> dict:
    runs = [fn() for _ in range(reps)]
    return min(runs, key=lambda r: r["total_s"] - r.get("verify_s", 0.0))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--only", help="comma-separated presets")
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--skip-rockit", action="store_true")
    ap.add_argument("--dymos", default="", help="Dymos transcriptions to run: gl, radau or gl,radau")
    ap.add_argument("--no-refinement", dest="refinement", action="store_false",
                    help="leave out the mesh-refinement row (benchmarks.ocp_refine)")
    ap.add_argument("--accuracy", default="", help="presets with a published optimum for the accuracy row "
                    "(benchmarks.ocp_accuracy; e.g. lunar-lander-bang-bang,scalar-lq-riccati,bryson-denham)")
    ap.add_argument("--no-save", dest="save", action="store_false",
                    help="do not merge the figures into benchmarks/results/latest.json")
    args = ap.parse_args()
    names = args.only.split(",") if args.only else list(HAND)
    figures = {}
    print(f"{'preset':<19}{'form':<10}{'grid':>6}{'build s':>9}{'ipopt s':>9}{'b+s s':>8}{'iter':>6}"
          f"{'objective':>14}{'ratio':>7}  status")
    for name in names:
        grid = grid_of(parse_problem(PRESETS[name]["params"]))
        ours = best(lambda name=name: trajlab(name), args.reps)
        ms = best(lambda name=name: opti_baseline(name, "ms"), args.reps)
        hs = best(lambda name=name: opti_baseline(name, "hs"), args.reps)
        ours_bs = ours["build_s"] + ours["ipopt_s"]
        faster = min(ms["total_s"], hs["total_s"])
        rows = [("trajlab", ours, ours_bs), ("Opti MS", ms, ms["total_s"]), ("Opti HS", hs, hs["total_s"])]
        rk = None if args.skip_rockit else best(lambda name=name: rockit_baseline(name) or {"total_s": float("nan")}, args.reps)
        if rk is not None and "status" in rk:
            rows.append(("rockit", rk, rk["total_s"]))
        dymos = {}
        for tx in filter(None, args.dymos.split(",")):
            from benchmarks.ocp_dymos import dymos_baseline
            d = dymos_baseline(name, tx, _setup)   # once: a Dymos solve takes seconds to minutes
            if d is not None:
                dymos[tx] = d
                rows.append((f"Dymos {tx}", d, d["total_s"]))
        for form, r, bs in rows:
            print(f"{name:<19}{form:<10}{grid.intervals:>6}{r['build_s']:>9.3f}{r['ipopt_s']:>9.3f}{bs:>8.3f}"
                  f"{r['iterations']:>6}{r['objective']:>14.7g}{bs / faster:>7.2f}  {r['status']}")
        print(f"{'':<19}{'':<10}{'':>6}  trajlab's DOP853 verification and result: {ours['verify_s']:.3f} s; "
              f"target build+solve <= 1.2x the faster hand-written form: "
              f"{'met' if ours_bs <= 1.2 * faster else 'MISSED'} ({ours_bs / faster:.2f}x)")
        figures[name] = {"intervals": grid.intervals, "trajlab": ours, "opti_ms": ms, "opti_hs": hs,
                         "rockit": rk, "dymos": dymos, "ratio_vs_faster_hand_written": ours_bs / faster}
        if name == "betts-shuttle-ocp":
            figures[name]["reentry_kind"] = reentry_kind_ratio(ours, args.reps)
    if args.refinement:
        from benchmarks.ocp_refine import refinement_rows
        figures["refinement"] = refinement_rows(reps=args.reps)
    if args.accuracy:
        from benchmarks.ocp_accuracy import rows as accuracy_rows
        figures["accuracy"] = accuracy_rows([n for n in args.accuracy.split(",") if n])
    if args.save:
        from benchmarks.results import write_results
        write_results("ocp", figures)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
