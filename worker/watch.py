"""The watcher: a small process beside each pool process that holds that process to its job's bounds
(``worker.guard`` starts it and says why it is a process of its own).

Run as ``python -m worker.watch PID``.  It reads one JSON line per command on its standard input:

* ``{"op": "start", "cap": bytes or null, "start": bytes, "first": bytes, "deadline": monotonic s,
  "grace_s": s, "time_limit_message": str, "handler": "module:function", "context": {...}}``: watch PID
  for one job;
* ``{"op": "stop"}``: the job ended; the watcher answers ``{"peak": bytes}`` on its standard output.

End of input (its pool process exited) ends it.  While a job runs it reads PID's resident memory from
``/proc/PID/statm`` at an interval that shrinks as the job nears its cap (:func:`next_sample_s`); past the
cap, or past ``deadline + grace_s``, it first stops PID with SIGSTOP (the growth stops there), calls
``handler(error, context)``, which stores the failure, then ends PID with SIGKILL and exits.  It imports nothing of the service
until then, so it holds a few MB.
"""
from __future__ import annotations

import importlib
import json
import os
import select
import signal
import sys
import threading
import time

MB = 1024 * 1024
_PAGE = os.sysconf("SC_PAGE_SIZE")

# The fastest a process grows, for the sampling interval: one thread writing fresh pages (memset into new
# anonymous memory) ran at 2.5-3.3 GB/s on this machine; 4 GB/s leaves room for a faster one.
GROWTH_BYTES_PER_S = 4e9
# The share of the cap a job may pass before a sample sees it: half the 5% the guard promises, the rest for
# a sample that comes late (a busy CPU wakes the watcher up to a few ms late).
SLACK = 0.025
MIN_SAMPLE_S = 0.001
# the longest a breaching job stays stopped while its failure is stored (see Watch.breach)
KILL_AFTER_S = 10.0
MAX_SAMPLE_S = 0.05


def next_sample_s(held: int, cap: int | None) -> float:
    """Seconds to the next sample: the time the job needs, growing at :data:`GROWTH_BYTES_PER_S`, to pass
    ``cap`` by :data:`SLACK`, held within [:data:`MIN_SAMPLE_S`, :data:`MAX_SAMPLE_S`]."""
    if cap is None:
        return MAX_SAMPLE_S
    return min(max((cap * (1 + SLACK) - held) / GROWTH_BYTES_PER_S, MIN_SAMPLE_S), MAX_SAMPLE_S)


def memory_error(held: int, cap: int) -> dict:
    # rounded apart, so that the memory reached always reads above the cap
    return {"code": "resource_limit", "message": (
        f"the job reached {-(-held // MB)} MB of memory, past the cap of {cap // MB} MB per job "
        "(TRAJLAB_JOB_MEMORY_MB); a smaller grid or fewer samples fit")}


def call_handler(path: str, error: dict, context: dict) -> None:
    module, _, name = path.partition(":")
    getattr(importlib.import_module(module), name)(error, context)


class Watch:
    def __init__(self, pid: int):
        self.pid = pid
        self.statm = os.open(f"/proc/{pid}/statm", os.O_RDONLY)
        self.job: dict | None = None
        self.peak = 0

    def resident(self) -> int:
        return int(os.pread(self.statm, 128, 0).split()[1]) * _PAGE

    def charged(self, rss: int) -> int:
        assert self.job is not None
        return max(rss - self.job["start"], 0) + self.job["first"]

    def sample(self) -> float | None:
        """One look at the job; the seconds to the next, or None when idle."""
        if self.job is None:
            return None
        held = self.charged(self.resident())
        self.peak = max(self.peak, held)
        cap = self.job["cap"]
        if cap is not None and held > cap:
            self.breach(memory_error(held, cap))
        left = self.job["deadline"] + self.job["grace_s"] - time.monotonic()
        if left < 0:
            self.breach({"code": "time_limit", "message": self.job["time_limit_message"]})
        return min(next_sample_s(held, cap), max(left, MIN_SAMPLE_S))

    def breach(self, error: dict) -> None:
        assert self.job is not None
        # Stopped first (the job may be inside native code, still allocating: SIGSTOP halts it at once), killed
        # only once the failure is stored: a process killed first has its message redelivered by the pool, and
        # a loaded machine's redelivery claimed a second attempt before this process had stored the first.
        os.kill(self.pid, signal.SIGSTOP)
        # a stopped process may hold a database lock (a progress write in flight) that the store below waits on:
        # past KILL_AFTER_S it is killed anyway, which ends its transaction
        threading.Timer(KILL_AFTER_S, os.kill, (self.pid, signal.SIGKILL)).start()
        print(f"trajlab watcher: job {self.job['context'].get('job_id', '?')}: {error['message']}; its worker "
              f"process {self.pid} is ended (SIGKILL) once the failure is stored and the pool starts a fresh one",
              file=sys.stderr, flush=True)
        try:
            call_handler(self.job["handler"], error, self.job["context"])
        except Exception as exc:  # the reaper takes the job over
            print(f"trajlab watcher: the {error['code']} failure was not stored ({type(exc).__name__}: {exc}); "
                  "the reaper takes the job over", file=sys.stderr, flush=True)
        finally:
            os.kill(self.pid, signal.SIGKILL)
        os._exit(0)

    def command(self, line: bytes) -> None:
        msg = json.loads(line)
        if msg["op"] == "start":
            self.job, self.peak = msg, msg["first"]
        elif msg["op"] == "stop":
            if self.job is not None:
                self.sample()
            self.job = None
            os.write(1, json.dumps({"peak": self.peak}).encode() + b"\n")


def main(pid: int) -> int:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # a ^C to the worker's group is the worker's to handle
    watch = Watch(pid)
    buf = b""
    wait: float | None = None
    while True:
        ready, _, _ = select.select([0], [], [], wait)
        if ready:
            chunk = os.read(0, 65536)
            if not chunk:  # the pool process is gone
                return 0
            buf += chunk
            while b"\n" in buf:
                line, buf = buf.split(b"\n", 1)
                watch.command(line)
        try:
            wait = watch.sample()
        except (OSError, ValueError, IndexError):  # the process is gone
            return 0


if __name__ == "__main__":
    sys.exit(main(int(sys.argv[1])))
