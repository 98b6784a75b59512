"""FastAPI dependency aliases: the settings, the database, the Celery app and the publisher of this process.

They are ``async``: FastAPI runs a plain ``def`` dependency in its thread pool, one hop (a thread hand-off
and back, measured at a quarter of a GET's CPU) per dependency per request, to read an attribute."""
from __future__ import annotations

from typing import Annotated

from celery import Celery
from fastapi import Depends, Request

from app.runtime.db import Database
from app.runtime.settings import Settings
from app.service.publisher import Publisher


async def _settings(request: Request) -> Settings:
    return request.app.state.settings


async def _database(request: Request) -> Database:
    return request.app.state.db


async def _celery(request: Request) -> Celery:
    return request.app.state.celery


async def _publisher(request: Request) -> Publisher:
    return request.app.state.publisher


SettingsDep = Annotated[Settings, Depends(_settings)]
DatabaseDep = Annotated[Database, Depends(_database)]
CeleryDep = Annotated[Celery, Depends(_celery)]
PublisherDep = Annotated[Publisher, Depends(_publisher)]
