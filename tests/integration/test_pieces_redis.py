"""A job's pieces (``worker/pieces.py``) claimed in real Redis: a claim held by a live computer is renewed
past its lease, a claim whose computer died lapses and the piece is computed by whoever asks next, and a
done piece is never computed again."""
from __future__ import annotations

import json
import threading
import time
import uuid

import pytest
import redis

from app.kinds.base import piece
from worker import pieces

pytestmark = pytest.mark.integration
CALLS: list[int] = []


@piece
def slow_square(spec: dict, index: int, should_stop) -> dict:
    CALLS.append(index)
    time.sleep(spec["sleep_s"])
    return {"square": index * index}


@pytest.fixture
def run(redis_url, monkeypatch):
    monkeypatch.setattr(pieces, "LEASE_S", 1.5)
    r = redis.Redis.from_url(redis_url)
    run_id = uuid.uuid4().hex
    keys = pieces._keys(run_id)
    r.set(keys["spec"], json.dumps({"name": f"{__name__}:slow_square", "spec": {"sleep_s": 2.5}}))
    CALLS.clear()
    yield r, run_id, keys
    r.delete(*keys.values(), *[f"{keys['claim']}:{i}" for i in range(3)])


def test_a_live_claim_is_renewed_and_a_done_piece_is_not_computed_again(run):
    r, run_id, keys = run
    first = threading.Thread(target=pieces.compute_piece, args=(r, run_id, 0), kwargs={"who": "a"})
    first.start()
    time.sleep(2.0)                      # past the 1.5 s lease: renewed while the piece runs
    assert pieces.compute_piece(r, run_id, 0, who="b") is False
    first.join()
    assert json.loads(r.hget(keys["results"], "0")) == {"by": "a", "output": {"square": 0}}
    assert pieces.compute_piece(r, run_id, 0, who="b") is False and CALLS == [0]


def test_a_dead_claimers_piece_is_computed_once_its_lease_lapses(run):
    r, run_id, keys = run
    r.set(f"{keys['claim']}:1", "dead", ex=1)       # claimed by a worker that died: nobody renews it
    assert pieces.compute_piece(r, run_id, 1, who="b") is False
    time.sleep(1.2)
    assert pieces.compute_piece(r, run_id, 1, who="b") is True
    assert json.loads(r.hget(keys["results"], "1")) == {"by": "b", "output": {"square": 1}} and CALLS == [1]


@piece
def index_of(spec: dict, index: int, should_stop) -> dict:
    return {"index": index}


WAIT_COMMANDS = ("hexists", "set", "hlen", "hkeys", "mget", "exists")


def test_the_job_waits_on_the_others_pieces_with_one_read_per_round(tmp_path, monkeypatch):
    """A job whose pieces all but one are held by other workers reads Redis once per round for all of them
    (counted by a redis-server of the test's own), not once per piece."""
    from types import SimpleNamespace

    from app.runtime.settings import Settings
    from app.service.broker import create_publisher
    from tests.faults.servers import RedisServer

    server = RedisServer(tmp_path).start()
    try:
        r = redis.Redis.from_url(server.url)
        count, run_id = 20, uuid.uuid4().hex
        monkeypatch.setattr(pieces, "uuid", SimpleNamespace(uuid4=lambda: SimpleNamespace(hex=run_id)))
        keys = pieces._keys(run_id)
        for i in range(1, count):  # held by live workers (their leases renewed): the job waits for them
            r.set(f"{keys['claim']}:{i}", "other", px=60_000)

        def the_others_finish():
            time.sleep(1.5)
            for i in range(1, count):
                r.hset(keys["results"], str(i), json.dumps({"by": "other", "output": {"index": i}}))

        threading.Thread(target=the_others_finish, daemon=True).start()
        out: list = []
        job = threading.Thread(target=lambda: out.append(pieces.run_distributed(
            create_publisher(Settings(database_url="sqlite://", broker_url=server.url)), r, index_of, {}, count,
            label="piece", who="job", should_stop=lambda: False, on_progress=lambda *_: None)))
        job.start()
        time.sleep(0.3)  # the job computed piece 0 and waits
        r.config_resetstat()
        start = time.monotonic()
        time.sleep(1.0)
        stats = r.info("commandstats")
        window = time.monotonic() - start
        commands = sum(int(stats.get(f"cmdstat_{c}", {}).get("calls", 0)) for c in WAIT_COMMANDS)
        job.join(timeout=30)
        assert out and [o["index"] for o in out[0]] == list(range(count))
        assert [o["by"] for o in out[0]] == ["job"] + ["other"] * (count - 1)
        # a round every POLL_S, each one pipelined read (HKEYS, MGET); before: HEXISTS and SET NX per piece,
        # 2 * 19 + 2 a round (about 200 in the second)
        rounds = window / pieces.POLL_S + 1
        assert commands <= 2 * rounds, (commands, stats)
    finally:
        server.kill()
