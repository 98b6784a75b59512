"""The guard of a running job: its memory cap (``TRAJLAB_JOB_MEMORY_MB``) and a time limit that
hold inside native code.

How memory is capped, and why this way:

* What is capped is what the job holds, its resident memory (``/proc/PID/statm``), not its address
  space: numba and LLVM (heyoka) reserve virtual memory they never touch (a reentry preset: VmSize
  about 600 MB for 130 MB resident), so an ``RLIMIT_AS`` low enough to matter kills healthy jobs.
* A watcher process (``worker.watch``, one beside each pool process, started at its first job and kept)
  samples it, at an interval that shrinks as the job nears its cap: 50 ms far below it, 1 ms at it, so
  that a job growing at 4 GB/s passes its cap by no more than about 2.5% before a sample sees it.  A
  process, not a thread: a thread of the job's process needs the GIL, and CasADi builds its expressions
  and IPOPT runs with the GIL held, so a thread sampling ten times a second saw a wide ``ocp`` (50 states,
  20 controls, 1,000 intervals, growing about 1 GB/s while building its NLP) only at 1,152 MB against a
  1,000 MB cap (15% over), and a native call that holds the GIL while it writes memory (``ctypes.PyDLL``)
  ran to 1,513 MB against 512.  Not a cgroup v2 ``memory.max`` per job: that needs a process per job in a
  cgroup of its own under a delegated subtree (root, or systemd's ``Delegate=yes``), which an
  unprivileged container or a cgroup v1 host (this one) does not give, and the kernel's OOM kill in that
  cgroup leaves no word: the job would be re-run as a lost worker.  The watcher works on any Linux as
  any user and says what happened.
* Past the cap the watcher ends the pool process (SIGKILL: the job's thread may be inside IPOPT, MUMPS or
  a numba kernel, where no Python exception reaches it, and would go on allocating), then stores the
  failure (code ``resource_limit``, naming the cap and the memory reached) through the handler the
  guard names (``worker.tasks.store_breach`` for a job and its Monte Carlo chunks and pieces), and
  exits.  Celery's pool starts a fresh process; the message it hands back is dropped at the claim (the
  job's heartbeat is fresh, then the job is finished), so the job is not retried, and the pool's other
  processes and their jobs are untouched.
* ``RLIMIT_DATA`` (data segment plus private writable mappings) is the backstop for a watcher that could
  not start: set per job to :data:`DATA_BACKSTOP` times the cap above the data size at the start, a malloc
  past it fails and the job fails as ``resource_limit`` (``worker.tasks`` maps ``MemoryError``) instead
  of waking the kernel's OOM killer.  Where the watcher cannot start, a thread of the job's process
  samples instead (ten times a second, when it gets the GIL), and the log says so.

What earlier jobs left in the process (cached CasADi solvers, compiled libraries, freed memory glibc
keeps) is not charged to the next job: a job is charged what the process holds above its own start,
plus what the process held at its first job (so the first job in a fresh process is charged that
process's whole resident memory, as a job run alone would be).  ``worker.celery_app`` replaces a
process whose leftovers grow past ``TRAJLAB_WORKER_RECYCLE_MB`` after a job, which bounds what a
charge can miss (a job reusing memory glibc kept from an earlier one) and keeps the caches otherwise.

The guard assumes Celery's prefork pool (one job per process, as every documented way of running a
worker starts it); under ``--pool solo`` a breach ends the whole worker and its supervisor restarts it.

The watcher enforces the time limit too, for a job that never returns to Python: Celery's soft limit
is a signal, which Python handles only between bytecodes, so a long native call holds it off and
Celery's hard limit would kill the process without a word (the job then looks lost and is re-run).
At half the hard margin past the soft limit the watcher ends the process and stores ``time_limit``.
"""
from __future__ import annotations

import ctypes
import json
import logging
import os
import resource
import select
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

from worker import watch

log = logging.getLogger("trajlab.worker")

SAMPLE_S = 0.1            # the in-process fallback's interval (a sample costs about 20 us of CPU)
# RLIMIT_DATA: this many caps above the data size at the job's start.  Data grows faster than resident
# memory (robust_reentry at 1000 intervals: VmData +1050 MB for +440 MB resident, 2.4x), so 4x.
DATA_BACKSTOP = 4.0
MB = 1024 * 1024
_PAGE = os.sysconf("SC_PAGE_SIZE")

# The resident memory of this process at its first guarded job (a forked pool process starts afresh).
_first: dict[int, int] = {}
# This process's watcher (keyed by pid: a process forked from one that had a watcher needs its own).
_watchers: dict[int, subprocess.Popen] = {}
_ROOT = Path(__file__).resolve().parents[1]


def resident_bytes() -> int | None:
    """Resident memory of this process, or None where ``/proc`` has no statm (not Linux)."""
    try:
        with open("/proc/self/statm", "rb") as f:
            return int(f.read().split()[1]) * _PAGE
    except (OSError, ValueError, IndexError):
        return None


def data_bytes() -> int | None:
    """``VmData`` (what RLIMIT_DATA counts) of this process, or None."""
    try:
        with open("/proc/self/statm", "rb") as f:
            return int(f.read().split()[5]) * _PAGE
    except (OSError, ValueError, IndexError):
        return None


def release_free_memory() -> None:
    """Give the heap's free pages back to the kernel (glibc ``malloc_trim``), so that the resident
    memory after a job is what it left in use, not what glibc keeps for later mallocs."""
    try:
        ctypes.CDLL("libc.so.6").malloc_trim(0)
    except (OSError, AttributeError):
        pass  # not glibc: nothing to trim


def reset_peak() -> None:
    """Reset the kernel's peak resident size of this process to its current size (``clear_refs`` 5,
    Linux 4.0+), so that Celery's ``worker_max_memory_per_child`` check, which reads the peak
    (``ru_maxrss``), compares what a finished job left rather than what it once held."""
    try:
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
    except OSError:
        pass  # then Celery compares the peak, which recycles more often, never less


def start_watcher() -> subprocess.Popen | None:
    """This process's watcher (``worker.watch``), started if it is not running; None if it cannot start."""
    pid = os.getpid()
    w = _watchers.get(pid)
    if w is not None and w.poll() is None:
        return w
    path = os.pathsep.join([str(_ROOT), *filter(None, [os.environ.get("PYTHONPATH")])])
    try:
        # exec'd, with no descriptor of ours but its pipes (close_fds): no database or broker connection
        # of this process reaches it
        w = subprocess.Popen([sys.executable, "-m", "worker.watch", str(pid)], stdin=subprocess.PIPE,
                             stdout=subprocess.PIPE, close_fds=True, env={**os.environ, "PYTHONPATH": path})
    except OSError as exc:
        log.error("the memory watcher did not start (%s): jobs in process %d are sampled from inside it", exc, pid)
        return None
    _watchers[pid] = w
    return w


class JobGuard:
    """Hold one job in this process to ``cap_bytes`` of memory (None: no cap) and to ``deadline + grace_s``
    (monotonic).  On a breach the process is ended and ``handler(error, context)`` stores the failure:
    ``handler`` is a ``module:function`` path, called in the watcher process (or, in the fallback, in this
    one just before it ends), so ``context`` is JSON.  A context manager around the job's run."""

    def __init__(self, *, job_id: str, cap_bytes: int | None, deadline: float, grace_s: float,
                 time_limit_message: str, handler: str, context: dict):
        self.job_id = job_id
        self.cap_bytes = cap_bytes
        self.deadline = deadline
        self.grace_s = grace_s
        self.time_limit_message = time_limit_message
        self.handler = handler
        self.context = {"job_id": job_id, **context}
        self.start_bytes = self.first_bytes = 0
        self.peak_bytes = 0
        self._rlimit: tuple[int, int] | None = None
        self._watcher: subprocess.Popen | None = None
        self._done = threading.Event()
        self._thread: threading.Thread | None = None

    def charged(self, rss: int) -> int:
        """The job's memory: what the process holds above the job's start, plus its first job's start."""
        return max(rss - self.start_bytes, 0) + self.first_bytes

    def __enter__(self) -> "JobGuard":
        self.start_bytes = resident_bytes() or 0
        self.first_bytes = _first.setdefault(os.getpid(), self.start_bytes)
        self.peak_bytes = self.first_bytes
        if self.cap_bytes is not None:
            self._limit_data()
        self._watcher = start_watcher() if self.start_bytes else None
        if self._watcher is not None:
            try:
                self._send({"op": "start", "cap": self.cap_bytes, "start": self.start_bytes,
                            "first": self.first_bytes, "deadline": self.deadline, "grace_s": self.grace_s,
                            "time_limit_message": self.time_limit_message, "handler": self.handler,
                            "context": self.context})
            except OSError as exc:
                log.error("job %s: the memory watcher is gone (%s); sampled from inside the process", self.job_id, exc)
                self._watcher = None
        if self._watcher is None:
            self._thread = threading.Thread(target=self._watch, name=f"guard-{self.job_id}", daemon=True)
            self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        if self._watcher is not None:
            try:
                self._send({"op": "stop"})
                out = self._watcher.stdout
                assert out is not None
                if select.select([out], [], [], 5.0)[0]:
                    self.peak_bytes = max(self.peak_bytes, int(json.loads(out.readline())["peak"]))
            except (OSError, ValueError, KeyError):
                log.warning("job %s: the memory watcher did not answer at the job's end", self.job_id)
        if self._thread is not None:
            self._done.set()
            self._thread.join(timeout=5)
        if self._rlimit is not None:
            resource.setrlimit(resource.RLIMIT_DATA, self._rlimit)

    def _send(self, msg: dict) -> None:
        assert self._watcher is not None and self._watcher.stdin is not None
        self._watcher.stdin.write(json.dumps(msg).encode() + b"\n")
        self._watcher.stdin.flush()

    # --- the fallback: sampled from a thread of this process --------------------------------------
    def _watch(self) -> None:
        while not self._done.wait(SAMPLE_S):
            rss = resident_bytes()
            if rss is not None:
                held = self.charged(rss)
                self.peak_bytes = max(self.peak_bytes, held)
                if self.cap_bytes is not None and held > self.cap_bytes:
                    self._breach(watch.memory_error(held, self.cap_bytes))
            if time.monotonic() > self.deadline + self.grace_s:
                self._breach({"code": "time_limit", "message": self.time_limit_message})

    def _breach(self, error: dict) -> None:
        log.error("job %s: %s; its worker process ends now (SIGKILL) and the pool starts a fresh one",
                  self.job_id, error["message"])
        try:
            watch.call_handler(self.handler, error, self.context)
        except Exception:  # exit all the same: the process must not run on past its bounds
            log.exception("job %s: the %s failure was not stored; the reaper takes the job over",
                          self.job_id, error["code"])
        for handler in logging.getLogger().handlers:
            handler.flush()
        sys.stdout.flush()
        sys.stderr.flush()
        # not a Python exit: the main thread may be inside native code, and nothing of this process
        # (atexit handlers, the pool's shutdown) may run on past the breach
        os.kill(os.getpid(), signal.SIGKILL)

    def _limit_data(self) -> None:
        data = data_bytes()
        if data is None or self.cap_bytes is None:
            return
        soft, hard = resource.getrlimit(resource.RLIMIT_DATA)
        want = int(data + DATA_BACKSTOP * self.cap_bytes)
        if hard != resource.RLIM_INFINITY:
            want = min(want, hard)
        if soft == resource.RLIM_INFINITY or want < soft:
            resource.setrlimit(resource.RLIMIT_DATA, (want, hard))
            self._rlimit = (soft, hard)
