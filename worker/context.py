"""The JobContext a running job sees: progress, cancellation, warm-start lookups.

Solvers call ``progress`` and ``should_stop`` from their iteration callbacks,
which can fire hundreds of times a second; both only touch memory.  A
background thread does the I/O: every ``heartbeat_interval_s`` it writes the
heartbeat and the latest progress to the job row and reads back the cancel
flag.  A job can therefore be cancelled within about one interval, and a solve
that sits inside a long native call still keeps its heartbeat fresh.
"""
from __future__ import annotations

import threading
import time

from app.service import jobs
from app.service.broker import redis_client, time_limit_s
from app.runtime.db import Database
from app.runtime.settings import Settings


class WorkerJobContext:
    def __init__(self, db: Database, claim: jobs.Claim, *, settings: Settings, celery=None):
        self.db = db
        self.settings = settings
        self.celery = celery
        self.job_id = claim.job_id
        self.attempt = claim.attempt
        self.interval = settings.heartbeat_interval_s
        self.deadline = time.monotonic() + time_limit_s(settings, claim.kind)
        self._progress = 0.0
        self._message: str | None = None
        self._stage: str | None = None
        self._round: int | None = None
        self.cancel_requested = False
        self.lost = False
        self._done = threading.Event()
        self._thread = threading.Thread(target=self._beat, name=f"heartbeat-{self.job_id}", daemon=True)

    # --- what the kind's run() uses -------------------------------------------------
    def progress(self, fraction: float, message: str) -> None:
        self._progress = max(self._progress, min(max(float(fraction), 0.0), 1.0))
        self._message = message
        # a solve that declares its stages (solvers.progress.ProgressMessage) names the one it is in; any
        # other message (a kind's own words, a stage-less solver) is in no declared stage
        stage = getattr(message, "stage", None)
        self._stage = None if stage is None else str(stage)
        self._round = getattr(message, "round", None) if stage is not None else None

    def should_stop(self) -> bool:
        return self.cancel_requested or self.lost or self.deadline_passed

    @property
    def deadline_passed(self) -> bool:
        return time.monotonic() > self.deadline

    def load_result(self, job_id: str) -> dict:
        job = jobs.get_job(self.db, job_id)
        if job is None or not self._may_read(job):
            # another owner's job reads as one that does not exist, as it does over HTTP
            raise LookupError(f"job {job_id} does not exist")
        if job.status != "succeeded":
            raise LookupError(f"job {job_id} is {job.status}; only a succeeded job can be used")
        result = jobs.get_result(self.db, job_id)
        if result is None:
            raise LookupError(f"job {job_id} has no stored result")
        return result

    def _may_read(self, job) -> bool:
        """Owners are kept apart in warm starts too: a job reads only its own owner's results
        (with auth off every job's owner is None, and every job is everyone's)."""
        own = jobs.get_job(self.db, self.job_id)
        return own is None or own.owner is None or job.owner == own.owner

    def run_monte_carlo(self, spec: dict, samples: int, seed: int, chunk_size: int | None = None) -> dict:
        """Monte Carlo of a JSON spec; above ``monte_carlo_chunk_samples`` split across the workers."""
        threshold = self.settings.monte_carlo_chunk_samples
        if self.celery is None or samples <= threshold:
            from solvers.uncertainty.montecarlo import run_monte_carlo

            return run_monte_carlo(spec, samples, seed, chunk_size)
        from worker import fanout

        return fanout.run_distributed(self.celery, redis_client(self.settings.broker_url, settings=self.settings),
                                      spec=spec, samples=samples, seed=seed,
                                      chunk_size=int(chunk_size or threshold), should_stop=self.should_stop,
                                      job=self.bounds())

    def run_pieces(self, fn, spec: dict, count: int, *, label: str, on_progress=None) -> list[dict]:
        """A job's pieces (``JobContext.run_pieces``): fanned out across the workers (``worker/pieces.py``),
        here alone without a broker."""
        from app.kinds.base import run_pieces_here

        if self.celery is None or count <= 1:
            return run_pieces_here(fn, spec, count, label=label, should_stop=self.should_stop,
                                   progress=on_progress or self.progress)
        import socket

        from worker import pieces

        return pieces.run_distributed(self.celery, redis_client(self.settings.broker_url, settings=self.settings),
                                      fn, spec, count, label=label, who=f"job@{socket.gethostname()}",
                                      should_stop=self.should_stop, on_progress=on_progress or self.progress,
                                      job=self.bounds())

    def bounds(self) -> dict:
        """What a share of this job's work run by another worker process needs to be held to its bounds
        (worker.tasks: its guard): the job, the attempt a breach fails, and its deadline on the wall clock."""
        return {"id": self.job_id, "attempt": self.attempt, "ends_at": time.time() + (self.deadline - time.monotonic())}

    # --- plumbing ---------------------------------------------------------------------
    def _write(self) -> None:
        flag = jobs.heartbeat(self.db, self.job_id, self.attempt, progress=self._progress, message=self._message,
                              stage=self._stage, stage_round=self._round)
        if flag is None:
            self.lost = True  # another delivery took the job over, or it was finished elsewhere
        else:
            self.cancel_requested = flag

    def _beat(self) -> None:
        while not self._done.wait(self.interval):
            try:
                self._write()
            except Exception:  # a transient database error must not kill the solve
                pass

    def __enter__(self) -> "WorkerJobContext":
        self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self._done.set()
        self._thread.join(timeout=10)
