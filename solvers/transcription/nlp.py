"""CasADi + IPOPT layer shared by every transcription.

What it adds on top of ``casadi.nlpsol``:

* **Build once, solve many**: :func:`cached_solver` keeps built solvers keyed by
  problem *structure* (grid size, which constraints exist, options), so a second
  job with the same structure skips the symbolic build and the code generation.
* **Progress and cooperative cancellation**: every built solver carries an
  iteration hook whose handler is swapped per solve; the handler reports
  ``(iteration, objective, infeasibility)`` and returns True to stop IPOPT
  (IPOPT then answers ``User_Requested_Stop``).
* **One status vocabulary**: IPOPT's ``return_status`` mapped to
  :class:`solvers.common.Outcome`, the solver's own word kept verbatim.
"""
from __future__ import annotations

import math
import threading
import time
from collections import OrderedDict
from dataclasses import dataclass, field
from typing import Any, Callable

import casadi as ca
import numpy as np

from solvers.common import Outcome, ProgressFn, SolveStatus, StopFn
from solvers.transcription import jit

_OPTIMAL = {"Solve_Succeeded", "Solved_To_Acceptable_Level"}
_INFEASIBLE = {"Infeasible_Problem_Detected"}
_NOT_CONVERGED = {
    "Maximum_Iterations_Exceeded",
    "Maximum_CpuTime_Exceeded",
    "Maximum_WallTime_Exceeded",
    "Diverging_Iterates",
    "Search_Direction_Becomes_Too_Small",
    "Restoration_Failed",
    "Error_In_Step_Computation",
    "Feasible_Point_Found",
}


def outcome_of(return_status: str, *, stopped: bool = False) -> Outcome:
    """Map IPOPT's ``return_status`` onto the service's outcome vocabulary."""
    if stopped or return_status == "User_Requested_Stop":
        return Outcome.CANCELLED
    if return_status in _OPTIMAL:
        return Outcome.OPTIMAL
    if return_status in _INFEASIBLE:
        return Outcome.INFEASIBLE
    if return_status in _NOT_CONVERGED:
        return Outcome.NOT_CONVERGED
    return Outcome.FAILED


@dataclass
class IterationInfo:
    iteration: int
    objective: float
    infeasibility: float
    x: np.ndarray


class _IterationHook(ca.Callback):
    """IPOPT iteration callback whose handler is replaced for each solve.

    CasADi fixes ``iteration_callback`` when the solver is built; a swappable
    handler lets one cached solver serve many jobs with their own progress and
    stop functions.
    """

    def __init__(self, name: str, nx: int, ng: int, np_: int):
        ca.Callback.__init__(self)
        self.nx, self.ng, self.np_ = nx, ng, np_
        self.handler: Callable[[dict], bool] | None = None
        self.construct(name, {})

    def get_n_in(self):
        return ca.nlpsol_n_out()

    def get_n_out(self):
        return 1

    def get_name_in(self, i):
        return ca.nlpsol_out(i)

    def get_name_out(self, i):
        return "ret"

    def get_sparsity_in(self, i):
        n = ca.nlpsol_out(i)
        if n == "f":
            return ca.Sparsity.scalar()
        if n in ("x", "lam_x"):
            return ca.Sparsity.dense(self.nx)
        if n in ("g", "lam_g"):
            return ca.Sparsity.dense(self.ng)
        return ca.Sparsity.dense(self.np_)

    def eval(self, arg):
        if self.handler is None:
            return [0]
        out = dict(zip((ca.nlpsol_out(i) for i in range(ca.nlpsol_n_out())), arg))
        return [1 if self.handler(out) else 0]


DEFAULT_IPOPT = {
    "print_level": 0,
    "sb": "yes",
    "max_iter": 1000,
    "tol": 1e-8,
    "acceptable_tol": 1e-6,
    "mu_strategy": "adaptive",
    "linear_solver": "mumps",
}


class NLPSolver:
    """A built IPOPT solver plus its iteration hook. Thread-safe per instance."""

    def __init__(self, nlp: dict, *, name: str = "nlp", ipopt: dict | None = None,
                 casadi_options: dict | None = None, blocks=None):
        """``blocks``: a :class:`solvers.transcription.blocks.BlockDerivatives` whose assembled
        Hessian and Jacobian replace CasADi's (and whose block functions are what is compiled)."""
        nx = int(nlp["x"].numel())
        ng = int(nlp["g"].numel())
        np_ = int(nlp["p"].numel()) if "p" in nlp else 0
        self.nx, self.ng, self.np_ = nx, ng, np_
        self.hook = _IterationHook(f"{name}_hook", nx, ng, np_)
        # how the builder that made this solver reads its x and g back (the builder's own type); a cached
        # solver carries it to the next problem of the same structure
        self.layout: Any = None
        opts: dict[str, Any] = {
            "ipopt": {**DEFAULT_IPOPT, **(ipopt or {})},
            "print_time": False,
            "iteration_callback": self.hook,
            "error_on_fail": False,
        }
        opts.update(casadi_options or {})
        self._lock = threading.Lock()
        self._nlp, self._name, self._opts, self._blocks = nlp, name, opts, blocks
        # Compiled derivatives (solvers.transcription.jit): from the disk cache when this
        # structure was compiled before, else (mode permitting) compiled now or in the background.
        key = None
        if jit.mode() != "off" and "p" in nlp and jit.compiler():
            key = jit.digest(nlp) if blocks is None else jit.digest_functions(blocks.functions)
        ext = self._compiled_options(key) if key else None
        self.compiled = ext is not None
        t0 = time.perf_counter()
        if ext is None and blocks is not None:
            ext = blocks.nlpsol_options(nlp)         # the blocks in the virtual machine
        self.solver = ca.nlpsol(name, "ipopt", nlp, {**opts, **(ext or {})})
        self._key = key
        self.sighted()
        self.build_time_s = time.perf_counter() - t0

    def sighted(self) -> None:
        """This structure is wanted (built, or handed out again by :func:`cached_solver`: another job of it, a
        search's next start): one sighting for the JIT's policy, and the compile once it pays."""
        key = self._key
        if not key or self.compiled or jit.skipped(key) or not jit.worth_compiling(key):
            return
        fns = None if self._blocks is None else self._blocks.functions
        if jit.mode() == "sync":
            if jit.build(self.solver, key) if fns is None else jit.build_functions(fns, key):
                self._use_compiled(key)
        else:
            jit.compile_async(self.solver, key, lambda: self._use_compiled(key), self._lock, fns=fns)

    def _compiled_options(self, key: str) -> dict | None:
        """nlpsol options with the compiled library of ``key``, or None when it is not cached."""
        if self._blocks is None:
            return jit.load(key)
        impl = jit.load_functions(key, self._blocks.functions)
        return None if impl is None else self._blocks.nlpsol_options(self._nlp, impl)

    def _use_compiled(self, key: str) -> None:
        """Swap in the solver whose Hessian and Jacobian are the compiled library's."""
        ext = self._compiled_options(key)
        if ext is None:
            return
        solver = ca.nlpsol(self._name, "ipopt", self._nlp, {**self._opts, **ext})
        with self._lock:
            self.solver, self.compiled = solver, True

    def solve(self, *, x0, lbx, ubx, lbg, ubg, p=None, on_progress: ProgressFn | None = None,
              should_stop: StopFn | None = None, progress_span: tuple[float, float] = (0.0, 1.0),
              label: str = "IPOPT", expected_iterations: int = 60,
              lam_x0=None, lam_g0=None) -> "NLPResult":
        """Solve from ``x0``; progress is mapped into ``progress_span`` of the job."""
        lbg = np.asarray(lbg, float)
        ubg = np.asarray(ubg, float)
        lo, hi = progress_span
        state: dict[str, Any] = {"iter": 0, "stopped": False, "best": None}

        def handler(out: dict) -> bool:
            it = state["iter"]
            state["iter"] = it + 1
            g = np.asarray(out["g"]).ravel()
            inf = float(np.max(np.maximum(np.maximum(lbg - g, g - ubg), 0.0), initial=0.0))
            f = float(out["f"])
            if on_progress is not None:
                # IPOPT gives no total; a saturating map keeps progress monotone and < hi.
                frac = lo + (hi - lo) * (1.0 - math.exp(-it / max(expected_iterations, 1)))
                on_progress(frac, f"{label} iteration {it}: objective {f:.6g}, infeasibility {inf:.2e}")
            if should_stop is not None and should_stop():
                state["stopped"] = True
                return True
            return False

        args = {"x0": x0, "lbx": lbx, "ubx": ubx, "lbg": lbg, "ubg": ubg}
        if p is not None:
            args["p"] = p
        if lam_x0 is not None:
            args["lam_x0"] = lam_x0
        if lam_g0 is not None:
            args["lam_g0"] = lam_g0
        with self._lock:
            self.hook.handler = handler
            t0 = time.perf_counter()
            try:
                sol = self.solver(**args)
            finally:
                self.hook.handler = None
            solve_time = time.perf_counter() - t0
            stats = self.solver.stats()
            compiled = self.compiled
        x = np.asarray(sol["x"]).ravel()
        g = np.asarray(sol["g"]).ravel()
        viol_g = np.maximum(np.maximum(lbg - g, g - ubg), 0.0)
        viol_x = np.maximum(np.maximum(np.asarray(lbx, float) - x, x - np.asarray(ubx, float)), 0.0)
        max_viol = float(max(np.max(viol_g, initial=0.0), np.max(viol_x, initial=0.0)))
        rs = str(stats.get("return_status", "unknown"))
        outcome = outcome_of(rs, stopped=state["stopped"])
        return NLPResult(
            x=x, g=g, f=float(sol["f"]),
            lam_x=np.asarray(sol["lam_x"]).ravel(), lam_g=np.asarray(sol["lam_g"]).ravel(),
            status=SolveStatus(
                outcome=outcome, solver_status=rs,
                message=f"IPOPT: {rs}; worst constraint violation {max_viol:.3e} (scaled)",
                iterations=int(stats.get("iter_count", state["iter"])),
                build_time_s=self.build_time_s, solve_time_s=solve_time,
                max_constraint_violation=max_viol,
                details={"worst_constraint_index": int(np.argmax(viol_g)) if viol_g.size else None,
                         "compiled_derivatives": compiled},
            ),
        )


@dataclass
class NLPResult:
    x: np.ndarray
    g: np.ndarray
    f: float
    lam_x: np.ndarray
    lam_g: np.ndarray
    status: SolveStatus = field(default_factory=lambda: SolveStatus(Outcome.FAILED))


_CACHE: "OrderedDict[tuple, NLPSolver]" = OrderedDict()
_CACHE_LOCK = threading.Lock()
CACHE_SIZE = 16


def clear_cache() -> None:
    """Forget every built solver (benchmarks time a cold build with it)."""
    with _CACHE_LOCK:
        _CACHE.clear()


def cached_solver(key: tuple, build: Callable[[], NLPSolver]) -> tuple[NLPSolver, bool]:
    """Return ``(solver, was_cached)`` for a problem structure ``key`` (hashable).

    The key must capture everything the symbolic graph depends on; numerical
    data that varies between jobs (initial state, bounds, limits) should be
    NLP parameters or bounds so it does not fragment the cache.
    """
    with _CACHE_LOCK:
        hit = _CACHE.get(key)
        if hit is not None:
            _CACHE.move_to_end(key)
    if hit is not None:
        hit.sighted()           # the structure came back: it may now be worth compiling (solvers.transcription.jit)
        return hit, True
    solver = build()
    with _CACHE_LOCK:
        _CACHE[key] = solver
        _CACHE.move_to_end(key)
        while len(_CACHE) > CACHE_SIZE:
            _CACHE.popitem(last=False)
    return solver, False
