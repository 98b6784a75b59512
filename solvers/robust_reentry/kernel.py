"""Compiled Monte Carlo propagation of the shuttle reentry (numba), the fast path of
:mod:`solvers.robust_reentry.mc`.

The same classical RK4 as :func:`solvers.uncertainty.montecarlo.propagate` (controls linear
between the nodes, ``substeps`` steps per interval, the path limits checked after every step and
at the nodes), for the vehicles it can express: polynomial aerodynamics, an exponential
atmosphere, Betts' heating fit or Sutton-Graves, either Earth model.  Anything else (aerodynamic
tables, the US 1976 or a tabulated atmosphere) takes the numpy path; :func:`supports` says which.

Why it is fast (10,000 samples of the RO design on one core, ``python -m benchmarks.robust --only mc``,
CPU s on the shared machine: 0.34 with the statistics, the kernel alone 0.30; the scalar
per-sample kernel before it 1.18; the plain numba loop 1.7-2.3, heyoka's batch mode 3.1-3.5):

* Everything that depends only on the controls (CL, CD, the bank's sine and cosine, the heating
  fit's alpha polynomial) is the same for all samples: computed once per RK stage
  (:func:`control_table`), not once per sample.
* The samples run in blocks of :data:`LANES`, the block's states in one flat working array (rows
  of ``LANES`` doubles, in L1), and every lane loop (one RK stage's right-hand side for the whole
  block, the path checks, the RK4 sums) has the sample as its innermost index, no call and no
  branch, so LLVM vectorizes it: four samples per AVX2 instruction.  ``math.exp/sin/cos`` are
  libm calls here (the llvmlite build has no SVML), which would stop that; :mod:`solvers.vmath`
  has branch-free versions (Cody-Waite reduction, fdlibm's polynomials, fma; within 1 ulp of
  libm over the ranges that occur) and a ``pow`` for the heating fit's ``v^3.07``.  The
  vectorized loops show in the assembly: ymm registers, ``vfmadd``, ``vdivpd``, no calls.
* Two divisions per right-hand side instead of nine (``1/(r v)`` and ``1/(cos gamma cos lat)``
  give the four reciprocals), ``-1/H`` and ``S/(2m)`` folded once per block; ``error_model="numpy"``
  (no zero-division branches).  The working array is flat with a constant row length so that
  LLVM proves the rows apart at compile time (no run-time alias checks per loop).
* The right-hand-side loop is compiled once per Earth model and the check loop once (the stage
  state always in the same rows, the node flag a select): inlining the whole step for both Earth
  models took 50 s CPU to compile; this takes 7.6 s (the scalar kernel 2.7 s), once per machine
  and source change: ``cache=True`` keeps it on disk.

Tried and dropped: carrying sin/cos/exp across the stages by short series (20% slower in the
scalar kernel, serial polynomial chains); blocks of 16 or 128 lanes (64 is fastest here: 16 pays
the loop overheads, 128 spills out of L1); Horner instead of Estrin for exp's degree-13
polynomial (a 12-fma dependency chain in a latency-bound loop).

The same numbers wherever a sample sits: no ``fastmath``, every lane runs the same IEEE
operations (fma only where written, :func:`solvers.vmath.fma`, exact in every lane), and the
last block is padded with copies of its last sample, so a sample's bits do not depend on its
position in a block, in a chunk or on the chunk size (the split-equals-unsplit property of the
Monte Carlo).  Against the numpy RK4 the results differ by rounding only (1e-12 relative in the
final states, below 1e-9 in every reported statistic; ``tests/unit/test_robust_reentry_kernel.py``).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from solvers import vmath as vm
from solvers.constants import G0_MPS2
from solvers.models import shuttle as sh

# Column order of the per-stage control table.
_CL, _CD, _COSB, _SINB, _HEATP, _NCTRL = 0, 1, 2, 3, 4, 5
# Column order of the per-sample path checks.
PATH_ORDER = ("heat_rate", "dynamic_pressure", "load_factor")


def supports(v: sh.Vehicle) -> bool:
    """True if the compiled path models this vehicle exactly as the numpy path does."""
    return v.aero_table is None and v.atmosphere.kind == "exponential"


def _poly(coeffs, a):
    out = np.full_like(a, coeffs[-1])
    for c in reversed(coeffs[:-1]):
        out = out * a + c
    return out


def control_table(v: sh.Vehicle, t_nodes, controls, substeps: int) -> np.ndarray:
    """Sample-independent control quantities at the 2*substeps+1 RK4 stage points of each interval.

    Row ``k * 2 * substeps + i`` is fraction ``i / (2 substeps)`` of interval ``k`` (starts, mid
    points and ends of the substeps); the last row is the final node.
    """
    U = np.asarray(controls, float)
    m = len(t_nodes) - 1
    frac = np.arange(2 * substeps) / (2 * substeps)
    alpha = (U[0, :m, None] + frac[None, :] * (U[0, 1:, None] - U[0, :m, None])).ravel()
    bank = (U[1, :m, None] + frac[None, :] * (U[1, 1:, None] - U[1, :m, None])).ravel()
    alpha = np.append(alpha, U[0, m])
    bank = np.append(bank, U[1, m])
    a_deg = alpha / sh.DEG
    out = np.empty((alpha.size, _NCTRL))
    out[:, _CL] = _poly(v.cl_coeffs, a_deg) * v.cl_scale
    out[:, _CD] = _poly(v.cd_coeffs, a_deg) * v.cd_scale
    out[:, _COSB] = np.cos(bank)
    out[:, _SINB] = np.sin(bank)
    out[:, _HEATP] = _poly(v.heat_coeffs, a_deg)
    return np.ascontiguousarray(out)


def constants(v: sh.Vehicle) -> np.ndarray:
    """The vehicle's numbers in the order the kernel reads them."""
    heating = v.heating
    heat_sg = heating is not None
    sg_k = 0.0
    if heating is not None:
        sg_k = (v.planet.sutton_graves_k if heating.k is None else heating.k) / math.sqrt(heating.nose_radius_m)
    return np.array([v.mass_kg, v.area_m2, v.atmosphere.rho0_kg_m3, v.atmosphere.scale_height_m,
                     v.planet.radius_m, v.planet.mu_m3_s2, v.planet.omega_rad_s if v.rotating_earth else 0.0,
                     1.0 if v.rotating_earth else 0.0, 1.0 if heat_sg else 0.0, sg_k, G0_MPS2], float)


# Samples per block: the lane loops run over them (vectorized, 4 doubles per AVX2 register); a
# block's working rows (33 x LANES doubles) stay in L1.
LANES = 64
# Rows of the per-block working array: state, stage state, RK4 sum, 1 + s1, 1 + s2, worst path
# values (fine grid, nodes), heating rate at the last check.
_X, _XT, _ACC, _K, _F1, _F2, _WF, _WN, _QH, _NROWS = 0, 6, 12, 18, 24, 25, 26, 29, 32, 33


@njit(inline="always")
def _at(row, lane):
    """Index of ``(row, lane)`` in the flat working array.  Flat with a constant row length, so
    LLVM sees at compile time that the rows do not overlap: no run-time alias checks in the loops."""
    return row * LANES + lane


@njit(inline="always", error_model="numpy")
def _rates(h, lat, v, gam, psi, cl, cd, cosb, sinb, rho0, m_ihs, qk, re, mu, w, rot):
    """The right-hand side at one state (rotating-Earth terms if ``rot``, a compile-time constant);
    ``m_ihs = -1 / scale height``, ``qk = area / (2 mass)``."""
    rho = rho0 * vm.exp(h * m_ihs)
    sg, cg = vm.sincos(gam)
    sp, cp = vm.sincos(psi)
    sl, cl_ = vm.sincos(lat)
    # two divisions instead of the right-hand side's nine (division is the slowest arithmetic,
    # 4-5 times a multiplication's throughput): 1/(r v) and 1/(cos gamma cos lat) give all four
    r = re + h
    irv, icc = 1.0 / (r * v), 1.0 / (cg * cl_)
    ir, iv, icg, icl = irv * v, irv * r, icc * cl_, icc * cg
    g = mu * ir * ir
    qs_m = rho * (v * v) * qk
    dh = v * sg
    vcg_r = v * cg * ir
    dlon = vcg_r * sp * icl
    dlat = vcg_r * cp
    dv = -qs_m * cd - g * sg
    dgam = qs_m * cl * cosb * iv + cg * (v * ir - g * iv)
    dpsi = qs_m * cl * sinb * iv * icg + vcg_r * sp * sl * icl
    if rot:
        dv = dv + w * w * r * cl_ * (sg * cl_ - cg * sl * cp)
        dgam = dgam + 2.0 * w * cl_ * sp + w * w * r * cl_ * (cg * cl_ + sg * cp * sl) * iv
        dpsi = dpsi - 2.0 * w * (sg * icg * cp * cl_ - sl) + w * w * r * sp * sl * cl_ * iv * icg
    return dh, dlon, dlat, dv, dgam, dpsi


@njit(inline="always", error_model="numpy")
def _heat(rho, v, heatp, sg, sg_k):
    """Heating rate: Sutton-Graves if ``sg`` else Betts' fit (``heatp``: its alpha polynomial)."""
    q_sg = sg_k * math.sqrt(rho) * v ** 3
    q_b = (heatp * 17700.0 * math.sqrt(rho * sh.KG_M3_TO_SLUG_FT3)
           * vm.pow_pos(1e-4 * (v / sh.FT_TO_M), 3.07) * sh.BTU_FT2_S_TO_W_M2)
    return q_sg if sg else q_b


@njit(error_model="numpy")
def _check_lanes(buf, row, ctrl, c, node):
    """Path values at the block's states ``buf[_X]`` with control row ``row``: worst values updated
    (the node worsts too if ``node``), heating rate kept in ``buf[_QH]``.  Non-finite counts as +inf."""
    cl0, cd0, heatp = ctrl[row, 0], ctrl[row, 1], ctrl[row, 4]
    area, rho0, m_ihs, sg, sg_k, i_mg0 = c[1], c[2], -1.0 / c[3], c[8] != 0.0, c[9], 1.0 / (c[0] * c[10])
    for l in range(LANES):
        v = buf[_at(_X + 3, l)]
        rho = rho0 * vm.exp(buf[_at(_X, l)] * m_ihs)
        q = _heat(rho, v, heatp, sg, sg_k)
        pd = 0.5 * rho * v ** 2
        cl = cl0 * buf[_at(_F2, l)]
        cd = cd0 * buf[_at(_F1, l)]
        nf = pd * area * math.sqrt(cl ** 2 + cd ** 2) * i_mg0
        buf[_at(_QH, l)] = q
        q = q if math.isfinite(q) else np.inf
        pd = pd if math.isfinite(pd) else np.inf
        nf = nf if math.isfinite(nf) else np.inf
        buf[_at(_WF, l)] = max(buf[_at(_WF, l)], q)
        buf[_at(_WF + 1, l)] = max(buf[_at(_WF + 1, l)], pd)
        buf[_at(_WF + 2, l)] = max(buf[_at(_WF + 2, l)], nf)
        # (selects: the loop stays one vectorized loop for both values of node)
        buf[_at(_WN, l)] = max(buf[_at(_WN, l)], q) if node else buf[_at(_WN, l)]
        buf[_at(_WN + 1, l)] = max(buf[_at(_WN + 1, l)], pd) if node else buf[_at(_WN + 1, l)]
        buf[_at(_WN + 2, l)] = max(buf[_at(_WN + 2, l)], nf) if node else buf[_at(_WN + 2, l)]


@njit(inline="always", error_model="numpy")
def _rates_lanes_impl(buf, row, ctrl, c, rot):
    """The rates at the block's stage states ``buf[_XT]`` with control row ``row`` into ``buf[_K]``."""
    cl0, cd0, cosb, sinb = ctrl[row, 0], ctrl[row, 1], ctrl[row, 2], ctrl[row, 3]
    rho0, m_ihs, qk, re, mu, w = c[2], -1.0 / c[3], 0.5 * c[1] / c[0], c[4], c[5], c[6]
    for l in range(LANES):
        d = _rates(buf[_at(_XT, l)], buf[_at(_XT + 2, l)], buf[_at(_XT + 3, l)], buf[_at(_XT + 4, l)],
                   buf[_at(_XT + 5, l)], cl0 * buf[_at(_F2, l)], cd0 * buf[_at(_F1, l)], cosb, sinb,
                   rho0, m_ihs, qk, re, mu, w, rot)
        for q in range(6):
            buf[_at(_K + q, l)] = d[q]


# one compiled copy of the lane loop per Earth model (the rotation terms cost nothing when off)
@njit(error_model="numpy")
def _rates_rotating(buf, row, ctrl, c):
    _rates_lanes_impl(buf, row, ctrl, c, True)


@njit(error_model="numpy")
def _rates_flat(buf, row, ctrl, c):
    _rates_lanes_impl(buf, row, ctrl, c, False)


@njit(inline="always", error_model="numpy")
def _rates_lanes(buf, row, ctrl, c, rot):
    if rot:
        _rates_rotating(buf, row, ctrl, c)
    else:
        _rates_flat(buf, row, ctrl, c)


@njit(error_model="numpy")
def _block(x0, s, b0, t_nodes, ctrl, substeps, c, kept_row, xf, worst_fine, worst_node, traces, buf):
    """Samples ``b0 .. b0+LANES-1`` (the last block padded with copies of its last sample)."""
    n = x0.shape[1]
    rot = c[7] != 0.0
    cnt = min(LANES, n - b0)
    for l in range(LANES):
        i = b0 + min(l, cnt - 1)
        for q in range(6):
            buf[_at(_X + q, l)] = x0[q, i]
            buf[_at(_XT + q, l)] = x0[q, i]
        buf[_at(_F1, l)] = 1.0 + s[0, i]
        buf[_at(_F2, l)] = 1.0 + s[1, i]
        for p in range(3):
            buf[_at(_WF + p, l)] = -np.inf
            buf[_at(_WN + p, l)] = -np.inf
    m = t_nodes.size - 1
    ns2 = 2 * substeps
    for k in range(m + 1):
        h = (t_nodes[min(k + 1, m)] - t_nodes[k]) / substeps
        a2, h6 = 0.5 * h, h / 6.0
        for j in range(substeps):
            ra = k * ns2 + 2 * j
            # the checks at the state reached (node k if j == 0), then step j of interval k
            node = j == 0
            _check_lanes(buf, ra, ctrl, c, node)
            if node:
                node_row = kept_row[k]
                if node_row >= 0:
                    for l in range(cnt):
                        traces[0, node_row, b0 + l] = buf[_at(_X, l)]
                        traces[1, node_row, b0 + l] = buf[_at(_X + 3, l)]
                        traces[2, node_row, b0 + l] = buf[_at(_QH, l)]
                if k == m:
                    break
            # classical RK4, the sum in the order x + h/6 (((k1 + 2 k2) + 2 k3) + k4); the stage
            # state buf[_XT] equals buf[_X] here
            _rates_lanes(buf, ra, ctrl, c, rot)
            for q in range(6):
                for l in range(LANES):
                    buf[_at(_ACC + q, l)] = buf[_at(_K + q, l)]
                    buf[_at(_XT + q, l)] = buf[_at(_X + q, l)] + a2 * buf[_at(_K + q, l)]
            _rates_lanes(buf, ra + 1, ctrl, c, rot)
            for q in range(6):
                for l in range(LANES):
                    buf[_at(_ACC + q, l)] += 2.0 * buf[_at(_K + q, l)]
                    buf[_at(_XT + q, l)] = buf[_at(_X + q, l)] + a2 * buf[_at(_K + q, l)]
            _rates_lanes(buf, ra + 1, ctrl, c, rot)
            for q in range(6):
                for l in range(LANES):
                    buf[_at(_ACC + q, l)] += 2.0 * buf[_at(_K + q, l)]
                    buf[_at(_XT + q, l)] = buf[_at(_X + q, l)] + h * buf[_at(_K + q, l)]
            _rates_lanes(buf, ra + 2, ctrl, c, rot)
            for q in range(6):
                for l in range(LANES):
                    x = buf[_at(_X + q, l)] + h6 * (buf[_at(_ACC + q, l)] + buf[_at(_K + q, l)])
                    buf[_at(_X + q, l)] = x
                    buf[_at(_XT + q, l)] = x
    for l in range(cnt):
        for q in range(6):
            xf[q, b0 + l] = buf[_at(_X + q, l)]
        for p in range(3):
            worst_fine[p, b0 + l] = buf[_at(_WF + p, l)]
            worst_node[p, b0 + l] = buf[_at(_WN + p, l)]


@njit(cache=True, error_model="numpy")
def propagate_samples(x0, s, t_nodes, ctrl, substeps, c, kept_row, xf, worst_fine, worst_node, traces):
    """RK4 of every sample (columns of ``x0`` (6, N), ``s`` (2, N)); fills ``xf`` (6, N), the
    per-sample worst path values ``worst_fine``/``worst_node`` (3, N) in :data:`PATH_ORDER`,
    and ``traces`` (3, rows, N): altitude, speed, heating rate at the nodes with
    ``kept_row[node] >= 0``.  Non-finite path values count as +inf (a failed sample)."""
    n = x0.shape[1]
    buf = np.empty(_NROWS * LANES)
    for b0 in range(0, n, LANES):
        _block(x0, s, b0, t_nodes, ctrl, substeps, c, kept_row, xf, worst_fine, worst_node, traces, buf)


def run_chunk(v: sh.Vehicle, *, x0, s, t_nodes, controls, substeps: int, kept_nodes, path: tuple):
    """Propagate a chunk: ``(xf (6, N), worst_fine {name: (N,)}, worst_node {name: (N,)},
    traces {"altitude_m", "speed_mps", "heat_rate_w_m2": (len(kept_nodes), N)})``, the pieces
    :func:`solvers.uncertainty.montecarlo.simulate_chunk` needs (``path``: the names it checks)."""
    t_nodes = np.ascontiguousarray(t_nodes, float)
    n = x0.shape[1]
    kept_row = np.full(t_nodes.size, -1, np.int64)
    kept_row[np.asarray(kept_nodes, np.int64)] = np.arange(len(kept_nodes))
    xf = np.empty((6, n))
    wf = np.empty((3, n))
    wn = np.empty((3, n))
    tr = np.full((3, len(kept_nodes), n), np.nan)
    propagate_samples(np.ascontiguousarray(x0, float), np.ascontiguousarray(s, float), t_nodes,
                      control_table(v, t_nodes, controls, substeps), int(substeps), constants(v), kept_row,
                      xf, wf, wn, tr)
    col = {name: PATH_ORDER.index(name) for name in path}
    return (xf, {nm: wf[i] for nm, i in col.items()}, {nm: wn[i] for nm, i in col.items()},
            {"altitude_m": tr[0], "speed_mps": tr[1], "heat_rate_w_m2": tr[2]})
