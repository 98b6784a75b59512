"""``/v1/admin``: the operator's commands (``trajlab keys``, ``trajlab purge``, ``trajlab backup``) over HTTP,
for an admin key (or auth off), so the CLI works against a service wherever it runs (``TRAJLAB_URL``) instead
of needing that service's database on the machine it runs on (issue 38).

An admin key can already see, cancel and delete every owner's jobs; minting keys and purging add nothing a
leaked admin key could not do otherwise, and a non-admin key is a 403 on every route here.
"""
from __future__ import annotations

import os
import subprocess
import sys
import tempfile
from datetime import timedelta
from pathlib import Path

from fastapi import APIRouter, Depends, HTTPException, Response
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import FileResponse
from pydantic import BaseModel, Field
from starlette.background import BackgroundTask

from app.api import auth
from app.api.access import Principal, PrincipalDep
from app.api.deps import DatabaseDep, SettingsDep
from app.runtime.models import FINAL_STATUSES
from app.service import retention


def _admin(principal: PrincipalDep) -> Principal:
    if not principal.admin:
        raise HTTPException(status_code=403, detail="this route needs an admin key (trajlab keys create --admin)")
    return principal


router = APIRouter(prefix="/v1/admin", tags=["admin"], dependencies=[Depends(_admin)],
                   responses={403: {"description": "The key is not an admin key"}})


class KeyRequest(BaseModel):
    name: str = Field(min_length=1, max_length=100, description="Unique name of the key (used to revoke it)")
    owner: str | None = Field(default=None, min_length=1, max_length=100,
                              description="Owner of the jobs submitted with it (default: the name)")
    admin: bool = Field(default=False, description="Sees and cancels every owner's jobs")


class KeyInfo(BaseModel):
    name: str
    owner: str
    key_prefix: str = Field(description="The key's first characters, to recognise it (never the key)")
    admin: bool
    created_at: str | None
    last_used_at: str | None
    revoked_at: str | None


class NewKey(KeyInfo):
    key: str = Field(description="The key itself: shown only in this answer")


def _info(k) -> dict:
    def t(dt):
        return dt.isoformat() if dt else None
    return {"name": k.name, "owner": k.owner, "key_prefix": k.key_prefix, "admin": k.admin,
            "created_at": t(k.created_at), "last_used_at": t(k.last_used_at), "revoked_at": t(k.revoked_at)}


@router.post("/keys", response_model=NewKey, status_code=201,
             responses={409: {"description": "A key with this name exists already"}})
def create_key(body: KeyRequest, db: DatabaseDep):
    """Create an API key; the answer is the only time the key is shown."""
    try:
        info, key = auth.create_key(db, name=body.name.strip(), owner=body.owner, admin=body.admin)
    except auth.KeyNameTaken:
        raise HTTPException(status_code=409, detail=f"a key named {body.name.strip()!r} exists already") from None
    return {**_info(info), "key": key}


@router.get("/keys", response_model=list[KeyInfo])
def list_keys(db: DatabaseDep):
    """Every key: names, owners, prefixes, when created, last used and revoked (never the keys)."""
    return [_info(k) for k in auth.list_keys(db)]


@router.delete("/keys/{name}", status_code=204, responses={404: {"description": "No key has this name"}})
def revoke_key(name: str, db: DatabaseDep) -> Response:
    """Revoke a key: its next request is a 401."""
    if not auth.revoke_key(db, name):
        raise HTTPException(status_code=404, detail=f"no key named {name!r}")
    return Response(status_code=204)


MAX_DAYS = 36525.0


class PurgeRequest(BaseModel):
    older_than_days: float = Field(ge=0, le=MAX_DAYS, allow_inf_nan=False,
                                   description="Finished more than this many days ago (0.5 is 12 hours; at most a "
                                               "century: further back than the calendar goes is no age)")
    statuses: list[str] = Field(default=list(FINAL_STATUSES), min_length=1, max_length=len(FINAL_STATUSES),
                                description="The final statuses to purge")
    dry_run: bool = Field(default=False, description="Count what would go, delete nothing")


class Purged(BaseModel):
    jobs: int
    studies: int
    stored_bytes: int


@router.post("/purge", response_model=Purged, responses={422: {"description": "A status that is not final"}})
def purge(body: PurgeRequest, db: DatabaseDep):
    """Delete finished jobs (and finished studies) older than ``older_than_days`` with their results, as
    ``TRAJLAB_RETENTION_DAYS`` does in the recovery loop."""
    try:
        return retention.purge(db, older_than=timedelta(days=body.older_than_days), statuses=body.statuses,
                               dry_run=body.dry_run)
    except ValueError as exc:
        raise HTTPException(status_code=422, detail=str(exc)) from None


@router.get("/backup", response_class=FileResponse,
            responses={200: {"content": {"application/octet-stream": {}},
                             "description": "The backup file (a SQLite database or a pg_dump archive)"},
                       503: {"description": "The backup could not be taken (its one-line reason)"}})
async def backup(settings: SettingsDep):
    """A consistent copy of the service's database taken while it runs, as ``trajlab backup FILE`` writes it.

    Taken by ``trajlab backup`` in a child process of this installation, with this service's database URL:
    the API layer never imports the command line (the layering rule), and the copy is the very same one."""
    tmp = Path(tempfile.mkdtemp(prefix="trajlab-backup-"))
    dest = tmp / "trajlab.backup"

    def take() -> subprocess.CompletedProcess:
        # this service's database, read locally (never TRAJLAB_URL: the command would download from us)
        env = {k: v for k, v in os.environ.items() if k != "TRAJLAB_URL"}
        env["TRAJLAB_DATABASE_URL"] = settings.database_url
        return subprocess.run([sys.executable, "-m", "app.cli.commands", "backup", str(dest)], env=env,
                              capture_output=True, text=True, timeout=3600, check=False)

    def clean() -> None:
        dest.unlink(missing_ok=True)
        tmp.rmdir()

    done = await run_in_threadpool(take)
    if done.returncode != 0 or not dest.exists():
        clean()
        reason = (done.stderr.strip().splitlines() or ["trajlab backup failed"])[-1]
        raise HTTPException(status_code=503, detail=reason)
    name = "trajlab.sqlite" if settings.database_url.startswith("sqlite") else "trajlab.pgdump"
    return FileResponse(dest, media_type="application/octet-stream", filename=name, background=BackgroundTask(clean))

