"""Compiled NLP derivatives: IPOPT's Hessian and constraint Jacobian as C, compiled once per
problem structure with the system compiler and kept on disk for every later process.

Why: on Betts' shuttle problem at 100 intervals, IPOPT spends ~85% of its time evaluating the
Hessian of the Lagrangian (12 forward-over-reverse sweeps of the mapped RK4 interval per
iteration) in CasADi's virtual machine: ~50 ms per iteration.  The same functions as C code take
~6 ms.  Compiling them costs 15-60 s (gcc -Og, 2.4 MB of C for the Hessian), so it is done
once per structure and cached by content:

* the key is a SHA-256 of the NLP's serialized expression graph (``f`` and ``g`` of ``(x, p)``),
  the CasADi version and the compiler flags: a changed model, grid or constraint set is a
  different key, never a stale library;
* ``TRAJLAB_JIT`` chooses the mode: ``off`` (the default: tests and CI never call a compiler),
  ``background`` (a job that misses the cache solves in the virtual machine at once while a
  thread compiles; later jobs of that structure, in this or any process, use the library) or
  ``sync`` (compile before the first solve; benchmarks);
* ``TRAJLAB_JIT_CACHE`` is the directory (default ``~/.cache/trajlab/jit``);
* ``TRAJLAB_JIT_MAX_MB`` (default 8) caps the generated C: the robust reentry NLP as a whole
  generates 21 MB, whose compile would take minutes and gigabytes; a structure over the cap is
  marked (``nlp_<key>.skip``) and stays in the virtual machine in every process.  The robust
  transcription therefore compiles its per-interval derivative blocks instead
  (:mod:`solvers.transcription.blocks`: 4.6 MB of C, 15-25 s and 0.6 GB for gcc -Og), keyed
  by the blocks' own content (:func:`digest_functions`); the deterministic reentry does too
  (0.4 MB of library instead of the whole NLP's 2.4 MB, IPOPT 63 instead of 84 ms on Betts);
* without a C compiler on ``PATH`` (``cc``, ``gcc`` or ``clang``) every mode falls back to the
  virtual machine, silently and permanently for the process.

Compiles that pay (issue 38): a compile costs 15-60 s of a core, so on a small machine (2 cores, two
worker pools) unbounded compiles swamped the solves they were meant to speed up.  Hence:

* **one compile at a time per host**: an exclusive ``fcntl.flock`` on a host-wide lock file
  (``TRAJLAB_JIT_LOCK``, default ``trajlab-jit-compile.lock`` in the system's temporary directory: every
  service, pool and test on the machine, whatever its cache directory), then on ``compile.lock`` in the
  cache directory (the compose workers share the cache volume but not ``/tmp``); whoever gets them second
  finds the library already there and compiles nothing (a structure is compiled once);
* **at low priority**: the compiler runs under ``os.nice(19)`` in a session of its own whose autogroup is at
  nice 19 too (:func:`_low_priority`: why both), so a solve waiting for a core wins it;
* **only structures likely to come back** (``background`` mode): a structure is compiled when it has been
  seen before (``TRAJLAB_JIT_SEEN`` sightings, default 2, counted per key in ``nlp_<key>.seen`` in the
  cache directory, across processes and restarts; a process's solver cache handing out a built solver
  again is a sighting too: another job of that structure, or a search's next start), or when the caller
  says it will come back (:func:`expected_again`: a preset as it stands, a study's points).  A problem
  posed once solves in the virtual machine and costs no compile.  ``sync`` (benchmarks) compiles at once,
  under the same locks.  A structure the compiler rejects is marked like one over the size cap, so it is
  not tried again at every sighting;
* ``compiles.log`` in the cache directory records each compile's start and end (time, pid, key), and
  each wait that found the library done: what the tests read, and an operator's answer to "what compiled".

-Og rather than -O1: as fast here (6.4 vs 7.4 ms per Hessian) for a seventh of the compile time.
"""
from __future__ import annotations

import contextlib
import contextvars
import ctypes
import ctypes.util
import fcntl
import hashlib
import os
import shutil
import signal
import subprocess
import tempfile
import threading
import time
from pathlib import Path

import casadi as ca

COMPILED = ("nlp_hess_l", "nlp_jac_g")          # the functions that cost: see the docstring
FLAGS = ("-Og", "-fPIC", "-shared")
_OPTION = {"nlp_hess_l": "hess_lag", "nlp_jac_g": "jac_g"}
_LOCK = threading.Lock()
_PENDING: dict[str, list] = {}   # key -> done() callbacks of the solvers waiting for it
# Set by the caller around building solvers whose structure will come back (see the docstring)
_EXPECTED_AGAIN: contextvars.ContextVar[bool] = contextvars.ContextVar("jit_expected_again", default=False)
LOCK_FILE, RECORDS = "compile.lock", "compiles.log"


def mode() -> str:
    m = os.environ.get("TRAJLAB_JIT", "off").strip().lower()
    return m if m in ("off", "background", "sync") else "off"


def compiler() -> str | None:
    for name in ("cc", "gcc", "clang"):
        path = shutil.which(name)
        if path:
            return path
    return None


def cache_dir() -> Path:
    return Path(os.environ.get("TRAJLAB_JIT_CACHE", Path.home() / ".cache" / "trajlab" / "jit"))


def digest(nlp: dict) -> str:
    """Content key of an NLP ``{"x", "p", "f", "g"}``: what the compiled derivatives depend on."""
    fn = ca.Function("nlp", [nlp["x"], nlp["p"]], [nlp["f"], nlp["g"]])
    h = hashlib.sha256(fn.serialize().encode())
    h.update(f"casadi {ca.CasadiMeta.version()} {' '.join(FLAGS)}".encode())
    return h.hexdigest()[:32]


def library(key: str) -> Path:
    return cache_dir() / f"nlp_{key}.so"


def skipped(key: str) -> bool:
    """Never compiled: this structure's C was over ``TRAJLAB_JIT_MAX_MB``, or the compiler rejected it."""
    return (cache_dir() / f"nlp_{key}.skip").exists()


def max_bytes() -> float:
    try:
        return float(os.environ.get("TRAJLAB_JIT_MAX_MB", "8")) * 1e6
    except ValueError:
        return 8e6


def load(key: str) -> dict | None:
    """nlpsol options ``{"hess_lag": ..., "jac_g": ...}`` from a cached library, or None."""
    path = library(key)
    if not path.exists():
        return None
    try:
        return {_OPTION[n]: ca.external(n, str(path)) for n in COMPILED}
    except RuntimeError:          # a truncated or foreign file: ignore it, it will be rebuilt
        return None


def digest_functions(fns: dict) -> str:
    """Content key of named functions compiled together (per-block derivatives,
    :mod:`solvers.transcription.blocks`)."""
    h = hashlib.sha256()
    for name in sorted(fns):
        h.update(name.encode())
        h.update(fns[name].serialize().encode())
    h.update(f"casadi {ca.CasadiMeta.version()} {' '.join(FLAGS)}".encode())
    return h.hexdigest()[:32]


def load_functions(key: str, names) -> dict | None:
    """``{name: external}`` from a cached library of named functions, or None."""
    path = library(key)
    if not path.exists():
        return None
    try:
        return {n: ca.external(n, str(path)) for n in names}
    except RuntimeError:
        return None


def sightings_needed() -> int:
    try:
        return max(1, int(os.environ.get("TRAJLAB_JIT_SEEN", "2")))
    except ValueError:
        return 2


def sight(key: str) -> int:
    """Count one sighting of the structure ``key`` (a line appended to ``nlp_<key>.seen``: O_APPEND
    writes of one short line do not interleave between processes); the number of sightings so far."""
    path = cache_dir() / f"nlp_{key}.seen"
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "a") as f:
        f.write(f"{os.getpid()}\n")
    with open(path) as f:
        return sum(1 for _ in f)


@contextlib.contextmanager
def expected_again():
    """Solvers built inside this block belong to structures that will come back (a preset, a study's
    point, a search that solves one structure many times): compiled on first sight in ``background``."""
    token = _EXPECTED_AGAIN.set(True)
    try:
        yield
    finally:
        _EXPECTED_AGAIN.reset(token)


def worth_compiling(key: str) -> bool:
    """Whether a structure missing from the cache is compiled now (and its sighting counted):
    always in ``sync``; in ``background`` when expected again or seen often enough."""
    seen = sight(key)
    return mode() == "sync" or _EXPECTED_AGAIN.get() or seen >= sightings_needed()


def _record(event: str, key: str) -> None:
    with open(cache_dir() / RECORDS, "a") as f:
        f.write(f"{time.time():.6f} {os.getpid()} {event} {key}\n")


def host_lock_path() -> Path:
    return Path(os.environ.get("TRAJLAB_JIT_LOCK") or Path(tempfile.gettempdir()) / "trajlab-jit-compile.lock")


@contextlib.contextmanager
def _flock(path: Path, *, required: bool):
    """An exclusive flock on ``path`` (blocks until its holder lets go; the kernel releases it if the holder
    dies).  Each call opens the file anew, so threads of one process exclude each other too.  A host-wide
    file that this user cannot open (another user's, in a sticky ``/tmp``) is skipped unless ``required``."""
    try:
        f = open(path, "a")
    except OSError:
        if required:
            raise
        f = None
    if f is None:
        yield
        return
    with f:
        fcntl.flock(f, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(f, fcntl.LOCK_UN)


@contextlib.contextmanager
def _host_lock(directory: Path):
    """One compile at a time on this host: the host-wide lock, then this cache directory's (always in
    that order, so two holders never wait for each other)."""
    with _flock(host_lock_path(), required=False), _flock(directory / LOCK_FILE, required=True):
        yield


try:
    _LIBC: ctypes.CDLL | None = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
except OSError:           # not Linux
    _LIBC = None
PR_SET_PDEATHSIG = 1


def _low_priority() -> None:
    """In the compiler's child between fork and exec (system calls only: safe in a process with threads).

    nice 19 alone does not keep a compile off the solves' cores: with the kernel's autogroup scheduling
    (``/proc/sys/kernel/sched_autogroup_enabled``, on by default) nice weighs only against processes of the
    same session, and the two pools are two sessions, so a compile started by an idle pool had its session's
    whole share against the other pool's solve.  Hence the compiler gets a session of its own
    (``start_new_session``) whose autogroup is at nice 19 too.  And the compiler driver dies with the thread
    that waits for it (``PR_SET_PDEATHSIG``): a pool killed mid-compile releases the lock, and an orphaned
    driver would go on to assemble and link beside the next compile.  A ``cc1`` the driver had started is not
    covered (the signal is not inherited): it finishes its translation unit alone, at nice 19, and exits."""
    os.nice(19)
    try:
        fd = os.open("/proc/self/autogroup", os.O_WRONLY)
        try:
            os.write(fd, b"19")
        finally:
            os.close(fd)
    except OSError:       # no autogroup (disabled, or not Linux): nice alone is what counts
        pass
    if _LIBC is not None:
        _LIBC.prctl(PR_SET_PDEATHSIG, signal.SIGKILL)


def build(solver: ca.Function, key: str, lock=None) -> bool:
    """Generate C for ``solver``'s Hessian and Jacobian and compile it into the cache (atomic).
    ``lock``: held while reading ``solver`` (not while compiling), so no solve runs meanwhile."""
    return _compile(lambda: [solver.get_function(name) for name in COMPILED], key, lock)


def build_functions(fns: dict, key: str, lock=None) -> bool:
    """Compile the named functions ``fns`` into one cached library (atomic)."""
    return _compile(lambda: list(fns.values()), key, lock)


def _compile(functions, key: str, lock=None) -> bool:
    cc = compiler()
    if cc is None:
        return False
    out = library(key)
    out.parent.mkdir(parents=True, exist_ok=True)
    with _host_lock(out.parent):
        if out.exists():          # compiled by whoever held the lock before us: never twice
            _record("found", key)
            return True
        if skipped(key):
            return False
        _record("start", key)
        try:
            return _generate_and_compile(cc, functions, key, lock)
        finally:
            _record("end", key)


def _generate_and_compile(cc: str, functions, key: str, lock) -> bool:
    out = library(key)
    with tempfile.TemporaryDirectory(dir=out.parent) as tmp:
        with lock or threading.Lock():
            gen = ca.CodeGenerator(f"nlp_{key}.c", {"with_header": False})
            for fn in functions():
                gen.add(fn)
            gen.generate(tmp + os.sep)
        source = Path(tmp) / f"nlp_{key}.c"
        if source.stat().st_size > max_bytes():
            (out.parent / f"nlp_{key}.skip").write_text(f"{source.stat().st_size} bytes of C\n")
            return False
        so = Path(tmp) / out.name
        res = subprocess.run([cc, *FLAGS, str(source), "-o", str(so), "-lm"],
                             capture_output=True, text=True, start_new_session=True, preexec_fn=_low_priority)
        if res.returncode > 0:    # the compiler rejected the code: remembered, like one over the cap
            (out.parent / f"nlp_{key}.skip").write_text(f"{cc} exit {res.returncode}: {res.stderr[-2000:]}\n")
            return False
        if res.returncode != 0 or not so.exists():     # killed (a signal): worth another try later
            return False
        os.replace(so, out)       # atomic: a reader sees no library or a whole one
    return True


def compile_async(solver: ca.Function | None, key: str, done, lock=None, *, fns: dict | None = None) -> None:
    """Compile in a daemon thread (once per key per process) and call ``done()`` when the
    library is in the cache: ``solver``'s derivatives, or the named functions ``fns``.  Solvers
    that share a key (the robust stages share their blocks) all get their ``done()``."""
    with _LOCK:
        if key in _PENDING:
            _PENDING[key].append(done)
            return
        _PENDING[key] = [done]

    def work():
        ok = False
        try:
            if fns is not None:
                ok = build_functions(fns, key, lock)
            elif solver is not None:
                ok = build(solver, key, lock)
        finally:
            with _LOCK:
                callbacks = _PENDING.pop(key, [])
        if ok:
            for cb in callbacks:
                cb()

    threading.Thread(target=work, name=f"jit-{key[:8]}", daemon=True).start()
