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
