"""A worker that keeps consuming while Redis refuses writes (``maxmemory`` reached, a failed dump's
``MISCONF``, a read-only replica).

kombu's Redis transport records each delivery in Redis (``unacked`` and ``unacked_index``) and
removes the record on acknowledgement, both in a ``MULTI`` transaction; its periodic restore of
overdue deliveries takes a lock with ``SET NX``.  With ``maxmemory`` reached (noeviction) Redis refuses
every command queued inside ``MULTI`` and every ``SET``, and the refusal surfaced in Celery's event loop
as an unrecoverable error: the worker exited (issue 27: 1,764 jobs left queued under a worker started
by hand).  Nothing here is lost by not writing to Redis: the jobs table is the truth, so

* an acknowledgement is written without ``MULTI``: ``HDEL`` and ``ZREM`` free memory and Redis accepts
  them at ``maxmemory``; one it still refuses (``MISCONF``, read-only) is kept and tried again with the
  next one; a record never removed is restored after the visibility timeout and its delivery dropped
  (the job is finished);
* a delivery Redis will not record is run anyway: the message is already off the queue, and if this
  worker dies with it the job's heartbeat goes stale and the reaper re-queues it;
* a refused restore of overdue deliveries is skipped until its next turn (every few seconds).

``install()`` puts :class:`GuardedQoS` in place of kombu's in this process (the worker's; the API's
publisher does not consume).  ``broker_channel_error_retry`` (worker.celery_app) covers what is left,
e.g. a worker started while Redis is full: its queue declarations (``SADD``) are refused and Celery
reconnects with backoff until they are accepted, instead of exiting.
"""
from __future__ import annotations

import logging
import time
from collections import deque

from kombu.transport import redis as kombu_redis
from kombu.transport import virtual
from redis.exceptions import ResponseError

from app.service.broker import refusal

log = logging.getLogger("trajlab.worker")
# Refusals are logged at most this often per kind: at maxmemory every delivery is refused.
_LOG_EVERY_S = 10.0
_last_logged: dict[str, float] = {}


def _warn(what: str, exc: BaseException) -> None:
    now = time.monotonic()
    if now - _last_logged.get(what, -_LOG_EVERY_S) >= _LOG_EVERY_S:
        _last_logged[what] = now
        log.warning("broker refused %s (%s); the worker goes on (the jobs table is the truth)", what, refusal(exc))


class GuardedQoS(kombu_redis.QoS):
    """kombu's Redis QoS with refused writes survived (module docstring)."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._unremoved: deque = deque(maxlen=10_000)  # acknowledged tags whose record Redis refused to drop

    def append(self, message, delivery_tag):
        try:
            super().append(message, delivery_tag)
        except ResponseError as exc:
            _warn("to record a delivery", exc)
            virtual.QoS.append(self, message, delivery_tag)

    def ack(self, delivery_tag):
        self._drop_records(delivery_tag)
        virtual.QoS.ack(self, delivery_tag)

    def reject(self, delivery_tag, requeue=False):
        if not requeue:
            self._drop_records(delivery_tag)
            virtual.QoS.ack(self, delivery_tag)
            return
        try:
            super().reject(delivery_tag, requeue=True)
        except ResponseError as exc:
            # left in the unacknowledged set: restored after the visibility timeout (or re-published
            # sooner by the recovery loop, which finds the queued job missing from the queues)
            _warn("to requeue a rejected delivery", exc)
            virtual.QoS.ack(self, delivery_tag)

    def _drop_records(self, delivery_tag) -> None:
        tags = [*self._unremoved, delivery_tag]
        try:
            with self.channel.conn_or_acquire() as client:
                pipe = client.pipeline(transaction=False)  # no MULTI: HDEL and ZREM pass at maxmemory
                for tag in tags:
                    pipe.hdel(self.unacked_key, tag)  # the message first: an index entry alone restores nothing
                    pipe.zrem(self.unacked_index_key, tag)
                pipe.execute()
            self._unremoved.clear()
        except ResponseError as exc:
            _warn("an acknowledgement", exc)
            self._unremoved.append(delivery_tag)

    def restore_visible(self, *args, **kwargs):
        try:
            return super().restore_visible(*args, **kwargs)
        except ResponseError as exc:
            _warn("the restore of overdue deliveries", exc)

    def restore_unacked(self, client=None):
        try:
            return super().restore_unacked(client)
        except ResponseError as exc:
            # at shutdown: the records stay in Redis and are restored after the visibility timeout
            _warn("to give prefetched deliveries back", exc)
            self._delivered.clear()


def install() -> None:
    """Use :class:`GuardedQoS` for every Redis channel of this process."""
    kombu_redis.Channel.QoS = GuardedQoS
