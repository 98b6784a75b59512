"""Compiled NLP derivatives (solvers.transcription.jit): cache by content, same answer, clean fallback."""
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
    # A new solver of the same structure (another job, another process) loads the library.
    s2, again = solve(toy_nlp())
    assert s2.compiled and again.status.details["compiled_derivatives"] and s2.build_time_s < 1.0


def test_without_a_compiler_it_falls_back_to_the_vm(cache, monkeypatch):
    monkeypatch.setenv("TRAJLAB_JIT", "sync")
    monkeypatch.setenv("PATH", "")
    s, r = solve(toy_nlp())
    assert not s.compiled and r.status.ok and not list(cache.glob("*.so"))


@pytest.mark.skipif(jit.compiler() is None, reason="no C compiler on PATH")
def test_background_mode_solves_at_once_then_swaps_in_the_library(cache, monkeypatch):
    import time
    monkeypatch.setenv("TRAJLAB_JIT", "background")
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
