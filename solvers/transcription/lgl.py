"""Legendre-Gauss-Lobatto (LGL) pseudospectral collocation: nodes, weights,
differentiation and integration matrices, Lagrange interpolation, a
multi-segment mesh, and the collocation constraints in two forms.

Sources: Fahroo & Ross, "Costate estimation by a Legendre pseudospectral
method", JGCD 24(2), 2001 (nodes, weights, D-matrix eq. 8-10, covector
mapping lambda_i = nu_i / w_i).  Refinement (which segments to split) belongs
to the solver using the mesh: see ``solvers.intercept.thrust``.

On one segment the state is the degree ``n-1`` polynomial through its values at
``n`` LGL nodes ``tau in [-1, 1]``; the collocation constraint is
``D @ X = (h/2) f(X, U)`` with ``h`` the segment's duration.  A mesh of several
segments (each with its own nodes, linked by state continuity) lets controls
jump at segment boundaries: this is how a bang-bang thrust switch is
represented exactly once a boundary sits on the switch.

Two forms of the collocation constraint:

* ``"differential"`` (Fahroo & Ross): ``D @ X = (h/2) F`` at all ``n`` nodes.
  ``D`` has rank ``n-1`` (its left null vector is ``w_i P_{n-1}(tau_i)``), so
  with the first node fixed the ``n`` equations overdetermine the ``n-1`` free
  states by one per state component: they hold only if the controls absorb
  ``sum_i w_i P_{n-1}(tau_i) f_i = 0``.  Fine where every node has a free
  control; an arc with no controls (a coast) is then infeasible.
* ``"integral"``: ``X_i = X_1 + (h/2) sum_j A_ij F_j`` for ``i = 2..n`` with the
  LGL integration matrix ``A_ij = int_{-1}^{tau_i} l_j`` (``l_j`` the Lagrange
  basis): ``n-1`` equations for ``n-1`` states, consistent with or without
  controls, and the same polynomial quadrature.  Its costate estimate is
  ``lambda_j = -(sum_i nu_i A_ij) / w_j`` (the multipliers are impulses of the
  costate, summed over the nodes whose integral covers node ``j``).
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np


@lru_cache(maxsize=64)
def _lgl(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    if n < 2:
        raise ValueError("LGL needs at least 2 nodes")
    N = n - 1
    # Chebyshev-Gauss-Lobatto start, then Newton on (1 - x^2) P_N'(x) using the
    # Legendre recurrence (converges to machine precision for n in the hundreds).
    x = np.cos(np.pi * np.arange(n) / N)
    P = np.zeros((n, n))
    x_old = np.full(n, 2.0)
    for _ in range(100):
        if np.max(np.abs(x - x_old)) <= 1e-15:
            break
        x_old = x.copy()
        P[:, 0] = 1.0
        P[:, 1] = x
        for k in range(2, n):
            P[:, k] = ((2 * k - 1) * x * P[:, k - 1] - (k - 1) * P[:, k - 2]) / k
        x = x_old - (x * P[:, N] - P[:, N - 1]) / (n * P[:, N])
    x = np.sort(x)
    x[0], x[-1] = -1.0, 1.0
    PN = legendre(N, x)
    w = 2.0 / (N * (N + 1) * PN**2)
    with np.errstate(divide="ignore", invalid="ignore"):
        D = (PN[:, None] / PN[None, :]) / (x[:, None] - x[None, :])
    np.fill_diagonal(D, 0.0)
    D[0, 0] = -N * (N + 1) / 4.0
    D[-1, -1] = N * (N + 1) / 4.0
    for a in (x, w, D):
        a.setflags(write=False)
    return x, w, D


def legendre(N: int, x: np.ndarray) -> np.ndarray:
    """Legendre polynomial ``P_N`` at ``x`` (three-term recurrence)."""
    p0, p1 = np.ones_like(x), x
    if N == 0:
        return p0
    for k in range(2, N + 1):
        p0, p1 = p1, ((2 * k - 1) * x * p1 - (k - 1) * p0) / k
    return p1


def lgl_nodes(n: int) -> np.ndarray:
    """The ``n`` LGL nodes on [-1, 1], ascending: -1, 1 and the roots of P'_{n-1}."""
    return _lgl(n)[0]


def lgl_weights(n: int) -> np.ndarray:
    """Quadrature weights ``2 / (N (N+1) P_N(x_i)^2)``, N = n-1: exact for degree <= 2n-3."""
    return _lgl(n)[1]


def lgl_diff_matrix(n: int) -> np.ndarray:
    """``D`` with ``(D @ p(x))_i = p'(x_i)`` exactly for polynomials of degree <= n-1."""
    return _lgl(n)[2]


@lru_cache(maxsize=64)
def lgl_integration_matrix(n: int) -> np.ndarray:
    """``A`` (n x n) with ``(A @ p(x))_i = int_{-1}^{x_i} p`` exactly for polynomials
    of degree <= n-1 (row 0 is zero, row n-1 equals the weights)."""
    x = lgl_nodes(n)
    g, gw = np.polynomial.legendre.leggauss(n)
    A = np.zeros((n, n))
    for i in range(1, n):
        half = 0.5 * (x[i] + 1.0)
        pts = -1.0 + half * (g + 1.0)
        A[i] = half * gw @ lagrange_matrix(x, pts)
    A.setflags(write=False)
    return A


def lagrange_matrix(nodes: np.ndarray, points: np.ndarray) -> np.ndarray:
    """``L`` (len(points) x len(nodes)) with ``L @ values`` the interpolant at ``points``.

    Barycentric form (Berrut & Trefethen 2004): stable for LGL nodes of any
    practical count, and exact at the nodes themselves.
    """
    nodes = np.asarray(nodes, float)
    points = np.atleast_1d(np.asarray(points, float))
    diff = nodes[:, None] - nodes[None, :]
    np.fill_diagonal(diff, 1.0)
    bw = 1.0 / np.prod(diff, axis=1)
    d = points[:, None] - nodes[None, :]
    exact = d == 0.0
    d[exact] = 1.0
    L = bw[None, :] / d
    L /= L.sum(axis=1, keepdims=True)
    rows = exact.any(axis=1)
    L[rows] = exact[rows].astype(float)
    return L


@dataclass(frozen=True)
class Mesh:
    """Segments on the normalized horizon [0, 1], each with ``nodes`` LGL nodes.

    ``boundaries`` are the segment edges as fractions of the horizon (first 0,
    last 1, strictly increasing).  One node count for all segments keeps one
    mapped segment function per NLP (h-refinement adds segments, not nodes).
    """

    boundaries: tuple[float, ...]
    nodes: int

    def __post_init__(self):
        b = np.asarray(self.boundaries, float)
        if b.size < 2 or abs(b[0]) > 1e-14 or abs(b[-1] - 1.0) > 1e-14 or np.any(np.diff(b) <= 0):
            raise ValueError("mesh boundaries must increase strictly from 0 to 1")
        if self.nodes < 3:
            raise ValueError("a segment needs at least 3 LGL nodes")

    @classmethod
    def uniform(cls, segments: int, nodes: int) -> "Mesh":
        return cls(tuple(np.linspace(0.0, 1.0, segments + 1).tolist()), nodes)

    @property
    def segments(self) -> int:
        return len(self.boundaries) - 1

    @property
    def total_nodes(self) -> int:
        return self.segments * self.nodes

    @property
    def fractions(self) -> np.ndarray:
        """Segment durations as fractions of the horizon."""
        return np.diff(np.asarray(self.boundaries, float))

    def node_fractions(self) -> np.ndarray:
        """Node positions on [0, 1], shape (segments, nodes); shared edges appear twice."""
        b = np.asarray(self.boundaries, float)
        tau = lgl_nodes(self.nodes)
        return b[:-1, None] + 0.5 * (tau[None, :] + 1.0) * np.diff(b)[:, None]

    def segment_of(self, s: np.ndarray) -> np.ndarray:
        """Index of the segment holding each normalized time ``s`` (right edge -> last segment)."""
        b = np.asarray(self.boundaries, float)
        return np.clip(np.searchsorted(b, s, side="right") - 1, 0, self.segments - 1)

    def interpolate(self, values: np.ndarray, s: np.ndarray) -> np.ndarray:
        """Evaluate per-segment Lagrange interpolants at normalized times ``s``.

        ``values`` has shape (k, segments, nodes); returns (k, len(s)).
        """
        s = np.atleast_1d(np.asarray(s, float))
        seg = self.segment_of(s)
        b = np.asarray(self.boundaries, float)
        tau = 2.0 * (s - b[seg]) / (b[seg + 1] - b[seg]) - 1.0
        out = np.empty((values.shape[0], s.size))
        nodes = lgl_nodes(self.nodes)
        for k in np.unique(seg):
            idx = seg == k
            out[:, idx] = values[:, k, :] @ lagrange_matrix(nodes, tau[idx]).T
        return out


def collocation_constraints(*, dynamics, X, U, params, seg_duration, nodes: int, segments: int,
                            form: str = "differential"):
    """Multi-segment LGL collocation constraints as CasADi expressions.

    ``X`` (nx, segments*nodes) and ``U`` (nu, segments*nodes) hold the node
    values segment after segment; ``seg_duration`` (1, segments) the segment
    durations; ``dynamics`` a ``ca.Function(x, u, p) -> xdot`` for one node and
    ``params`` its parameter vector ``p`` (shared by all nodes).
    Returns ``(defects, continuity)``: ``defects`` (nx, segments*nodes) is
    ``X_k D^T - (h_k/2) f(X_k, U_k)`` per segment (one segment function,
    ``map``-ped), ``continuity`` (nx, segments-1) the jump of the state between
    the last node of a segment and the first of the next.  With
    ``defects``' multipliers ``nu``, the costate estimate is ``-nu_i / w_i``
    (Fahroo & Ross 2001, sign for CasADi's Lagrangian ``f + lam_g' g``).
    With ``form="integral"`` (see the module docstring) ``defects`` is
    (nx, segments*(nodes-1)): ``X_i - X_1 - (h_k/2) (A F)_i`` for ``i >= 2``.
    """
    import casadi as ca

    nx = X.shape[0]
    nu = U.shape[0]
    D = lgl_diff_matrix(nodes)
    Xs = ca.SX.sym("Xs", nx, nodes)
    Us = ca.SX.sym("Us", nu, nodes)
    hs = ca.SX.sym("hs")
    ps = ca.SX.sym("ps", params.shape[0])
    F = dynamics.map(nodes)(Xs, Us, ps)
    if form == "differential":
        defect = ca.mtimes(Xs, ca.DM(D.T)) - 0.5 * hs * F
    elif form == "integral":
        A = lgl_integration_matrix(nodes)[1:]
        defect = Xs[:, 1:] - ca.repmat(Xs[:, 0], 1, nodes - 1) - 0.5 * hs * ca.mtimes(F, ca.DM(A.T))
    else:
        raise ValueError(f"unknown collocation form {form!r}")
    seg = ca.Function("lgl_segment", [Xs, Us, hs, ps], [defect])
    defects = seg.map(segments)(X, U, seg_duration, params)
    last = [k * nodes + nodes - 1 for k in range(segments - 1)]
    first = [(k + 1) * nodes for k in range(segments - 1)]
    continuity = X[:, last] - X[:, first] if segments > 1 else ca.SX(nx, 0)
    return defects, continuity
