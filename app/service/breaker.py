"""The broker's circuit breaker: a process remembers that Redis does not answer, so nothing waits on it twice.

A silent loss (packets dropped: a dead switch, a firewall, a cut cable) gives no error, only silence: every
Redis call waits out its socket timeout.  An API host that lost Redis that way took 6.1 s per POST and
served a seventh of its usual rate (issue 36), because each request waited on Redis in turn.  Here one
:class:`BrokerBreaker` per process and broker URL holds the verdict:

* **closed** (Redis answers): callers use Redis as usual;
* **open** (a call or a probe failed): callers do not touch Redis at all and take their documented
  fallback at once (:meth:`BrokerBreaker.call`): the publisher keeps the jobs for later
  (app.service.publisher), the failed-key limit counts in the process (app.api.key_attempts), ``/readyz``
  answers "down", ``/metrics`` leaves the broker's families out, a worker's metrics wait in memory
  (app.service.metrics).

A monitor thread PINGs Redis every ``interval_s`` with a reply bound of ``timeout_s``: while closed it
notices a silent loss within ``interval_s + timeout_s`` even when no request has touched Redis (and says so
in the log); while open it is the probe that closes the breaker when Redis answers again, and then runs
the callbacks registered with :meth:`BrokerBreaker.on_close` (the publisher sends what it kept).  The
monitor stops after ``IDLE_STOP_S`` without a caller (a test's app that is gone, an idle process; the
publisher asks every probe interval while it keeps jobs) and starts again on the next use.

The API's monitor PINGs every ``TRAJLAB_BROKER_PROBE_INTERVAL_S`` with ``TRAJLAB_BROKER_PROBE_TIMEOUT_S``;
a worker's (worker.broker_watch) every third of ``TRAJLAB_REDIS_HEALTH_CHECK_INTERVAL_S`` with the same
third as its bound, so it logs a silent loss within two thirds of the health-check interval the README
states.
"""
from __future__ import annotations

import logging
import os
import threading
import time
from typing import Callable, TypeVar

from app.runtime.settings import Settings

T = TypeVar("T")
IDLE_STOP_S = 60.0  # a monitor with no caller for this long (and Redis answering) stops
# A request's own Redis call (/readyz, /metrics) waits at most this long: in the second between a silent loss
# and the monitor's verdict it is the most a request loses; it answers "down" without opening the breaker
# (a slow reply under load is not a lost broker: the monitor's PING, with its longer bound, decides that).
REQUEST_BOUND_S = 0.25


def describe(exc: BaseException) -> str:
    """An exception's class and Redis's words for a refusal (never an address)."""
    from app.service.broker import refusal

    return f"{type(exc).__name__}: {refusal(exc)}" if not unreachable(exc) else type(exc).__name__


def unreachable(exc: BaseException) -> bool:
    """Whether ``exc`` says Redis did not answer (as opposed to a command it refused: OOM, MISCONF)."""
    from redis.exceptions import ConnectionError as RedisConnectionError
    from redis.exceptions import TimeoutError as RedisTimeoutError

    return isinstance(exc, (RedisConnectionError, RedisTimeoutError, OSError))


class BrokerBreaker:
    """Whether this process may use Redis now (module docstring)."""

    def __init__(self, broker_url: str, *, interval_s: float, timeout_s: float, log: logging.Logger):
        self.broker_url = broker_url
        self.interval_s, self.timeout_s, self.log = interval_s, timeout_s, log
        self._open_since: float | None = None
        self._last_use = time.monotonic()
        self._lock = threading.Lock()
        self._wake = threading.Event()
        self._callbacks: list[Callable[[], None]] = []
        self._monitor: threading.Thread | None = None
        self._watching = False

    # --- what callers ask -----------------------------------------------------------------
    @property
    def open(self) -> bool:
        """True while Redis is held unreachable: do not call it."""
        self._last_use = time.monotonic()
        self._ensure_monitor()
        return self._open_since is not None

    def call(self, fn: Callable[[], T], default: T, *, trip: bool = True) -> T:
        """``fn()`` (a Redis call), or ``default`` at once while the breaker is open; a call that finds Redis
        unreachable returns ``default`` and opens the breaker (unless ``trip`` is false: a call bounded
        tighter than the monitor's PING leaves the verdict to it).  Refusals (``ResponseError``) are the
        caller's."""
        if self.open:
            return default
        try:
            return fn()
        except Exception as exc:
            if not unreachable(exc):
                raise
            if trip:
                self.trip(exc)
            return default

    def trip(self, exc: BaseException) -> None:
        """Redis did not answer a call: open the breaker (the monitor probes it closed again)."""
        with self._lock:
            if self._open_since is not None:
                return
            self._open_since = time.monotonic()
        self.log.warning("broker unreachable (%s); PINGed every %.1f s until it answers",
                         f"{type(exc).__name__}: {exc}"[:200], self.interval_s)
        self._ensure_monitor()
        self._wake.set()

    def watch(self) -> None:
        """Keep the monitor running for the life of the process, used or not (a worker's watch)."""
        self._watching = True
        self._ensure_monitor()

    def on_close(self, callback: Callable[[], None]) -> None:
        """Run ``callback()`` (in the monitor's thread) each time the breaker closes."""
        with self._lock:
            self._callbacks.append(callback)

    # --- the monitor ----------------------------------------------------------------------------
    def probe(self) -> bool:
        """One PING within ``timeout_s``; opens or closes the breaker by its outcome."""
        from app.service.broker import REDIS_SCHEMES, bounded_client

        if not self.broker_url.startswith(REDIS_SCHEMES):
            self._close()  # nothing to PING (another transport): Celery's own errors are the only signal
            return True
        try:
            bounded_client(self.broker_url, self.timeout_s).ping()
        except Exception as exc:
            self.trip(exc)
            return False
        self._close()
        return True

    def _close(self) -> None:
        with self._lock:
            since = self._open_since
            if since is None:
                return
            self._open_since = None
            callbacks = list(self._callbacks)
        self.log.warning("broker reachable again after %.1f s", time.monotonic() - since)
        for callback in callbacks:
            try:
                callback()
            except Exception:  # a callback's failure is its own (it logs); the breaker stays closed
                self.log.exception("broker-back callback failed")

    def _ensure_monitor(self) -> None:
        monitor = self._monitor
        if monitor is not None and monitor.is_alive():
            return
        with self._lock:
            if self._monitor is None or not self._monitor.is_alive():
                self._monitor = threading.Thread(target=self._run, name="trajlab-broker-breaker", daemon=True)
                self._monitor.start()

    def _run(self) -> None:
        while True:
            self._wake.wait(self.interval_s)
            self._wake.clear()
            idle = time.monotonic() - self._last_use > IDLE_STOP_S
            if idle and not self._watching:  # open or not: the next caller starts it again
                with self._lock:
                    self._monitor = None
                return
            self.probe()


_breakers: dict[tuple[int, str, str], BrokerBreaker] = {}
_breakers_lock = threading.Lock()


def for_process(settings: Settings, *, role: str = "api", interval_s: float | None = None,
                timeout_s: float | None = None) -> BrokerBreaker:
    """This process's breaker for ``settings.broker_url`` (``role`` names its log; a forked child has its own)."""
    key = (os.getpid(), settings.broker_url, role)
    breaker = _breakers.get(key)
    if breaker is None:
        with _breakers_lock:
            breaker = _breakers.get(key)
            if breaker is None:
                breaker = _breakers[key] = BrokerBreaker(
                    settings.broker_url, log=logging.getLogger(f"trajlab.{role}"),
                    interval_s=settings.broker_probe_interval_s if interval_s is None else interval_s,
                    timeout_s=settings.broker_probe_timeout_s if timeout_s is None else timeout_s)
    return breaker
