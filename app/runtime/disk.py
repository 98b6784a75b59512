"""Free space where this host's service writes, and what a full disk looks like in a database error.

Readiness (``/readyz``) reports a filesystem as full when less than ``min_free_disk_mb`` is left on it:
the SQLite database's (``database_storage``) and, in embedded mode, the data directory's (``data_dir``:
the Redis dump, the logs, the compiled-derivative cache).  A PostgreSQL server's disk is the server's:
its "disk full" comes back as an error on the statement (SQLSTATE 53100), which
:func:`is_disk_full` recognises, as it does SQLite's ``SQLITE_FULL``.
"""
from __future__ import annotations

import os
import sqlite3
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from app.runtime.settings import Settings

PG_DISK_FULL = "53100"  # SQLSTATE disk_full: "could not extend file", "could not write block"


def free_mb(path: Path) -> float:
    st = os.statvfs(path)
    return st.f_bavail * st.f_frsize / 2**20


def _watched(settings: "Settings") -> dict[str, Path]:
    paths: dict[str, Path] = {}
    embedded = settings.broker_url.startswith("redis+socket://")
    if settings.database_url.startswith("sqlite:///"):
        paths["database_storage"] = Path(settings.database_url.removeprefix("sqlite:///")).parent
        embedded = True
    if embedded:
        paths["data_dir"] = Path(settings.data_dir)
    return paths


def storage_checks(settings: "Settings") -> dict[str, str]:
    """``{part: "up" | "full: N MB free (below TRAJLAB_MIN_FREE_DISK_MB=M)"}`` for each watched
    filesystem that exists (nothing on a PostgreSQL service without a data directory)."""
    out: dict[str, str] = {}
    for part, path in _watched(settings).items():
        try:
            free = free_mb(path)
        except OSError:
            continue  # not created yet: nothing written there to fill
        out[part] = "up" if free >= settings.min_free_disk_mb else (
            f"full: {free:.0f} MB free (below TRAJLAB_MIN_FREE_DISK_MB={settings.min_free_disk_mb:g})")
    return out


def is_disk_full(exc: BaseException) -> bool:
    """Whether a database error (SQLAlchemy's, or the driver's under it) says its disk is full."""
    orig = getattr(exc, "orig", exc)
    if getattr(orig, "sqlstate", None) == PG_DISK_FULL:
        return True
    return isinstance(orig, sqlite3.Error) and getattr(orig, "sqlite_errorcode", None) == sqlite3.SQLITE_FULL
