"""The ``ocp`` problem as typed, frozen dataclasses: what :func:`solvers.ocp.spec.parse_problem` returns.

One model for one phase and several (as dymos' ``Trajectory`` of ``Phase`` objects): an
:class:`OcpProblem` is a sequence of named phases (:class:`NamedPhase`), their links, the shared
constants, tables and parameters and the objective; a problem posed with the single-phase fields
is the one-phase case (``single``: its phase has no name, its time starts where the problem says
and its objective's Mayer term is the phase's own).  Each phase is seen by the transcription as a
:class:`PhaseProblem`: the :class:`Phase` with the problem's constants, tables, parameters and the
phase's share of the objective.  Standard library only.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

from solvers.ocp.expressions import Expr, to_text
from solvers.ocp.robust.model import RobustSpec

PHASE_FIELDS = ("states", "controls", "time", "expressions", "dynamics", "path", "boundary", "transcription",
                "guess", "state_names", "control_names")


@dataclass(frozen=True)
class VariableDecl:
    """What states and controls declare alike: bounds over the whole phase, a typical magnitude
    (``scale``; by default the largest finite bound or boundary value) and a unit for display."""

    name: str
    lower: float | None = None
    upper: float | None = None
    scale: float | None = None
    unit: str | None = None


@dataclass(frozen=True)
class ControlDecl(VariableDecl):
    pass


@dataclass(frozen=True)
class StateDecl(VariableDecl):
    initial: float | None = None      # a number fixes the value at t0, None leaves it free
    final: float | None = None


@dataclass(frozen=True)
class ParameterDecl:
    name: str
    lower: float | None = None
    upper: float | None = None
    guess: float | None = None


@dataclass(frozen=True)
class TableDecl:
    """Gridded data on 1 or 2 strictly increasing axes, ``values`` row-major (first axis slowest)."""

    name: str
    axes: tuple[tuple[float, ...], ...]
    values: tuple[float, ...]


@dataclass(frozen=True)
class Constraint:
    expr: Expr
    text: str
    lower: float | None = None
    upper: float | None = None
    name: str = ""


@dataclass(frozen=True)
class Objective:
    sense: str                         # "minimize" | "maximize"
    expr: Expr | None = None           # Mayer term
    integrand: Expr | None = None      # Lagrange term
    expr_text: str = ""
    integrand_text: str = ""


@dataclass(frozen=True)
class TimeSpec:
    initial: float = 0.0
    final: float | None = None         # None: free final time
    final_lower: float | None = None
    final_upper: float | None = None
    final_guess: float | None = None


@dataclass(frozen=True)
class Transcription:
    method: str = "multiple_shooting"
    intervals: int = 50
    control: str = "linear"            # multiple shooting: "linear" | "constant"
    substeps: int = 2                  # multiple shooting: RK4 steps per interval
    nodes: int = 4                     # lgl: nodes per segment (polynomial degree nodes - 1)
    max_refinements: int = 8           # mesh-refinement rounds at most when ``accuracy`` is set
    # A refined mesh (solvers.ocp.refine): interval boundaries in normalized time [0, 1] and, for
    # LGL, the nodes of each interval; None: ``intervals`` equal intervals of ``nodes`` nodes.
    boundaries: tuple[float, ...] | None = None
    segment_nodes: tuple[int, ...] | None = None


@dataclass(frozen=True)
class Guess:
    states: dict = field(default_factory=dict)      # name -> (first, last)
    controls: dict = field(default_factory=dict)
    tf: float | None = None
    from_job: str | None = None


@dataclass(frozen=True)
class Phase:
    """One phase: what a multi-phase problem will repeat."""

    states: tuple[StateDecl, ...]
    controls: tuple[ControlDecl, ...]
    time: TimeSpec
    expressions: tuple[tuple[str, Expr], ...]
    dynamics: tuple[Expr, ...]         # in the order of ``states``
    path: tuple[Constraint, ...]
    boundary: tuple[Constraint, ...]
    transcription: Transcription
    guess: Guess

    @property
    def state_names(self) -> tuple[str, ...]:
        return tuple(s.name for s in self.states)

    @property
    def control_names(self) -> tuple[str, ...]:
        return tuple(c.name for c in self.controls)


@dataclass(frozen=True)
class PhaseProblem:
    """One phase as the transcription sees it (:mod:`solvers.ocp.phase`, :mod:`solvers.ocp.symbolic`):
    the phase, the problem's constants, tables and parameters, and the phase's share of the objective
    (its integrand; the Mayer term too when the phase is the whole problem)."""

    title: str
    constants: tuple[tuple[str, float], ...]
    tables: tuple[TableDecl, ...]
    parameters: tuple[ParameterDecl, ...]
    phase: Phase
    objective: Objective
    accuracy: float | None = None
    accuracy_required: bool = True     # False: a refinement that misses ``accuracy`` ends with a note
    plots: tuple[tuple[str, str], ...] = ()

    def __getattr__(self, name: str):
        # The single phase's fields read as the spec names them (problem.states, problem.dynamics).
        if name in PHASE_FIELDS:
            return getattr(self.phase, name)
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")

    def structure(self) -> tuple:
        """What the NLP's symbolic graph depends on (the solver cache key): names, trees, tables,
        which bounds exist, the objective's form and the grid.  Constants, bounds, fixed boundary
        values and t0 are not in it: they reach the NLP as parameters or bounds."""
        ph = self.phase
        return (
            tuple(n for n, _ in self.constants),
            tuple((tb.name, tb.axes, tb.values) for tb in self.tables),
            tuple(p.name for p in self.parameters),
            ph.state_names, ph.control_names,
            tuple((n, to_text(e)) for n, e in ph.expressions),
            tuple(to_text(e) for e in ph.dynamics),
            tuple(to_text(c.expr) for c in ph.path),
            tuple(to_text(c.expr) for c in ph.boundary),
            self.objective.sense,
            None if self.objective.expr is None else to_text(self.objective.expr),
            None if self.objective.integrand is None else to_text(self.objective.integrand),
            ph.time.final is None,
            replace(ph.transcription, max_refinements=0),   # the rounds do not shape the NLP
        )


@dataclass(frozen=True)
class PhaseTime:
    """A phase's time window: fixed or free ends with bounds; None where not given."""

    initial: float | None = None
    initial_lower: float | None = None
    initial_upper: float | None = None
    initial_guess: float | None = None
    final: float | None = None
    final_lower: float | None = None
    final_upper: float | None = None
    final_guess: float | None = None


@dataclass(frozen=True)
class NamedPhase:
    """One phase of the problem: its name ("" for a problem posed as one phase), its time window and
    the phase as the transcription sees it (``problem.phase.time.initial`` and ``final_guess`` hold
    the guesses of its t0 and tf)."""

    name: str
    time: PhaseTime
    problem: PhaseProblem


@dataclass(frozen=True)
class Link(Constraint):
    phases: tuple[str, ...] = ()          # the phases it names, in the problem's order
    non_consecutive: bool = False


@dataclass(frozen=True)
class OcpProblem:
    """The problem: phases in time order, linked, solved as one NLP (module docstring)."""

    title: str
    constants: tuple[tuple[str, float], ...]
    tables: tuple[TableDecl, ...]
    parameters: tuple[ParameterDecl, ...]
    phases: tuple[NamedPhase, ...]
    objective: Objective                  # several phases: the Mayer term over events (integrands in the phases)
    links: tuple[Link, ...] = ()
    time_links: tuple[int, ...] = ()      # k: t0(k+1) = tf(k) (default); else t0(k+1) >= tf(k)
    state_links: tuple[tuple[int, str], ...] = ()   # (k, x): initial(x, k+1) = final(x, k)
    from_job: str | None = None
    plots: tuple[tuple[str, str], ...] = ()
    accuracy: float | None = None         # mesh refinement of every phase (solvers.ocp.refine)
    accuracy_required: bool = True        # False: a refinement that misses ``accuracy`` ends with a note
    single: bool = False                  # posed with the single-phase fields (no ``phases``)
    starts: int = 1                       # search.starts: initial guesses (solvers.ocp.starts)
    seed: int = 0                         # search.seed: the varied starts' random numbers
    robust: RobustSpec | None = None      # uncertainty and robust design (solvers.ocp.robust)

    @property
    def phase_names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.phases)

    def named(self, name: str) -> NamedPhase:
        return self.phases[self.phase_names.index(name)]

    def on_phases(self, problems) -> OcpProblem:
        """The same problem with each phase's :class:`PhaseProblem` replaced (a refined grid)."""
        return replace(self, phases=tuple(replace(ph, problem=p) for ph, p in zip(self.phases, problems)))

    def __getattr__(self, name: str):
        # A problem posed as one phase reads its phase's fields as the spec names them (problem.states).
        if name in PHASE_FIELDS and self.single:
            return getattr(self.phases[0].problem.phase, name)
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")

    def structure(self) -> tuple:
        """What the NLP's graph depends on (the solver cache key)."""
        if self.single:
            return self.phases[0].problem.structure()
        return (tuple(p.problem.structure() for p in self.phases),
                None if self.objective.expr is None else to_text(self.objective.expr),
                tuple(to_text(lk.expr) for lk in self.links), self.time_links, self.state_links)
