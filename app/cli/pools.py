"""The worker's process pools: quick jobs keep solver processes of their own.

One Celery pool that consumes both queues starves quick jobs: once every slot holds a heavy job (a
takeover after a cut-off host re-queues several at once), no quick job runs until one of them ends
(issue 30: 72-76 s with 489 quick jobs waiting).  So a worker started for both queues (``trajlab
worker``, ``trajlab serve``) is two Celery workers side by side:

* ``quick-<name>``: ``TRAJLAB_QUICK_CONCURRENCY`` processes on the quick queue only, reserved for it;
* ``<name>``: ``TRAJLAB_WORKER_CONCURRENCY`` processes on the heavy queue and the quick queue, so heavy
  capacity idles only when there is no work at all.

``--queues jobs`` or ``--queues heavy`` is one pool on that queue (the production compose's split);
``TRAJLAB_QUICK_CONCURRENCY=0`` is the old single pool on both (it can starve).
"""
from __future__ import annotations

import signal
import subprocess
import sys
import threading

from app.runtime.embedded import exit_with_parent
from app.service.broker import QUEUE_HEAVY, QUEUE_JOBS, QUEUES

QUEUE_CHOICES = {"both": QUEUES, "jobs": (QUEUE_JOBS,), "heavy": (QUEUE_HEAVY,)}


def celery_worker(*, name: str, queues: tuple[str, ...], concurrency: int, loglevel: str = "WARNING") -> list[str]:
    # WARNING by default: an idle worker logs nothing (INFO adds lines for every delivery and heartbeat).
    return [sys.executable, "-m", "celery", "-A", "worker.celery_app:celery_app", "worker",
            f"--loglevel={loglevel}", f"--concurrency={concurrency}", "-n", name, "-Q", ",".join(queues)]


def worker_pools(settings, *, name: str, queues: str = "both", loglevel: str = "WARNING") -> dict[str, list[str]]:
    """The Celery worker commands of one ``trajlab worker`` (module docstring), by pool name."""
    if queues != "both" or settings.quick_concurrency == 0:
        return {name: celery_worker(name=name, queues=QUEUE_CHOICES[queues], concurrency=settings.worker_concurrency,
                                    loglevel=loglevel)}
    return {f"quick-{name}": celery_worker(name=f"quick-{name}", queues=(QUEUE_JOBS,),
                                           concurrency=settings.quick_concurrency, loglevel=loglevel),
            name: celery_worker(name=name, queues=(QUEUE_HEAVY, QUEUE_JOBS), concurrency=settings.worker_concurrency,
                                loglevel=loglevel)}


def run_pools(commands: dict[str, list[str]]) -> int:
    """Run the pools in the foreground until one exits or SIGTERM/SIGINT arrives; then stop every pool (a
    warm shutdown: SIGTERM, running jobs finish) and return the first exit code, so the process manager
    (systemd, compose) restarts the worker as a whole.  The pools stay in this process group (a signal
    to the group, a terminal's Ctrl-C or a kill of the group, reaches them as it would one Celery
    worker) and die with this process if it is killed alone."""
    # preexec_fn before any thread of ours starts (PLW1509: unsafe only with threads running)
    procs = [subprocess.Popen(cmd, preexec_fn=exit_with_parent) for cmd in commands.values()]  # noqa: PLW1509
    ended = threading.Event()
    for sig in (signal.SIGTERM, signal.SIGINT):
        signal.signal(sig, lambda *_: ended.set())
    code = None
    while code is None:
        code = next((p.returncode for p in procs if p.poll() is not None), None)
        if code is None and ended.wait(0.5):
            code = 0
    for proc in procs:
        if proc.poll() is None:
            proc.send_signal(signal.SIGTERM)
    for proc in procs:
        proc.wait()
    return code
