"""Independent check of an ``ocp`` answer: re-fly its controls with scipy's DOP853 on a dense grid.

The controls are interpolated exactly as the transcription defines them (linear or constant
between multiple-shooting nodes; the segment's Lagrange polynomial through the LGL nodes) and
the states integrated from the answer's initial state with ``solve_ivp(method="DOP853",
rtol=1e-10)``, one interval after the other without restarting at the nodes (the state is
carried over, so a matching defect shows as drift), which keeps a control's kink at an interval
end from costing the integrator rejected steps.  Reported: per state, the largest difference
to the NLP's nodes, absolute and divided by the state's scale; per path constraint, the worst
value on the dense grid against its bounds (Betts, *Practical Methods for Optimal Control*,
2nd ed., sec. 4.7: a limit enforced at the nodes can be exceeded between them), and per
interval the worst excess, which the limit loop of :mod:`solvers.ocp.limits` tightens against.

When the dynamics amplify errors past what a flight from t0 can follow (:mod:`solvers.ocp.growth`:
an eigenvalue of +2 over 20 s multiplies the NLP's 1e-8 by 2e17), ``restart=True`` flies each
interval from its own first node instead (``mode`` ``interval_by_interval``): a node's difference is
then that interval's defect, and the dense grid each interval's own flight.

An LGL control is the polynomial through its nodes, which holds the control's bounds at the nodes
only (a bang-bang control overshoots between them: +-1.131 on [-1, 1] for the double integrator).
Per bounded control the interpolant's worst value on the dense grid is reported with its time and
excursion beyond the bounds (:func:`control_excursions`), and ``controls_held`` says whether every
excursion is within :data:`LIMIT_TOLERANCE` of the bounds' width.  It is reported, not clipped and
not made a failure: the NLP defines the control at the nodes, where the bounds hold, and the
overshoot stays at any grid when a switch falls on a segment end (the shared node forces the
polynomial through it), so clipping the re-flight or tightening rounds would turn every converged
LGL bang-bang answer into a failure (the double integrator: ``terminal_not_held`` after three
refinements to 80 segments).  Multiple-shooting controls (constant or linear between the nodes)
hold their bounds by construction.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.integrate import solve_ivp

from solvers.ocp.growth import FROM_T0, INTERVALS
from solvers.transcription.lgl import lagrange_matrix, lgl_nodes

METHOD = "scipy DOP853, rtol 1e-10, continuous from the initial state, controls as transcribed"
METHOD_INTERVALS = "scipy DOP853, rtol 1e-10, each interval from its own first node, controls as transcribed"
SAMPLES_PER_INTERVAL = 20
LIMIT_TOLERANCE = 1e-3
MAX_RHS_CALLS = 2_000_000   # about 10 s of DOP853      # a path bound holds to 0.1% of the constraint's scale (as reentry's limits)


@dataclass
class Verification:
    t: np.ndarray                                # dense times
    x: np.ndarray                                # (nx, len(t))
    u: np.ndarray                                # (nu, len(t))
    max_abs_difference: dict[str, float]         # per state, over the nodes
    max_scaled_difference: dict[str, float]
    path: dict[str, dict] = field(default_factory=dict)
    controls: dict[str, dict] = field(default_factory=dict)   # per bounded LGL control, its excursion
    interval_excess: list[np.ndarray] = field(default_factory=list)   # per path constraint, (m,)
    limits_held: bool = True
    ok: bool = True
    message: str = ""
    restart: bool = False                        # each interval flown from its own first node
    interval_error: np.ndarray | None = None     # restart: per interval, its worst scaled defect at its nodes

    @property
    def mode(self) -> str:
        return INTERVALS if self.restart else FROM_T0

    def as_dict(self) -> dict:
        return {"method": METHOD_INTERVALS if self.restart else METHOD, "mode": self.mode,
                "samples_per_interval": SAMPLES_PER_INTERVAL,
                "max_state_difference": self.max_abs_difference,
                "max_state_difference_scaled": self.max_scaled_difference,
                "max_state_difference_scaled_overall": max(self.max_scaled_difference.values(), default=0.0),
                "path": self.path, "controls": self.controls,
                "controls_held": all(e["held"] for e in self.controls.values()), "limits_held": self.limits_held, "limit_tolerance": LIMIT_TOLERANCE,
                "ok": self.ok, "message": self.message}


def control_function(grid, t_nodes: np.ndarray, U: np.ndarray):
    """``u(t, interval)``: the transcription's control on interval ``interval`` at times ``t``."""
    m = grid.intervals
    if U.shape[0] == 0:
        return lambda t, k: np.zeros((0, np.size(t)))
    if grid.method == "multiple_shooting":
        if grid.control == "constant":
            return lambda t, k: np.repeat(U[:, k:k + 1], np.size(t), axis=1)
        return lambda t, k: np.vstack([np.interp(np.atleast_1d(t), t_nodes[k:k + 2], U[i, k:k + 2])
                                       for i in range(U.shape[0])])
    off, per = grid.offsets(), grid.nodes_per_interval()

    def u(t, k):
        ta, tb = t_nodes[off[k]], t_nodes[off[k + 1]]
        s = 2.0 * (np.atleast_1d(t) - ta) / (tb - ta) - 1.0
        return U[:, off[k]:off[k] + per[k]] @ lagrange_matrix(lgl_nodes(int(per[k])), s).T
    del m
    return u


def control_excursions(t: np.ndarray, u: np.ndarray, names: list[str],
                       bounds: list[tuple[float | None, float | None]]) -> dict[str, dict]:
    """Per bounded control, the interpolant's extremes on the dense grid and the largest distance by
    which it left its bounds there (0 when it stayed inside), with the time of that worst value;
    ``held`` when that is within :data:`LIMIT_TOLERANCE` of the bounds' width (of the one bound's
    size, at least 1, for a control bounded on one side)."""
    out = {}
    for i, (name, (lo, hi)) in enumerate(zip(names, bounds)):
        if lo is None and hi is None:
            continue
        v = u[i]
        over = np.zeros(v.shape)
        if hi is not None:
            over = np.maximum(over, v - hi)
        if lo is not None:
            over = np.maximum(over, lo - v)
        j = int(np.argmax(over))
        ends = [b for b in (lo, hi) if b is not None]
        width = ends[1] - ends[0] if len(ends) == 2 else max(1.0, abs(ends[0]))
        out[name] = {"lower": lo, "upper": hi, "min": float(v.min()), "max": float(v.max()),
                     "worst_value": float(v[j]), "worst_t": float(t[j]), "excursion": float(over[j]),
                     "held": bool(over[j] <= LIMIT_TOLERANCE * width)}
    return out


def _fast_rhs(fns, args):
    """``rhs(t, x, u) -> xdot`` through a CasADi function buffer: about 4 us a call where a plain
    call of the function on numpy arrays costs 50-200 us (argument conversion), which made the
    DOP853 re-flight of the Betts shuttle cost 2 s."""
    import casadi as ca
    nx, nu = fns.nx, fns.nu
    t, x, u = ca.SX.sym("t"), ca.SX.sym("x", nx), ca.SX.sym("u", nu)
    rest = ca.SX.sym("rest", fns.ntheta + fns.nc + 2)
    theta, c = rest[:fns.ntheta], rest[fns.ntheta:fns.ntheta + fns.nc]
    out = fns.rhs(t, x, u, theta, c, rest[-2], rest[-1])[:nx]
    f = ca.Function("ocp_rhs_flat", [ca.vertcat(t, x, u, rest)], [out])
    buf, trigger = f.buffer()
    a = np.zeros(1 + nx + nu + rest.numel())
    a[1 + nx + nu:] = np.concatenate([args[0], args[1], [args[2], args[3]]])
    res = np.zeros(nx)
    # casadi's stubs want the byte size too, which its Python binding reads from the buffer itself
    buf.set_arg(0, a.data)  # type: ignore[call-arg]
    buf.set_res(0, res.data)  # type: ignore[call-arg]

    calls = [0]

    def rhs(ti, xi, ui):
        a[0] = ti
        a[1:1 + nx] = xi
        a[1 + nx:1 + nx + nu] = ui
        trigger()
        calls[0] += 1
        # DOP853 keeps shrinking its step on a NaN (it never stops by itself), and a stiff or
        # singular problem can cost millions of steps: both end the re-flight as a failed check.
        if not np.isfinite(res).all():
            raise FloatingPointError(f"the dynamics are not finite at t = {ti:.6g}")
        if calls[0] > MAX_RHS_CALLS:
            raise RuntimeError(f"more than {MAX_RHS_CALLS} right-hand-side evaluations (a stiff or "
                               "singular trajectory)")
        return res.copy()
    rhs.buffer = buf  # type: ignore[attr-defined]  # keeps the buffer alive with the closure
    return rhs


def interval_bounds(grid, t_nodes: np.ndarray) -> np.ndarray:
    return t_nodes[grid.offsets()]


def _interval_rhs(grid, U, uf, rhs, k, ta, tb):
    """``f(t, x)`` on interval ``k``: the controls as the transcription defines them there."""
    ua, ub = U[:, k], U[:, k + 1]
    if grid.method == "multiple_shooting" and grid.control == "linear":
        du = (ub - ua) / (tb - ta)

        def f(t, x):
            return rhs(t, x, ua + (t - ta) * du)
    elif grid.method == "multiple_shooting":
        def f(t, x):
            return rhs(t, x, ua)
    else:
        def f(t, x):
            return rhs(t, x, uf(t, k)[:, 0])
    return f


def local_errors(*, fns, grid, t_nodes, X, U, theta, c, t0, tf, x_scale) -> np.ndarray:
    """Per interval, the worst scaled difference between its nodes and the interval re-flown from its
    own first node (DOP853 as :func:`verify`): what that interval's discretization adds, the error
    model of mesh refinement (:mod:`solvers.transcription.refine`); NaN where the flight fails."""
    U = np.asarray(U, float)
    uf = control_function(grid, t_nodes, U)
    ends, off = interval_bounds(grid, t_nodes), grid.offsets()
    rhs = _fast_rhs(fns, (np.asarray(theta, float), np.asarray(c, float), t0, tf))
    scale = np.asarray(x_scale, float)
    out = np.full(grid.intervals, np.nan)
    for k in range(grid.intervals):
        nodes_k = t_nodes[off[k] + 1:off[k + 1] + 1]
        f = _interval_rhs(grid, U, uf, rhs, k, ends[k], ends[k + 1])
        try:
            loc = solve_ivp(f, (ends[k], ends[k + 1]), X[:, off[k]], method="DOP853", rtol=1e-10,
                            atol=1e-10 * scale, t_eval=nodes_k)
        except (ValueError, ArithmeticError, RuntimeError):
            continue
        if loc.success and loc.y.shape[1] == len(nodes_k):
            out[k] = float((np.abs(loc.y - X[:, off[k] + 1:off[k + 1] + 1]) / scale[:, None]).max())
    return out


def verify(*, fns, grid, t_nodes, X, U, theta, c, t0, tf, state_names, x_scale,
           path_bounds, path_names, path_scale, control_names: list[str] | None = None,
           control_bounds: list[tuple[float | None, float | None]] | None = None,
           restart: bool = False) -> Verification:
    """Re-fly ``U`` from ``X[:, 0]`` (module docstring); ``restart``: each interval from its own first node
    instead (dynamics that amplify, :mod:`solvers.ocp.growth`), so a node's difference is that interval's
    defect.  ``path_bounds``: (lower, upper) per path
    constraint (None for a side without a bound); ``control_bounds`` the same per control (named by
    ``control_names``): an LGL interpolant's excursion beyond them is reported (module docstring)."""
    uf = control_function(grid, t_nodes, np.asarray(U, float))
    lgl_bounds = control_bounds if grid.method == "lgl" else None
    ends = interval_bounds(grid, t_nodes)
    m = grid.intervals
    args = (np.asarray(theta, float), np.asarray(c, float), t0, tf)
    rhs = _fast_rhs(fns, args)
    atol = 1e-10 * np.asarray(x_scale, float)
    ts, xs_, us_, node_x, fail = [], [], [], [X[:, 0].copy()], ""
    y = np.asarray(X[:, 0], float).copy()
    off = grid.offsets()
    scale = np.asarray(x_scale, float)
    for k in range(m):
        ta, tb = ends[k], ends[k + 1]
        nodes_k = t_nodes[off[k] + 1:off[k + 1] + 1]
        dense = np.linspace(ta, tb, SAMPLES_PER_INTERVAL + 1)[:-1]
        t_eval = np.unique(np.concatenate([dense, nodes_k]))

        if restart:
            y = np.asarray(X[:, off[k]], float).copy()
        f = _interval_rhs(grid, U, uf, rhs, k, ta, tb)
        try:
            sol = solve_ivp(f, (ta, tb), y, method="DOP853", rtol=1e-10, atol=atol, t_eval=t_eval)
        except (ValueError, ArithmeticError, RuntimeError) as e:   # NaN/overflow in the user's dynamics
            fail = f"re-propagation failed on interval {k}: {e}"
            break
        if not sol.success or sol.y.shape[1] != t_eval.size or not np.all(np.isfinite(sol.y)):
            fail = f"re-propagation failed on interval {k}: {sol.message}"
            break
        keep = np.isin(t_eval, dense)
        ts.append(t_eval[keep])
        xs_.append(sol.y[:, keep])
        us_.append(uf(t_eval[keep], k))
        node_x += [sol.y[:, np.searchsorted(t_eval, tn)] for tn in nodes_k]
        y = sol.y[:, -1].copy()
    ts.append(np.array([t_nodes[-1]]))
    xs_.append(y[:, None])
    us_.append(uf(np.array([t_nodes[-1]]), m - 1))
    t_d, x_d, u_d = np.concatenate(ts), np.hstack(xs_), np.hstack(us_)
    excursions = {} if lgl_bounds is None else control_excursions(t_d, u_d, control_names or [], lgl_bounds)
    if fail:
        nan = {s: float("nan") for s in state_names}
        return Verification(t=t_d, x=x_d, u=u_d, max_abs_difference=nan, max_scaled_difference=dict(nan),
                            controls=excursions, limits_held=False, ok=False, message=fail, restart=restart)
    diff = np.abs(np.column_stack(node_x) - X)
    abs_d = {s: float(diff[i].max()) for i, s in enumerate(state_names)}
    scaled = {s: float(diff[i].max() / scale[i]) for i, s in enumerate(state_names)}
    ver = Verification(t=t_d, x=x_d, u=u_d, max_abs_difference=abs_d, max_scaled_difference=scaled,
                       controls=excursions, restart=restart)
    if restart:            # what local_errors would fly again: each interval's defects, from this flight
        node_scaled = (diff / scale[:, None]).max(axis=0)
        ver.interval_error = np.array([node_scaled[off[k] + 1:off[k + 1] + 1].max() for k in range(m)])
    if fns.npath:
        vals = np.asarray(fns.path.map(t_d.size)(t_d[None, :], x_d, u_d, args[0], args[1], t0, tf))
        interval = np.minimum(np.searchsorted(ends, t_d, side="right") - 1, m - 1)
        for i, (name, (lo, hi), sc) in enumerate(zip(path_names, path_bounds, path_scale)):
            v = vals[i]
            over = np.full(v.shape, -np.inf)
            if hi is not None:
                over = np.maximum(over, (v - hi) / sc)
            if lo is not None:
                over = np.maximum(over, (lo - v) / sc)
            per = np.full(m, -np.inf)
            np.maximum.at(per, interval, over)
            ver.interval_excess.append(per)
            worst = float(over.max())
            held = worst <= LIMIT_TOLERANCE
            ver.limits_held &= held
            ver.path[name] = {"lower": lo, "upper": hi, "min": float(v.min()), "max": float(v.max()),
                              "worst_t": float(t_d[int(np.argmax(over))]),
                              "excess_scaled": worst, "scale": float(sc), "held": bool(held)}
    ver.message = (("each interval re-flown from its own first node: its defects at the nodes reach "
                    if restart else "re-propagated states agree with the nodes to ")
                   + f"{max(scaled.values()):.2e} (scaled); path limits "
                   f"{'hold' if ver.limits_held else 'do NOT hold'} on the dense grid")
    outside = {n: e for n, e in excursions.items() if not e["held"]}
    if outside:   # said only when it happens, so answers that keep their bounds read as before
        n, worst_c = max(outside.items(), key=lambda kv: kv[1]["excursion"])
        ver.message += (f"; controls leave their bounds between the nodes (worst: {n} = "
                        f"{worst_c['worst_value']:.4g} at t = {worst_c['worst_t']:.4g}; held at the nodes)")
    return ver
