"""Metric writes of a process, sent to Redis by a thread of their own and kept while Redis does not answer.

A worker cut from Redis used to drop its jobs' metrics (issue 36): each job wrote its observations in its
own thread, waited out the socket timeout and logged "metrics not recorded".  Here :func:`add` only
appends the commands to this process's buffer and returns; a flusher thread sends them, in batches of at
most ``BATCH`` commands, and keeps a batch Redis did not take until it does, retrying every ``RETRY_S``.

A batch whose reply was lost may have been applied all the same (a silent cut drops the reply, or the
kernel delivers the request when the link returns), so each batch goes as one Lua script with a token of
its own: the script applies the commands only if it can create the token's key (``SET NX``, expiring
after ``TOKEN_TTL_S``, longer than the kernel's retransmissions last), so a batch sent again is applied
once.  At most ``MAX_KEPT`` commands wait; past that the oldest are dropped, with a warning that counts
them.  A forked child starts with an empty buffer (its parent flushes its own); a Celery pool child
flushes at its exit (worker.celery_app, within ``flush``'s bound).
"""
from __future__ import annotations

import logging
import os
import threading
import time
import uuid
from collections import deque

log = logging.getLogger("trajlab.metrics")
BATCH = 1000
MAX_KEPT = 100_000
RETRY_S = 2.0
IDLE_EXIT_S = 60.0
TOKEN_PREFIX = "trajlab:metrics:flush:"
TOKEN_TTL_S = 3600
# The only commands a metric write is (app.service.metrics): anything else is refused here and by the
# script, so the script applies counter updates and nothing else, whatever its arguments.
COMMANDS = frozenset({"HINCRBY", "HINCRBYFLOAT", "SET"})
# A constant server-side script (no text of ours or a user's is ever evaluated): ARGV is the token's
# expiry, then each command as its argument count followed by its arguments; every command is checked
# against the allow-list before any is applied.
_APPLY_ONCE = """
local allowed = {HINCRBY = true, HINCRBYFLOAT = true, SET = true}
local i = 2
while i <= #ARGV do
  if not allowed[ARGV[i + 1]] then return redis.error_reply('metrics: command not allowed') end
  i = i + tonumber(ARGV[i]) + 1
end
if not redis.call('SET', KEYS[1], '1', 'NX', 'EX', ARGV[1]) then return 0 end
i = 2
while i <= #ARGV do
  local n = tonumber(ARGV[i])
  redis.call(unpack(ARGV, i + 1, i + n))
  i = i + n + 1
end
return 1
"""


class _Buffer:
    def __init__(self) -> None:
        self.cv = threading.Condition()
        self.waiting: deque[tuple[object, tuple]] = deque()  # (client, command) not yet in a batch
        self.batches: deque[tuple[object, str, list[tuple]]] = deque()  # (client, token, commands)
        self.thread: threading.Thread | None = None
        self.dropped = 0
        self.failing_since: float | None = None

    def add(self, client, commands: list[tuple]) -> None:
        if not commands:
            return
        refused = {c[0] for c in commands} - COMMANDS
        if refused:
            raise ValueError(f"not a metric write: {sorted(refused)}")
        with self.cv:
            self.waiting.extend((client, c) for c in commands)
            kept = len(self.waiting) + sum(len(b[2]) for b in self.batches)
            while kept > MAX_KEPT and self.waiting:
                self.waiting.popleft()
                self.dropped += 1
                kept -= 1
            if self.thread is None or not self.thread.is_alive():
                self.thread = threading.Thread(target=self._run, name="trajlab-metrics", daemon=True)
                self.thread.start()
            self.cv.notify_all()

    def _next(self):
        """The oldest batch (forming batches from what waits), or None once idle for ``IDLE_EXIT_S``."""
        with self.cv:
            if not self.cv.wait_for(lambda: self.waiting or self.batches, timeout=IDLE_EXIT_S):
                self.thread = None
                return None
            while self.waiting:
                client, first = self.waiting.popleft()
                commands = [first]
                while self.waiting and len(commands) < BATCH and self.waiting[0][0] is client:
                    commands.append(self.waiting.popleft()[1])
                self.batches.append((client, uuid.uuid4().hex, commands))
            return self.batches[0]

    def _run(self) -> None:
        while (batch := self._next()) is not None:
            client, token, commands = batch
            args: list = [TOKEN_TTL_S]
            for command in commands:
                args += [len(command), *command]
            try:
                client.eval(_APPLY_ONCE, 1, TOKEN_PREFIX + token, *args)
            except Exception as exc:
                if self.failing_since is None:
                    self.failing_since = time.monotonic()
                    log.warning("metrics kept in memory: Redis did not take them (%s); retrying every %.0f s",
                                type(exc).__name__, RETRY_S)
                time.sleep(RETRY_S)
                continue
            with self.cv:
                self.batches.popleft()
                done = not self.batches and not self.waiting
                self.cv.notify_all()
            if done and self.failing_since is not None:
                log.warning("metrics kept in memory written to Redis after %.1f s%s",
                            time.monotonic() - self.failing_since,
                            f" ({self.dropped} dropped past {MAX_KEPT})" if self.dropped else "")
                self.failing_since, self.dropped = None, 0

    def flush(self, timeout_s: float) -> bool:
        with self.cv:
            return self.cv.wait_for(lambda: not self.waiting and not self.batches, timeout=timeout_s)


_buffer = _Buffer()


def _forget_after_fork() -> None:
    global _buffer
    _buffer = _Buffer()  # the parent's commands are the parent's to send; its thread does not exist here


os.register_at_fork(after_in_child=_forget_after_fork)


def add(client, commands: list[tuple]) -> None:
    """Send these Redis commands (tuples of arguments) soon, and once, through ``client``."""
    _buffer.add(client, commands)


def flush(timeout_s: float) -> bool:
    """Wait until everything added is in Redis, at most ``timeout_s``; whether it is."""
    return _buffer.flush(timeout_s)
