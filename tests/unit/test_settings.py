"""Settings: TRAJLAB_DATA_DIR moves the embedded SQLite file; an explicit URL wins."""
from __future__ import annotations

from app.runtime.settings import Settings


def test_data_dir_moves_the_sqlite_file(monkeypatch, tmp_path):
    monkeypatch.delenv("TRAJLAB_DATABASE_URL", raising=False)
    monkeypatch.setenv("TRAJLAB_DATA_DIR", str(tmp_path / "elsewhere"))
    assert Settings().database_url == f"sqlite:///{tmp_path / 'elsewhere' / 'trajlab.db'}"


def test_an_explicit_database_url_wins(monkeypatch, tmp_path):
    monkeypatch.setenv("TRAJLAB_DATA_DIR", str(tmp_path))
    monkeypatch.setenv("TRAJLAB_DATABASE_URL", "postgresql+psycopg://u@h/db")
    assert Settings().database_url == "postgresql+psycopg://u@h/db"
