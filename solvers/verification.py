"""Independent check of an optimal-control answer: re-propagate its controls accurately.

The optimal node controls are interpolated exactly as the transcription defines them
(:func:`solvers.transcription.multiple_shooting.control_at`) and integrated from the initial
state with scipy's DOP853 (rtol 1e-10), interval by interval so the integrator never steps over a
kink of the control.  The report gives the final-state difference to the NLP's final node and
the worst value of each path quantity along the whole dense trajectory, not only at the nodes
(a limit enforced at nodes overshoots between them: Betts, *Practical Methods for Optimal
Control*, 2nd ed., sec. 4.7 on the accuracy of discretized path constraints).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np
from scipy.integrate import solve_ivp

from solvers.transcription.multiple_shooting import control_at


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


def repropagate(*, rhs: Callable[[np.ndarray, np.ndarray], np.ndarray], x0, t_nodes, x_nodes,
                u_nodes, control: str, path: dict[str, Callable] | None = None,
                samples_per_interval: int = 10, rtol: float = 1e-10,
                atol: np.ndarray | float = 1e-10) -> Verification:
    """``rhs(x, u) -> xdot`` on (nx,) arrays; ``path[name](x, u) -> values`` on (nx, N) arrays."""
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
            def f(t, y, ta=ta, tb=tb, ua=ua, ub=ub):
                return rhs(y, ua + (t - ta) / (tb - ta) * (ub - ua))
        else:
            def f(t, y, ua=ua):
                return rhs(y, ua)
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
    node_x = np.array(node_x).T
    n = node_x.shape[1]
    x_nodes = np.asarray(x_nodes, float)
    node_diff = np.max(np.abs(node_x - x_nodes[:, :n]), axis=1)
    report = Verification(x_final=x, final_difference=x - x_nodes[:, -1],
                          max_node_difference=node_diff, t=t, x=X, u=U, ok=ok, message=msg)
    for name, fn in (path or {}).items():
        vals = np.asarray(fn(X, U), float).reshape(-1, X.shape[1])
        report.path_values[name] = vals[0] if vals.shape[0] == 1 else vals
        j = int(np.argmax(vals.max(axis=0)))
        report.path_max[name] = float(vals[:, j].max())
        report.path_argmax_t[name] = float(t[j])
    return report
