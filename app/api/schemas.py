"""HTTP schemas shared by all kinds: the job document, listings, errors, and the
submission body as a discriminated union on ``kind`` built from the registry."""
from __future__ import annotations

from datetime import datetime
from typing import TYPE_CHECKING, Annotated, Any, Literal, Optional, Union

from pydantic import BaseModel, Field, create_model

from app.kinds import KINDS
from app.kinds.base import KindSpec, StrictModel
from app.kinds.failures import ERROR_CODES, WHAT

JobStatus = Literal["queued", "running", "succeeded", "failed", "cancelled"]
# Every code a job can be stored with, from its one declaration (app.kinds.failures.WHAT): a code added
# there is in the OpenAPI enum, so generated clients accept every stored job.
ErrorCode = Literal[ERROR_CODES]  # type: ignore[valid-type]


class JobError(BaseModel):
    code: ErrorCode = Field(description="Why, in one word: " + "; ".join(f"`{c}`: {w}" for c, w in WHAT.items()))
    message: str = Field(description="Why the job failed: the solver's own status and the worst constraint violation")
    details: dict[str, Any] | None = Field(default=None, description="Stored diagnostic (solver status, iterations, ...)")


class JobStage(BaseModel):
    name: str = Field(description='The stage, nested stages joined by " / ", e.g. "refinement round 2 / solve"')
    round: int | None = Field(None, description="The round number of the innermost repeating stage (a limit or "
                              "refinement round); null for a stage that does not repeat")


class JobOut(BaseModel):
    id: str
    kind: str
    label: str | None
    preset: str | None
    status: JobStatus
    progress: float = Field(description="Fraction in [0, 1]; only grows while the job runs")
    message: str = Field(description='What the job is doing, e.g. "IPOPT iteration 31", "generation 120/500"')
    stage: JobStage | None = Field(None, description="The stage the job is in (build, solve, verification, a "
                                   "limit or refinement round, the Monte Carlo), for a kind that announces its "
                                   "stages; null before the first")
    created_at: datetime
    started_at: datetime | None
    finished_at: datetime | None
    params: dict[str, Any] = Field(description="The fully resolved parameters: re-submit them to re-run exactly")
    error: JobError | None
    attempts: int = Field(description="Deliveries so far (more than 1 after a worker was lost)")


class JobList(BaseModel):
    items: list[JobOut]
    total: int


class PresetOut(BaseModel):
    name: str
    kind: str
    description: str
    params: dict[str, Any] = Field(description="The preset's fully resolved parameters")


def _submission_model(spec: KindSpec) -> type[BaseModel]:
    names = tuple(p.name for p in spec.presets)
    preset_type = Optional[Literal[names]] if names else Optional[str]
    title = "".join(part.capitalize() for part in spec.kind.split("_"))
    # field types built at run time (a Literal of this kind's names): Any to the type checker
    fields: dict[str, Any] = dict(
        kind=(Literal[spec.kind], Field(description="Job kind")),
        preset=(preset_type, Field(default=None, description="A named case (GET /v1/presets); `params` override it")),
        params=(Optional[spec.params_model], Field(
            default=None, description="Parameters; deep-merged onto the preset's (or the defaults), "
                                      "only the fields you give override")),
        label=(Optional[str], Field(default=None, max_length=200, description="Free text to find the job again")),
    )
    return create_model(f"{title}Submission", __base__=StrictModel,
                        __doc__=spec.summary or f"Submit a {spec.kind} job.", **fields)


SUBMISSION_MODELS: dict[str, type[BaseModel]] = {kind: _submission_model(spec) for kind, spec in KINDS.items()}

if TYPE_CHECKING:
    class JobSubmission(StrictModel):
        """To the type checker: the fields every kind's submission model has (built at run time below)."""

        kind: str
        preset: str | None
        params: BaseModel | None
        label: str | None
elif len(SUBMISSION_MODELS) > 1:
    JobSubmission = Annotated[Union[tuple(SUBMISSION_MODELS.values())], Field(discriminator="kind")]
else:
    JobSubmission = next(iter(SUBMISSION_MODELS.values()))


class ErrorBody(BaseModel):
    """The body of a 404 (unknown or another owner's job/preset/table/plot), a 409 of the files routes, ..."""
    detail: str = Field(description="What went wrong, in one sentence")


class ValidationIssue(BaseModel):
    loc: list[str | int] = Field(description="Where: body/params/..., field names and list indexes")
    msg: str
    type: str
    input: Any = None


class ValidationErrorBody(BaseModel):
    """The body of every 422: one issue per bad field and a one-line summary."""
    detail: list[ValidationIssue] | str
    message: str | None = Field(default=None, description="All issues in one line, naming the fields")


class NotSucceededBody(BaseModel):
    """The 409 of ``GET /v1/jobs/{id}/result``: the job has not succeeded (yet)."""
    detail: str
    status: JobStatus
    error: JobError | None = None
    partial_result: dict[str, Any] | None = None
