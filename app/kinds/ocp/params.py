"""Parameters of the ``ocp`` kind: an optimal-control problem posed as data (``shared/specs/ocp.md``).

The models mirror the spec's request table field by field, so ``/docs`` teaches the format; what
the fields *mean* together (names that resolve, dynamics for every state, expressions in the
language, bounds in order, the limits) is decided once, by :func:`solvers.ocp.spec.parse_problem`
(stdlib only, safe here), through :func:`check_problem`.

Why the whole-problem check hangs on :meth:`OcpParams.model_validate`, not on a model validator: a
submission's ``params`` override a preset (``{"constants": {"g": 1.62}}`` on ``brachistochrone``), so
the problem exists only once they are merged; :func:`app.service.params.resolve_params` validates the
merged set with ``model_validate`` (so do the worker and the studies): a malformed problem is a 422
naming ``params.<path>`` before anything is stored.  Robust design's models: :mod:`app.kinds.ocp.robust.params`.
"""
from __future__ import annotations

from typing import Any, Literal

from pydantic import Field, PrivateAttr, field_validator, model_validator
from pydantic_core import PydanticCustomError, ValidationError

from app.kinds.base import StrictModel
from app.kinds.ocp.service_limits import limits, setting_of
from app.kinds.ocp.robust.params import OcpRobust, OcpUncertainty
from app.kinds.renamed import move_renamed

NAME_PATTERN = r"^[A-Za-z_][A-Za-z0-9_]*$"
MAX_NAME_CHARS = 64
MAX_PLOT_PAIRS = 50

# A bare JSON number is an expression too ("dynamics": {"x": 0}).
Expression = str | float


def _name(example: str):
    return Field(description="Identifier (letters, digits, _; not starting with a digit) used in expressions; "
                             "must not repeat another declared name or shadow a function or t, t0, tf, pi, "
                             "initial, final", examples=[example], pattern=NAME_PATTERN,
                 max_length=MAX_NAME_CHARS)


def _num(description: str, example: Any = None):
    return Field(None, description=description, examples=[example])


class OcpVariable(StrictModel):
    """What a state and a control declare alike: a name, bounds over the whole trajectory, a typical
    magnitude for scaling and a unit."""

    name: str = _name("x")
    lower: float | None = _num("Lower bound over the whole trajectory; null: none", None)
    upper: float | None = _num("Upper bound over the whole trajectory; null: none", None)
    scale: float | None = Field(None, gt=0, description="Typical magnitude (the NLP works in value/scale); "
                                "null: from the bounds (and a state's boundary values)", examples=[10.0])
    unit: str | None = Field(None, max_length=32, description="Unit shown on plots and tables (free text)",
                             examples=["m"])


class OcpState(OcpVariable):
    """A state: its boundary values (a number fixes it, null leaves it free), bounds over the whole
    trajectory, and a typical magnitude for scaling."""

    initial: float | None = _num("Value at t0; null: free", 0.0)
    final: float | None = _num("Value at tf; null: free", 10.0)


class OcpControl(OcpVariable):
    """A control: bounds over the whole trajectory and a typical magnitude."""


class OcpParameter(StrictModel):
    """A static decision variable: a constant the optimizer chooses."""

    name: str = _name("k")
    lower: float | None = _num("Lower bound; null: none", 0.0)
    upper: float | None = _num("Upper bound; null: none", 10.0)
    guess: float | None = _num("Initial guess; null: from the bounds", 1.0)


class OcpTable(StrictModel):
    """Gridded data called in expressions as NAME(x) or NAME(x, y): a smooth B-spline interpolant."""

    axes: list[list[float]] = Field(min_length=1, max_length=2, description="One or two axes, each strictly "
                                    "increasing", examples=[[[0.0, 1.0, 2.0, 3.0]]])
    values: list[float] = Field(description="Values at the grid points, row-major (the last axis fastest); "
                                "len = product of the axes' lengths", examples=[[1.0, 0.5, 0.25, 0.125]])


class OcpTime(StrictModel):
    """The phase's time: fixed or free final time."""

    initial: float = Field(0.0, description="t0 (s)", examples=[0.0])
    final: float | None = Field(None, description="tf (s); null: free within final_lower..final_upper",
                                examples=[None])
    final_lower: float | None = _num("Lower bound of a free tf (s)", 0.1)
    final_upper: float | None = _num("Upper bound of a free tf (s)", 10.0)
    final_guess: float | None = _num("Initial guess of a free tf (s)", 2.0)


class OcpConstraint(StrictModel):
    """lower <= expr <= upper (give one or both; equal bounds make an equality)."""

    expr: Expression = Field(description="An expression of the language", examples=["x - 2*y"])
    lower: float | None = _num("Lower bound; null: none", 0.0)
    upper: float | None = _num("Upper bound; null: none", None)
    name: str | None = Field(None, pattern=NAME_PATTERN, max_length=MAX_NAME_CHARS,
                             description="Name in the verification report; default path_<i> / boundary_<i>",
                             examples=["ground"])


class OcpObjective(StrictModel):
    """Mayer term ``expr`` plus Lagrange ``integrand`` (at least one)."""

    sense: Literal["minimize", "maximize"] = Field("minimize", description="minimize or maximize",
                                                   examples=["minimize"])
    expr: Expression | None = Field(None, description="Mayer term in initial(), final(), t0, tf, parameters "
                                    "and constants", examples=["tf"])
    integrand: Expression | dict[str, Expression] | None = Field(
        None, description="Lagrange integrand, integrated over the phase (states, controls, t, expressions); "
        "with several phases one expression integrated over every phase, or an object phase name -> "
        "expression for those phases only", examples=[None])


class OcpTranscription(StrictModel):
    """How the problem becomes an NLP."""

    method: Literal["multiple_shooting", "lgl"] = Field(
        "multiple_shooting", description="multiple_shooting (RK4 substeps, as paper 000) or lgl "
        "(Legendre-Gauss-Lobatto collocation, as paper 003)", examples=["multiple_shooting"])
    intervals: int = Field(50, ge=1, description="Mesh intervals (capped by TRAJLAB_OCP_MAX_INTERVALS)",
                           examples=[50])
    control: Literal["linear", "constant"] = Field("linear", description="Control within an interval: "
                                                   "linear between nodes or constant", examples=["linear"])
    substeps: int = Field(2, ge=1, le=16, description="multiple_shooting: RK4 steps per interval",
                          examples=[2])
    nodes: int = Field(4, ge=2, le=12, description="lgl: collocation nodes per interval", examples=[4])
    max_refinements: int = Field(8, ge=0, description="Mesh-refinement rounds at most when `accuracy` is set "
                                 "(capped by TRAJLAB_OCP_MAX_REFINEMENTS)", examples=[8])
    boundaries: list[float] | None = Field(None, description="A non-uniform mesh: interval boundaries as fractions "
                                           "of the horizon (0 first, 1 last, increasing), e.g. a refined result's "
                                           "solver.boundaries; it sets the number of intervals; null: `intervals` equal intervals",
                                           examples=[None])
    segment_nodes: list[int] | None = Field(None, description="lgl with boundaries: the nodes of each interval "
                                            "(a refined result's solver.segment_nodes)", examples=[None])


class OcpGuess(StrictModel):
    """The initial guess: straight lines by default, or a stored ocp result."""

    states: dict[str, list[float]] = Field(default_factory=dict, description="state name -> [first, last]: "
                                           "a straight line", examples=[{"x": [0.0, 10.0]}])
    controls: dict[str, list[float]] = Field(default_factory=dict, description="control name -> [first, "
                                             "last]", examples=[{"theta": [0.1, 1.5]}])
    tf: float | None = _num("Guess of a free final time (s)", 2.0)
    from_job: str | None = Field(None, max_length=64, description="Warm start from this succeeded ocp job's "
                                 "trajectory (interpolated onto the new grid)", examples=[None])

    @field_validator("states", "controls")
    @classmethod
    def _pairs(cls, v: dict[str, list[float]]):
        for name, pair in v.items():
            if len(pair) != 2:
                raise ValueError(f"{name}: give [first, last], two numbers")
        return v


class OcpSearch(StrictModel):
    """Several starts: the problem solved from several initial guesses, the best answer kept."""

    starts: int = Field(1, ge=1, description="Initial guesses (capped by TRAJLAB_OCP_MAX_STARTS): the one given and "
                        "starts - 1 varied ones (result: search.rule), fanned out across the workers", examples=[1])
    seed: int = Field(0, ge=0, le=2**31 - 1, description="Seed of the varied starts' random numbers", examples=[0])


class OcpPhaseTime(StrictModel):
    """A phase's time window.  The first phase starts at 0 unless ``initial`` (or its bounds) is given;
    a later phase starts where the one before ends unless a link says otherwise."""

    initial: float | None = _num("t0 of the phase (s); null: free (a later phase: continuous with the one "
                                  "before)", None)
    initial_lower: float | None = _num("Lower bound of a free t0 (s)", None)
    initial_upper: float | None = _num("Upper bound of a free t0 (s)", None)
    initial_guess: float | None = _num("Guess of a free t0 (s)", None)
    final: float | None = _num("tf of the phase (s); null: free within final_lower..final_upper", None)
    final_lower: float | None = _num("Lower bound of a free tf (s)", None)
    final_upper: float | None = _num("Upper bound of a free tf (s)", 1.0)
    final_guess: float | None = _num("Guess of a free tf (s)", None)


class OcpPhaseGuess(StrictModel):
    """A phase's initial guess: straight lines (a warm start is params.initial_guess.from_job, for all phases)."""

    states: dict[str, list[float]] = Field(default_factory=dict, description="state name -> [first, last]")
    controls: dict[str, list[float]] = Field(default_factory=dict, description="control name -> [first, last]")
    tf: float | None = _num("Guess of the phase's free final time (s)", None)


class OcpPhase(StrictModel):
    """One phase of a multi-phase problem: a single-phase block with a name (constants, tables,
    parameters and the objective are the problem's)."""

    name: str = Field(description="Unique phase name, used in the event functions initial(x, \"name\"), "
                      "final(x, \"name\"), t0(\"name\"), tf(\"name\") and in study paths "
                      "(phases.<name>.time.final_upper)", pattern=r"^[A-Za-z_][A-Za-z0-9_-]*$",
                      max_length=MAX_NAME_CHARS, examples=["boost"])
    states: list[OcpState] = Field(default_factory=list, description="The phase's states (a state both "
                                   "consecutive phases declare is continuous unless a link says otherwise)")
    controls: list[OcpControl] = Field(default_factory=list, description="The phase's controls")
    time: OcpPhaseTime = Field(default_factory=OcpPhaseTime, description="The phase's time window")
    expressions: dict[str, Expression] = Field(default_factory=dict, description="name -> expression, in order")
    dynamics: dict[str, Expression] = Field(default_factory=dict, description="state name -> its derivative")
    path: list[OcpConstraint] = Field(default_factory=list, description="Constraints along the phase")
    boundary: list[OcpConstraint] = Field(default_factory=list, description="Event constraints of this phase "
                                          "in initial(x), final(x), t0, tf")
    transcription: OcpTranscription = Field(default_factory=OcpTranscription, description="The phase's grid")
    guess: OcpPhaseGuess = Field(default_factory=OcpPhaseGuess, description="The phase's initial guess")


class OcpLink(OcpConstraint):
    """lower <= expr <= upper over the phases' events: initial(x, "phase"), final(x, "phase"),
    t0("phase"), tf("phase"), parameters, constants.  A link relating final(x, "a") and initial(x, "b")
    of consecutive phases replaces the default continuity of x between them (tf("a") and t0("b"): of
    time)."""

    expr: Expression = Field(description="An expression over the phases' events",
                             examples=['initial(m, "stage2") - final(m, "stage1") + 1200'])
    non_consecutive: bool = Field(False, description="Allow this link to name phases that are not "
                                  "consecutive (a 422 otherwise)")


class OcpParams(StrictModel):
    """Your own optimal-control problem: declarations, expressions, constraints, objective (one phase),
    or ``phases`` with ``links`` (several)."""

    title: str | None = Field(None, max_length=200, description="Free text shown in the console and report",
                              examples=["Brachistochrone"])
    constants: dict[str, float] = Field(default_factory=dict, description="name -> number, usable in every "
                                        "expression", examples=[{"g": 9.80665}])
    tables: dict[str, OcpTable] = Field(default_factory=dict, description="name -> gridded data, called as "
                                        "NAME(x) or NAME(x, y)", examples=[{}])
    states: list[OcpState] = Field(default_factory=list, description="The states, each with exactly one "
                                   "dynamics entry", examples=[[{"name": "x", "initial": 0.0, "final": 10.0}]])
    controls: list[OcpControl] = Field(default_factory=list, description="The controls",
                                       examples=[[{"name": "theta", "lower": 0.0, "upper": 3.14159}]])
    parameters: list[OcpParameter] = Field(default_factory=list, description="Static decision variables",
                                           examples=[[]])
    time: OcpTime = Field(default_factory=OcpTime, description="Initial and final time")
    expressions: dict[str, Expression] = Field(
        default_factory=dict, description="name -> expression, in order: each may use t, states, controls, "
        "parameters, constants, tables and earlier expressions; reported along the trajectory",
        examples=[{"speed": "sqrt(2*g*(10 - y))"}])
    dynamics: dict[str, Expression] = Field(
        default_factory=dict, description="state name -> its time derivative, exactly one per state",
        examples=[{"x": "v*sin(theta)", "y": "-v*cos(theta)", "v": "g*cos(theta)"}])
    path: list[OcpConstraint] = Field(default_factory=list, description="Constraints along the whole "
                                      "trajectory; verified between the nodes", examples=[[]])
    boundary: list[OcpConstraint] = Field(default_factory=list, description="Event constraints in initial(x), "
                                          "final(x), t0, tf and parameters", examples=[[]])
    objective: OcpObjective | None = Field(None, description="What to optimize (required once the preset and "
                                           "your overrides are merged)", examples=[{"sense": "minimize",
                                                                                    "expr": "tf"}])
    transcription: OcpTranscription = Field(default_factory=OcpTranscription, description="Transcription")
    initial_guess: OcpGuess = Field(default_factory=OcpGuess, description="Initial guess or warm start "
                                    "(initial_guess.from_job)")
    # the old name of initial_guess, moved there before validation (app.kinds.renamed)
    guess: OcpGuess | None = Field(None, deprecated="use initial_guess", exclude=True,
                                   description="Deprecated: initial_guess")
    accuracy: float | None = Field(None, gt=0, lt=1, description="Target relative error of the re-propagated "
                                   "states (mesh refinement); null: the grid as given", examples=[None])
    accuracy_required: bool = Field(True, description="With `accuracy`: true fails the job as "
                                    "accuracy_not_reached when the refinement rounds end short of it (the best "
                                    "round stored); false accepts the best round with a note", examples=[True])
    search: OcpSearch = Field(default_factory=OcpSearch, description="Several starts: keep the best of several guesses")
    phases: list[OcpPhase] | None = Field(
        None, max_length=20, description="Several phases instead of the single-phase fields (states, controls, "
        "time, expressions, dynamics, path, boundary, transcription): each a single-phase block with a name; "
        "consecutive phases continuous in time and in every state both declare", examples=[None])
    links: list[OcpLink] = Field(default_factory=list, description="With phases: event constraints between "
                                 "phases (a stage's dropped mass, a time gap); each replaces the default "
                                 "continuity it relates", examples=[[]])
    uncertainty: OcpUncertainty | None = Field(None, description="Uncertain constants and initial states "
                                               "(robust design)", examples=[None])
    robust: OcpRobust | None = Field(None, description="Robust design (with uncertainty)", examples=[None])
    plots: list[list[str]] = Field(default_factory=list, max_length=MAX_PLOT_PAIRS,
                                   description="Extra plots: pairs [x, y] of names (t, states, controls, "
                                   "expressions), drawn besides every quantity against time",
                                   examples=[[["x", "y"]]])

    _problem: Any = PrivateAttr(None)

    @model_validator(mode="before")
    @classmethod
    def _renamed(cls, data):
        return move_renamed(data, ("guess",), ("initial_guess",))

    @classmethod
    def model_validate(cls, obj: Any, **kwargs) -> OcpParams:
        """Field shapes, then the whole problem (:func:`check_problem`): see the module docstring."""
        model = super().model_validate(obj, **kwargs)
        model._problem = check_problem(model)
        return model

    @property
    def problem(self):
        """The parsed :class:`solvers.ocp.spec.OcpProblem` (parsed once by ``model_validate``)."""
        if self._problem is None:
            self._problem = check_problem(self)
        return self._problem


# --- the whole-problem check ----------------------------------------------------------------------
# The parser (solvers.ocp) reads the problem-level guess as "guess"; the API's name is initial_guess.
PARSER_GUESS = "guess"


def _loc(path: str) -> tuple:
    parts = [p for p in path.split(".") if p]
    if parts and parts[0] == "params":
        parts = parts[1:]
    if parts and parts[0] == PARSER_GUESS:
        parts[0] = "initial_guess"
    return tuple(int(p) if p.isdigit() else p for p in parts)


def _get(data: Any, loc: tuple) -> Any:
    if loc and loc[0] == "initial_guess":  # the parser's data: its own key
        loc = (PARSER_GUESS, *loc[1:])
    for part in loc:
        if isinstance(data, dict) and part in data or isinstance(data, list) and isinstance(part, int) and part < len(data):
            data = data[part]
        else:
            return None
    return data


def _fail(loc: tuple, reason: str, data: dict):
    raise ValidationError.from_exception_data("OcpParams", [{
        "type": PydanticCustomError("ocp_problem", "{reason}", {"reason": reason}),
        "loc": loc, "input": _get(data, loc)}])


def check_problem(params: OcpParams, settings=None):
    """Parse the whole problem with the service's limits; a ``ValidationError`` located at the field
    the parser names (``dynamics.v``), its message the reason, and the setting for a limit."""
    from solvers.ocp.spec import OcpInputError, parse_problem

    data = parser_data(params)
    if params.phases is None and params.links:
        _fail(("links",), "links relate phases: give params.phases", data)
    try:
        return parse_problem(data, limits(settings))
    except OcpInputError as exc:
        _fail(_loc(exc.path), setting_of(str(exc.reason)), data)
    except RecursionError:   # defence in depth: the parser bounds its recursion by the node limit
        _fail((), "the problem is nested too deeply", data)


def parser_data(params: OcpParams) -> dict:
    """The params as the parser (:func:`solvers.ocp.parse_problem`) reads them: what a worker parses again."""
    if params.phases is not None:
        return _multiphase_data(params)
    data = {k: v for k, v in params.model_dump(mode="json").items() if k not in ("phases", "links")}
    data[PARSER_GUESS] = data.pop("initial_guess")
    return data


def _multiphase_data(params: OcpParams) -> dict:
    """The params of several phases as the parser reads them: null means not given (so the first
    phase's t0 defaults to 0), and a single-phase field at its model default counts as absent (a
    stored job's params carry every default)."""
    data = params.model_dump(mode="json", exclude_none=True)
    defaults = OcpParams().model_dump(mode="json", exclude_none=True)
    out = {k: v for k, v in data.items() if k in ("phases", "objective") or v != defaults.get(k)}
    guess = {k: v for k, v in (out.pop("initial_guess", None) or {}).items() if v not in ({}, [])}
    if guess:
        out[PARSER_GUESS] = guess
    return out
