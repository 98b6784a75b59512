"""Monte Carlo validation of open-loop controls under constant uncertain parameters, in mergeable chunks.

Paper 001 validates its deterministic and robust designs with 10,000 runs of the
open-loop controls through the dynamics with sampled aerodynamic errors.  Here
all samples of a chunk are integrated together: the state is an (nx, N) array
and one classical RK4 step advances every sample (a Python loop over samples
would be 100x slower; see ``benchmarks/robust.py``).  Controls are linear
between the NLP nodes, as in the multiple-shooting transcription (paper 000).

Scale-out: :func:`simulate_chunk` is a pure function of a JSON-serializable
spec, a seed and a sample range; it returns mergeable partial statistics
(counts, and per quantity ``n, mean, M2`` combined with Chan et al.'s parallel
update).  Sample ``i`` always draws from the same random stream (block
``i // BLOCK`` of a :class:`numpy.random.SeedSequence`), so any split of the
sample range over workers gives the statistics of one process.
:func:`merge_chunks` folds a list of partials into the summary.

For plots a model may name ``trace`` quantities (e.g. altitude, speed, heating rate): each chunk
keeps their mean and ``M2`` at up to ``MAX_TRACE_TIMES`` node times (merged like the terminal
moments: the envelope), their histories for the samples with index below ``MAX_TRACE_SAMPLES``
and the ``sampled_terminal`` quantities of those below ``MAX_TERMINAL_SAMPLES``; chunks are merged
in sample order, so the kept samples are the first ones whatever the split.

Dynamics are named in the spec (``"model"``), resolved through a registry of
factories so a worker in another process can rebuild them from the name and
``model_params``.
"""
from __future__ import annotations

import importlib
import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

BLOCK = 256
"""Samples per random block: the granularity of the per-sample stream (not of the chunks)."""
MAX_TRACE_TIMES = 200        # node times of the envelope and the sample traces
MAX_TRACE_SAMPLES = 200      # samples whose trace histories are kept
MAX_TERMINAL_SAMPLES = 2000  # samples whose sampled_terminal values are kept

ArrayFn = Callable[..., np.ndarray]


@dataclass
class PathConstraint:
    """``fn(x, u, s) <= limit`` sample-wise; ``fn`` returns shape (N,)."""

    fn: ArrayFn
    limit: float


@dataclass
class MCModel:
    """What the Monte Carlo needs to know about a system (numpy, SI, radians).

    ``rhs(x, u, s)``: x (nx, N), u (nu, N), s (ns, N) -> (nx, N).
    ``terminal(x, x0=, s=)``: dict of named terminal quantities, each (N,), from the final states and each
    sample's draw (initial state and parameters: an objective in initial values or in an uncertain constant,
    as an ``ocp`` problem's Mayer term may be; a model that needs neither ignores them).
    ``trace(x, u, s)``: optional dict of named quantities, each (N,), recorded over time for plots;
    ``sampled_terminal``: names of ``terminal`` quantities kept per sample for plots.
    """

    nx: int
    nu: int
    ns: int
    rhs: ArrayFn
    terminal: Callable[..., dict[str, np.ndarray]]
    path: dict[str, PathConstraint] = field(default_factory=dict)
    trace: Callable[..., dict[str, np.ndarray]] | None = None
    sampled_terminal: tuple[str, ...] = ()
    # Optional compiled propagation of a whole chunk, used instead of rhs/path/trace when set:
    # kernel(x0=, s=, t_nodes=, controls=, substeps=, kept_nodes=) -> (xf, worst_fine, worst_node,
    # traces), the last three dicts by path or trace name; the same RK4, steps and checks.
    kernel: Callable[..., tuple] | None = None


_REGISTRY: dict[str, Callable[[dict], MCModel]] = {}
_LAZY = {
    # Resolved on first use so that importing this module stays cheap and a worker
    # needs nothing but the name.
    "shuttle_reentry": "solvers.robust_reentry.mc:monte_carlo_model",
    "ocp": "solvers.ocp.robust.montecarlo:monte_carlo_model",
}


def register_model(name: str, factory: Callable[[dict], MCModel]) -> None:
    """Make ``factory(model_params) -> MCModel`` available under ``name``."""
    _REGISTRY[name] = factory


def resolve_model(name: str, params: dict | None = None) -> MCModel:
    if name not in _REGISTRY:
        if name not in _LAZY:
            raise KeyError(f"unknown Monte Carlo model {name!r}")
        mod, attr = _LAZY[name].split(":")
        _REGISTRY[name] = getattr(importlib.import_module(mod), attr)
    return _REGISTRY[name](params or {})


# -- random streams -----------------------------------------------------------------
def _sqrt_cov(cov) -> np.ndarray:
    """A square root of a PSD covariance (eigen, so singular covariances are fine)."""
    cov = np.atleast_2d(np.asarray(cov, float))
    w, V = np.linalg.eigh(0.5 * (cov + cov.T))
    return V * np.sqrt(np.maximum(w, 0.0))


def standard_normals(seed: int, start: int, count: int, dim: int) -> np.ndarray:
    """Standard normals (dim, count) for samples ``start .. start+count-1``, independent of chunking."""
    out = np.empty((dim, count))
    if count == 0:
        return out
    first, last = start // BLOCK, (start + count - 1) // BLOCK
    ss = np.random.SeedSequence(seed)
    pos = 0
    for b in range(first, last + 1):
        rng = np.random.default_rng(np.random.SeedSequence(ss.entropy, spawn_key=(b,)))
        block = rng.standard_normal((BLOCK, dim))
        lo = max(start, b * BLOCK) - b * BLOCK
        hi = min(start + count, (b + 1) * BLOCK) - b * BLOCK
        out[:, pos:pos + hi - lo] = block[lo:hi].T
        pos += hi - lo
    return out


def draw_samples(spec: dict, seed: int, start: int, count: int, *, nx: int, ns: int):
    """Initial states (nx, count) and parameters (ns, count) of samples ``start..``.

    ``spec["s_uniform"]`` (optional, one entry per parameter): ``[lower, upper]`` draws that parameter
    uniformly (the normal CDF of its own standard normal, so the stream stays the same whatever the
    split), ``null`` keeps the normal law of ``s_mean``, ``s_cov``.
    """
    z = standard_normals(seed, start, count, nx + ns)
    x0 = np.asarray(spec["x0_mean"], float)[:, None] + np.zeros((nx, count))
    if spec.get("x0_cov") is not None:
        x0 = x0 + _sqrt_cov(spec["x0_cov"]) @ z[:nx]
    s = np.asarray(spec["s_mean"], float)[:, None] + _sqrt_cov(spec["s_cov"]) @ z[nx:]
    for i, band in enumerate(spec.get("s_uniform") or []):
        if band is not None:
            from scipy.special import ndtr
            s[i] = band[0] + (band[1] - band[0]) * ndtr(z[nx + i])
    return x0, s


# -- integration ----------------------------------------------------------------------
def propagate(model: MCModel, *, x0, s, t_nodes, controls, substeps: int,
              on_step: Callable[[int, int, np.ndarray, np.ndarray], None] | None = None) -> np.ndarray:
    """RK4 of all samples along node controls (nu, n+1), linear in between.

    ``on_step(k, j, x, u)`` sees the state after substep ``j`` (1..substeps) of interval
    ``k`` with the control there, and ``j = 0, k = 0`` for the initial state.
    """
    t_nodes = np.asarray(t_nodes, float)
    U = np.asarray(controls, float).reshape(model.nu, -1)
    x = np.array(x0, float, copy=True)
    n_s = x.shape[1]
    if on_step is not None:
        on_step(0, 0, x, np.repeat(U[:, :1], n_s, axis=1))
    for k in range(t_nodes.size - 1):
        h = (t_nodes[k + 1] - t_nodes[k]) / substeps
        du = U[:, k + 1] - U[:, k]
        for j in range(substeps):
            ua = (U[:, k] + (j / substeps) * du)[:, None]
            ub = (U[:, k] + ((j + 0.5) / substeps) * du)[:, None]
            uc = (U[:, k] + ((j + 1) / substeps) * du)[:, None]
            k1 = model.rhs(x, ua, s)
            k2 = model.rhs(x + 0.5 * h * k1, ub, s)
            k3 = model.rhs(x + 0.5 * h * k2, ub, s)
            k4 = model.rhs(x + h * k3, uc, s)
            x = x + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
            if on_step is not None:
                on_step(k, j + 1, x, np.broadcast_to(uc, (model.nu, n_s)))
    return x


# -- chunks ---------------------------------------------------------------------------
def _moments(v: np.ndarray) -> dict:
    n = int(v.size)
    if n == 0:
        return {"n": 0, "mean": 0.0, "m2": 0.0}
    mean = float(np.mean(v))
    return {"n": n, "mean": mean, "m2": float(np.sum((v - mean) ** 2))}


def _merge_moments(a: dict, b: dict) -> dict:
    n = a["n"] + b["n"]
    if n == 0:
        return {"n": 0, "mean": 0.0, "m2": 0.0}
    d = b["mean"] - a["mean"]
    mean = a["mean"] + d * b["n"] / n
    m2 = a["m2"] + b["m2"] + d * d * a["n"] * b["n"] / n
    return {"n": n, "mean": mean, "m2": m2}


def trace_nodes(n_nodes: int) -> np.ndarray:
    """Indices of the node times the envelope is kept at: all of them up to ``MAX_TRACE_TIMES``."""
    if n_nodes <= MAX_TRACE_TIMES:
        return np.arange(n_nodes)
    return np.unique(np.linspace(0, n_nodes - 1, MAX_TRACE_TIMES).round().astype(int))


def simulate_chunk(spec: dict, seed: int, start_index: int, count: int) -> dict:
    """Simulate samples ``start_index .. start_index+count-1`` and return mergeable partial statistics.

    ``spec`` (JSON-serializable): ``model``, ``model_params``, ``t_nodes`` (n+1),
    ``controls`` (nu lists of n+1), ``x0_mean``, ``x0_cov`` (or null), ``s_mean``,
    ``s_cov``, ``substeps`` (RK4 steps per interval, also the fine check grid),
    ``required`` ({quantity: value}) and ``bands`` ({quantity: {band: half width}})
    for the "within required value +- band" counts; optional ``propagator``: ``"numpy"`` forces
    the numpy RK4 where the model also has a compiled kernel (the reference, for checks).
    """
    model = resolve_model(spec["model"], spec.get("model_params"))
    x0, s = draw_samples(spec, seed, start_index, count, nx=model.nx, ns=model.ns)
    substeps = int(spec.get("substeps", 10))
    names = list(model.path)
    worst_fine = {nm: np.full(count, -np.inf) for nm in names}
    worst_node = {nm: np.full(count, -np.inf) for nm in names}
    t_nodes = np.asarray(spec["t_nodes"], float)
    kept_nodes = trace_nodes(t_nodes.size) if model.trace is not None else np.arange(0)
    row_of_node = {int(node): row for row, node in enumerate(kept_nodes)}
    traces: dict[str, np.ndarray] = {}

    trace = model.trace

    def on_step(k, j, x, u):
        node = 0 if j == 0 else (k + 1 if j == substeps else -1)
        row = row_of_node.get(node)
        if row is not None and trace is not None:
            for q, v in trace(x, u, s).items():
                if q not in traces:
                    traces[q] = np.full((kept_nodes.size, count), np.nan)
                traces[q][row] = v
        for nm in names:
            c = model.path[nm].fn(x, u, s)
            c = np.where(np.isfinite(c), c, np.inf)
            np.maximum(worst_fine[nm], c, out=worst_fine[nm])
            if j == 0 or j == substeps:
                np.maximum(worst_node[nm], c, out=worst_node[nm])

    with np.errstate(all="ignore"):
        if model.kernel is not None and spec.get("propagator", "compiled") != "numpy":
            xf, worst_fine, worst_node, traces = model.kernel(
                x0=x0, s=s, t_nodes=t_nodes, controls=spec["controls"], substeps=substeps, kept_nodes=kept_nodes)
            if model.trace is None:
                traces = {}
        else:
            xf = propagate(model, x0=x0, s=s, t_nodes=spec["t_nodes"], controls=spec["controls"],
                           substeps=substeps, on_step=on_step)
        term = model.terminal(xf, x0=x0, s=s)
    ok = np.all(np.isfinite(xf), axis=0)
    out: dict = {"count": int(count), "failed": int(count - ok.sum()), "terminal": {}, "within": {},
                 "path": {}}
    required = spec.get("required", {})
    bands = spec.get("bands", {})
    for q, v in term.items():
        v = np.asarray(v, float)
        out["terminal"][q] = _moments(v[ok])
        if q in required:
            dev = np.abs(v - float(required[q]))
            out["within"][q] = {b: int(np.sum(ok & (dev <= float(w)))) for b, w in bands.get(q, {}).items()}
    for nm in names:
        lim = model.path[nm].limit
        out["path"][nm] = {
            "kept_fine": int(np.sum(ok & (worst_fine[nm] <= lim))),
            "kept_nodes": int(np.sum(ok & (worst_node[nm] <= lim))),
            "worst": float(np.max(worst_fine[nm], initial=-np.inf)) if count else None,
            "limit": float(lim),
        }
    if model.trace is not None:
        out["trace"] = _trace_partial(traces, ok, t_nodes[kept_nodes], start_index)
    first = max(0, min(count, MAX_TERMINAL_SAMPLES - start_index))
    out["terminal_samples"] = {q: np.asarray(term[q], float)[:first].tolist() for q in model.sampled_terminal}
    return out


def _trace_partial(traces: dict[str, np.ndarray], ok: np.ndarray, t_s: np.ndarray, start_index: int) -> dict:
    """Per trace quantity: moments over the finite samples at each kept time, and the histories
    of the samples with index below ``MAX_TRACE_SAMPLES`` (NaN where a sample failed)."""
    first = max(0, min(ok.size, MAX_TRACE_SAMPLES - start_index))
    n = int(ok.sum())
    moments, histories = {}, {}
    for q, v in traces.items():
        good = v[:, ok]
        mean = good.mean(axis=1) if n else np.zeros(v.shape[0])
        moments[q] = {"mean": mean.tolist(), "m2": ((good - mean[:, None]) ** 2).sum(axis=1).tolist()}
        histories[q] = v[:, :first].T.tolist()
    return {"t_s": t_s.tolist(), "n": n, "moments": moments, "samples": histories}


def _merge_traces(parts: list[dict]) -> tuple[dict, dict]:
    """The envelope (mean, std per kept time) and the first samples' histories, from chunk traces."""
    envelope: dict = {"t_s": parts[0]["t_s"]}
    histories: dict = {}
    for q in parts[0]["moments"]:
        acc: dict | None = None
        for p in parts:
            mom = {"n": p["n"], "mean": np.asarray(p["moments"][q]["mean"], float),
                   "m2": np.asarray(p["moments"][q]["m2"], float)}
            acc = mom if acc is None else _merge_moments(acc, mom)
        assert acc is not None  # parts is never empty
        std = np.sqrt(acc["m2"] / (acc["n"] - 1)) if acc["n"] > 1 else np.zeros_like(acc["mean"])
        ones = np.ones(len(envelope["t_s"]))  # all samples failed: the moments are scalars
        envelope[q] = {"mean": (acc["mean"] * ones).tolist(), "std": (std * ones).tolist()}
        histories[q] = [row for p in parts for row in p["samples"][q]][:MAX_TRACE_SAMPLES]
    return envelope, histories


def merge_chunks(chunks: list[dict]) -> dict:
    """Fold partials of :func:`simulate_chunk` into fractions, means and standard deviations."""
    if not chunks:
        raise ValueError("merge_chunks needs at least one chunk")
    n = sum(c["count"] for c in chunks)
    failed = sum(c["failed"] for c in chunks)
    terminal: dict = {}
    for c in chunks:
        for q, mom in c["terminal"].items():
            terminal[q] = _merge_moments(terminal[q], mom) if q in terminal else dict(mom)
    summary: dict = {"samples": int(n), "failed_samples": int(failed), "terminal": {}, "within": {}, "path": {}}
    for q, mom in terminal.items():
        std = math.sqrt(mom["m2"] / (mom["n"] - 1)) if mom["n"] > 1 else 0.0
        summary["terminal"][q] = {"mean": float(mom["mean"]), "std": float(std)}
    for q in chunks[0]["within"]:
        summary["within"][q] = {b: sum(c["within"][q][b] for c in chunks) / n for b in chunks[0]["within"][q]}
    for nm in chunks[0]["path"]:
        worst = [c["path"][nm]["worst"] for c in chunks if c["path"][nm]["worst"] is not None]
        w = max(worst) if worst else None
        summary["path"][nm] = {
            "kept_fraction": sum(c["path"][nm]["kept_fine"] for c in chunks) / n,
            "kept_fraction_nodes": sum(c["path"][nm]["kept_nodes"] for c in chunks) / n,
            "worst": float(w) if w is not None and math.isfinite(w) else None,
            "limit": chunks[0]["path"][nm]["limit"],
        }
    # Chunks come in sample order (run_monte_carlo, worker.fanout), so these are the first samples.
    if all("trace" in c for c in chunks):
        summary["envelope"], summary["sample_traces"] = _merge_traces([c["trace"] for c in chunks])
    if chunks[0].get("terminal_samples"):
        summary["terminal_samples"] = {
            q: [v for c in chunks for v in c["terminal_samples"][q]][:MAX_TERMINAL_SAMPLES]
            for q in chunks[0]["terminal_samples"]}
    return summary


def run_monte_carlo(spec: dict, samples: int, seed: int, chunk_size: int | None = None) -> dict:
    """In-process fan-out: the same chunks a distributed run would make, merged."""
    chunk_size = int(chunk_size or samples)
    chunks = [simulate_chunk(spec, seed, a, min(chunk_size, samples - a))
              for a in range(0, samples, chunk_size)]
    return merge_chunks(chunks)
