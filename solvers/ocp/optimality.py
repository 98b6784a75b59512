"""Evidence that a phase's answer is an optimum, not only feasible (``shared/specs/ocp.md``, "Optimality").

The costates come from the NLP's multipliers (:mod:`solvers.ocp.costates`, both transcriptions), the
Hamiltonian from :mod:`solvers.ocp.hamiltonian` with the path constraints' multipliers per unit time
(``mu_j = pi_j / W_j``: the node's multiplier over its quadrature weight, the trapezoid's for multiple
shooting, the LGL weights times ``h / 2`` summed over the segments sharing the node).

Checks (each ``{"value", "tolerance", "held"}``), those that apply:

- ``hamiltonian_constant`` (nothing names ``t``: the dynamics, integrand and path constraints): the spread
  of H over the nodes;
- ``hamiltonian_final`` (the phase's final time is free): ``H(tf) = -d(sign Phi + nu' psi)/dtf``, the events'
  multipliers (boundary constraints, links between phases, a bound on tf) included;
- ``stationarity``: ``dH/du = 0`` where every control is strictly inside its box, the path constraints'
  multipliers in H (so an arc on a mixed constraint counts too), in the form each control's unknown acts:
  at the LGL nodes; for multiple shooting's linear controls ``dH/du`` averaged with the node's hat
  function over its two intervals (Simpson); per interval for piecewise-constant ones (the trapezoid of its
  two ends).  Nodal values alone would misjudge the ends and the junctions of arcs, where ``dH/du`` kinks
  and a node's unknown balances the average, not its own value;
- ``minimum_principle`` (:mod:`solvers.ocp.minimum_principle`): the control used minimises H over its
  admissible set at the dense re-flight's samples;
- ``transversality`` (a state whose value at an end is not fixed): the costate there against
  ``+-d(sign Phi + nu' psi)/dx`` with the path rows and bounds of that node; for LGL the mapping's own end
  value is compared (the endpoint correction's size), for multiple shooting it is the end node's KKT
  condition and holds to IPOPT's tolerance.

Each is measured against the size of H's terms (the largest sum of their magnitudes over the nodes, as H
may be 0; transversality: a costate's error times the largest rate of its state) and held to the answer's
tolerance, 1% (or the answer's ``accuracy`` where that is coarser: the costates converge at their own
rate, a singular arc's more slowly than the states, so a tighter state accuracy does not tighten their
estimate).  One allowance is derived from the mesh: the multipliers fix the sign of the switching
function ``sigma = dH/du`` on each interval of a control on its bounds, not where it crosses zero, so
where a control switches the costates are not unique.  A piecewise-constant control's zero can sit
anywhere within half an interval of the switching node (between the two intervals' midpoints) and H may
jump there by up to ``|du| |dsigma/dt| h / 2`` (H is evaluated on each interval with that interval's
control at both its ends); a control at the nodes (LGL, linear) crosses between two nodes, anywhere in
that gap ``dt``, and H departs by up to ``|du| |dsigma/dt| dt``.  The sum of those bounds over the mesh
(``allowance``, reported, relative) is added to the tolerance of ``hamiltonian_constant`` and
``hamiltonian_final``.  It vanishes where a control is interior (``sigma = 0`` there) or stays on a bound
(``du = 0``): it counts the switches only.
"""
from __future__ import annotations

import numpy as np

from solvers.ocp.costates import right_costates
from solvers.ocp.hamiltonian import HamiltonianFunctions, evaluate
from solvers.ocp.minimum_principle import minimum_principle
from solvers.transcription.lgl import lgl_weights

INSIDE = 1e-3        # a control within this fraction of its bounds' span from a bound is on it


def node_weights(grid, t_nodes: np.ndarray) -> np.ndarray:
    """Each node's quadrature weight in time: what a path row's multiplier is spread over."""
    W = np.zeros(t_nodes.size)
    if grid.method == "multiple_shooting":
        h = np.diff(t_nodes)
        W[:-1] += h / 2
        W[1:] += h / 2
        return W
    off = grid.offsets()
    for s, n in enumerate(grid.nodes_per_interval()):
        h = t_nodes[off[s + 1]] - t_nodes[off[s]]
        W[off[s]:off[s] + n] += 0.5 * h * lgl_weights(int(n))
    return W


def path_rates(*, phase, mult, num, grid, t_nodes) -> tuple[np.ndarray, np.ndarray]:
    """The path constraints' multipliers per unit time at the nodes, and the bound each one's sign names."""
    pi = mult.path / num.path_scale[:, None] if mult.path.size else mult.path
    mu = pi / node_weights(grid, t_nodes)[None, :] if pi.size else pi
    cb = np.zeros_like(mu)
    for j, k in enumerate(phase.path):
        cb[j] = np.where(pi[j] > 0, k.upper if k.upper is not None else 0.0,
                         k.lower if k.lower is not None else 0.0)
    return mu, cb


def _inside(values: np.ndarray, lower, upper, span: float) -> np.ndarray:
    keep = np.ones(values.shape, bool)
    if lower is not None:
        keep &= values > lower + INSIDE * span
    if upper is not None:
        keep &= values < upper - INSIDE * span
    return keep


def _entry(value: float, tolerance: float, **more) -> dict:
    return {"value": value, "tolerance": tolerance, "held": bool(value <= tolerance), **more}


def checks(*, problem, nlp, hf: HamiltonianFunctions, att, lam, U, t_nodes, c, t0: float, F: np.ndarray,
           H: np.ndarray, size: float, tolerance: float, num, mult, path: tuple[np.ndarray, np.ndarray],
           mapped: dict, dense: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None) -> dict:
    """``verification.optimality`` of the phase (module docstring); ``hf``: its Hamiltonian; ``F``: the
    dynamics at the nodes (:func:`solvers.ocp.hamiltonian.node_rates`); ``size``: the size of H's terms; ``mult``:
    its :class:`solvers.ocp.costates.PhaseMultipliers`; ``path``: its :func:`path_rates`; ``mapped``: LGL's
    mapped end costates; ``dense``: the re-flight's ``(t, x, u)`` samples, for the minimum principle (none:
    not checked)."""
    fns, ph, grid = nlp.fns, problem.phase, nlp.grid
    scale = size if size > 0.0 else 1.0
    out: dict[str, dict] = {}
    piecewise = grid.piecewise
    Hvals, H_end, allowance = H, float(H[-1]), 0.0
    common = {"att": att, "c": c, "t0": t0}
    plus = right_costates(nlp=nlp, num=num, mult=mult, lam=lam)
    sigma = _switching(hf=hf, piecewise=piecewise, att=att, lam=lam, plus=plus, U=U, t_nodes=t_nodes, c=c,
                       t0=t0) if fns.nu else ()
    if piecewise and fns.nu:
        Uc, X = att.U, att.X
        Ha = evaluate(hf.H, t=t_nodes[:-1], X=X[:, :-1], U=Uc, lam=plus[:, :-1], **common)[0]
        Hb = evaluate(hf.H, t=t_nodes[1:], X=X[:, 1:], U=Uc, lam=lam[:, 1:], **common)[0]
        Sa, Sb = sigma
        Hvals, H_end = np.concatenate([Ha, Hb]), float(Hb[-1])
        if Uc.shape[1] > 1:
            h = np.diff(t_nodes)
            sdot = (Sb[:, 1:] - Sa[:, :-1]) / (t_nodes[2:] - t_nodes[:-2])[None, :]
            jumps = np.abs(np.diff(Uc, axis=1)) * np.abs(sdot) * np.maximum(h[:-1], h[1:])[None, :] / 2
            allowance = float(np.sum(jumps))
    elif fns.nu and t_nodes.size > 1:
        # controls at the nodes: where one moves across the gap between two nodes, the switching function's
        # zero can sit anywhere in that gap and H departs from its value by up to |du| |dsigma/dt| dt there
        (S,) = sigma
        dt = np.diff(t_nodes)
        ok = dt > 0.0                                     # a node shared by two LGL segments appears once
        sdot = np.diff(S, axis=1)[:, ok] / dt[ok]
        allowance = float(np.sum(np.abs(np.diff(U, axis=1))[:, ok] * np.abs(sdot) * dt[ok]))
    slack = allowance / scale
    if hf.autonomous:
        out["hamiltonian_constant"] = _entry(float(np.ptp(Hvals)) / scale, tolerance + slack, allowance=slack)
    if mult.upper[0] > mult.lower[0]:              # the final time is free
        want = -float(mult.ends[0] + mult.bounds[0]) / num.t_scale
        out["hamiltonian_final"] = _entry(abs(H_end - want) / scale, tolerance + slack, expected=want,
                                          allowance=slack)
    if fns.nu:
        mu, cb = path
        st = _stationarity(problem=problem, nlp=nlp, hf=hf, att=att, lam=lam, plus=plus, U=U, t_nodes=t_nodes, c=c,
                           t0=t0, mu=mu, cb=cb, sigma=sigma, num=num, mult=mult)
        if st is not None:
            out["stationarity"] = _entry(st[0] / scale, tolerance, **st[1])
        if dense is not None:
            mp = minimum_principle(problem=problem, fns=fns, hf=hf, nlp_grid=grid, att=att, lam=lam,
                                   t_nodes=t_nodes, c=c, t0=t0, dense=dense, path_scale=num.path_scale)
            if mp is not None:
                out["minimum_principle"] = _entry(mp[0] / scale, tolerance, t=mp[1], samples=mp[2])
    tv = _transversality(names=ph.state_names, nlp=nlp, lam=lam, F=F, num=num, mult=mult, mapped=mapped)
    if tv is not None:
        out["transversality"] = _entry(tv[0] / scale, tolerance, **tv[1])
    held = all(v["held"] for v in out.values())
    failed = [k for k, v in out.items() if not v["held"]]
    message = (f"checked {', '.join(out) or 'nothing that applies'}; "
               + ("held" if held else f"NOT held: {', '.join(failed)}"))
    return {"held": held, "checks": out, "message": message}


def _switching(*, hf, piecewise: bool, att, lam, plus, U, t_nodes, c, t0) -> tuple[np.ndarray, ...]:
    """The switching function ``sigma = dH/du`` without the path term: for piecewise-constant controls the
    pair (each interval's start, with the right costates; its end), else ``(its values at the nodes,)``."""
    common = {"att": att, "c": c, "t0": t0}
    if piecewise:
        X = att.X
        return (evaluate(hf.dH_du, t=t_nodes[:-1], X=X[:, :-1], U=att.U, lam=plus[:, :-1], **common),
                evaluate(hf.dH_du, t=t_nodes[1:], X=X[:, 1:], U=att.U, lam=lam[:, 1:], **common))
    return (evaluate(hf.dH_du, t=t_nodes, X=att.X, U=U, lam=lam, **common),)


def _stationarity(*, problem, nlp, hf, att, lam, plus, U, t_nodes, c, t0, mu, cb, sigma, num, mult):
    """The worst ``|dH/du|`` times the control's scale where the controls are strictly inside their box, and
    where it was measured (``nodes`` or ``intervals``), or None where nowhere; ``sigma``: :func:`_switching`."""
    ph, grid, fns = problem.phase, nlp.grid, nlp.fns
    common = {"att": att, "c": c, "t0": t0}
    # a control's size: its scale, else its bounds' magnitude, else (unbounded) the largest value it takes
    uscale = np.array([k.scale if k.scale is not None
                       else max(abs(k.lower or 0.0), abs(k.upper or 0.0)) or float(np.max(np.abs(U[i]))) or 1.0
                       for i, k in enumerate(ph.controls)])
    spans = [(k.upper - k.lower) if k.lower is not None and k.upper is not None else max(1.0, float(np.ptp(U[i])))
             for i, k in enumerate(ph.controls)]
    if grid.piecewise:
        Uc, X, m = att.U, att.X, grid.intervals
        inside = np.ones(m, bool)
        for i, k in enumerate(ph.controls):
            inside &= _inside(Uc[i], k.lower, k.upper, spans[i])
        if not inside.any():
            return None
        h = np.diff(t_nodes)
        Sa, Sb = sigma
        G = 0.5 * (Sa + Sb)
        if fns.npath:       # the path rows of the interval's nodes that hold its control (the last: two)
            pi = mult.path / num.path_scale[:, None]
            G += evaluate(hf.dpath_du, t=t_nodes[:-1], X=X[:, :-1], U=Uc, lam=lam[:, :-1], mu=pi[:, :-1],
                          **common) / h[None, :]
            G[:, -1] += evaluate(hf.dpath_du, t=t_nodes[-1:], X=X[:, -1:], U=Uc[:, -1:], lam=lam[:, -1:],
                                 mu=pi[:, -1:], **common)[:, 0] / h[-1]
        return float(np.max(np.abs(G[:, inside]) * uscale[:, None])), {"intervals": int(inside.sum())}
    inside = np.ones(t_nodes.size, bool)
    for i, k in enumerate(ph.controls):
        inside &= _inside(U[i], k.lower, k.upper, spans[i])
    if not inside.any():
        return None
    G = evaluate(hf.dH_du, t=t_nodes, X=att.X, U=U, lam=lam, mu=mu, cb=cb, **common)
    if grid.method == "multiple_shooting":
        # a linear control's node value acts on its hat function: the condition is dH/du averaged with the
        # hat's weight over the node's two intervals (Simpson on each, exact for the linear parts), the path
        # row's multiplier at the node as it is; at the ends and where the arc changes (a bound, a mixed
        # constraint) that average is what the transcription balances, not the node's own value
        X = att.X
        tm = 0.5 * (t_nodes[:-1] + t_nodes[1:])
        mid = {"X": 0.5 * (X[:, :-1] + X[:, 1:]), "U": 0.5 * (U[:, :-1] + U[:, 1:]),
               "lam": 0.5 * (plus[:, :-1] + lam[:, 1:])}
        Sm = evaluate(hf.dH_du, t=tm, **mid, **common)
        (Sn,) = sigma                                                            # the left intervals' ends
        Sp = evaluate(hf.dH_du, t=t_nodes, X=X, U=U, lam=plus, **common)         # the right intervals' starts
        h = np.diff(t_nodes)
        acc = np.zeros_like(Sn)
        acc[:, 1:] += h * (2 * Sm + Sn[:, 1:]) / 6
        acc[:, :-1] += h * (2 * Sm + Sp[:, :-1]) / 6
        G = acc / node_weights(grid, t_nodes)[None, :] + (G - Sn)
    return float(np.max(np.abs(G[:, inside]) * uscale[:, None])), {"nodes": int(inside.sum())}


def _transversality(*, names, nlp, lam, F, num, mult, mapped):
    """The worst gap between a free end's costate and what the ends' multipliers say it is, times the
    largest rate of that state over the nodes (``F``: the dynamics there), and where; None when every end
    state is fixed."""
    fns, g = nlp.fns, nlp.grid
    nx = fns.nx
    rate = np.max(np.abs(F[:nx]), axis=1)
    worst, where = -1.0, None
    for end, node, sign in (("initial", 0, -1.0), ("final", g.n_nodes - 1, 1.0)):
        cols = 1 + fns.ntheta + nx * node + np.arange(nx)
        free = mult.upper[cols] > mult.lower[cols]
        if not free.any():
            continue
        want = sign * (mult.ends[cols] + mult.path_ends[cols] + mult.bounds[cols]) / num.x_scale
        have = mapped.get(end, lam[:, node])
        gap = np.abs(have - want) * rate
        gap[~free] = 0.0
        i = int(np.argmax(gap))
        if gap[i] > worst:
            worst, where = float(gap[i]), {"end": end, "state": names[i], "costate": float(have[i]), "expected": float(want[i])}
    if where is None:
        return None
    return worst, where
