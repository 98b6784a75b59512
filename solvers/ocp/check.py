"""One phase of an answer checked on its own, the same way whether it is the whole problem or one of
several: its controls re-flown from its own solved initial state, or interval by interval from its nodes
when its dynamics amplify errors past what that flight can follow (:mod:`solvers.ocp.growth`,
:mod:`solvers.ocp.verify`), its
path limits on the dense grid, its terminal conditions on the re-flight (:mod:`solvers.ocp.terminal`),
the agreement of the re-flown states with the answer, and the phase's block of the report (times,
ends, trajectory at the nodes with the named expressions, verification, transcription).

:class:`PhaseCheck` is what the solve loop (:mod:`solvers.ocp.solver`), the limit rounds
(:mod:`solvers.ocp.limits`) and the mesh refinement (:mod:`solvers.ocp.refine`) read of a phase;
later per-phase checks (costates, the Hamiltonian) belong here too.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from solvers.ocp.growth import INTERVALS, growth
from solvers.ocp.costates import PhaseMultipliers, costates
from solvers.ocp.hamiltonian import HamiltonianFunctions, evaluate, node_rates
from solvers.ocp.hamiltonian import functions as h_functions
from solvers.ocp.hamiltonian import nodal as hamiltonian
from solvers.ocp.optimality import checks as optimality_checks
from solvers.ocp.optimality import path_rates
from solvers.ocp.scaling import Attempt, Numbers
from solvers.ocp.terminal import TERMINAL_TOLERANCE, terminal_checks
from solvers.ocp.verify import Verification, local_errors, verify

# Without ``accuracy``, re-flown states within 1% of their scale count as agreeing with the answer.
AGREEMENT_TOLERANCE = 1e-2


@dataclass
class PhaseCheck:
    """One phase of one answer, checked (module docstring)."""

    name: str
    label: str                      # "" for a problem posed as one phase, else "phase NAME: " (messages)
    attempt: Attempt
    verification: Verification
    terminal: dict
    terminal_held: bool
    agrees: bool
    worst: float                    # the largest scaled state difference of the re-flight
    report: dict                    # {name, t0, tf, initial, final, trajectory, verification, solver}
    errors: dict                    # "path": worst scaled excess per interval; "state": local errors, on demand

    @property
    def ok(self) -> bool:
        return self.verification.ok

    @property
    def limits_held(self) -> bool:
        return self.verification.limits_held


def transcription_words(grid) -> dict:
    """The phase's transcription as the result's ``solver`` block reports it."""
    ms = grid.method == "multiple_shooting"
    return {"method": grid.method, "intervals": grid.intervals, "control": grid.control if ms else "polynomial",
            "substeps": grid.substeps if ms else None,
            "nodes_per_interval": grid.nodes if grid.method == "lgl" and grid.segment_nodes is None else None,
            "boundaries": None if grid.boundaries is None else list(grid.boundaries),
            "segment_nodes": None if grid.segment_nodes is None else list(grid.segment_nodes)}


def check_phase(block, num: Numbers, z: np.ndarray, *, t0: float, agreement: float, single: bool,
                mult: PhaseMultipliers | None = None) -> PhaseCheck:
    """Phase ``block`` (:class:`solvers.ocp.trajectory.Block`) of the answer whose phase columns are ``z``,
    starting at ``t0``: re-flown, held to its limits and terminal conditions, reported; ``mult``: its
    multipliers, for the costates and the optimality checks (:mod:`solvers.ocp.optimality`)."""
    nlp, fns = block.nlp, block.nlp.fns
    prob = block.problem
    prob = replace(prob, phase=replace(prob.phase, time=replace(prob.phase.time, initial=t0)))
    att = Attempt(nlp, num, z)
    ph, grid = prob.phase, nlp.grid
    c = num.p[:fns.nc]
    t_nodes = t0 + (att.tf - t0) * grid.tau()
    U = nlp.node_controls(att.U)
    u_bounds = [(k.lower, k.upper) for k in ph.controls]
    amp = growth(fns=fns, t_nodes=t_nodes, X=att.X, U=U, theta=att.theta, c=c, t0=t0, tf=att.tf, agreement=agreement)
    ver = verify(fns=fns, grid=grid, t_nodes=t_nodes, X=att.X, U=U, theta=att.theta, c=c, t0=t0, tf=att.tf,
                 state_names=ph.state_names, x_scale=num.x_scale,
                 path_bounds=[(k.lower, k.upper) for k in ph.path],
                 path_names=[k.name for k in ph.path], path_scale=num.path_scale,
                 control_names=[k.name for k in ph.controls], control_bounds=u_bounds,
                 restart=amp.mode == INTERVALS)
    terminal = terminal_checks(problem=prob, fns=fns, x_scale=num.x_scale, c=c, theta=att.theta, tf=att.tf,
                               x=ver.x, u=ver.u) if ver.ok else {}
    held = all(v["held"] for v in terminal.values())
    worst = max(ver.max_scaled_difference.values(), default=0.0)
    agrees = bool(ver.ok and worst <= agreement)
    verification = ver.as_dict()
    verification.update(agrees=agrees, agreement_tolerance=agreement, terminal=terminal, terminal_held=held,
                        terminal_tolerance=TERMINAL_TOLERANCE, mode_reason=amp.reason(), growth=amp.as_dict())
    traj = {"t": t_nodes}
    traj.update({s.name: att.X[i] for i, s in enumerate(ph.states)})
    traj.update({k.name: U[i] for i, k in enumerate(ph.controls)})
    if ph.expressions:
        E = np.asarray(fns.named.map(t_nodes.size)(t_nodes[None, :], att.X, U, att.theta, c, t0, att.tf))
        traj.update({n: E[i] for i, (n, _) in enumerate(ph.expressions)})
    extra = {}
    if mult is not None:
        # built and evaluated once for the costates, H and every optimality check of this phase
        hf = h_functions(fns, nlp.sign)
        mu, cb = path_rates(phase=ph, mult=mult, num=num, grid=grid, t_nodes=t_nodes)
        F = node_rates(fns=fns, att=att, U=U, t_nodes=t_nodes, c=c, t0=t0)
        hx = _hx(hf, att=att, U=U, t_nodes=t_nodes, c=c, t0=t0, mu=mu, cb=cb) if grid.method == "lgl" else None
        lam, mapped = costates(nlp=nlp, num=num, att=att, mu=mult.defects, t_nodes=t_nodes, c=c, t0=t0, hx=hx)
        H, size = hamiltonian(fns=fns, sign=nlp.sign, lam=lam, F=F)
        verification["optimality"] = optimality_checks(problem=prob, nlp=nlp, hf=hf, att=att, lam=lam, U=U,
                                                       t_nodes=t_nodes, c=c, t0=t0, F=F, H=H, size=size, num=num,
                                                       tolerance=max(agreement, AGREEMENT_TOLERANCE),
                                                       mult=mult, path=(mu, cb), mapped=mapped,
                                                       dense=(ver.t, ver.x, ver.u) if ver.ok else None)
        extra = {"costates": {s.name: lam[i] for i, s in enumerate(ph.states)}, "hamiltonian": H}
    report = {"name": block.name, "t0": t0, "tf": att.tf, **extra,
              "initial": {s.name: float(att.X[i, 0]) for i, s in enumerate(ph.states)},
              "final": {s.name: float(att.X[i, -1]) for i, s in enumerate(ph.states)},
              "trajectory": traj, "verification": verification, "solver": transcription_words(grid)}

    def state_errors():           # a second re-flight, each interval from its own first node
        return local_errors(fns=fns, grid=grid, t_nodes=t_nodes, X=att.X, U=U, theta=att.theta, c=c, t0=t0,
                            tf=att.tf, x_scale=num.x_scale)

    # flown interval by interval, the verification has them already
    local = ver.interval_error if ver.interval_error is not None else state_errors
    errors = {"path": np.max(ver.interval_excess, axis=0) if ver.interval_excess else None, "state": local}
    return PhaseCheck(name=block.name, label="" if single else f"phase {block.name}: ", attempt=att,
                      verification=ver, terminal=terminal, terminal_held=held, agrees=agrees, worst=worst,
                      report=report, errors=errors)


def _hx(hf: HamiltonianFunctions, *, att, U, t_nodes, c, t0, mu, cb):
    """``dH/dx`` at node ``j`` for costate ``lam``, the node's path multipliers ``mu`` (on the bounds ``cb``)
    included: LGL's end corrections."""

    def hx(j: int, lam: np.ndarray) -> np.ndarray:
        return evaluate(hf.dH_dx, t=t_nodes[j:j + 1], X=att.X[:, j:j + 1], U=U[:, j:j + 1], att=att, c=c, t0=t0,
                        lam=lam[:, None], mu=mu[:, j:j + 1], cb=cb[:, j:j + 1])[:, 0]
    return hx
