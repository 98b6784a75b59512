"""``trajlab backup FILE`` and ``trajlab restore FILE [--force]``: a copy of the configured database
(``TRAJLAB_DATABASE_URL``) taken while the service runs, and put back into an empty database.

* **SQLite** (embedded): SQLite's online backup API (``sqlite3.Connection.backup``) copies every page
  in one step inside one read transaction, so the copy is the database as it was at one instant while
  the API and the workers go on writing (WAL: the readers never block the writer).  The file is a
  plain SQLite database (``sqlite3 FILE`` opens it), switched out of WAL so it is one file.
* **PostgreSQL**: ``pg_dump -Fc`` (custom format; its snapshot is one transaction, consistent under
  writes) and, to restore, ``pg_restore``'s SQL run by ``psql`` in a single transaction: a restore
  that fails half-way leaves the database as it was.  The client tools must be at least the server's
  major version (``pg_dump`` refuses a newer server); both are checked first with a message that says so.

The file says which database it holds by its own first bytes ("SQLite format 3" or ``PGDMP``), so a
SQLite backup is never fed to ``pg_restore``, nor a dump to SQLite.  It is written beside its final
name and renamed when complete: a backup interrupted half-way never leaves a file that looks whole.

Nothing in a backup is trusted (app.runtime.restore_check, callable by any restore path): before the
target is opened for writing, a SQLite backup's schema must be exactly the migrations' at its own revision
and a dump's table of contents must hold only their objects (then restored from that checked list); a
damaged file is one line.

A restore refuses a database that holds jobs, results, studies or API keys unless ``--force``: it replaces
everything in it.  Stop the service (API, workers, recovery) while restoring.  A backup taken at an
older schema revision is restored as it was; ``trajlab migrate`` brings it to this version's.
"""
from __future__ import annotations

import argparse
import os
import re
import shutil
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

SQLITE_MAGIC = b"SQLite format 3\x00"
PG_MAGIC = b"PGDMP"
KINDS = {"sqlite": "SQLite", "postgresql": "PostgreSQL"}
# The tables that hold what users and operators made: a database with rows in none of them is empty, whatever
# bookkeeping a migration seeds (the schema revision, a recovery lease row)
DATA_TABLES = ("jobs", "job_results", "studies", "api_keys")


class BackupError(Exception):
    """A refusal or failure, said to the operator in one line (exit status 1)."""


def add_commands(sub) -> None:
    p = sub.add_parser("backup", help="copy the service's database to FILE while the service runs")
    p.add_argument("file", type=Path, help="the backup file to write (replaced if it exists)")
    p.add_argument("--url", help="download it from this service's API with an admin key (TRAJLAB_URL, "
                                 "TRAJLAB_API_KEY); without it: the database as `trajlab serve` finds it")
    p.set_defaults(fn=_run_backup)
    p = sub.add_parser("restore", help="restore a backup FILE into the configured (empty) database")
    p.add_argument("file", type=Path, help="a file written by trajlab backup")
    p.add_argument("--force", action="store_true", help="replace a database that is not empty")
    p.set_defaults(fn=_run_restore)


def _url() -> str:
    from app.runtime.settings import get_settings

    return get_settings().database_url


def _run_backup(args: argparse.Namespace) -> int:
    from app.cli import operator

    if operator.service_url(args):  # the service's own copy, downloaded (GET /v1/admin/backup runs this command)
        def download() -> int:
            t0 = time.monotonic()
            size = operator.client(args).backup(args.file)
            print(f"trajlab backup: {KINDS.get(file_kind(args.file) or '', 'unknown')} backup of the service at "
                  f"{operator.service_url(args)} written to {args.file} ({size / 1e6:.1f} MB) in "
                  f"{time.monotonic() - t0:.1f} s", file=sys.stderr)
            return 0

        return operator.run("backup", download)
    done: dict = {}

    def take() -> int:
        done.update(backup(operator.database_url(), args.file))
        return 0

    try:
        failed = operator.run("backup", take)  # a missing or unreadable database: one line, exit 1
        if failed:
            return failed
    except BackupError as exc:
        print(f"trajlab backup: {exc}", file=sys.stderr)
        return 1
    print(f"trajlab backup: {KINDS[done['kind']]} database {done['database']} (schema {done['revision']}) "
          f"written to {args.file} ({done['bytes'] / 1e6:.1f} MB) in {done['seconds']:.1f} s", file=sys.stderr)
    return 0


def _run_restore(args: argparse.Namespace) -> int:
    try:
        done = restore(_url(), args.file, force=args.force)
    except BackupError as exc:
        print(f"trajlab restore: {exc}", file=sys.stderr)
        return 1
    print(f"trajlab restore: {args.file} restored into {KINDS[done['kind']]} database {done['database']} "
          f"in {done['seconds']:.1f} s (schema {done['revision']})", file=sys.stderr)
    if done["revision"] != done["head"]:
        print(f"trajlab restore: this version's schema is {done['head']}: run `trajlab migrate` before starting "
              "the service", file=sys.stderr)
    return 0


# ----------------------------------------------------------------------------- what is what
def database_kind(url: str) -> str:
    if url.startswith("sqlite"):
        return "sqlite"
    if url.startswith("postgresql"):
        return "postgresql"
    raise BackupError(f"cannot back up a database of this kind ({url.split(':', 1)[0]}); "
                      "SQLite and PostgreSQL are supported")


def file_kind(path: Path) -> str | None:
    """Which database a backup file holds, from its first bytes; None: not a trajlab backup."""
    with open(path, "rb") as f:
        head = f.read(len(SQLITE_MAGIC))
    if head.startswith(SQLITE_MAGIC):
        return "sqlite"
    if head.startswith(PG_MAGIC):
        return "postgresql"
    return None


def _shown(url: str) -> str:
    from sqlalchemy.engine import make_url

    return make_url(url).render_as_string(hide_password=True)


def head_revision() -> str:
    import logging

    from alembic.script import ScriptDirectory

    from app.runtime.migrate import alembic_config

    logging.getLogger("alembic").setLevel(logging.WARNING)  # its plugin set-up lines are noise here
    return ScriptDirectory.from_config(alembic_config("")).get_current_head() or "none"


def backup(url: str, dest: Path) -> dict:
    """Write a backup of the database at ``url`` to ``dest``; what was written (kind, bytes, seconds, revision)."""
    kind, t0 = database_kind(url), time.monotonic()
    dest = Path(dest)
    partial = dest.with_name(dest.name + ".partial")
    try:
        revision = (_sqlite_backup if kind == "sqlite" else _pg_backup)(url, dest, partial)
        with open(partial, "rb") as f:
            os.fsync(f.fileno())
        os.replace(partial, dest)
    finally:
        partial.unlink(missing_ok=True)
    return {"kind": kind, "database": _shown(url), "revision": revision, "bytes": dest.stat().st_size,
            "seconds": time.monotonic() - t0}


def restore(url: str, src: Path, *, force: bool = False) -> dict:
    """Restore the backup ``src`` into the database at ``url`` (refused if it holds rows, unless ``force``)."""
    kind, t0 = database_kind(url), time.monotonic()
    src = Path(src)
    if not src.is_file():
        raise BackupError(f"no backup file at {src}")
    held = file_kind(src)
    if held is None:
        raise BackupError(f"{src} is not a trajlab backup (neither a SQLite database nor a pg_dump custom-format file)")
    if held != kind:
        raise BackupError(f"{src} holds a {KINDS[held]} backup and the configured database "
                          f"({_shown(url)}) is {KINDS[kind]}; restore it into a {KINDS[held]} database")
    from app.runtime.restore_check import UnsafeBackup

    try:
        revision = (_sqlite_restore if kind == "sqlite" else _pg_restore)(url, src, force=force)
    except UnsafeBackup as exc:
        raise BackupError(str(exc)) from None
    return {"kind": kind, "database": _shown(url), "revision": revision, "head": head_revision(),
            "seconds": time.monotonic() - t0}


def _refuse_unless_forced(url: str, tables_with_rows: list[str], force: bool) -> None:
    if tables_with_rows and not force:
        raise BackupError(f"the database {_shown(url)} is not empty (rows in {', '.join(sorted(tables_with_rows))}); "
                          "a restore replaces everything in it: run again with --force to do so")


# ----------------------------------------------------------------------------- SQLite
def _sqlite_path(url: str) -> Path:
    from sqlalchemy.engine import make_url

    name = make_url(url).database
    if not name or name == ":memory:":
        raise BackupError("the configured SQLite database is in memory: there is nothing to back up or restore into")
    return Path(name)


def _sqlite_rows(conn: sqlite3.Connection) -> list[str]:
    names = [r[0] for r in conn.execute("SELECT name FROM sqlite_master WHERE type = 'table' "
                                        "AND name NOT LIKE 'sqlite_%'")]
    return [n for n in names if n in DATA_TABLES
            and conn.execute(f'SELECT 1 FROM "{n}" LIMIT 1').fetchone() is not None]


def _sqlite_revision(conn: sqlite3.Connection) -> str:
    try:
        row = conn.execute("SELECT version_num FROM alembic_version").fetchone()
    except sqlite3.DatabaseError:
        return "none"
    return row[0] if row else "none"


def _sqlite_check(conn: sqlite3.Connection, what: str) -> None:
    found = conn.execute("PRAGMA quick_check").fetchone()[0]
    if found != "ok":
        raise BackupError(f"{what} fails SQLite's integrity check: {found}")


def _sqlite_backup(url: str, dest: Path, partial: Path) -> str:
    path = _sqlite_path(url)
    if not path.is_file():
        raise BackupError(f"no SQLite database at {path}")
    if dest.resolve() == path.resolve():
        raise BackupError(f"{dest} is the database itself; write the backup to another file")
    partial.unlink(missing_ok=True)
    # the busy timeout: a backup step waits for a writer's lock instead of failing
    with sqlite3.connect(path, timeout=30) as source, sqlite3.connect(partial) as copy:
        source.backup(copy)  # pages=-1: every page in one step, one read transaction, one instant
        copy.execute("PRAGMA journal_mode=DELETE")  # one self-contained file (the source runs in WAL)
        _sqlite_check(copy, "the backup just written")
        revision = _sqlite_revision(copy)
    source.close()
    copy.close()
    return revision


def _sqlite_restore(url: str, src: Path, *, force: bool) -> str:
    from app.runtime.restore_check import check_sqlite

    path = _sqlite_path(url)
    check_sqlite(src)   # the schema of the migrations at its revision, or refused before the target is opened
    path.parent.mkdir(parents=True, exist_ok=True)
    with sqlite3.connect(f"file:{src}?mode=ro", uri=True) as backup_db:
        target = sqlite3.connect(path, timeout=30)
        try:
            _refuse_unless_forced(url, _sqlite_rows(target), force)
            # the backup API writes every page of the target in one transaction: all or nothing
            backup_db.backup(target)
            target.execute("PRAGMA journal_mode=WAL")  # as the service runs it (app.runtime.db)
            revision = _sqlite_revision(target)
        finally:
            target.close()
    backup_db.close()
    return revision


# ----------------------------------------------------------------------------- PostgreSQL
def _pg_target(url: str) -> tuple[str, dict]:
    """A libpq URI for the tools without the password (which goes in PGPASSWORD, not on a command line
    that ``ps`` shows) and their environment."""
    from sqlalchemy.engine import make_url

    u = make_url(url)
    env = {**os.environ}
    if u.password is not None:
        env["PGPASSWORD"] = str(u.password)
    return u.set(drivername="postgresql", password=None).render_as_string(hide_password=False), env


def _pg_connect(url: str):
    import psycopg

    dsn, env = _pg_target(url)
    try:
        return psycopg.connect(dsn, password=env.get("PGPASSWORD"), autocommit=True, connect_timeout=10)
    except psycopg.OperationalError as exc:
        raise BackupError(f"cannot connect to {_shown(url)}: {str(exc).strip().splitlines()[0]}") from None


def _tool(name: str, server_major: int) -> str:
    path = shutil.which(name)
    if path is None:
        raise BackupError(f"{name} is not installed; install the PostgreSQL {server_major} client tools "
                          f"(Debian: postgresql-client-{server_major})")
    out = subprocess.run([path, "--version"], capture_output=True, text=True, timeout=30).stdout
    m = re.search(r"\)\s+(\d+)", out)
    if m is None or int(m.group(1)) < server_major:
        raise BackupError(f"{name} is version {m.group(1) if m else 'unknown'} and the server is PostgreSQL "
                          f"{server_major}: install the PostgreSQL {server_major} client tools "
                          f"(Debian: postgresql-client-{server_major})")
    return path


def _pg_revision(conn) -> str:
    has = conn.execute("SELECT to_regclass('public.alembic_version') IS NOT NULL").fetchone()[0]
    row = conn.execute("SELECT version_num FROM alembic_version").fetchone() if has else None
    return row[0] if row else "none"


def _run(cmd: list[str], *, env: dict, what: str, **kwargs) -> subprocess.CompletedProcess:
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True, **kwargs)
    if proc.returncode != 0:
        detail = " ".join(proc.stderr.strip().splitlines()[-3:]) or f"exit status {proc.returncode}"
        raise BackupError(f"{what} failed: {detail}")
    return proc


def _pg_backup(url: str, dest: Path, partial: Path) -> str:
    with _pg_connect(url) as conn:
        major = conn.info.server_version // 10000
        revision = _pg_revision(conn)
    pg_dump, pg_restore = _tool("pg_dump", major), _tool("pg_restore", major)
    dsn, env = _pg_target(url)
    _run([pg_dump, "--format=custom", "--file", str(partial), "--dbname", dsn], env=env, what="pg_dump")
    _run([pg_restore, "--list", str(partial)], env=env, what="reading the dump back (pg_restore --list)")
    return revision


# Everything of ours in the schema, dropped in the restore's own transaction before the dump's objects are made.
_OBJECTS = """
SELECT 'TABLE', quote_ident(c.relname) FROM pg_class c JOIN pg_namespace n ON n.oid = c.relnamespace
 WHERE n.nspname = 'public' AND c.relkind IN ('r', 'p')
UNION ALL
SELECT 'VIEW', quote_ident(c.relname) FROM pg_class c JOIN pg_namespace n ON n.oid = c.relnamespace
 WHERE n.nspname = 'public' AND c.relkind = 'v'
UNION ALL
SELECT 'SEQUENCE', quote_ident(c.relname) FROM pg_class c JOIN pg_namespace n ON n.oid = c.relnamespace
 WHERE n.nspname = 'public' AND c.relkind = 'S'
UNION ALL
SELECT 'TYPE', quote_ident(t.typname) FROM pg_type t JOIN pg_namespace n ON n.oid = t.typnamespace
 WHERE n.nspname = 'public' AND t.typtype IN ('e', 'd')
"""


def _pg_restore(url: str, src: Path, *, force: bool) -> str:
    import tempfile

    from app.runtime.restore_check import check_pg_dump

    with _pg_connect(url) as conn:
        major = conn.info.server_version // 10000
    pg_restore, psql = _tool("pg_restore", major), _tool("psql", major)
    dsn, env = _pg_target(url)
    # the archive's objects against the migrations' at its revision, before anything is written
    _, checked = check_pg_dump(src, pg_restore=pg_restore, env=env)
    with _pg_connect(url) as conn:
        objects = conn.execute(_OBJECTS).fetchall()
        tables = [name for what, name in objects if what == "TABLE"]
        with_rows = [t for t in tables if t in DATA_TABLES
                     and conn.execute(f"SELECT EXISTS (SELECT 1 FROM public.{t})").fetchone()[0]]
        _refuse_unless_forced(url, with_rows, force)
    drops = [f"DROP {what} IF EXISTS public.{name} CASCADE;" for what, name in objects]
    # kept past the block (pg_restore reads it by name), removed once pg_restore is done
    with tempfile.NamedTemporaryFile("w", prefix="trajlab-restore-", suffix=".list", delete=False) as listing:
        listing.write(checked)
    # pg_restore writes the checked entries only (--use-list) as SQL; psql runs it and the drops as ONE
    # transaction (-1), stopping at the first error (ON_ERROR_STOP): a restore that fails leaves the
    # database as it was
    script = subprocess.Popen([pg_restore, "--no-owner", "--no-privileges", "--use-list", listing.name,
                               "--file", "-", str(src)], env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    assert script.stdout is not None and script.stderr is not None  # PIPE
    try:
        _run([psql, "-X", "-q", "-v", "ON_ERROR_STOP=1", "--single-transaction", "--dbname", dsn,
              "-c", " ".join(drops) or "SELECT 1", "-f", "-"], env=env, what="psql (restoring)",
             stdin=script.stdout)
    finally:
        script.stdout.close()
        err = script.stderr.read().decode(errors="replace")
        script.stderr.close()
        script.wait(timeout=60)
        os.unlink(listing.name)
    if script.returncode != 0:
        raise BackupError(f"pg_restore failed: {' '.join(err.strip().splitlines()[-3:])}")
    with _pg_connect(url) as conn:
        return _pg_revision(conn)
