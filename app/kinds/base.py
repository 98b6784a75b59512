"""The contract between the job service and one job kind.

A kind package (``app/kinds/<kind>/``) is the API edge of one solver: it
declares the pydantic parameter model (SI units, angles in degrees, every field
defaulted and documented), the named presets, and ``run(params, ctx)``, which
converts parameters to the solver's SI/radian dataclass, calls the solver with
the context's progress and stop callbacks, and turns the solution into the
JSON result of ``shared/specs/api.md``; its :class:`KindSpec` says everything
else the service asks of the kind (cost, memory, tables, OEM, ...).  Nothing
here knows about HTTP, Celery or SQL: the worker supplies a :class:`JobContext`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Callable, Literal, Protocol

from pydantic import BaseModel, ConfigDict


class StrictModel(BaseModel):
    """Base for parameter models: unknown fields are a 422, NaN/inf are rejected."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, validate_default=True)


class JobContext(Protocol):
    """What a running job may ask of the service."""

    job_id: str

    def progress(self, fraction: float, message: str) -> None:
        """Report progress in [0, 1] (kept monotone by the service) and a short message."""

    def should_stop(self) -> bool:
        """True once the job was cancelled; poll it from the solver's iteration callback."""

    def load_result(self, job_id: str) -> dict:
        """The stored result of another succeeded job (for warm starts).

        Raises ``LookupError`` with a user-facing message if the job does not
        exist or has not succeeded.
        """

    def run_monte_carlo(self, spec: dict, samples: int, seed: int, chunk_size: int | None = None) -> dict:
        """The summary of :func:`solvers.uncertainty.montecarlo.run_monte_carlo` for ``spec``.

        The service decides where it runs: in this process, or split into chunks
        across the workers (the heavy queue) when ``samples`` is large.  The answer
        is the same either way for the same seed and chunk size.  Raises
        :class:`JobCancelled` when the job is cancelled while the chunks run.
        """


    def run_pieces(self, fn: Callable[[dict, int, Callable[[], bool]], dict], spec: dict, count: int, *,
                   label: str, on_progress: Callable[[float, str], None] | None = None) -> list[dict]:
        """``[fn(spec, i, should_stop) for i in range(count)]`` (``fn`` declared with :func:`piece`; its output
        JSON), in index order; a piece that raised is ``{"raised": "<type>: <message>"}``, so one piece's
        failure is the kind's to judge.  The service decides where they run: here, or fanned out across
        the workers as a study's points are (``worker/pieces.py``); progress says ``"<label> i/count done"``
        to ``on_progress`` (a stage's callback, :mod:`solvers.progress`; default the job's own).
        Raises :class:`JobCancelled` when the job is cancelled meanwhile."""


# The functions a job may fan out (JobContext.run_pieces), by name: a worker finds one here, never by a
# name it was sent alone (the kind's module declares it when the registry imports it).
PIECES: dict[str, Callable[[dict, int, Callable[[], bool]], dict]] = {}


def piece_name(fn: Callable) -> str:
    return f"{fn.__module__}:{fn.__qualname__}"


def piece(fn: Callable[[dict, int, Callable[[], bool]], dict]) -> Callable[[dict, int, Callable[[], bool]], dict]:
    """Declare ``fn(spec, index, should_stop) -> dict`` a piece of work a job may fan out (module level)."""
    PIECES[piece_name(fn)] = fn
    return fn


def run_piece(fn: Callable[[dict, int, Callable[[], bool]], dict], spec: dict, index: int,
              should_stop: Callable[[], bool]) -> dict:
    """One piece, its exception kept as its output (JobContext.run_pieces)."""
    try:
        return fn(spec, index, should_stop)
    except JobCancelled:
        raise
    except Exception as exc:  # one piece's failure is the kind's to judge, not the job's end
        return {"raised": f"{type(exc).__name__}: {str(exc)[:500]}"}


def run_pieces_here(fn, spec: dict, count: int, *, label: str, should_stop: Callable[[], bool],
                    progress: Callable[[float, str], None]) -> list[dict]:
    """The pieces one after the other in this process (JobContext.run_pieces without a service)."""
    out = []
    for i in range(count):
        if should_stop():
            raise JobCancelled(f"cancelled before {label} {i + 1}/{count}")
        out.append(run_piece(fn, spec, i, should_stop))
        progress((i + 1) / count, f"{label} {i + 1}/{count} done")
    return out


class InProcessContext:
    """A :class:`JobContext` without a service: a job run in this process (benchmarks, notebooks, tests).

    Progress is recorded in ``messages``; ``stored`` holds results that warm starts may load;
    ``should_stop`` turns True from the ``stop_after``-th poll on (None: never); the Monte Carlo
    runs here, as a worker runs it below its fan-out threshold.
    """

    def __init__(self, stored: dict | None = None, stop_after: int | None = None, *, job_id: str = "local"):
        self.job_id = job_id
        self.messages: list[tuple[float, str]] = []
        self.stored = stored or {}
        self.stop_after = stop_after
        self.polls = 0

    def progress(self, fraction: float, message: str) -> None:
        self.messages.append((fraction, message))

    def should_stop(self) -> bool:
        self.polls += 1
        return self.stop_after is not None and self.polls >= self.stop_after

    def load_result(self, job_id: str) -> dict:
        if job_id not in self.stored:
            raise LookupError(f"job {job_id} not found or not succeeded")
        return self.stored[job_id]

    def run_monte_carlo(self, spec: dict, samples: int, seed: int, chunk_size: int | None = None) -> dict:
        from solvers.uncertainty.montecarlo import run_monte_carlo

        return run_monte_carlo(spec, samples, seed, chunk_size)

    def run_pieces(self, fn, spec: dict, count: int, *, label: str, on_progress=None) -> list[dict]:
        return run_pieces_here(fn, spec, count, label=label, should_stop=self.should_stop,
                               progress=on_progress or self.progress)


class JobFailure(Exception):
    """Raised by ``run`` for an expected, user-facing failure (bad warm-start id,
    data that validates but cannot be solved).  ``code`` is one of the API's
    error codes; ``details`` is stored as the diagnostic."""

    def __init__(self, code: str, message: str, details: dict | None = None):
        super().__init__(message)
        self.code = code
        self.message = message
        self.details = details or {}


class JobCancelled(Exception):
    """Raised from deep inside a run (e.g. a fanned-out Monte Carlo) when the job was cancelled."""


@dataclass
class RunOutcome:
    """What ``run`` returns.

    ``status`` ``succeeded`` needs ``result``; ``failed`` needs ``error``
    (``{"code", "message"}`` plus optional ``details``) and may still carry a
    ``result`` as the stored diagnostic (e.g. the last iterate);
    ``cancelled`` may carry a partial ``result`` (e.g. the best Pareto front so far).
    """

    status: Literal["succeeded", "failed", "cancelled"]
    result: dict | None = None
    error: dict | None = None


@dataclass
class Preset:
    name: str
    kind: str
    description: str
    params: dict[str, Any]   # partial parameters in API units, deep-merged onto the defaults


@dataclass(frozen=True)
class MemoryModel:
    """A job's peak resident memory from its resolved params, as measured for the kind
    (:mod:`app.service.job_memory` refuses a job past ``TRAJLAB_JOB_MEMORY_MB`` with a 422 by it).

    ``floor_mb`` is the resident memory of the kind's preset in a fresh pool process (libraries, the
    solver's fixed structures); a kind whose memory grows with its size adds ``per_unit_mb`` per unit of
    ``size(params)`` past ``floor_size`` (the preset's size), and ``grows_with`` names that size in the 422.
    """

    floor_mb: float
    size: Callable[[dict], float] | None = None
    floor_size: float = 0.0
    per_unit_mb: float = 0.0
    grows_with: str = ""


@dataclass(frozen=True)
class CompareSeries:
    """The one curve that best shows a job of a kind on the console's compare plot."""

    x: list
    y: list
    x_label: str
    y_label: str
    style: str = "-"


@dataclass(frozen=True)
class OemExport:
    """A kind's trajectory as a CCSDS OEM (``GET /v1/jobs/{id}/result.oem``; the writer is
    :func:`app.results.oem.write_oem`).

    ``available(result)``: whether the result has a trajectory to write (else a 404).
    ``prepare(result, params, *, object_name, point, trajectory) -> (view, make)``: ``view`` names the
    file among the job's (ETag, cache key and file name; ``()`` for a kind with one file), ``make()``
    writes its text; raises ``LookupError`` with a user-facing message for a choice the result does not
    have (a 404).  ``point`` and ``trajectory`` are the route's query parameters; a kind with one
    trajectory ignores them.
    """

    available: Callable[[dict], bool]
    prepare: Callable[..., tuple[tuple[str, ...], Callable[[], str]]]


@dataclass(kw_only=True)
class KindSpec:
    """Everything the service needs to know about one kind: adding a kind is its
    package (``app/kinds/<kind>/``, with ``solvers/<kind>/``) plus a line in the registry
    (``app/kinds/__init__.py``).  The shared code asks these fields and never lists kinds by name
    (``tests/unit/test_kind_names.py``); ``docs/architecture.md`` "How to add a kind" walks through them.

    ``cost`` and ``memory`` have no default: a kind that forgot them would be free under the quota and
    never refused for memory, so a new kind states both.
    """

    kind: str
    params_model: type[StrictModel]
    run: Callable[[Any, JobContext], RunOutcome]
    # Estimated cost in app.service.quota's work units from the resolved params (about one RK4 step of one
    # shooting interval of the reentry NLP per unit): the per-owner budget and the heavy-queue choice.
    cost: Callable[[dict], float]
    # The job's memory from its resolved params (app.service.job_memory: a 422 past TRAJLAB_JOB_MEMORY_MB).
    memory: MemoryModel
    presets: list[Preset] = field(default_factory=list)
    summary: str = ""
    # Every job of the kind on the heavy queue, whatever its cost (otherwise: cost past TRAJLAB_HEAVY_COST).
    always_heavy: bool = False
    # Soft Celery time limit; TRAJLAB_TIME_LIMIT_<KIND>_S overrides it (Settings.time_limit_s).
    time_limit_s: float = 600.0
    # The few numbers the CLI, the console and trade tables show (app.service.summary); None: a generic pick.
    key_numbers: Callable[[dict], dict] | None = None
    # A key number whose better direction never depends on the params, (dotted key, "min" | "max"): a study
    # keeps each point's best job by it and retries a point from a neighbour that did better; None: none.
    fixed_objective: tuple[str, str] | None = None
    # Typed model of the stored result, for documentation and validation; None: untyped JSON.  Its place in
    # the OpenAPI union is derived (app.api.result_body: a model that extends another's is tried first).
    result_model: type[BaseModel] | None = None
    # The plots of one result (app.results.plots.PlotDef list; app/kinds/<kind>/plots.py); None: no plots.
    plots: Callable[[dict], list] | None = None
    # The CSV tables of one result, name -> (result -> columns or None) (app.results.tables has the pickers
    # every kind uses: columns_at("trajectory")); GET .../result.csv?table=name serves them.
    tables: dict[str, Callable[[dict], dict | None]] = field(default_factory=dict)
    # The default GET .../result body, (result, include) -> body with its bulkiest arrays thinned unless
    # ``include`` asks for them (app.results.compact); None: the stored result as is.
    compact: Callable[[dict, set[str]], dict] | None = None
    # The trajectory as a CCSDS OEM; None: the kind has none.
    oem: OemExport | None = None
    # The params field a stored job's id goes in to warm-start a new job from it (a dotted path): the
    # console's "warm start" button and a study's continuation fill it in; None: the kind takes no warm start.
    warm_start_field: str | None = None
    # The curve of one result on the console's compare plot; ValueError (a 422) for a result without it;
    # None: the kind's jobs cannot be compared.
    compare: Callable[[dict], CompareSeries] | None = None
    # The params are a document (names, expressions, lists) rather than settings: the console's "New job"
    # edits them as JSON instead of a form of fields.
    json_editor: bool = False
    # Extra sections of the console's job page the kind's results fill (app/web/static/job.js):
    # "front_table" (the Pareto-front points with a choice of point for the OEM download).
    console_extras: tuple[str, ...] = ()
    # The headline numbers of one result, (result, params) -> list[app.kinds.headlines.Headline]
    # (app/kinds/<kind>/headlines.py): what the CLI, the console, the job list and the report lead with.
    headlines: Callable[[dict, dict | None], list] | None = None
    # Why a stored result of this kind cannot warm-start these resolved params, (result, params) -> reason
    # or None (app.service.warm_start: a 422 at the door); None: any succeeded job of the kind can.
    warm_start_misfit: Callable[[dict, dict], str | None] | None = None
    # What a study charts against its swept value, (result, params) -> list[app.kinds.trade.TradeOutput]
    # (key numbers with their labels and units; the rest stay in the trade table); None: every float key
    # number, labelled by its name and the unit its suffix says.
    trade_outputs: Callable[[dict, dict | None], list] | None = None
    # The (label, unit) of a swept parameter, (params, dotted path) -> (label, unit), for paths whose name
    # carries no unit suffix (app.kinds.trade.name_unit reads those); None: the suffix alone.
    swept_label: Callable[[dict, str], tuple[str, str]] | None = None


def json_float(x) -> float | None:
    """The one policy for numbers in results: a non-finite value is ``null``, never ``0.0`` or ``"nan"``."""
    x = float(x)
    return x if math.isfinite(x) else None


def json_value(x):
    """Plain JSON from solver output (numpy arrays and scalars, nested dicts and lists),
    every float through :func:`json_float`."""
    if isinstance(x, dict):
        return {k: json_value(v) for k, v in x.items()}
    if hasattr(x, "tolist") and not isinstance(x, (bool, int, float)):
        x = x.tolist()   # numpy arrays and scalars to Python lists and numbers
    if isinstance(x, (list, tuple)):
        return [json_value(v) for v in x]
    if isinstance(x, float):
        return json_float(x)
    return x


def warm_start_from_job(ctx: JobContext, job_id: str, parse, *, field: str, what: str):
    """``parse(stored result)`` of another job as a warm start; a user-facing
    :class:`JobFailure` (``invalid_input``) naming ``field`` when the job is missing or unusable: the
    user's reference is wrong, not trajlab (the door checks it too, but the job may be deleted since)."""
    try:
        return parse(ctx.load_result(job_id))
    except LookupError as exc:
        raise JobFailure("invalid_input", f"{field}: {exc}") from None
    except (KeyError, TypeError, ValueError) as exc:
        raise JobFailure("invalid_input", f"{field}: job {job_id} has no usable {what} ({exc})") from None


def outcome_from_status(status, result: dict | None) -> RunOutcome:
    """Turn a solver's :class:`solvers.common.SolveStatus` into a :class:`RunOutcome`."""
    from solvers.common import Outcome

    if status.outcome in (Outcome.OPTIMAL, Outcome.OPTIMALITY_NOT_VERIFIED):   # the latter: a feasible answer
        return RunOutcome("succeeded", result=result)
    if status.outcome is Outcome.CANCELLED:
        return RunOutcome("cancelled", result=result,
                          error={"code": "cancelled", "message": "cancelled by request"})
    code = {
        Outcome.INFEASIBLE: "infeasible",
        Outcome.NOT_CONVERGED: "not_converged",
        Outcome.LIMIT_NOT_HELD: "limit_not_held",
        Outcome.TERMINAL_NOT_HELD: "terminal_not_held",
        Outcome.ACCURACY_NOT_REACHED: "accuracy_not_reached",
        Outcome.NUMERICAL_OVERFLOW: "numerical_overflow",
    }.get(status.outcome, "solver_failed")  # Outcome.FAILED: the solver's error, not a crash of ours (internal)
    msg = status.message or status.solver_status
    if status.solver_status and status.solver_status not in msg:
        msg = f"{status.solver_status}: {msg}"
    details = {
        "solver_status": status.solver_status,
        "iterations": status.iterations,
        "max_constraint_violation": status.max_constraint_violation,
        **status.details,
    }
    return RunOutcome("failed", result=result, error={"code": code, "message": msg, "details": details})
