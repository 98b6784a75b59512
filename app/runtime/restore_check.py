"""What a backup may hold before a restore writes a byte: the schema the migrations build at the backup's
own revision, and nothing else (issue 36 item 4).

A backup is a file from elsewhere.  A SQLite file carrying an extra table and a trigger on ``jobs`` was
restored as it was, the trigger live in the service's database; a damaged file ended in a traceback.  So a
restore first builds the reference: a scratch SQLite database upgraded by the migrations to the revision
the backup names (which must be one of this version's revisions), and compares:

* **SQLite**: every object of ``sqlite_master`` (tables, indexes, triggers, views) by type, name and
  definition (whitespace aside): an object the reference lacks, lacks one it has, or defines otherwise is
  refused, by name.  A file SQLite cannot read or whose integrity check fails is one line saying so.
* **PostgreSQL** (``pg_dump -Fc``): the archive's table of contents (``pg_restore --list``) may hold
  only the reference's tables (definition and data), their primary-key, unique and foreign-key
  constraints and their indexes, by name, in schema ``public``; anything else (a function, a trigger, a
  view, a rule, a policy, an extension, another schema, a table of another name) is refused, and the
  restore then uses the checked list (``pg_restore --use-list``), so nothing unchecked is restored.

The checks only read the backup; the callers (``trajlab restore``, app.cli.backup, and whatever else
restores) call them before they open the target for writing.  Not checked: a column default or check
expression inside a table the reference has (they can only call functions that exist, and a function
of the dump's own is refused).
"""
from __future__ import annotations

import functools
import re
import sqlite3
import subprocess
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

# SQLite's own tables: created by SQLite itself (AUTOINCREMENT, ANALYZE), never by a migration
_SQLITE_INTERNAL = {"sqlite_sequence": "CREATE TABLE sqlite_sequence(name,seq)",
                    "sqlite_stat1": "CREATE TABLE sqlite_stat1(tbl,idx,stat)",
                    "sqlite_stat4": "CREATE TABLE sqlite_stat4(tbl,idx,neq,nlt,ndlt,sample)"}
SHOWN = 6   # objects named in a refusal, at most


class UnsafeBackup(Exception):
    """A backup that is refused, in one line for the operator (nothing was written)."""


def revisions() -> set[str]:
    """Every revision of this version's migrations."""
    from alembic.script import ScriptDirectory

    from app.runtime.migrate import alembic_config

    return {s.revision for s in ScriptDirectory.from_config(alembic_config("")).walk_revisions()}


@dataclass(frozen=True)
class Reference:
    """The schema the migrations build at one revision, read from a scratch SQLite database."""

    sqlite_objects: dict[tuple[str, str], str]     # (type, name) -> definition
    tables: frozenset[str]
    constraints: frozenset[tuple[str, str]] = field(default_factory=frozenset)  # (table, name)
    indexes: frozenset[str] = field(default_factory=frozenset)


def _normal(sql: str | None) -> str:
    return " ".join((sql or "").split())


def _objects(conn: sqlite3.Connection) -> dict[tuple[str, str], str]:
    return {(t, n): _normal(sql) for t, n, sql in conn.execute("SELECT type, name, sql FROM sqlite_master")}


@functools.lru_cache(maxsize=8)
def reference(revision: str) -> Reference:
    """The schema at ``revision`` (one of :func:`revisions`), built by the migrations in a scratch file."""
    import logging

    from sqlalchemy import create_engine, inspect

    from app.runtime.migrate import upgrade

    logging.getLogger("alembic").setLevel(logging.WARNING)
    with tempfile.TemporaryDirectory(prefix="trajlab-reference-") as tmp:
        path = Path(tmp) / "reference.db"
        upgrade(f"sqlite:///{path}", revision)
        with sqlite3.connect(path) as conn:
            objects = _objects(conn)
        conn.close()
        engine = create_engine(f"sqlite:///{path}")
        try:
            insp = inspect(engine)
            tables = frozenset(insp.get_table_names())
            constraints: set[tuple[str, str]] = set()
            indexes: set[str] = set()
            for t in tables:
                named = [insp.get_pk_constraint(t)] + insp.get_unique_constraints(t) + insp.get_foreign_keys(t)
                constraints |= {(t, name) for c in named if (name := c.get("name"))}
                indexes |= {name for i in insp.get_indexes(t) if (name := i.get("name"))}
        finally:
            engine.dispose()
    return Reference(objects, tables, frozenset(constraints), frozenset(indexes))


def _known(revision: str, what: str) -> Reference:
    if revision not in revisions():
        raise UnsafeBackup(f"{what} is at schema revision {revision!r}, which this version's migrations do not "
                           "have (a newer trajlab's backup, or not one of trajlab's): refused, nothing was written")
    return reference(revision)


def _names(items) -> str:
    items = sorted(items)
    more = f" and {len(items) - SHOWN} more" if len(items) > SHOWN else ""
    return ", ".join(items[:SHOWN]) + more


# ----------------------------------------------------------------------------- SQLite
def check_sqlite(src: Path) -> str:
    """The revision of the SQLite backup ``src`` once its schema is exactly the migrations' at that
    revision; :class:`UnsafeBackup` otherwise (a damaged file included)."""
    try:
        # read-only and immutable: nothing in the file runs or changes while it is read (no journal replay)
        conn = sqlite3.connect(f"file:{Path(src).resolve()}?mode=ro&immutable=1", uri=True)
        try:
            found = conn.execute("PRAGMA quick_check").fetchone()[0]
            if found != "ok":
                raise UnsafeBackup(f"{src} fails SQLite's integrity check ({found}): refused, nothing was written")
            objects = _objects(conn)
            revision = None
            if ("table", "alembic_version") in objects:
                row = conn.execute("SELECT version_num FROM alembic_version").fetchall()
                revision = row[0][0] if len(row) == 1 else None
        finally:
            conn.close()
    except sqlite3.DatabaseError as exc:
        raise UnsafeBackup(f"{src} is not a readable SQLite database ({exc}): refused, nothing was written") from None
    if revision is None:
        raise UnsafeBackup(f"{src} has no single schema revision (alembic_version): not a trajlab database; "
                           "refused, nothing was written")
    ref = _known(revision, str(src))
    for name, sql in _SQLITE_INTERNAL.items():
        if objects.get(("table", name)) == _normal(sql):
            objects.pop(("table", name))
    extra = {f"{t} {n}" for (t, n) in objects.keys() - ref.sqlite_objects.keys()}
    missing = {f"{t} {n}" for (t, n) in ref.sqlite_objects.keys() - objects.keys()}
    changed = {f"{t} {n}" for (t, n) in objects.keys() & ref.sqlite_objects.keys()
               if objects[(t, n)] != ref.sqlite_objects[(t, n)]}
    problems = [f"{what}: {_names(items)}" for what, items in
                (("not made by the migrations", extra), ("missing", missing), ("defined otherwise", changed))
                if items]
    if problems:
        raise UnsafeBackup(f"{src} does not hold the schema of revision {revision} ({'; '.join(problems)}): "
                           "refused, nothing was written")
    return revision


# ----------------------------------------------------------------------------- PostgreSQL
# pg_restore --list: "<dump id>; <catalog oid> <oid> <TYPE> <schema> <tag> <owner>"; the types we accept,
# longest first (a type is one or more words)
_ENTRY = re.compile(r"^(\d+); (\d+) (\d+) (.*)$")
_HEADER_TYPES = ("ENCODING", "STDSTRINGS", "SEARCHPATH")
_TYPES = ("FK CONSTRAINT", "TABLE DATA", "CONSTRAINT", "TABLE", "INDEX", "SCHEMA", "COMMENT") + _HEADER_TYPES


def _entry_ok(kind: str, schema: str, tag: str, ref: Reference) -> bool:
    if kind in _HEADER_TYPES:
        return True
    if kind == "SCHEMA":
        return schema == "-" and tag == "public"
    if kind == "COMMENT":
        return schema == "-" and tag == "SCHEMA public"
    if schema != "public":
        return False
    if kind in ("TABLE", "TABLE DATA"):
        return tag in ref.tables
    if kind == "INDEX":
        return tag in ref.indexes
    table, _, name = tag.partition(" ")
    return (table, name) in ref.constraints    # CONSTRAINT, FK CONSTRAINT: "<table> <name>"


def _pg_revision(src: Path, pg_restore: str, env: dict | None) -> str | None:
    proc = subprocess.run([pg_restore, "--data-only", "--schema=public", "--table=alembic_version", "--file=-",
                           str(src)], capture_output=True, text=True, env=env, timeout=120, check=False)
    if proc.returncode != 0:
        return None
    lines = proc.stdout.splitlines()
    try:
        start = next(i for i, line in enumerate(lines) if line.startswith("COPY public.alembic_version "))
    except StopIteration:
        return None
    rows = []
    for line in lines[start + 1:]:
        if line == "\\.":
            break
        rows.append(line.strip())
    return rows[0] if len(rows) == 1 else None


def check_pg_dump(src: Path, *, pg_restore: str, env: dict | None = None) -> tuple[str, str]:
    """The revision of the ``pg_dump -Fc`` archive ``src`` and its checked list of entries (for
    ``pg_restore --use-list``) once it holds only the migrations' objects at that revision;
    :class:`UnsafeBackup` otherwise."""
    proc = subprocess.run([pg_restore, "--list", str(src)], capture_output=True, text=True, env=env, timeout=120, check=False)
    if proc.returncode != 0:
        detail = " ".join(proc.stderr.strip().splitlines()[-2:]) or f"exit status {proc.returncode}"
        raise UnsafeBackup(f"{src} is not a readable pg_dump archive ({detail}): refused, nothing was written")
    revision = _pg_revision(src, pg_restore, env)
    if revision is None:
        raise UnsafeBackup(f"{src} has no single schema revision (alembic_version): not a trajlab database; "
                           "refused, nothing was written")
    ref = _known(revision, str(src))
    checked, unexpected = [], set()
    for line in proc.stdout.splitlines():
        if not line.strip() or line.startswith(";"):
            checked.append(line)
            continue
        m = _ENTRY.match(line)
        rest = m.group(4) if m else ""
        kind = next((t for t in _TYPES if rest.startswith(t + " ")), None)
        if kind is not None:
            words = rest[len(kind) + 1:].split(" ")
            schema, tag = words[0], " ".join(words[1:-1])   # the last word is the owner
            if _entry_ok(kind, schema, tag, ref):
                checked.append(line)
                continue
        unexpected.add(rest.rsplit(" ", 1)[0] if rest else line)
    if unexpected:
        raise UnsafeBackup(f"{src} holds objects the migrations at revision {revision} do not make "
                           f"({_names(unexpected)}): refused, nothing was written")
    return revision, "\n".join(checked) + "\n"
