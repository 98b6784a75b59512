"""Failed API-key attempts, limited per client address: past the limit a 429 with ``Retry-After``.

A key has 256 random bits, so guessing one is hopeless; what the limit stops is a client that keeps
sending bad keys (a leaked list, a scanner): an address with ``auth_max_failures`` failed attempts (an
unknown or revoked key) within ``auth_failure_window_s`` has its next bad keys answered 429, until the
oldest of those failures leaves the window.  A missing key is a plain 401, never counted (a browser that
has no key yet is not guessing).

Two rules keep the limit from being turned against users (issue 36):

* **A valid key is never refused.**  The key is looked up first and the limit is consulted only for a
  key that failed, so many users behind one address (a proxy, Docker's network, an office NAT) are not
  locked out by one of them, or by an attacker among them.  The lookup is one indexed read of a hash;
  a malformed key is refused before it (app.api.auth.authenticate), so junk costs nothing.
* **The address cannot be chosen by the client.**  It is the peer's, or what ``X-Forwarded-For`` says
  only when the peer is one of ``TRAJLAB_TRUSTED_PROXIES`` (none by default; app.api.main installs the
  reading, and ``trajlab api``/``serve`` switch uvicorn's own, which trusts 127.0.0.1, off).

The failures are counted in Redis (the broker's server), so every API process, on any host, shares one
count per address: a sorted set of failure times per address, trimmed to the window, expiring with it.
When Redis does not answer, each process counts on its own (:class:`FailedKeyAttempts`): while the
process's broker breaker is open (app.service.breaker: until a PING is answered again), without asking
Redis at all, so no request waits on a lost Redis; after a refusal (``OOM``, ``MISCONF``) for
``REDIS_RETRY_S``.  The limit then holds per process.
"""
from __future__ import annotations

import logging
import math
import threading
import time
import uuid
from collections import OrderedDict, deque
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from app.service.breaker import BrokerBreaker

log = logging.getLogger(__name__)

MAX_ADDRESSES = 10_000  # the oldest address is forgotten past this many (memory stays bounded)
REDIS_KEY = "trajlab:auth-failures:"  # + the address
REDIS_RETRY_S = 5.0  # after a Redis error, count in the process this long before asking Redis again
REDIS_TIMEOUT_S = 0.5  # the limiter's Redis calls: a failed key is never held longer than this by Redis


class FailedKeyAttempts:
    """The failures of one process, per address (the fallback while Redis is down, and the unit under test)."""

    def __init__(self, *, max_failures: int, window_s: float, clock=time.monotonic):
        self.max_failures, self.window_s, self.clock = max_failures, window_s, clock
        self._failures: OrderedDict[str, deque[float]] = OrderedDict()
        self._lock = threading.Lock()

    def _recent(self, address: str, now: float) -> deque[float] | None:
        times = self._failures.get(address)
        if times is None:
            return None
        while times and times[0] <= now - self.window_s:
            times.popleft()
        if not times:
            del self._failures[address]
            return None
        return times

    def retry_after_s(self, address: str) -> int | None:
        """Seconds until ``address`` may try a key again, or None if it may now."""
        now = self.clock()
        with self._lock:
            times = self._recent(address, now)
            if times is None or len(times) < self.max_failures:
                return None
            return max(1, math.ceil(times[0] + self.window_s - now))

    def failed(self, address: str) -> None:
        now = self.clock()
        with self._lock:
            times = self._recent(address, now)
            if times is None:
                times = self._failures[address] = deque()
                if len(self._failures) > MAX_ADDRESSES:
                    self._failures.popitem(last=False)
            times.append(now)
            self._failures.move_to_end(address)


class SharedKeyAttempts:
    """The failures of every API process, per address, in Redis; the process's own count while Redis is down."""

    def __init__(self, redis, *, max_failures: int, window_s: float, breaker: BrokerBreaker):
        self.redis, self.max_failures, self.window_s = redis, max_failures, window_s
        self.breaker = breaker
        self.local = FailedKeyAttempts(max_failures=max_failures, window_s=window_s)
        self._redis_down_until = 0.0

    def _shared(self, fn):
        """``fn()`` against Redis, or None (use the local count): while the breaker is open, when Redis does
        not answer (the breaker's call opens it: every Redis user of this process knows it now), and for
        ``REDIS_RETRY_S`` after a refusal."""
        from redis.exceptions import RedisError

        if self.breaker.open or time.monotonic() < self._redis_down_until:
            return None
        try:
            result = self.breaker.call(fn, None)  # fn never returns None: None is the breaker's "not answered"
        except RedisError as exc:  # answered, but refused (OOM, MISCONF): the breaker stays closed
            self._redis_down_until = time.monotonic() + REDIS_RETRY_S
            why = type(exc).__name__
        else:
            if result is not None:
                return result
            why = "unreachable"
        log.warning("failed API-key attempts counted per process: Redis did not answer (%s)", why)
        return None

    def retry_after_s(self, address: str) -> int | None:
        """Seconds until ``address`` may try a key again, or None if it may now."""
        key = REDIS_KEY + address

        def ask():
            now = time.time()  # wall clock: the processes sharing the count may be on other hosts
            pipe = self.redis.pipeline(transaction=True)
            pipe.zremrangebyscore(key, "-inf", now - self.window_s)
            pipe.zcard(key)
            pipe.zrange(key, 0, 0, withscores=True)
            _, count, oldest = pipe.execute()
            if count < self.max_failures or not oldest:
                return 0
            return max(1, math.ceil(oldest[0][1] + self.window_s - now))

        wait = self._shared(ask)
        if wait is None:
            return self.local.retry_after_s(address)
        return wait or None

    def failed(self, address: str) -> None:
        key = REDIS_KEY + address

        def add():
            now = time.time()
            pipe = self.redis.pipeline(transaction=True)
            pipe.zadd(key, {uuid.uuid4().hex: now})
            pipe.zremrangebyscore(key, "-inf", now - self.window_s)
            pipe.expire(key, math.ceil(self.window_s) + 1)
            pipe.execute()
            return True

        if self._shared(add) is None:
            self.local.failed(address)


def for_app(state, settings) -> SharedKeyAttempts:
    """The app's counter (one per app, made on first use), counting in the broker's Redis."""
    limiter = getattr(state, "failed_key_attempts", None)
    if limiter is None:
        from redis.backoff import NoBackoff
        from redis.retry import Retry

        from app.service.broker import redis_client

        # one immediate retry (a pooled connection a Redis restart closed), then the local count
        client = redis_client(settings.broker_url, settings=settings, socket_timeout=REDIS_TIMEOUT_S,
                              socket_connect_timeout=REDIS_TIMEOUT_S, retry=Retry(NoBackoff(), 1))
        from app.service import breaker

        limiter = state.failed_key_attempts = SharedKeyAttempts(client, max_failures=settings.auth_max_failures,
                                                                window_s=settings.auth_failure_window_s,
                                                                breaker=breaker.for_process(settings))
    return limiter
