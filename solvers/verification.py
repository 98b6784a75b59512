"""Independent check of an optimal-control answer: re-propagate its controls accurately.

The optimal node controls are interpolated exactly as the transcription defines them
(:func:`solvers.transcription.multiple_shooting.control_at`) and integrated from the initial
state in one continuous propagation (never restarted at the nodes, so matching defects show up as
a drift).  The report gives the final-state difference to the NLP's final node, the difference at
every node, and the worst value of each path quantity along the whole dense trajectory, not only
at the nodes (a limit enforced at nodes overshoots between them: Betts, *Practical Methods for
Optimal Control*, 2nd ed., sec. 4.7 on the accuracy of discretized path constraints).

Two integrators:

* :func:`propagate_dense` (the reentry kind's default): classical RK4 with fixed steps,
  ``samples_per_interval`` output points per shooting interval and two RK4 steps between output
  points (so 40 steps per interval where the NLP takes 2 by default), written once as a CasADi SX
  step function and ``mapaccum``-ed over the output points and the intervals: one compiled-graph
  call instead of a Python loop (about 20 ms for 100 intervals where per-interval ``solve_ivp``
  took 0.5-0.8 s).  The same propagation with one step between output points runs alongside, and
  Richardson's step-doubling estimate ``|x_2h - x_h| / 15`` of the global error is reported
  (``error_estimate``), so the check says how accurate it is.
* :func:`repropagate`: scipy's DOP853 (rtol 1e-10) interval by interval, kept for callers with a
  plain numpy right-hand side and as the reference the fast one is tested against.
"""
from __future__ import annotations

import threading
from collections import OrderedDict
from dataclasses import dataclass, field
from typing import Callable

import casadi as ca
import numpy as np

from solvers.transcription.multiple_shooting import control_at

DENSE_METHOD = ("RK4, {n} output points and {k} steps per interval, continuous from the initial "
                "state, step-doubling error estimate")
DOP853_METHOD = "scipy DOP853, rtol 1e-10, controls interpolated as in the transcription"


@dataclass
class Verification:
    x_final: np.ndarray                 # re-propagated final state
    final_difference: np.ndarray        # re-propagated minus NLP final node, per state
    max_node_difference: np.ndarray     # worst |difference| over all nodes, per state
    t: np.ndarray                       # dense times
    x: np.ndarray                       # dense states (nx, len(t))
    u: np.ndarray                       # dense controls
    path_max: dict[str, float] = field(default_factory=dict)
    path_argmax_t: dict[str, float] = field(default_factory=dict)
    path_values: dict[str, np.ndarray] = field(default_factory=dict)   # each on the dense times t
    ok: bool = True
    message: str = ""
    method: str = DOP853_METHOD
    samples_per_interval: int = 0
    # Richardson estimate of the dense trajectory's global error, worst over time, per state
    # (None for DOP853, whose tolerance is its own estimate).
    error_estimate: np.ndarray | None = None
    node_x: np.ndarray | None = None    # re-propagated state at every node (nx, m+1)
    # Per limited path quantity: limit, worst dense value and its time, excess, held (within the
    # tolerance); filled by the caller that knows the limits (solvers.reentry.limits.limit_checks).
    limits: dict[str, dict] = field(default_factory=dict)
    # Per fixed terminal component: requested, reached, miss, tolerance, held (filled by the caller
    # that knows the terminal conditions: solvers.reentry.terminal.terminal_checks).
    terminal: dict[str, dict] = field(default_factory=dict)

    def interval_max(self, name: str, intervals: int) -> np.ndarray:
        """Worst value of path quantity ``name`` on each shooting interval, both ends included
        (needs the dense samples to be ``samples_per_interval`` per interval)."""
        n = self.samples_per_interval
        v = np.asarray(self.path_values[name], float)
        v = v.max(axis=0) if v.ndim == 2 else v
        inner = v[:-1].reshape(intervals, n).max(axis=1)
        return np.maximum(inner, v[n::n])     # v[n::n]: each interval's end node


def _report(*, t, X, U, node_x, x_nodes, path, ok, msg, **extra) -> Verification:
    x_nodes = np.asarray(x_nodes, float)
    n = node_x.shape[1]
    x_end = node_x[:, -1]
    report = Verification(x_final=x_end, final_difference=x_end - x_nodes[:, -1],
                          max_node_difference=np.max(np.abs(node_x - x_nodes[:, :n]), axis=1),
                          t=t, x=X, u=U, ok=ok, message=msg, node_x=node_x, **extra)
    for name, fn in (path or {}).items():
        vals = np.asarray(fn(X, U), float).reshape(-1, X.shape[1])
        report.path_values[name] = vals[0] if vals.shape[0] == 1 else vals
        j = int(np.argmax(vals.max(axis=0)))
        report.path_max[name] = float(vals[:, j].max())
        report.path_argmax_t[name] = float(t[j])
    return report


# --- fixed-step RK4 in one CasADi call ------------------------------------------------------------
_CACHE: "OrderedDict[tuple, ca.Function]" = OrderedDict()
_LOCK = threading.Lock()


def _build_dense(dynamics, *, nx: int, nu: int, n_params: int, intervals: int, control: str,
                 samples: int) -> ca.Function:
    """``(x0, ua (nu, m), ub (nu, m), dt, p) -> (fine (nx, m*n), coarse (nx, m*n))``: the states
    at every output point after the first, with 2 and with 1 RK4 step(s) between output points."""
    x = ca.SX.sym("x", nx)
    xc = ca.SX.sym("xc", nx)
    ua, ub = ca.SX.sym("ua", nu), ca.SX.sym("ub", nu)
    f0 = ca.SX.sym("f0")
    dt = ca.SX.sym("dt")
    p = ca.SX.sym("p", n_params)
    df = 1.0 / samples

    def u_of(frac):
        return ua + frac * (ub - ua) if control == "linear" else ua

    def rk4(y, fa, fb):
        h = (fb - fa) * dt
        um = u_of(0.5 * (fa + fb))
        k1 = dynamics(y, u_of(fa), p)
        k2 = dynamics(y + 0.5 * h * k1, um, p)
        k3 = dynamics(y + 0.5 * h * k2, um, p)
        k4 = dynamics(y + h * k3, u_of(fb), p)
        return y + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)

    fine = rk4(rk4(x, f0, f0 + 0.5 * df), f0 + 0.5 * df, f0 + df)
    coarse = rk4(xc, f0, f0 + df)
    z = ca.vertcat(x, xc)
    step = ca.Function("dense_step", [z, f0, ua, ub, dt, p], [ca.vertcat(fine, coarse)])
    inner = step.mapaccum("dense_interval", samples)
    # One interval: the accumulator runs over its output points, each with its own start fraction.
    zi = ca.MX.sym("z", 2 * nx)
    mua, mub = ca.MX.sym("ua", nu), ca.MX.sym("ub", nu)
    mdt, mp = ca.MX.sym("dt"), ca.MX.sym("p", n_params)
    fr = ca.DM(np.arange(samples) * df).T
    zs = inner(zi, fr, ca.repmat(mua, 1, samples), ca.repmat(mub, 1, samples),
               ca.repmat(mdt, 1, samples), ca.repmat(mp, 1, samples))
    interval = ca.Function("dense_one", [zi, mua, mub, mdt, mp], [zs[:, -1], ca.vec(zs)])
    # The intervals chained: mapaccum with only the first output accumulated.
    chain = interval.mapaccum("dense_chain", intervals, 1)
    x0 = ca.MX.sym("x0", nx)
    Ua, Ub = ca.MX.sym("Ua", nu, intervals), ca.MX.sym("Ub", nu, intervals)
    T, P = ca.MX.sym("dt"), ca.MX.sym("p", n_params)
    _, zall = chain(ca.vertcat(x0, x0), Ua, Ub, ca.repmat(T, 1, intervals), ca.repmat(P, 1, intervals))
    zall = ca.reshape(zall, 2 * nx, samples * intervals)
    return ca.Function("dense", [x0, Ua, Ub, T, P], [zall[:nx, :], zall[nx:, :]])


def dense_propagator(dynamics, *, key: tuple, nx: int, nu: int, n_params: int, intervals: int,
                     control: str, samples: int) -> ca.Function:
    """The (cached) CasADi function :func:`propagate_dense` evaluates; ``key`` must identify what
    ``dynamics`` computes (as :class:`~solvers.transcription.multiple_shooting.ShootingProblem`'s)."""
    ck = (key, nx, nu, n_params, intervals, control, samples)
    with _LOCK:
        if ck in _CACHE:
            _CACHE.move_to_end(ck)
            return _CACHE[ck]
    fn = _build_dense(dynamics, nx=nx, nu=nu, n_params=n_params, intervals=intervals,
                      control=control, samples=samples)
    with _LOCK:
        _CACHE[ck] = fn
        while len(_CACHE) > 16:
            _CACHE.popitem(last=False)
    return fn


def propagate_dense(*, dynamics: Callable, p, key: tuple, x0, t_nodes, x_nodes, u_nodes,
                    control: str, path: dict[str, Callable] | None = None,
                    samples_per_interval: int = 20) -> Verification:
    """Re-propagate on equal shooting intervals with fixed-step RK4 (see the module docstring).

    ``dynamics(x, u, p)``: CasADi SX right-hand side in physical units (the transcription's own,
    evaluated with the job's parameter vector ``p``); ``path[name](X, U) -> values`` on (nx, N)
    numpy arrays.  Dense samples at ``t = linspace(0, tf, m * samples_per_interval + 1)``.
    """
    t_nodes = np.asarray(t_nodes, float)
    u_nodes = np.asarray(u_nodes, float)
    x0 = np.asarray(x0, float)
    m, n = len(t_nodes) - 1, int(samples_per_interval)
    nx, nu = x0.size, u_nodes.shape[0]
    p = np.asarray(p, float)
    fn = dense_propagator(dynamics, key=key, nx=nx, nu=nu, n_params=p.size, intervals=m,
                          control=control, samples=n)
    ua = u_nodes[:, :m]
    ub = u_nodes[:, 1:m + 1] if control == "linear" else ua
    dt = (t_nodes[-1] - t_nodes[0]) / m
    fine, coarse = (np.asarray(v) for v in fn(x0, ua, ub, dt, p))
    X = np.hstack([x0[:, None], fine])
    err = np.max(np.abs(fine - coarse), axis=1) / 15.0
    t = np.linspace(t_nodes[0], t_nodes[-1], m * n + 1)
    U = control_at(t, t_nodes, u_nodes, control)
    ok = bool(np.all(np.isfinite(X)))
    msg = "" if ok else "re-propagation produced non-finite states"
    return _report(t=t, X=X, U=U, node_x=X[:, ::n], x_nodes=x_nodes, path=path, ok=ok, msg=msg,
                   method=DENSE_METHOD.format(n=n, k=2 * n), samples_per_interval=n,
                   error_estimate=err)


# --- adaptive reference (scipy) -------------------------------------------------------------------
RhsT = Callable[[float, np.ndarray], np.ndarray]


def _linear_control_rhs(rhs: Callable, *, ta: float, tb: float, ua: np.ndarray, ub: np.ndarray) -> RhsT:
    def f(t, y):
        return rhs(y, ua + (t - ta) / (tb - ta) * (ub - ua))
    return f


def _constant_control_rhs(rhs: Callable, ua: np.ndarray) -> RhsT:
    def f(t, y):
        return rhs(y, ua)
    return f


def repropagate(*, rhs: Callable[[np.ndarray, np.ndarray], np.ndarray], x0, t_nodes, x_nodes,
                u_nodes, control: str, path: dict[str, Callable] | None = None,
                samples_per_interval: int = 10, rtol: float = 1e-10,
                atol: np.ndarray | float = 1e-10) -> Verification:
    """``rhs(x, u) -> xdot`` on (nx,) arrays; ``path[name](x, u) -> values`` on (nx, N) arrays.
    DOP853 restarted at each node so it never steps over a kink of the control."""
    from scipy.integrate import solve_ivp   # 1-2 s to import: only callers of this function pay

    t_nodes = np.asarray(t_nodes, float)
    x = np.asarray(x0, float)
    ts, xs = [], []
    node_x = [x.copy()]
    ok, msg = True, ""
    for i in range(len(t_nodes) - 1):
        ta, tb = t_nodes[i], t_nodes[i + 1]
        # Controls frozen per interval as the transcription defines them (linear or constant).
        ua = control_at(ta, t_nodes, u_nodes, control)[:, 0]
        if control == "linear":
            ub = control_at(tb, t_nodes, u_nodes, control)[:, 0]
            f = _linear_control_rhs(rhs, ta=ta, tb=tb, ua=ua, ub=ub)
        else:
            f = _constant_control_rhs(rhs, ua)
        te = np.linspace(ta, tb, samples_per_interval + 1)
        sol = solve_ivp(f, (ta, tb), x, method="DOP853", rtol=rtol, atol=atol, t_eval=te)
        if not sol.success:
            ok, msg = False, f"re-propagation failed in interval {i}: {sol.message}"
            break
        ts.append(sol.t[:-1] if i < len(t_nodes) - 2 else sol.t)
        xs.append(sol.y[:, :-1] if i < len(t_nodes) - 2 else sol.y)
        x = sol.y[:, -1]
        node_x.append(x.copy())
    t = np.concatenate(ts) if ts else np.array([t_nodes[0]])
    X = np.hstack(xs) if xs else np.asarray(x0, float)[:, None]
    U = control_at(t, t_nodes, u_nodes, control)
    return _report(t=t, X=X, U=U, node_x=np.array(node_x).T, x_nodes=x_nodes, path=path, ok=ok,
                   msg=msg, samples_per_interval=samples_per_interval)
