"""FastAPI dependency aliases: the settings, the database and the Celery app of this process."""
from __future__ import annotations

from typing import Annotated

from celery import Celery
from fastapi import Depends, Request

from app.db import Database
from app.settings import Settings


def _settings(request: Request) -> Settings:
    return request.app.state.settings


def _database(request: Request) -> Database:
    return request.app.state.db


def _celery(request: Request) -> Celery:
    return request.app.state.celery


SettingsDep = Annotated[Settings, Depends(_settings)]
DatabaseDep = Annotated[Database, Depends(_database)]
CeleryDep = Annotated[Celery, Depends(_celery)]
