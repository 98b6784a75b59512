"""Alembic migrations for the trajlab database (SQLite and PostgreSQL)."""
