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

import logging
import signal
import subprocess
import sys
import threading
import time

from app.runtime.embedded import exit_with_parent
from app.service.broker import QUEUE_HEAVY, QUEUE_JOBS, QUEUES

log = logging.getLogger("trajlab")
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


def run_pools(commands: dict[str, list[str]], *, backoff_max_s: float = 30.0, healthy_after_s: float = 60.0) -> int:
    """Run the pools in the foreground until SIGTERM/SIGINT arrives; then stop every pool (a warm
    shutdown: SIGTERM, running jobs finish) and return 0.

    ``trajlab worker`` supervises its pools, so a worker started by hand (the README's way) survives a
    pool that dies: one that exits with an error or a signal (an unrecoverable broker error, the OOM
    killer) is started again after a backoff of 0.5 s doubling up to ``backoff_max_s``, back to 0.5 s once
    it has run ``healthy_after_s``.  Issue 27: a worker started by hand died of a full Redis and 1,764
    accepted jobs stayed queued.  A pool that exits 0 on its own (Celery's remote shutdown) stops the
    worker, with that status.  The pools stay in this process group (a signal to the group, a terminal's
    Ctrl-C or a kill of the group, reaches them as it would one Celery worker) and die with this process
    if it is killed alone; systemd or compose restart this process in turn (deploy/systemd,
    docker-compose.yml)."""
    def spawn(cmd: list[str]) -> subprocess.Popen:
        # preexec_fn while no thread of ours runs (PLW1509: unsafe only with threads running)
        return subprocess.Popen(cmd, preexec_fn=exit_with_parent)  # noqa: PLW1509

    procs: dict[str, subprocess.Popen | None] = {name: spawn(cmd) for name, cmd in commands.items()}
    started = dict.fromkeys(commands, time.monotonic())
    backoff = dict.fromkeys(commands, 0.5)
    restart_at: dict[str, float] = {}
    ended = threading.Event()
    for sig in (signal.SIGTERM, signal.SIGINT):
        signal.signal(sig, lambda *_: ended.set())
    while not ended.wait(0.5):
        now = time.monotonic()
        for name, proc in procs.items():
            if proc is None:
                if now >= restart_at[name]:
                    procs[name], started[name] = spawn(commands[name]), now
                continue
            status = proc.poll()
            if status is None:
                continue
            if status == 0:
                ended.set()
                break
            if now - started[name] >= healthy_after_s:
                backoff[name] = 0.5
            log.warning("worker pool %s exited with %s; starting it again in %.1f s", name, status, backoff[name])
            procs[name], restart_at[name] = None, now + backoff[name]
            backoff[name] = min(2 * backoff[name], backoff_max_s)
    for proc in procs.values():
        if proc is not None and proc.poll() is None:
            proc.send_signal(signal.SIGTERM)
    for proc in procs.values():
        if proc is not None:
            proc.wait()
    return 0
