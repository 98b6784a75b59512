"""Alembic on the embedded SQLite database: upgrade, check, downgrade, upgrade again."""
from __future__ import annotations

from alembic import command
from sqlalchemy import inspect

from app.runtime.db import make_engine
from app.runtime.migrate import alembic_config, check, upgrade


def test_upgrade_check_downgrade_roundtrip(tmp_path):
    url = f"sqlite:///{tmp_path / 'm.db'}"
    upgrade(url)
    check(url)  # models and migrations agree
    engine = make_engine(url)
    assert {"jobs", "job_results"} <= set(inspect(engine).get_table_names())
    command.downgrade(alembic_config(url), "base")
    assert "jobs" not in set(inspect(engine).get_table_names())
    upgrade(url)
    assert "jobs" in set(inspect(engine).get_table_names())
    with engine.connect() as conn:
        assert conn.exec_driver_sql("PRAGMA journal_mode").scalar() == "wal"
    engine.dispose()
