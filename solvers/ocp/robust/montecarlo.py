"""Monte Carlo of a robust ``ocp`` design: the problem as a :mod:`solvers.uncertainty.montecarlo` model.

:func:`monte_carlo_spec` turns a design (its open-loop node controls, final time and parameters) into
the JSON spec a worker runs: the problem travels as its own params (parsed again by
:func:`solvers.ocp.parse_problem` in the worker, registered as the model ``"ocp"``), the draws as the
uncertainty's means and covariances (a uniform constant by its ends).  :func:`monte_carlo_model`
rebuilds the dynamics from the same CasADi symbols the NLP used: the state is ``[x; q; t]`` (the
integral of a Lagrange term, and time, so that a time-dependent right-hand side needs nothing more),
and the compiled propagation (``kernel``) advances all samples of a chunk by one RK4 step per call of
a CasADi function ``map``-ped over them (``substeps`` RK4 steps between neighbouring nodes, the dense grid on
which each named path constraint is checked, the control at every RK4 stage the transcription's own: linear
or constant between shooting nodes, on LGL the segment's interpolating polynomial through its node controls,
as :func:`solvers.ocp.verify.control_function` re-flies a deterministic answer).  Terminal quantities: ``objective`` (the Mayer term plus the integral, in the user's
sense), each named boundary constraint's value and ``kept:NAME`` (1 where it holds), so the merged
means are the kept fractions; ``objective`` and the named boundary values are kept per draw (the first
:data:`solvers.uncertainty.montecarlo.MAX_TERMINAL_SAMPLES`: the result's histograms and CSV).  The problem
is also traced at the kept node times (the envelope of the result's plots): every state (``state:NAME``) and
the value of every named path constraint (``path:NAME``), several phases on one time axis (their node times
one after another, NaN where a phase has not the quantity).  The numpy propagator of
:mod:`solvers.uncertainty.montecarlo` (a reference for checks, ``"propagator": "numpy"``) flies the node
controls linearly between the nodes, so it matches the kernel on shooting only.
"""
from __future__ import annotations

import json
import threading
from collections import OrderedDict

import casadi as ca
import numpy as np

from solvers.ocp.grid import grid_of
from solvers.ocp.phase import positive_scale
from solvers.ocp.robust.links import carried_links, solve_link
from solvers.transcription.lgl import lagrange_matrix, lgl_nodes

from solvers.uncertainty.montecarlo import MCModel
from solvers.uncertainty.montecarlo import PathConstraint as MCPath

SUBSTEPS = 10            # RK4 steps per interval: the dense grid of the kept fractions


def monte_carlo_spec(params: dict, *, problem, rob, design=None, t_nodes=None, U=None, x0=None, tf=None,
                     theta=None, substeps: int = SUBSTEPS) -> dict:
    """The JSON-serializable spec of the design's re-flight over the draws (module docstring): ``design``
    (:class:`solvers.ocp.robust.nlp.Design`, every phase) or, for a problem posed as one phase, its node
    times, controls, initial state, final time and parameters."""
    from solvers.ocp.robust.nlp import Design, PhaseDesign

    if design is None:
        x0 = np.asarray(x0, float)
        design = Design([PhaseDesign(t0=float(t_nodes[0]), tf=float(tf), theta=np.atleast_1d(theta), Z=x0[:, None],
                                     U=np.asarray(U, float), t_nodes=np.asarray(t_nodes, float))])
    phases = []
    for named, d in zip(problem.phases, design.phases):
        ph = named.problem.phase
        nx = len(ph.states)
        Uc = np.asarray(d.U, float)
        if Uc.shape[1] == len(d.t_nodes) - 1:      # constant controls: the last node repeats the last interval's
            Uc = np.hstack([Uc, Uc[:, -1:]])
        lgl = ph.transcription.method == "lgl"
        phases.append({"t0": float(d.t0), "tf": float(d.tf), "t_nodes": [float(v) for v in d.t_nodes],
                       "controls": Uc.tolist(), "u0": Uc[:, 0].tolist(), "uf": Uc[:, -1].tolist(),
                       "control": "lgl" if lgl else ph.transcription.control,
                       **({"segment_nodes": grid_of(named.problem).nodes_per_interval().tolist()} if lgl else {}),
                       # the design's initial state (a free one solved; a later phase's unlinked states)
                       "x0": [float(v) for v in np.asarray(d.Z, float)[:nx, 0]]})
    first = problem.phases[0].problem
    ph = first.phase
    nx = len(ph.states)
    nq = 1 if first.objective.integrand is not None else 0
    cov0 = np.zeros((nx + nq + 1, nx + nq + 1))
    for s in rob.initial:
        i = ph.state_names.index(s.state)
        cov0[i, i] = s.sigma ** 2
    return {
        "model": "ocp",
        "model_params": {"params": params, "theta": [float(v) for v in np.atleast_1d(design.theta)],
                         "constraints": list(rob.constraints), "phases": phases},
        "t_nodes": [t for p in phases for t in p["t_nodes"]],   # the traces' times (each phase flies its own)
        "controls": phases[0]["controls"],
        "x0_mean": phases[0]["x0"] + [0.0] * nq + [phases[0]["t0"]],
        "x0_cov": cov0.tolist() if rob.initial else None,
        "s_mean": [float(p.mean) for p in rob.parameters],
        "s_cov": np.diag([p.sigma ** 2 for p in rob.parameters]).tolist(),
        "s_uniform": [[p.lower, p.upper] if p.distribution == "uniform" else None for p in rob.parameters],
        "substeps": int(substeps),
    }


_MODELS: OrderedDict[str, MCModel] = OrderedDict()
_MODELS_LOCK = threading.Lock()
MODELS_KEPT = 4          # designs whose models a worker keeps (a job's rounds, a few jobs at once)


def monte_carlo_model(mp: dict) -> MCModel:
    """The problem of ``mp["params"]`` with its uncertain constants sampled (module docstring), built once per
    design in this process: every chunk of a Monte Carlo asks for it again."""
    key = json.dumps(mp, sort_keys=True)
    with _MODELS_LOCK:
        model = _MODELS.get(key)
        if model is not None:
            _MODELS.move_to_end(key)
            return model
    model = _build_model(mp)
    with _MODELS_LOCK:
        _MODELS[key] = model
        while len(_MODELS) > MODELS_KEPT:
            _MODELS.popitem(last=False)
    return model


class _PhaseFlight:
    """One phase flown over the samples: its RK4 interval, the named path constraints' scaled excesses and its
    events (boundary values, the Mayer term) of a sample's ends; the state is ``[x; q; t]``."""

    def __init__(self, problem, index: int, mp: dict, names: set[str]):
        from solvers.ocp.symbolic import functions_of

        rob = problem.robust
        self.php = php = problem.phases[index].problem
        ph = php.phase
        self.fns = fns = functions_of(php)
        self.nx, self.nu, self.nq = nx, nu, nq = fns.nx, fns.nu, fns.nq
        self.n = nx + nq + 1
        self.d = mp["phases"][index]
        cnames = [n for n, _ in problem.constants]
        s_index = [cnames.index(p.name) for p in rob.parameters]
        self.ns = ns = len(s_index)
        theta = ca.DM(mp["theta"])
        t0, tf = float(self.d["t0"]), float(self.d["tf"])
        x, u, s = ca.SX.sym("x", self.n), ca.SX.sym("u", nu), ca.SX.sym("s", ns)
        c_parts = [ca.SX(v) for _, v in problem.constants]
        for j, i in enumerate(s_index):
            c_parts[i] = s[j]
        self.c = c = ca.vertcat(*c_parts) if c_parts else ca.SX.zeros(0)
        self.s = s
        t = x[nx + nq]
        f = fns.rhs(t, x[:nx], u, theta, c, t0, tf)
        self.rhs = rhs = ca.Function("mc_rhs", [x, u, s], [ca.vertcat(f, ca.SX(1.0))])

        # one RK4 step, the control at its start, middle and end given
        ua, um, ub, h = ca.SX.sym("ua", nu), ca.SX.sym("um", nu), ca.SX.sym("ub", nu), ca.SX.sym("h")
        k1 = rhs(x, ua, s)
        k2 = rhs(x + 0.5 * h * k1, um, s)
        k3 = rhs(x + 0.5 * h * k2, um, s)
        k4 = rhs(x + h * k3, ub, s)
        self.step = ca.Function("mc_step", [x, ua, um, ub, h, s], [x + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)])

        self.path_named = [(j, cn) for j, cn in enumerate(ph.path) if cn.name in names]
        g = fns.path(t, x[:nx], u, theta, c, t0, tf)
        excess = []
        for j, cn in self.path_named:
            sc = positive_scale(cn.lower, cn.upper)
            parts = []
            if cn.upper is not None:
                parts.append((g[j] - cn.upper) / sc)
            if cn.lower is not None:
                parts.append((cn.lower - g[j]) / sc)
            excess.append(parts[0] if len(parts) == 1 else ca.fmax(parts[0], parts[1]))
        self.pathf = ca.Function("mc_path", [x, u, s], [ca.vertcat(*excess) if excess else ca.SX.zeros(0)])
        # the traced quantities: the states, then each named path constraint's value (not its excess)
        self.trace_names = [f"state:{n}" for n in ph.state_names] + [f"path:{cn.name}" for _, cn in self.path_named]
        self.tracef = ca.Function("mc_trace", [x, u, s], [ca.vertcat(x[:nx], *[g[j] for j, _ in self.path_named])])
        self.bnd_named = [(j, cn) for j, cn in enumerate(ph.boundary) if cn.name in names]
        self.u0, self.uf, self.theta = ca.DM(self.d["u0"]), ca.DM(self.d["uf"]), theta
        self.intervals: dict = {}

    def events(self, x0, xf):
        """The phase's boundary values and Mayer term (its own: the problem posed as one phase) at a
        sample's ends ``[x; q; t]``."""
        d = self.d
        return self.fns.events(float(d["t0"]), float(d["tf"]), x0[:self.nx], xf[:self.nx], self.u0, self.uf,
                               self.theta, self.c)

    def interval_fn(self, substeps: int):
        """``substeps`` RK4 steps of one sample between two neighbouring nodes: (x, Us, h, s) -> (x_end, the
        worst excess of each named path constraint over the steps' ends, the excess at the end); ``Us``
        (nu x 2 substeps + 1) the control at the steps' ends and middles (:func:`stage_controls`)."""
        if substeps not in self.intervals:
            nu, npath, s = self.nu, len(self.path_named), self.s
            xa, Us, hi = ca.SX.sym("x", self.n), ca.SX.sym("Us", nu, 2 * substeps + 1), ca.SX.sym("h")
            xk = xa
            e = worst = ca.SX.zeros(npath) - ca.inf
            for j in range(substeps):
                xk = self.step(xk, Us[:, 2 * j], Us[:, 2 * j + 1], Us[:, 2 * j + 2], hi / substeps, s)
                e = self.pathf(xk, Us[:, 2 * j + 2], s)
                worst = ca.fmax(worst, e)
            self.intervals[substeps] = ca.Function("mc_interval", [xa, Us, hi, s], [xk, worst, e])
        return self.intervals[substeps]


def stage_controls(d: dict, nu: int, substeps: int) -> list[np.ndarray]:
    """Per pair of neighbouring nodes of the phase ``d`` (a spec's phase), the control at the ends and middles
    of its ``substeps`` RK4 steps (nu x 2 substeps + 1): linear or constant between shooting nodes, on LGL the
    segment's Lagrange polynomial through its node controls (the transcription's own control, which the
    Monte Carlo re-flies)."""
    Uc = np.asarray(d["controls"], float).reshape(nu, len(d["t_nodes"]))
    tn = np.asarray(d["t_nodes"], float)
    f = np.arange(2 * substeps + 1) / (2.0 * substeps)
    if d["control"] != "lgl":
        return [Uc[:, j:j + 1] + f[None, :] * ((Uc[:, j + 1] if d["control"] == "linear" else Uc[:, j]) - Uc[:, j])[:, None]
                for j in range(tn.size - 1)]
    out, a = [], 0
    for n in d["segment_nodes"]:
        b = a + int(n) - 1
        L = lgl_nodes(int(n))
        for j in range(a, b):
            s = 2.0 * (tn[j] + f * (tn[j + 1] - tn[j]) - tn[a]) / (tn[b] - tn[a]) - 1.0
            out.append(Uc[:, a:b + 1] @ lagrange_matrix(L, s).T)
        a = b
    return out


def _build_model(mp: dict) -> MCModel:
    from solvers.ocp import parse_problem

    problem = parse_problem(mp["params"])
    rob = problem.robust
    assert rob is not None, "the Monte Carlo model of an ocp problem needs its uncertainty"
    names = set(mp.get("constraints") or [])
    flights = [_PhaseFlight(problem, i, mp, names) for i in range(len(problem.phases))]
    first = flights[0]
    ns, nu = first.ns, first.nu
    maps: dict = {}

    def mapped(fn, n):
        key = (id(fn), n)
        if key not in maps:
            maps[key] = (fn, fn.map(n, "serial"))
        return maps[key][1]

    # the ends of every phase, stacked: [x0; xf] of phase 1, of phase 2, ...; the objective over all of them
    ends = [(ca.SX.sym(f"x0_{i}", f.n), ca.SX.sym(f"xf_{i}", f.n)) for i, f in enumerate(flights)]
    s_sym = first.s
    outs, mayer = [], ca.SX(0)
    for f, (a, b) in zip(flights, ends):
        bvals, m = f.events(a, b)
        outs += [bvals[j] for j, _ in f.bnd_named]
        mayer = mayer + (m if problem.single else 0) + (b[f.nx] if f.nq else 0)
    if not problem.single and problem.objective.expr is not None:
        mayer = mayer + _events_objective(problem, flights, ends)
    stacked = ca.vertcat(*[ca.vertcat(a, b) for a, b in ends])
    termf = ca.Function("mc_terminal", [stacked, s_sym], [ca.vertcat(mayer, *outs)])
    bnd = [cn for f in flights for _, cn in f.bnd_named]

    def terminal(xf, x0=None, s=None):
        n = xf.shape[1]
        if problem.single:           # the numpy propagator's xf is the last state alone
            xf = np.vstack([x0, xf]) if xf.shape[0] == first.n else xf
        out = np.asarray(mapped(termf, n)(xf, s if ns else np.zeros((0, n))), float).reshape(-1, n)
        d = {"objective": out[0]}
        kept: dict[str, np.ndarray] = {}
        for r, cn in enumerate(bnd, start=1):
            v = out[r]
            ok = np.isfinite(v)
            tol = 1e-9 * positive_scale(cn.lower, cn.upper)
            if cn.lower is not None:
                ok &= v >= cn.lower - tol
            if cn.upper is not None:
                ok &= v <= cn.upper + tol
            d[f"boundary:{cn.name}"] = v          # a name in several phases: the last phase's value
            kept[cn.name] = kept.get(cn.name, np.ones(n, bool)) & ok
        for name, ok in kept.items():
            d[f"kept:{name}"] = ok.astype(float)
        return d

    def rhs_np(xv, uv, sv):
        n = xv.shape[1]
        return np.asarray(mapped(first.rhs, n)(xv, np.broadcast_to(uv, (nu, n)), sv if ns else np.zeros((0, n))),
                          float)

    path_names = list(dict.fromkeys(cn.name for f in flights for _, cn in f.path_named))
    path = {}
    if problem.single:           # the numpy propagator (the reference) flies a problem posed as one phase
        path = {cn.name: MCPath(fn=_row(first.pathf, r, nu, ns, mapped), limit=0.0)
                for r, (_, cn) in enumerate(first.path_named)}
    else:
        path = {name: MCPath(fn=_not_numpy, limit=0.0) for name in path_names}

    trace_names = list(dict.fromkeys(q for f in flights for q in f.trace_names))   # every phase's

    def kernel(*, x0, s, t_nodes, controls, substeps, kept_nodes):
        del t_nodes, controls        # every phase's own, from the model's params
        n = x0.shape[1]
        sv = ca.DM(s if ns else np.zeros((0, n)))
        worst_fine = {nm: np.full(n, -np.inf) for nm in path_names}
        worst_node = {nm: np.full(n, -np.inf) for nm in path_names}
        stack = []
        xk = ca.DM(np.ascontiguousarray(x0, float))
        rows = {int(node): r for r, node in enumerate(kept_nodes)}     # nodes of all phases, one after another
        traces = np.full((len(trace_names), len(rows), n), np.nan)     # NaN: a quantity this phase has not

        def keep(node: int, Uc: np.ndarray) -> None:
            if node + offset in rows:
                u = ca.DM(Uc[:, min(node, Uc.shape[1] - 1)])
                traces[quantities, rows[node + offset], :] = np.asarray(mapped(f.tracef, n)(xk, u, sv),
                                                                        float).reshape(-1, n)
        offset = 0
        for i, f in enumerate(flights):
            quantities = [trace_names.index(q) for q in f.trace_names]
            if i:
                xk = ca.DM(_start_of(problem, flights, i, np.asarray(xk, float), n, np.asarray(sv, float)))
            stack.append(np.asarray(xk, float))
            d = f.d
            Uc = np.asarray(d["controls"], float).reshape(f.nu, len(d["t_nodes"]))
            tn = d["t_nodes"]
            F = mapped(f.interval_fn(int(substeps)), n)
            stages = stage_controls(d, f.nu, int(substeps))
            npath = len(f.path_named)
            wf, wn = np.full((npath, n), -np.inf), np.full((npath, n), -np.inf)
            if npath:
                e0 = np.asarray(mapped(f.pathf, n)(xk, ca.DM(Uc[:, 0]), sv), float).reshape(npath, n)
                wf, wn = np.maximum(wf, e0), np.maximum(wn, e0)
            keep(0, Uc)
            for j in range(len(tn) - 1):
                xk, w, e = F(xk, ca.DM(stages[j]), float(tn[j + 1] - tn[j]), sv)
                keep(j + 1, Uc)
                if npath:
                    w = np.asarray(w, float).reshape(npath, n)
                    e = np.asarray(e, float).reshape(npath, n)
                    np.maximum(wf, np.where(np.isfinite(w), w, np.inf), out=wf)
                    np.maximum(wn, np.where(np.isfinite(e), e, np.inf), out=wn)
            stack.append(np.asarray(xk, float))
            for r, (_, cn) in enumerate(f.path_named):
                np.maximum(worst_fine[cn.name], wf[r], out=worst_fine[cn.name])
                np.maximum(worst_node[cn.name], wn[r], out=worst_node[cn.name])
            offset += len(tn)
        return np.vstack(stack), worst_fine, worst_node, dict(zip(trace_names, traces)) if rows else {}

    def traced(xv, uv, sv):
        n = xv.shape[1]
        out = np.asarray(mapped(first.tracef, n)(xv, np.broadcast_to(uv, (nu, n)), sv if ns else np.zeros((0, n))),
                         float).reshape(-1, n)
        return dict(zip(first.trace_names, out))

    sampled = ("objective",) + tuple(dict.fromkeys(f"boundary:{cn.name}" for cn in bnd))
    return MCModel(nx=first.n, nu=nu, ns=ns, rhs=rhs_np, terminal=terminal, path=path, kernel=kernel,
                   trace=traced if problem.single else _not_numpy, sampled_terminal=sampled)


def _start_of(problem, flights, i: int, xprev: np.ndarray, n: int, s: np.ndarray) -> np.ndarray:
    """Phase ``i``'s start of every sample: the states linked by continuity from phase ``i - 1``'s end, those a
    link sets solved from it (:mod:`solvers.ocp.robust.links`), the others where the design sets them, the
    integral at zero, the clock at the phase's start."""
    f, fp = flights[i], flights[i - 1]
    x = np.zeros((f.n, n))
    x[:f.nx] = np.asarray(f.d["x0"], float)[:, None]
    names_prev = fp.php.phase.state_names
    names = f.php.phase.state_names
    for k, name in problem.state_links:
        if k == i - 1:
            x[names.index(name)] = xprev[names_prev.index(name)]
    for cl in carried_links(problem):
        if cl.after == i:
            x[names.index(cl.target)] = _solve_link(problem, cl, fp, f, xprev[:fp.nx], s)
    x[f.nx + f.nq] = float(f.d["t0"])
    return x


def _solve_link(problem, cl, fp, f, xf: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Each sample's state that ``cl`` sets, from the samples' previous ends ``xf`` and constants ``s``."""
    return solve_link(problem, cl, y0=float(f.d["x0"][f.php.phase.state_names.index(cl.target)]), xf=xf,
                      u=np.concatenate([fp.d["u0"], fp.d["uf"], f.d["u0"], f.d["uf"]]).astype(float),
                      times=np.array([fp.d["t0"], fp.d["tf"], f.d["t0"], f.d["tf"]], float),
                      theta=np.asarray(fp.theta, float).ravel(), s=s)


def _events_objective(problem, flights, ends):
    """The Mayer term of several phases over their events (the samples' ends; times and controls the design's)."""
    from solvers.ocp.symbolic import to_sx

    first = flights[0]
    env = {n: first.c[i] for i, (n, _) in enumerate(problem.constants)}
    env.update({q.name: first.theta[i] for i, q in enumerate(problem.parameters)})
    ev: dict = {}
    for named, f, (a, b) in zip(problem.phases, flights, ends):
        nm = named.name
        ev[("t0", nm)], ev[("tf", nm)] = ca.SX(float(f.d["t0"])), ca.SX(float(f.d["tf"]))
        for j, x in enumerate(named.problem.phase.state_names):
            ev[("initial", x, nm)], ev[("final", x, nm)] = a[j], b[j]
        for j, u in enumerate(named.problem.phase.control_names):
            ev[("initial", u, nm)], ev[("final", u, nm)] = ca.SX(f.d["u0"][j]), ca.SX(f.d["uf"][j])
    return to_sx(problem.objective.expr, env, {t.name: t for t in problem.tables}, ev)


def _not_numpy(x, u, s):
    raise NotImplementedError("a problem of several phases is flown by its compiled kernel only")


def _row(pathf, r: int, nu: int, ns: int, mapped):
    def fn(x, u, s):
        n = x.shape[1]
        return np.asarray(mapped(pathf, n)(x, np.broadcast_to(u, (nu, n)), s if ns else np.zeros((0, n))),
                          float).reshape(-1, n)[r]
    return fn
