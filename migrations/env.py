"""Alembic environment: URL from app.runtime.settings (or -x url=...), batch mode on SQLite."""
from __future__ import annotations

from alembic import context

from app.runtime.db import make_engine
from app.runtime.models import Base
from app.runtime.settings import get_settings

config = context.config


def _url() -> str:
    return context.get_x_argument(as_dictionary=True).get("url") or config.attributes.get("url") or get_settings().database_url


def run_migrations_offline() -> None:
    url = _url()
    context.configure(url=url, target_metadata=Base.metadata, literal_binds=True,
                      render_as_batch=url.startswith("sqlite"), compare_type=True)
    with context.begin_transaction():
        context.run_migrations()


def run_migrations_online() -> None:
    url = _url()
    engine = make_engine(url, statement_timeout=False)  # a migration may run longer than a query
    with engine.connect() as connection:
        sqlite = connection.dialect.name == "sqlite"
        if sqlite:
            # A batch migration copies a table and drops the old one; with foreign keys on (app.runtime.db)
            # dropping ``jobs`` deletes every job_results row by ON DELETE CASCADE (0004 did, issue 36).
            # The pragma is a no-op inside a transaction, so it goes to the driver's connection before the
            # migrations' transaction begins; the keys are checked when they are done instead.
            connection.connection.driver_connection.execute("PRAGMA foreign_keys=OFF")
        context.configure(connection=connection, target_metadata=Base.metadata,
                          render_as_batch=sqlite, compare_type=True)
        with context.begin_transaction():
            context.run_migrations()
            if sqlite:
                broken = connection.exec_driver_sql("PRAGMA foreign_key_check").fetchall()
                if broken:   # an upgrade that broke a key stops, naming the rows
                    raise RuntimeError(f"the migrations left rows whose foreign key points nowhere: {broken[:5]}")
    engine.dispose()


if context.is_offline_mode():
    run_migrations_offline()
else:
    run_migrations_online()
