"""Service settings, read from ``TRAJLAB_*`` environment variables (pydantic-settings).

The defaults are the embedded single-machine shape (SQLite file under ``var/``,
a broker URL filled in by ``trajlab serve`` from its embedded Redis); production
sets ``TRAJLAB_DATABASE_URL`` and ``TRAJLAB_BROKER_URL`` to PostgreSQL and Redis.
"""
from __future__ import annotations

import math
import os
import re
from functools import lru_cache
from pathlib import Path
from typing import Literal

from pydantic import Field, model_validator
from dotenv import dotenv_values
from pydantic_settings import BaseSettings, SettingsConfigDict

from app.runtime.resources import default_job_memory_mb

DEFAULT_DATA_DIR = Path("var")
_TIME_LIMIT_VAR = re.compile(r"TRAJLAB_TIME_LIMIT_([A-Z0-9_]+)_S")


class Settings(BaseSettings):
    model_config = SettingsConfigDict(env_prefix="TRAJLAB_", env_file=".env", extra="ignore")

    database_url: str = Field(
        default="",
        description="SQLAlchemy URL: sqlite:///path (embedded) or postgresql+psycopg://user@host/db; "
                    "unset: trajlab.db in data_dir",
    )
    broker_url: str = Field(
        default="redis://127.0.0.1:6379/0",
        description="Celery broker: redis://host:port/db or redis+socket:///path/redis.socket",
    )
    data_dir: Path = Field(default=DEFAULT_DATA_DIR, description="Embedded mode: SQLite file, Redis socket, logs")
    min_free_disk_mb: float = Field(
        default=32.0, ge=0, description="/readyz is 503 when the SQLite database's filesystem or the embedded data "
                                        "directory has less than this free (app.runtime.disk)")
    worker_concurrency: int = Field(default=1, ge=1, description="Solver processes per worker (heavy and quick jobs)")
    quick_concurrency: int = Field(
        default=1, ge=0, description="Solver processes a worker started for both queues reserves for quick jobs "
                                     "(app.cli.pools); 0: one pool for both, which heavy jobs can fill")
    # One process serves at most one core (the GIL): on PostgreSQL a single process spent its core on
    # Python while PostgreSQL and the clients had the other (benchmarks/api_load.py, 2 cores).  Two, not
    # one per core: each keeps a pool of up to 16 connections (app.runtime.db) of PostgreSQL's 100 by default.
    api_workers: int = Field(default=2, ge=1, description="`trajlab api` processes (uvicorn workers) on one port")
    log_format: Literal["text", "json"] = Field(
        default="text", description="json: one JSON object per log line (time, level, logger, message, request_id, "
                                    "job_id, kind, owner), for a log collector")
    metrics_public: bool = Field(
        default=False, description="GET /metrics without an admin key while TRAJLAB_AUTH=required (a scraper "
                                   "on a private network)")
    access_log: bool = Field(default=False, description="`trajlab api` writes one log line per request (uvicorn's "
                                                         "access log; it costs about a tenth of a request's CPU)")

    # Per-kind Celery time limits (s). The soft limit raises inside the task so the
    # job fails with code time_limit and a message; the hard limit kills the child.
    # Each kind declares its own (KindSpec.time_limit_s); TRAJLAB_TIME_LIMIT_<KIND>_S
    # overrides it, collected into time_limits_s below (app.service.broker.time_limit_s merges the two:
    # the runtime never imports the kinds).
    time_limits_s: dict[str, float] = Field(
        default_factory=dict, description="Soft time limit overrides by kind; set as TRAJLAB_TIME_LIMIT_<KIND>_S")
    hard_time_limit_margin_s: float = 60.0

    # Worker liveness: a running job writes heartbeat_at every heartbeat_interval_s;
    # the reaper re-queues a running job whose heartbeat is older than stale_after_s.
    heartbeat_interval_s: float = 2.0
    stale_after_s: float = 60.0
    reaper_interval_s: float = Field(default=15.0, description="Period of the recovery loop (reaper, re-publisher)")
    republish_after_s: float = Field(
        default=30.0, description="A queued job published longer ago than this and missing from the broker is re-sent")
    # The recovery duties run in every worker's main process (and trajlab serve, trajlab recover) under a
    # lease in the database (app.service.lease): its holder renews it every third of its length; when the
    # holder dies another candidate takes over within about 4/3 of it.  /readyz reports the recovery
    # heartbeat stale past one length.
    recovery_lease_s: float = Field(
        default=10.0, ge=1, description="Length of the recovery lease: a dead holder is replaced within about "
                                        "4/3 of it, and /readyz is 503 when no holder renewed it for this long")
    recovery_in_worker: bool = Field(
        default=True, description="Each Celery worker's main process is a candidate for the recovery lease "
                                  "(false: only trajlab recover and trajlab serve run recovery)")
    db_retry_max_s: float = Field(
        default=30.0, description="Longest backoff of a worker retrying a delivery while the database is down")
    max_attempts: int = Field(default=3, ge=1, description="Deliveries of one job before it fails with worker_lost")

    # Timeouts on every network call (README "Network clients and their timeouts"): a call over a dead
    # link fails within its bound instead of waiting for the kernel (tcp_retries2: about 15 minutes), so
    # the worker's store retry (worker.tasks._store: up to stale_after_s) runs as written and a worker
    # cut off from the database gives its slot up within stale_after_s + db_tcp_user_timeout_s.
    db_connect_timeout_s: int = Field(default=5, ge=2, description="PostgreSQL: libpq connect_timeout (min. 2)")
    db_tcp_user_timeout_s: float = Field(
        default=10.0, gt=0, description="PostgreSQL: tcp_user_timeout, the longest data may stay unacknowledged")
    db_keepalives_idle_s: int = Field(default=5, ge=1, description="PostgreSQL: idle seconds before a keepalive")
    db_keepalives_interval_s: int = Field(default=2, ge=1, description="PostgreSQL: seconds between keepalives")
    db_keepalives_count: int = Field(default=3, ge=1, description="PostgreSQL: keepalives lost before the link is dead")
    db_statement_timeout_s: float = Field(
        default=30.0, gt=0, description="PostgreSQL: statement_timeout of the service's own queries (migrations "
                                        "run without it)")
    db_pool_timeout_s: float = Field(default=10.0, gt=0, description="Wait for a pooled database connection")
    redis_socket_timeout_s: float = Field(
        default=5.0, gt=1, description="Redis: a command's reply (above kombu's 1 s BRPOP timeout)")
    redis_connect_timeout_s: float = Field(default=3.0, gt=0, description="Redis: TCP connect")
    broker_probe_interval_s: float = Field(
        default=1.0, gt=0, description="API: the broker is PINGed this often (app.service.breaker); a silent loss "
                                       "is noticed within this plus the probe timeout, and no request waits on it")
    broker_probe_timeout_s: float = Field(
        default=1.0, gt=0, description="API: the reply bound of that PING (/readyz's and /metrics' own Redis calls "
                                       "wait at most 0.25 s of it)")
    redis_health_check_interval_s: int = Field(
        default=10, ge=0, description="Redis: a connection idle this long is pinged before use; kombu also drops "
                                      "a BRPOP connection overdue by this much")

    # Caps that keep one request from exhausting the machine.
    job_memory_mb: int | None = Field(
        default=None, ge=0, description="Resident memory one job may hold (worker.guard): past it the job fails "
                                        "with resource_limit and a job estimated past it is a 422; unset: "
                                        "(memory - memory_reserve_mb) / (job_processes x 1.55), so that every "
                                        "process of the host can hold a job at its cap, 5% overshoot and half a "
                                        "cap of an earlier job's leftovers at once (app.runtime.resources); 0: no cap")
    job_processes: int | None = Field(
        default=None, ge=1, description="Solver processes of every worker pool on this host, for the default "
                                        "job_memory_mb; unset: worker_concurrency + quick_concurrency (one "
                                        "`trajlab worker`)")
    memory_reserve_mb: int | None = Field(
        default=None, ge=0, description="Memory kept for everything but the jobs (PostgreSQL, Redis, the API, the "
                                        "Celery parents, the kernel), for the default job_memory_mb; unset: 1/8 "
                                        "of the machine's memory, at least 1024")
    worker_recycle_mb: int | None = Field(
        default=None, ge=0, description="A worker process holding more than this after a job is replaced "
                                        "(Celery's worker_max_memory_per_child); unset: half of job_memory_mb")
    max_grid_intervals: int = Field(default=1000, description="reentry/robust_reentry grid.intervals cap")
    max_grid_refinements: int = Field(default=20, ge=0, description="reentry grid.max_refinements cap "
                                      "(mesh-refinement rounds when accuracy is set)")
    lambert_max_problems: int = Field(default=100_000, description="POST /v1/lambert problems per request")
    monte_carlo_max_samples: int = Field(default=1_000_000)
    monte_carlo_chunk_samples: int = Field(
        default=50_000, description="Above this many samples a Monte Carlo is split across workers"
    )
    # The ocp kind's limits (shared/specs/ocp.md): a problem past one is a 422 naming the setting.
    ocp_max_expression_chars: int = Field(default=2000, ge=1, description="ocp: characters per expression")
    ocp_max_expression_nodes: int = Field(default=400, ge=1, description="ocp: parse-tree nodes per expression")
    ocp_max_states: int = Field(default=50, ge=1, description="ocp: states per problem")
    ocp_max_controls: int = Field(default=20, ge=0, description="ocp: controls per problem")
    ocp_max_parameters: int = Field(default=20, ge=0, description="ocp: static parameters per problem")
    ocp_max_expressions: int = Field(default=200, ge=0, description="ocp: named expressions per problem")
    ocp_max_tables: int = Field(default=50, ge=0, description="ocp: tables per problem")
    ocp_max_table_values: int = Field(default=100_000, ge=1, description="ocp: values per table")
    ocp_max_intervals: int = Field(default=1000, ge=1, description="ocp: transcription.intervals")
    ocp_max_constraints: int = Field(default=200, ge=0, description="ocp: path (and boundary) constraints")
    ocp_max_starts: int = Field(default=16, ge=1, description="ocp: search.starts (initial guesses, each a solve)")
    ocp_max_monte_carlo_samples: int = Field(default=100_000, ge=100, description="ocp: robust.monte_carlo.samples")
    ocp_max_refinements: int = Field(default=20, ge=0, description="ocp: transcription.max_refinements "
                                     "(mesh-refinement rounds when accuracy is set)")

    # Security (README "Security"). Required unless switched off: `trajlab serve` on a
    # loopback address switches it off (one local user) and says so at start.
    auth: Literal["required", "off"] = Field(
        default="required", description="required: every /v1 request needs `Authorization: Bearer KEY`; "
                                         "off: no keys, every caller sees every job (local use only)")
    auth_max_failures: int = Field(
        default=10, ge=1, description="Failed API-key attempts one client address may make per "
                                      "auth_failure_window_s before it is answered 429 (app.api.key_attempts)")
    auth_failure_window_s: float = Field(default=60.0, gt=0, description="Window of auth_max_failures (s)")
    trusted_proxies: str = Field(
        default="", description="Addresses (IPs or CIDR networks, comma-separated; * for any) of the reverse "
                                "proxies whose X-Forwarded-For and X-Forwarded-Proto are believed: the client "
                                "address of the failed-key limit and the logs. Empty (default): none, the peer's "
                                "address is the client's")
    max_body_bytes: int = Field(default=1_048_576, ge=0, description="Request body cap (413 before parsing)")
    max_queued_per_owner: int = Field(default=10, ge=1, description="Queued jobs one owner may have (429 past it)")
    max_active_per_owner: int = Field(default=20, ge=1, description="Queued + running jobs of one owner (429)")
    max_active_cost_per_owner: float = Field(
        default=100_000.0, gt=0, description="Budget of estimated cost (app.service.quota) over an owner's queued + "
                                             "running jobs; one job alone may exceed it")
    heavy_cost: float = Field(default=5_000.0, gt=0, description="Jobs estimated above this go to the heavy queue")
    # Read by the registry (app.kinds) from the environment when it is first imported, before any Settings
    # exists: the submission schema is built from the registry then.  Declared here to be listed and documented.
    extra_kinds: str = Field(default="", description="Kinds outside app/kinds: comma-separated module paths, each "
                                                     "module with a SPEC (a KindSpec), registered in the API process "
                                                     "and every worker (set it for both)")
    quota_retry_after_s: int = Field(default=30, ge=1, description="Retry-After of a 429")
    # What the service keeps (README "Limits and data"; app.service.storage, app.service.retention).
    max_stored_mb_per_owner: float | None = Field(
        default=None, gt=0, description="Storage quota: MiB of params and (compressed) results one owner's jobs "
                                        "may keep; a submission past it is a 429 (unset: no quota)")
    retention_days: float | None = Field(
        default=None, gt=0, description="Finished jobs (and finished studies) older than this many days are "
                                        "deleted by the recovery loop (unset: kept until deleted)")
    retention_interval_s: float = Field(
        default=600.0, gt=0, description="How often the recovery loop applies TRAJLAB_RETENTION_DAYS")

    @model_validator(mode="after")
    def _embedded_database_in_data_dir(self) -> "Settings":
        # TRAJLAB_DATA_DIR moves everything the embedded mode writes, the SQLite file included.
        if not self.database_url:
            self.database_url = f"sqlite:///{Path(self.data_dir) / 'trajlab.db'}"
        return self

    @model_validator(mode="after")
    def _memory_from_the_machine(self) -> "Settings":
        if self.job_memory_mb is None:
            self.job_memory_mb = default_job_memory_mb(
                processes=self.job_processes or self.worker_concurrency + self.quick_concurrency,
                reserve=self.memory_reserve_mb, recycle_mb=self.worker_recycle_mb)
        if self.worker_recycle_mb is None:
            self.worker_recycle_mb = self.job_memory_mb // 2
        return self

    @model_validator(mode="after")
    def _time_limit_overrides(self) -> "Settings":
        # Per-kind variables are not fields (a kind must not need a line here), so they
        # are read by pattern: the environment wins over the .env file, as for fields.
        found = {**dotenv_values(".env"), **os.environ} if Path(".env").is_file() else dict(os.environ)
        for name, value in found.items():
            m = _TIME_LIMIT_VAR.fullmatch(name.upper())
            if m and value is not None:
                kind = m.group(1).lower()
                limit = float(value)
                if not (limit > 0 and math.isfinite(limit)):
                    raise ValueError(f"{name} must be a positive number of seconds")
                self.time_limits_s.setdefault(kind, limit)
        return self



@lru_cache
def get_settings() -> Settings:
    return Settings()
