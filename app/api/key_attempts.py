"""Failed API-key attempts, limited per client address: past the limit a 429 with ``Retry-After``.

A key has 256 random bits, so guessing one is hopeless; what the limit stops is a client that tries
keys anyway (a leaked list, a scanner), which costs a database read per attempt.  An address with
``auth_max_failures`` failed attempts (an unknown or revoked key) within ``auth_failure_window_s``
is answered 429 before its key is looked up, until the oldest of those failures leaves the window.
A missing key is a plain 401, never counted (a browser that has no key yet is not guessing).

The counts live in each API process (no shared state, no database write per failure): with
``TRAJLAB_API_WORKERS`` processes an address gets at most that many times the limit.  Behind a proxy
the address is the proxy's unless uvicorn is told to trust its ``X-Forwarded-For``
(``--forwarded-allow-ips``).
"""
from __future__ import annotations

import math
import threading
import time
from collections import OrderedDict, deque

MAX_ADDRESSES = 10_000  # the oldest address is forgotten past this many (memory stays bounded)


class FailedKeyAttempts:
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


def for_app(state, settings) -> FailedKeyAttempts:
    """The app's counter (one per app, made on first use)."""
    limiter = getattr(state, "failed_key_attempts", None)
    if limiter is None:
        limiter = state.failed_key_attempts = FailedKeyAttempts(max_failures=settings.auth_max_failures,
                                                                window_s=settings.auth_failure_window_s)
    return limiter
