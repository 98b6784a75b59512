"""Monte Carlo of a robust ``ocp`` design: the problem as a :mod:`solvers.uncertainty.montecarlo` model.

:func:`monte_carlo_spec` turns a design (its open-loop node controls, final time and parameters) into
the JSON spec a worker runs: the problem travels as its own params (parsed again by
:func:`solvers.ocp.parse_problem` in the worker, registered as the model ``"ocp"``), the draws as the
uncertainty's means and covariances (a uniform constant by its ends).  :func:`monte_carlo_model`
rebuilds the dynamics from the same CasADi symbols the NLP used: the state is ``[x; q; t]`` (the
integral of a Lagrange term, and time, so that a time-dependent right-hand side needs nothing more),
and the compiled propagation (``kernel``) advances all samples of a chunk by one RK4 step per call of
a CasADi function ``map``-ped over them (the RK4 of the transcription, its controls linear or constant
between the nodes; ``substeps`` steps per interval, the dense grid on which each named path constraint
is checked).  Terminal quantities: ``objective`` (the Mayer term plus the integral, in the user's
sense), each named boundary constraint's value and ``kept:NAME`` (1 where it holds), so the merged
means are the kept fractions.
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from solvers.uncertainty.montecarlo import MCModel
from solvers.uncertainty.montecarlo import PathConstraint as MCPath

SUBSTEPS = 10            # RK4 steps per interval: the dense grid of the kept fractions


def monte_carlo_spec(params: dict, *, problem, rob, t_nodes, U, x0, tf: float, theta,
                     substeps: int = SUBSTEPS) -> dict:
    """The JSON-serializable spec of the design's re-flight over the draws (module docstring)."""
    php = problem.phases[0].problem
    ph = php.phase
    nx = len(ph.states)
    x0 = [float(v) for v in np.asarray(x0, float)[:nx]]      # the design's initial state (a free one solved)
    nq = 1 if php.objective.integrand is not None else 0
    cov0 = np.zeros((nx + nq + 1, nx + nq + 1))
    for s in rob.initial:
        i = ph.state_names.index(s.state)
        cov0[i, i] = s.sigma ** 2
    U = np.asarray(U, float)
    if U.shape[1] == len(t_nodes) - 1:            # constant controls: the last node repeats the last interval's
        U = np.hstack([U, U[:, -1:]])
    return {
        "model": "ocp",
        "model_params": {"params": params, "theta": [float(v) for v in np.atleast_1d(theta)], "tf": float(tf),
                         "t0": float(t_nodes[0]), "constraints": list(rob.constraints), "u0": U[:, 0].tolist(),
                         "uf": U[:, -1].tolist(), "control": ph.transcription.control},
        "t_nodes": [float(v) for v in t_nodes],
        "controls": U.tolist(),
        "x0_mean": x0 + [0.0] * nq + [float(t_nodes[0])],
        "x0_cov": cov0.tolist() if rob.initial else None,
        "s_mean": [float(p.mean) for p in rob.parameters],
        "s_cov": np.diag([p.sigma ** 2 for p in rob.parameters]).tolist(),
        "s_uniform": [[p.lower, p.upper] if p.distribution == "uniform" else None for p in rob.parameters],
        "substeps": int(substeps),
    }


def monte_carlo_model(mp: dict) -> MCModel:
    """The problem of ``mp["params"]`` with its uncertain constants sampled (module docstring)."""
    from solvers.ocp import parse_problem
    from solvers.ocp.symbolic import functions_of

    problem = parse_problem(mp["params"])
    rob = problem.robust
    assert rob is not None, "the Monte Carlo model of an ocp problem needs its uncertainty"
    php = problem.phases[0].problem
    ph = php.phase
    fns = functions_of(php)
    nx, nu, nq = fns.nx, fns.nu, fns.nq
    cnames = [n for n, _ in problem.constants]
    s_index = [cnames.index(p.name) for p in rob.parameters]
    ns = len(s_index)
    theta = ca.DM(mp["theta"])
    t0, tf = float(mp["t0"]), float(mp["tf"])
    c_base = [v for _, v in problem.constants]
    x, u, s = ca.SX.sym("x", nx + nq + 1), ca.SX.sym("u", nu), ca.SX.sym("s", ns)
    c_parts = [ca.SX(v) for v in c_base]
    for j, i in enumerate(s_index):
        c_parts[i] = s[j]
    c = ca.vertcat(*c_parts) if c_parts else ca.SX.zeros(0)
    t = x[nx + nq]
    f = fns.rhs(t, x[:nx], u, theta, c, t0, tf)
    xdot = ca.vertcat(f, ca.SX(1.0))
    rhs = ca.Function("mc_rhs", [x, u, s], [xdot])

    # one RK4 step, the control linear from ua to ub over it (constant: ua = ub)
    ua, ub, h = ca.SX.sym("ua", nu), ca.SX.sym("ub", nu), ca.SX.sym("h")
    k1 = rhs(x, ua, s)
    k2 = rhs(x + 0.5 * h * k1, 0.5 * (ua + ub), s)
    k3 = rhs(x + 0.5 * h * k2, 0.5 * (ua + ub), s)
    k4 = rhs(x + h * k3, ub, s)
    step = ca.Function("mc_step", [x, ua, ub, h, s], [x + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)])

    names = set(mp.get("constraints") or [])
    path_named = [(j, cn) for j, cn in enumerate(ph.path) if cn.name in names]
    g = fns.path(t, x[:nx], u, theta, c, t0, tf)
    excess = []
    for j, cn in path_named:
        sc = _scale(cn.lower, cn.upper)
        parts = []
        if cn.upper is not None:
            parts.append((g[j] - cn.upper) / sc)
        if cn.lower is not None:
            parts.append((cn.lower - g[j]) / sc)
        excess.append(parts[0] if len(parts) == 1 else ca.fmax(parts[0], parts[1]))
    pathf = ca.Function("mc_path", [x, u, s], [ca.vertcat(*excess) if excess else ca.SX.zeros(0)])

    u0, uf = ca.DM(mp["u0"]), ca.DM(mp["uf"])
    x0s = ca.SX.sym("x0", nx + nq + 1)
    bvals, mayer = fns.events(t0, tf, x0s[:nx], x[:nx], u0, uf, theta, c)
    if nq:
        mayer = mayer + x[nx]
    bnd_named = [(j, cn) for j, cn in enumerate(ph.boundary) if cn.name in names]
    term_out = [mayer] + [bvals[j] for j, _ in bnd_named]
    termf = ca.Function("mc_terminal", [x, x0s, s], [ca.vertcat(*term_out)])
    maps: dict = {}

    def mapped(fn, n):
        key = (fn.name(), n)
        if key not in maps:
            maps[key] = fn.map(n, "serial")
        return maps[key]

    def terminal(xf, x0=None, s=None):
        n = xf.shape[1]
        out = np.asarray(mapped(termf, n)(xf, x0, s if ns else np.zeros((0, n))), float).reshape(-1, n)
        d = {"objective": out[0]}
        for r, (_, cn) in enumerate(bnd_named, start=1):
            v = out[r]
            ok = np.isfinite(v)
            if cn.lower is not None:
                ok &= v >= cn.lower - 1e-9 * _scale(cn.lower, cn.upper)
            if cn.upper is not None:
                ok &= v <= cn.upper + 1e-9 * _scale(cn.lower, cn.upper)
            d[f"boundary:{cn.name}"] = v
            d[f"kept:{cn.name}"] = ok.astype(float)
        return d

    def rhs_np(xv, uv, sv):
        n = xv.shape[1]
        return np.asarray(mapped(rhs, n)(xv, np.broadcast_to(uv, (nu, n)), sv if ns else np.zeros((0, n))), float)

    path = {cn.name: MCPath(fn=_row(pathf, r, nu, ns, mapped), limit=0.0) for r, (_, cn) in enumerate(path_named)}
    control = mp.get("control", "linear")

    npath = len(path_named)
    intervals: dict = {}

    def interval_fn(substeps: int):
        """One interval of ``substeps`` RK4 steps of one sample: (x, ua, ub, h, s) -> (x_end, the worst
        excess of each named path constraint over the steps' ends, the excess at the end)."""
        if substeps not in intervals:
            xa, a, b, hi = ca.SX.sym("x", nx + nq + 1), ca.SX.sym("ua", nu), ca.SX.sym("ub", nu), ca.SX.sym("h")
            xk = xa
            e = worst = ca.SX.zeros(npath) - ca.inf
            for j in range(substeps):
                u1, u2 = a + (j / substeps) * (b - a), a + ((j + 1) / substeps) * (b - a)
                xk = step(xk, u1, u2, hi / substeps, s)
                e = pathf(xk, u2, s)
                worst = ca.fmax(worst, e)
            intervals[substeps] = ca.Function("mc_interval", [xa, a, b, hi, s], [xk, worst, e])
        return intervals[substeps]

    def kernel(*, x0, s, t_nodes, controls, substeps, kept_nodes):
        n = x0.shape[1]
        Uc = np.asarray(controls, float).reshape(nu, -1)
        F = mapped(interval_fn(int(substeps)), n)
        sv = ca.DM(s if ns else np.zeros((0, n)))
        xk = ca.DM(np.ascontiguousarray(x0, float))
        worst_fine = np.full((npath, n), -np.inf)
        worst_node = np.full((npath, n), -np.inf)
        if npath:
            e0 = np.asarray(mapped(pathf, n)(xk, ca.DM(Uc[:, 0]), sv), float).reshape(npath, n)
            worst_fine = np.maximum(worst_fine, e0)
            worst_node = np.maximum(worst_node, e0)
        for i in range(len(t_nodes) - 1):
            a, b = Uc[:, i], (Uc[:, i + 1] if control == "linear" else Uc[:, i])
            xk, w, e = F(xk, ca.DM(a), ca.DM(b), float(t_nodes[i + 1] - t_nodes[i]), sv)
            if npath:
                w = np.asarray(w, float).reshape(npath, n)
                e = np.asarray(e, float).reshape(npath, n)
                np.maximum(worst_fine, np.where(np.isfinite(w), w, np.inf), out=worst_fine)
                np.maximum(worst_node, np.where(np.isfinite(e), e, np.inf), out=worst_node)
        names_ = [cn.name for _, cn in path_named]
        return np.asarray(xk, float), dict(zip(names_, worst_fine)), dict(zip(names_, worst_node)), {}

    return MCModel(nx=nx + nq + 1, nu=nu, ns=ns, rhs=rhs_np, terminal=terminal, path=path, kernel=kernel,
                   terminal_of_draw=True)


def _row(pathf, r: int, nu: int, ns: int, mapped):
    def fn(x, u, s):
        n = x.shape[1]
        return np.asarray(mapped(pathf, n)(x, np.broadcast_to(u, (nu, n)), s if ns else np.zeros((0, n))),
                          float).reshape(-1, n)[r]
    return fn


def _scale(lo, hi) -> float:
    mags = [abs(v) for v in (lo, hi) if v is not None and v != 0.0]
    return max(mags) if mags else 1.0
