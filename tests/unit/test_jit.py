"""Compiled NLP derivatives (solvers.transcription.jit): cache by content, same answer, clean fallback."""
import time

import casadi as ca
import numpy as np
import pytest

from solvers.transcription import jit
from solvers.transcription.nlp import NLPSolver


def toy_nlp(scale=1.0):
    """Rosenbrock with a parameter and a nonlinear constraint: small, so its C compiles in a second."""
    x, p = ca.MX.sym("x", 2), ca.MX.sym("p")
    f = (p - x[0]) ** 2 + 100 * scale * (x[1] - x[0] ** 2) ** 2
    return {"x": x, "p": p, "f": f, "g": ca.sin(x[0]) + x[1] ** 2}


def solve(nlp):
    s = NLPSolver(nlp, name="toy")
    r = s.solve(x0=[-1.0, 1.0], lbx=[-5, -5], ubx=[5, 5], lbg=[-ca.inf], ubg=[1.5], p=[1.2])
    return s, r


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("TRAJLAB_JIT_CACHE", str(tmp_path))
    return tmp_path


def test_key_is_the_content():
    assert jit.digest(toy_nlp()) == jit.digest(toy_nlp())
    assert jit.digest(toy_nlp()) != jit.digest(toy_nlp(scale=2.0))


@pytest.mark.skipif(jit.compiler() is None, reason="no C compiler on PATH")
def test_compiled_solver_gives_the_vm_answer_and_is_reused(cache, monkeypatch):
    monkeypatch.setenv("TRAJLAB_JIT", "off")
    _, vm = solve(toy_nlp())
    assert not vm.status.details["compiled_derivatives"]
    monkeypatch.setenv("TRAJLAB_JIT", "sync")
    s, compiled = solve(toy_nlp())
    assert s.compiled and compiled.status.details["compiled_derivatives"]
    assert list(cache.glob("nlp_*.so")) == [jit.library(jit.digest(toy_nlp()))]
    assert compiled.status.ok and compiled.status.iterations == vm.status.iterations
    np.testing.assert_allclose(compiled.x, vm.x, rtol=0, atol=1e-12)
    # A new solver of the same structure (another job, another process) loads the library: the same file,
    # not compiled again (its inode and modification time unchanged; a time bound would measure the machine).
    lib = jit.library(jit.digest(toy_nlp()))
    before = (lib.stat().st_ino, lib.stat().st_mtime_ns)
    s2, again = solve(toy_nlp())
    assert s2.compiled and again.status.details["compiled_derivatives"]
    assert (lib.stat().st_ino, lib.stat().st_mtime_ns) == before


def test_without_a_compiler_it_falls_back_to_the_vm(cache, monkeypatch):
    monkeypatch.setenv("TRAJLAB_JIT", "sync")
    monkeypatch.setenv("PATH", "")
    s, r = solve(toy_nlp())
    assert not s.compiled and r.status.ok and not list(cache.glob("*.so"))


@pytest.mark.skipif(jit.compiler() is None, reason="no C compiler on PATH")
def test_background_mode_solves_at_once_then_swaps_in_the_library(cache, monkeypatch):
    monkeypatch.setenv("TRAJLAB_JIT", "background")
    with jit.expected_again():              # compiled on first sight (a preset, a study's point)
        s, first = solve(toy_nlp(scale=3.0))
    assert first.status.ok                  # answered without waiting for the compiler
    deadline = time.monotonic() + 60
    while not s.compiled and time.monotonic() < deadline:
        time.sleep(0.05)
    assert s.compiled
    again = s.solve(x0=[-1.0, 1.0], lbx=[-5, -5], ubx=[5, 5], lbg=[-ca.inf], ubg=[1.5], p=[1.2])
    assert again.status.details["compiled_derivatives"]
    np.testing.assert_allclose(again.x, first.x, rtol=0, atol=1e-12)


@pytest.mark.skipif(jit.compiler() is None, reason="no C compiler on PATH")
def test_code_over_the_size_cap_is_never_compiled(cache, monkeypatch):
    monkeypatch.setenv("TRAJLAB_JIT", "sync")
    monkeypatch.setenv("TRAJLAB_JIT_MAX_MB", "0.001")     # the toy's C is ~10 kB
    s, r = solve(toy_nlp(scale=5.0))
    key = jit.digest(toy_nlp(scale=5.0))
    assert r.status.ok and not s.compiled and jit.skipped(key) and not jit.library(key).exists()
    s2, _ = solve(toy_nlp(scale=5.0))          # remembered across solvers (and processes)
    assert not s2.compiled


def test_background_compiles_only_structures_that_come_back(cache, monkeypatch):
    """Posed once: no compile; seen a second time (in any process: the count is on disk) or expected
    again by the caller: compiled.  sync always compiles."""
    monkeypatch.setenv("TRAJLAB_JIT", "background")
    key = jit.digest(toy_nlp(scale=7.0))
    assert not jit.worth_compiling(key)
    assert jit.worth_compiling(key)                     # the second sighting
    assert (cache / f"nlp_{key}.seen").read_text().count("\n") == 2
    other = jit.digest(toy_nlp(scale=8.0))
    with jit.expected_again():
        assert jit.worth_compiling(other)
    monkeypatch.setenv("TRAJLAB_JIT_SEEN", "3")
    third = jit.digest(toy_nlp(scale=9.0))
    assert [jit.worth_compiling(third) for _ in range(3)] == [False, False, True]
    monkeypatch.setenv("TRAJLAB_JIT", "sync")
    assert jit.worth_compiling(jit.digest(toy_nlp(scale=10.0)))


# Compiles two toy structures in the order given (TRAJLAB_JIT=sync: each is built at once, under the
# host's compile lock); run as two processes at once by the test below.
_COMPILE_BOTH = """
import sys
from tests.unit.test_jit import toy_nlp
from solvers.transcription.nlp import NLPSolver
for scale in map(float, sys.argv[1:]):
    assert NLPSolver(toy_nlp(scale=scale), name="toy").compiled
"""


@pytest.mark.skipif(jit.compiler() is None, reason="no C compiler on PATH")
def test_two_processes_compile_one_at_a_time_and_each_structure_once(cache):
    """Two processes want the same two structures, in opposite orders, at the same moment: the records
    in the cache directory show one compiler at a time (every start followed by its own end before the
    next start) and one compile per structure."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    env = {**os.environ, "TRAJLAB_JIT": "sync", "TRAJLAB_JIT_CACHE": str(cache), "PYTHONPATH": str(root)}
    procs = [subprocess.Popen([sys.executable, "-c", _COMPILE_BOTH, *order], env=env, cwd=root)
             for order in (["11", "12"], ["12", "11"])]
    assert [p.wait(timeout=300) for p in procs] == [0, 0]
    keys = {jit.digest(toy_nlp(scale=s)) for s in (11.0, 12.0)}
    records = [line.split() for line in (cache / jit.RECORDS).read_text().splitlines()]
    events = [(pid, event, key) for _, pid, event, key in records]
    compiles = [e for e in events if e[1] != "found"]
    assert [e[1] for e in compiles] == ["start", "end"] * 2           # never two at once
    assert all(a[0] == b[0] and a[2] == b[2] for a, b in zip(compiles[::2], compiles[1::2]))
    assert sorted(e[2] for e in compiles[::2]) == sorted(keys)        # each structure once
    compiled_by = {key: pid for pid, _, key in compiles[::2]}
    # a process that waited for the lock found the other's library done (one that came later loaded it)
    assert all(compiled_by[key] != pid for pid, event, key in events if event == "found")
    assert all(jit.library(k).exists() for k in keys)


@pytest.mark.skipif(jit.compiler() is None, reason="no C compiler on PATH")
def test_a_structure_handed_out_again_by_the_solver_cache_is_a_sighting(cache, monkeypatch):
    """A worker keeps built solvers (nlp.cached_solver): the same structure in the next job, or a search's next
    start, never builds it again, so the cache's hit is what says the structure came back."""
    from solvers.transcription import nlp as nlp_mod

    monkeypatch.setenv("TRAJLAB_JIT", "background")
    nlp_mod.clear_cache()
    key = jit.digest(toy_nlp(scale=13.0))
    first, cached = nlp_mod.cached_solver(("toy", 13), lambda: NLPSolver(toy_nlp(scale=13.0), name="toy"))
    assert not cached and not first.compiled
    assert (cache / f"nlp_{key}.seen").read_text().count("\n") == 1 and not (cache / jit.RECORDS).exists()
    again, cached = nlp_mod.cached_solver(("toy", 13), lambda: pytest.fail("built again"))
    assert cached and again is first
    deadline = time.monotonic() + 60
    while not first.compiled and time.monotonic() < deadline:
        time.sleep(0.05)
    assert first.compiled and jit.library(key).exists()
    assert [line.split()[2] for line in (cache / jit.RECORDS).read_text().splitlines()] == ["start", "end"]
    nlp_mod.clear_cache()


def test_two_holders_of_the_host_lock_never_overlap(cache, tmp_path, monkeypatch):
    """The host-wide lock is taken before the cache directory's: two cache directories (two services, a test and
    a service) still compile one at a time."""
    import threading

    monkeypatch.setenv("TRAJLAB_JIT_LOCK", str(tmp_path / "host.lock"))
    inside, overlaps = [], []

    def hold(directory):
        directory.mkdir(exist_ok=True)
        with jit._host_lock(directory):
            inside.append(1)
            overlaps.append(len(inside))
            time.sleep(0.2)
            inside.pop()

    threads = [threading.Thread(target=hold, args=(tmp_path / name,)) for name in ("a", "b", "c")]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert overlaps == [1, 1, 1]


@pytest.mark.skipif(jit.compiler() is None, reason="no C compiler on PATH")
def test_code_the_compiler_rejects_is_not_tried_again(cache, monkeypatch, tmp_path):
    monkeypatch.setenv("TRAJLAB_JIT", "sync")
    fake = tmp_path / "bin"
    fake.mkdir()
    (fake / "cc").write_text("#!/bin/sh\necho 'cc1: out of memory' >&2\nexit 1\n")
    (fake / "cc").chmod(0o755)
    monkeypatch.setenv("PATH", f"{fake}:/usr/bin:/bin")
    s, r = solve(toy_nlp(scale=14.0))
    key = jit.digest(toy_nlp(scale=14.0))
    assert r.status.ok and not s.compiled and jit.skipped(key)
    assert "out of memory" in (cache / f"nlp_{key}.skip").read_text()
