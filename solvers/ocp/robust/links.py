"""Which links between phases carry the covariance of a robust ``ocp`` design, and the map they carry it by
(``shared/specs/ocp.md``, "Robust design"; issue 37).

A link that *sets* a state of the next phase's start from the previous phase's end carries the covariance:
an equality ``h(initial(y, "b"), final(x1, "a"), final(x2, "a"), ..., constants, parameters, times,
controls) = c`` between consecutive phases ``a``, ``b``, naming exactly one state ``y`` of ``b``'s start.
An identity between different states (``initial(X, "b") - final(x, "a")``), an affine map
(``initial(V, "b") - 2*final(v, "a")``, a stage's structure dropped: ``initial(m, "b") - final(m, "a") +
dry``) and any expression map are of this form.  Every draw's ``y`` then solves ``h = c``: to first order
(the implicit function theorem, CasADi's exact Jacobians of the same expression)

    S_b(t0)[y] = -(h_xf S_a(tf) + [0, h_s]) / h_y,    so    P_b(t0)[y, y] = J P J^T,  J = -[h_xf, h_s] / h_y,

with ``S = dx/dw`` the sensitivities to the draw ``w = [whitened initial sigmas; uncertain constants]``
(:mod:`solvers.ocp.robust.phases`).  The Monte Carlo solves ``h = c`` per draw (Newton from the design's
``y``; one step is exact for an affine map).

A link of states of another form cannot say what a draw's start is, and is refused (a 422 naming the
link): an inequality (it bounds the plan, no draw's state follows from it), one naming two or more states
of ``b``'s start (one equation cannot set two of them), the end of the later phase or the start of the
earlier one, or phases that are not consecutive, and a link setting a state that another link or the
default continuity already sets.  Links of times and controls alone hold for the plan (the means), as
before.  Classification: standard library only (the API validates with it); the map imports CasADi when
called.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from solvers.ocp.expressions import Boundary, OcpInputError, walk


@dataclass(frozen=True)
class CarriedLink:
    """A link that sets ``target`` at the start of phase ``after`` from the end of phase ``after - 1``."""

    index: int               # in ``problem.links``
    after: int               # the later phase's index
    target: str              # the state of the later phase it sets
    value: float             # h = value


def carried_links(problem) -> tuple[CarriedLink, ...]:
    """The links of ``problem`` (an :class:`solvers.ocp.problem.OcpProblem`) that carry the covariance;
    a link of states of any other form is an :class:`OcpInputError` naming it (module docstring)."""
    names = problem.phase_names
    out: list[CarriedLink] = []
    for j, lk in enumerate(problem.links):
        states = [n for n in walk(lk.expr) if isinstance(n, Boundary) and n.kind == "state"]
        if not states:
            continue                 # times and controls: the plan's, held for the means
        where, label = f"params.links.{j}", f"link '{lk.name}' ({lk.text})"
        idx = sorted({names.index(n.phase) for n in states})
        if len(idx) != 2 or idx[1] != idx[0] + 1:
            raise OcpInputError(where, f"{label} cannot carry the covariance: a robust link of states relates the "
                                       "end of one phase to the start of the next (its states, no others)")
        a, b = names[idx[0]], names[idx[1]]
        wrong = [n for n in states if (n.phase, n.which) in ((a, "initial"), (b, "final"))]
        if wrong:
            n = wrong[0]
            raise OcpInputError(where, f"{label} cannot carry the covariance: it names {n.which}({n.name}, "
                                       f"\"{n.phase}\"); a robust link sets the start of '{b}' from the end of '{a}'")
        targets = sorted({n.name for n in states if n.phase == b})
        if len(targets) != 1:
            raise OcpInputError(where, f"{label} cannot carry the covariance: it names {len(targets)} states of "
                                       f"'{b}''s start ({', '.join(targets)}); one equation sets one state, write "
                                       "one link per state")
        if lk.lower is None or lk.upper is None or lk.lower != lk.upper:
            raise OcpInputError(where, f"{label} cannot carry the covariance: an inequality between states bounds "
                                       "the plan but sets no draw's start; give lower = upper")
        y = targets[0]
        if (idx[0], y) in problem.state_links or any(c.after == idx[1] and c.target == y for c in out):
            raise OcpInputError(where, f"{label} sets initial({y}, \"{b}\"), which "
                                + ("the default continuity" if (idx[0], y) in problem.state_links else
                                   "another link") + " already sets")
        out.append(CarriedLink(index=j, after=idx[1], target=y, value=float(lk.lower)))
    return tuple(out)


def link_map(problem, link: CarriedLink):
    """``h, h_y, h_xf, h_s`` of ``link`` (CasADi, exact) as a function of ``(y, xf, u_ends, times, theta, c,
    s)``: ``y`` the target's value, ``xf`` the earlier phase's final states, ``u_ends`` both phases' end
    controls ``[u0_a; uf_a; u0_b; uf_b]``, ``times`` ``[t0_a, tf_a, t0_b, tf_b]``, ``c`` every constant
    (the uncertain ones' entries replaced by ``s``)."""
    import casadi as ca

    from solvers.ocp.symbolic import to_sx

    lk = problem.links[link.index]
    A, B = problem.phases[link.after - 1], problem.phases[link.after]
    pa, pb = A.problem.phase, B.problem.phase
    rob = problem.robust
    cnames = [n for n, _ in problem.constants]
    s_index = [cnames.index(p.name) for p in rob.parameters] if rob is not None else []
    y, xf = ca.SX.sym("y"), ca.SX.sym("xf", len(pa.state_names))
    nua, nub = len(pa.control_names), len(pb.control_names)
    ue, times = ca.SX.sym("u", 2 * (nua + nub)), ca.SX.sym("t", 4)
    theta, c, s = ca.SX.sym("theta", len(problem.parameters)), ca.SX.sym("c", len(cnames)), ca.SX.sym("s", len(s_index))
    c_parts = [c[i] for i in range(len(cnames))]
    for k, i in enumerate(s_index):
        c_parts[i] = s[k]
    env = {n: c_parts[i] for i, n in enumerate(cnames)}
    env.update({q.name: theta[i] for i, q in enumerate(problem.parameters)})
    ev = {("t0", A.name): times[0], ("tf", A.name): times[1], ("t0", B.name): times[2], ("tf", B.name): times[3],
          ("initial", link.target, B.name): y}
    for j, x in enumerate(pa.state_names):
        ev[("final", x, A.name)] = xf[j]
    for j, u in enumerate(pa.control_names):
        ev[("initial", u, A.name)], ev[("final", u, A.name)] = ue[j], ue[nua + j]
    for j, u in enumerate(pb.control_names):
        ev[("initial", u, B.name)], ev[("final", u, B.name)] = ue[2 * nua + j], ue[2 * nua + nub + j]
    h = to_sx(lk.expr, env, {t.name: t for t in problem.tables}, ev) - link.value
    return ca.Function(f"link_{link.index}", [y, xf, ue, times, theta, c, s],
                       [h, ca.jacobian(h, y), ca.jacobian(h, xf), ca.jacobian(h, s)],
                       ["y", "xf", "u", "times", "theta", "c", "s"], ["h", "h_y", "h_xf", "h_s"])


def _ends(problem, link: CarriedLink, prev: dict, this: dict) -> tuple:
    """The numeric ``(y, xf, u_ends, times)`` of ``link`` from two phases' answers (``trajectory``, ``t0``,
    ``tf``, as :class:`solvers.ocp.solution.OcpSolution` keeps them)."""
    import numpy as np

    pa, pb = problem.phases[link.after - 1].problem.phase, problem.phases[link.after].problem.phase
    ta, tb = prev["trajectory"], this["trajectory"]
    u = [ta[n][0] for n in pa.control_names] + [ta[n][-1] for n in pa.control_names] + \
        [tb[n][0] for n in pb.control_names] + [tb[n][-1] for n in pb.control_names]
    return (float(tb[link.target][0]), np.array([ta[x][-1] for x in pa.state_names], float), np.array(u, float),
            np.array([prev["t0"], prev["tf"], this["t0"], this["tf"]], float))


def carried_start(problem, index: int, *, S_prev, prev: dict | None, this: dict, theta, c, s, r0: int) -> dict[int, Any]:
    """Row of each state that a link sets at phase ``index``'s start -> its sensitivities there (the guess of
    :class:`solvers.ocp.robust.nlp.RobustNLP`): ``-(h_xf S_prev + [0, h_s]) / h_y`` at the answers ``prev``
    and ``this`` of the two phases; ``S_prev`` the previous phase's final sensitivities."""
    import numpy as np

    names = problem.phases[index].problem.phase.state_names
    nxa = len(problem.phases[index - 1].problem.phase.state_names)
    out: dict[int, Any] = {}
    for cl in carried_links(problem):
        if cl.after == index and prev is not None:
            y, xf, u, times = _ends(problem, cl, prev, this)
            _, h_y, h_xf, h_s = (np.asarray(v, float) for v in link_map(problem, cl)(y, xf, u, times, theta, c, s))
            row = h_xf @ S_prev[:nxa] + np.concatenate([np.zeros((1, r0)), h_s], axis=1)
            out[names.index(cl.target)] = -row.ravel() / h_y.item()
    return out


LINK_NEWTON_STEPS = 30   # Newton steps per draw (an affine map needs one)


def solve_link(problem, link: CarriedLink, *, y0: float, xf, u, times, theta, s):
    """Each draw's target of ``h(y, xf, s) = 0`` (the Monte Carlo's start of the later phase): Newton from the
    design's ``y0`` to round-off, vectorised over the draws (columns of ``xf`` and ``s``); a draw whose
    iteration does not settle is NaN (a failed draw)."""
    import numpy as np

    n = xf.shape[1]
    fn = link_map(problem, link).map(n, "serial")
    c = np.array([v for _, v in problem.constants], float)
    fixed = [np.broadcast_to(np.asarray(v, float).reshape(-1, 1), (np.size(v), n)) for v in (u, times, theta, c)]
    sv = s if s.shape[0] else np.zeros((0, n))
    y = np.full(n, float(y0))
    step = np.full(n, np.inf)
    for _ in range(LINK_NEWTON_STEPS):
        h, h_y, _, _ = fn(y[None, :], xf, *fixed, sv)
        step = np.asarray(h, float).ravel() / np.asarray(h_y, float).ravel()
        y = y - step
        if np.all(np.abs(step) <= 1e-13 * (1.0 + np.abs(y))):
            return y
    return np.where(np.abs(step) <= 1e-9 * (1.0 + np.abs(y)), y, np.nan)
