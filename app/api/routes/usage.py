"""``GET /v1/usage``: what the caller's jobs hold (jobs by status, stored bytes) against the storage quota."""
from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Query
from pydantic import BaseModel, Field

from app.api.access import PrincipalDep
from app.api.deps import DatabaseDep, SettingsDep
from app.service import storage

router = APIRouter(prefix="/v1/usage", tags=["usage"])


class Usage(BaseModel):
    """An owner's jobs and the bytes they keep."""

    owner: str | None = Field(description="The owner counted (null: every owner, for an admin or with auth off)")
    jobs: int = Field(description="Jobs the owner has, in every status")
    jobs_by_status: dict[str, int] = Field(description="Jobs per status (statuses with none are left out)")
    stored_bytes: int = Field(description="Bytes the jobs keep in the database: params as JSON plus results "
                                          "as stored (compressed)", examples=[38_621])
    max_stored_bytes: int | None = Field(description="The storage quota (TRAJLAB_MAX_STORED_MB_PER_OWNER, in "
                                                     "bytes); submissions are a 429 at or past it; null: none")
    retention_days: float | None = Field(description="Finished jobs older than this are deleted "
                                                     "(TRAJLAB_RETENTION_DAYS); null: kept until deleted")


@router.get("", response_model=Usage)
def get_usage(db: DatabaseDep, settings: SettingsDep, principal: PrincipalDep,
              owner: Annotated[str | None, Query(max_length=100,
                                                description="Admins only: another owner's usage")] = None):
    """The caller's usage; an admin sees every owner's together, or one owner's with `owner`."""
    who = owner if principal.admin and owner is not None else principal.owner_filter
    return storage.usage(db, settings, owner=who)
