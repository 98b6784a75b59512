"""The recovery duties in every worker: a candidate for the recovery lease in Celery's main process.

``worker_ready`` and ``worker_shutdown`` fire in the main process only, so with the prefork pool there
is one candidate per worker node, never one per pool child.  Its thread runs
:class:`app.service.recovery.Recovery` under the lease (that module says how the lease works); a warm
shutdown gives the lease up, a killed worker's lease expires after ``recovery_lease_s``.

Pool children are forked from this process while the thread runs (a child is replaced after
``worker_max_tasks_per_child`` jobs or when it dies).  The thread does not exist in a child; what it
owns must not be used there: its database engine is its own (not the cached one the tasks use), and a
child drops every Database's pooled connections without closing them (app.runtime.db does it for every
Database at a fork), and redis-py's pools reconnect on a change of pid by themselves.
``TRAJLAB_RECOVERY_IN_WORKER=false`` leaves recovery to ``trajlab recover`` and ``trajlab serve``.
"""
from __future__ import annotations

import logging
import threading

from celery import current_app, signals

from app.runtime.db import Database
from app.runtime.settings import get_settings
from app.service.recovery import Recovery

log = logging.getLogger("trajlab.recovery")
_running: list[tuple[Recovery, threading.Thread]] = []


@signals.worker_ready.connect
def start(**_) -> None:
    settings = get_settings()
    if not settings.recovery_in_worker or _running:
        return
    db = Database(settings.database_url, settings)   # forgotten in forked children by app.runtime.db
    worker_app = current_app._get_current_object()
    recovery = Recovery(settings, db)
    worker_app.set_current()  # Recovery's producer-only Celery app made itself the current one: the worker's is
    _running.append((recovery, recovery.start_thread()))


@signals.worker_shutdown.connect
def stop(**_) -> None:
    while _running:
        recovery, thread = _running.pop()
        recovery.stop()
        thread.join(timeout=10)  # it gives the lease up on its way out
