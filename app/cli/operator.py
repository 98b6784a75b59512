"""Where the operator's commands (``keys``, ``purge``, ``backup``) find the service, and how they fail.

* ``--url`` or ``TRAJLAB_URL`` given: through the service's API (``/v1/admin``) with the admin key in
  ``TRAJLAB_API_KEY`` (any key with auth off), wherever the service and its data directory are;
* otherwise the service's database found exactly as ``trajlab serve`` finds it: ``TRAJLAB_DATABASE_URL``, else
  ``trajlab.db`` in ``TRAJLAB_DATA_DIR`` (default ``var`` under the current directory), from the environment
  and ``./.env`` (app.runtime.settings).

A database that is not there (a moved data directory, another current directory) or cannot be read is one
line naming it and what to set, never a traceback; so is an API's refusal.
"""
from __future__ import annotations

import os
import sys
from collections.abc import Callable
from pathlib import Path


class NoDatabase(Exception):
    """The configured database is not there: said in one line."""


def add_url(p) -> None:
    p.add_argument("--url", help="go through this service's API with an admin key (TRAJLAB_URL, TRAJLAB_API_KEY); "
                                 "without it: the database as `trajlab serve` finds it (TRAJLAB_DATA_DIR)")


def service_url(args) -> str | None:
    return getattr(args, "url", None) or os.environ.get("TRAJLAB_URL") or None


def client(args):
    from app.cli.client import Client

    return Client(service_url(args))


def _where() -> str:
    return ("set TRAJLAB_DATA_DIR (or TRAJLAB_DATABASE_URL) as for `trajlab serve`, or TRAJLAB_URL to go through "
            "the running service's API")


def database_url() -> str:
    """The database ``trajlab serve`` would use from here; :class:`NoDatabase` when a SQLite file is missing
    (opening it would create an empty one)."""
    from app.runtime.settings import get_settings

    settings = get_settings()
    url = settings.database_url
    if url.startswith("sqlite"):
        path = Path(url.split(":///", 1)[-1]) if ":///" in url else None
        if path is not None and not path.exists():
            raise NoDatabase(f"no trajlab database at {path.resolve()} (data directory "
                             f"{Path(settings.data_dir).resolve()}); {_where()}")
    return url


def database():
    from app.runtime.db import get_database

    return get_database(database_url())


def run(command: str, fn: Callable[[], int]) -> int:
    """``fn()``'s exit status; a missing database, a database error or an API refusal is one line on stderr."""
    from app.cli.client import TrajlabError

    try:
        return fn()
    except NoDatabase as exc:
        print(f"trajlab {command}: {exc}", file=sys.stderr)
        return 1
    except TrajlabError as exc:
        print(f"trajlab {command}: {exc.message}", file=sys.stderr)
        return 4 if exc.status_code == 0 else (1 if exc.status_code >= 500 else 2)
    except Exception as exc:
        if not type(exc).__module__.startswith(("sqlalchemy", "psycopg", "sqlite3")):
            raise
        first = (str(getattr(exc, "orig", None) or exc).strip().splitlines() or [""])[0]
        print(f"trajlab {command}: the database cannot be read ({type(exc).__name__}: {first[:200]}); "
              f"{_where()}", file=sys.stderr)
        return 1
