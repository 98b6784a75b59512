"""Compiled Monte Carlo propagation of the shuttle reentry (numba), the fast path of
:mod:`solvers.robust_reentry_mc`.

The same classical RK4 as :func:`solvers.uncertainty.montecarlo.propagate` (controls linear
between the nodes, ``substeps`` steps per interval, the path limits checked after every step and
at the nodes), for the vehicles it can express: polynomial aerodynamics, an exponential
atmosphere, Betts' heating fit or Sutton-Graves, either Earth model.  Anything else (aerodynamic
tables, the US 1976 or a tabulated atmosphere) takes the numpy path; :func:`supports` says which.

Why it is faster than the numpy RK4: everything that depends only on the controls (CL, CD, the
bank's sine and cosine, the heating fit's alpha polynomial) is the same for all samples, so it is
computed once per RK stage instead of once per sample; each sample's state stays in registers
for the whole flight instead of streaming 6 x N temporaries through memory 40 times per step; and
the right-hand side uses reciprocals (4 divisions instead of 9) with ``error_model="numpy"`` (no
zero-division branches).  Carrying sin/cos/exp across the stages by short series instead of the
library calls was tried: 20% slower here (serial polynomial chains), so the library it is.
No ``fastmath``: each sample is an independent scalar loop, so its numbers do not depend on its
position in a chunk or on the chunk size (the split-equals-unsplit property of the Monte Carlo).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

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
    heat_sg = v.heating is not None
    sg_k = 0.0
    if heat_sg:
        sg_k = (v.planet.sutton_graves_k if v.heating.k is None else v.heating.k) / math.sqrt(v.heating.nose_radius_m)
    return np.array([v.mass_kg, v.area_m2, v.atmosphere.rho0_kg_m3, v.atmosphere.scale_height_m,
                     v.planet.radius_m, v.planet.mu_m3_s2, v.planet.omega_rad_s if v.rotating_earth else 0.0,
                     1.0 if v.rotating_earth else 0.0, 1.0 if heat_sg else 0.0, sg_k, G0_MPS2], float)


@njit(cache=True, inline="always", error_model="numpy")
def _eom(h, v, rho, sg, cg, sp, cp, sl, cl_, cl, cd, cosb, sinb, c):
    # reciprocals once: 4 divisions per call instead of 9 (division is the slowest arithmetic)
    mass, area, re, mu, w, rot = c[0], c[1], c[4], c[5], c[6], c[7]
    r = re + h
    ir, iv, icg, icl = 1.0 / r, 1.0 / v, 1.0 / cg, 1.0 / cl_
    g = mu * ir * ir
    qs_m = 0.5 * rho * v * v * area / mass
    dh = v * sg
    vcg_r = v * cg * ir
    dlon = vcg_r * sp * icl
    dlat = vcg_r * cp
    dv = -qs_m * cd - g * sg
    dgam = qs_m * cl * cosb * iv + cg * (v * ir - g * iv)
    dpsi = qs_m * cl * sinb * iv * icg + vcg_r * sp * sl * icl
    if rot != 0.0:
        dv = dv + w * w * r * cl_ * (sg * cl_ - cg * sl * cp)
        dgam = dgam + 2.0 * w * cl_ * sp + w * w * r * cl_ * (cg * cl_ + sg * cp * sl) * iv
        dpsi = dpsi - 2.0 * w * (sg * icg * cp * cl_ - sl) + w * w * r * sp * sl * cl_ * iv * icg
    return dh, dlon, dlat, dv, dgam, dpsi


@njit(cache=True, inline="always", error_model="numpy")
def _stage(x0, k, a, row, ctrl, f1, f2, c, xt):
    """The rates at ``x0 + a k`` with the control quantities of table row ``row``."""
    for q in range(6):
        xt[q] = x0[q] + a * k[q]
    rho = c[2] * math.exp(-xt[0] / c[3])
    return _eom(xt[0], xt[3], rho, math.sin(xt[4]), math.cos(xt[4]), math.sin(xt[5]), math.cos(xt[5]),
                math.sin(xt[2]), math.cos(xt[2]), ctrl[row, 0] * f2, ctrl[row, 1] * f1, ctrl[row, 2],
                ctrl[row, 3], c)


@njit(cache=True, inline="always", error_model="numpy")
def _checks(x, row, ctrl, s1, s2, c, out):
    """Heating rate, dynamic pressure, load factor at state ``x`` and control row ``row``."""
    v = x[3]
    rho = c[2] * math.exp(-x[0] / c[3])
    if c[8] != 0.0:
        q = c[9] * math.sqrt(rho) * v ** 3
    else:
        rho_e = rho * sh.KG_M3_TO_SLUG_FT3
        q = ctrl[row, 4] * 17700.0 * math.sqrt(rho_e) * (1e-4 * (v / sh.FT_TO_M)) ** 3.07 * sh.BTU_FT2_S_TO_W_M2
    pd = 0.5 * rho * v ** 2
    cl = ctrl[row, 0] * (1.0 + s2)
    cd = ctrl[row, 1] * (1.0 + s1)
    out[0] = q
    out[1] = pd
    out[2] = pd * c[1] * math.sqrt(cl ** 2 + cd ** 2) / (c[0] * c[10])


@njit(cache=True, error_model="numpy")
def propagate_samples(x0, s, t_nodes, ctrl, substeps, c, kept_row, xf, worst_fine, worst_node, traces):
    """RK4 of every sample (columns of ``x0`` (6, N), ``s`` (2, N)); fills ``xf`` (6, N), the
    per-sample worst path values ``worst_fine``/``worst_node`` (3, N) in :data:`PATH_ORDER`,
    and ``traces`` (3, rows, N): altitude, speed, heating rate at the nodes with
    ``kept_row[node] >= 0``.  Non-finite path values count as +inf (a failed sample)."""
    n = x0.shape[1]
    m = t_nodes.size - 1
    x = np.empty(6)
    k1 = np.empty(6)
    k2 = np.empty(6)
    k3 = np.empty(6)
    xt = np.empty(6)
    chk = np.empty(3)
    ns2 = 2 * substeps
    for i in range(n):
        s1, s2 = s[0, i], s[1, i]
        f1, f2 = 1.0 + s1, 1.0 + s2
        for j in range(6):
            x[j] = x0[j, i]
            k1[j] = 0.0
        for p in range(3):
            worst_fine[p, i] = -np.inf
            worst_node[p, i] = -np.inf
        _checks(x, 0, ctrl, s1, s2, c, chk)
        for p in range(3):
            v = chk[p] if math.isfinite(chk[p]) else np.inf
            worst_fine[p, i] = v
            worst_node[p, i] = v
        for k in range(m + 1):
            if k > 0:
                h = (t_nodes[k] - t_nodes[k - 1]) / substeps
                base = (k - 1) * ns2
                for j in range(substeps):
                    ra, rb, rc = base + 2 * j, base + 2 * j + 1, base + 2 * j + 2
                    d = _stage(x, k1, 0.0, ra, ctrl, f1, f2, c, xt)
                    for q in range(6):
                        k1[q] = d[q]
                    d = _stage(x, k1, 0.5 * h, rb, ctrl, f1, f2, c, xt)
                    for q in range(6):
                        k2[q] = d[q]
                    d = _stage(x, k2, 0.5 * h, rb, ctrl, f1, f2, c, xt)
                    for q in range(6):
                        k3[q] = d[q]
                    d = _stage(x, k3, h, rc, ctrl, f1, f2, c, xt)
                    for q in range(6):
                        x[q] = x[q] + (h / 6.0) * (k1[q] + 2.0 * k2[q] + 2.0 * k3[q] + d[q])
                    _checks(x, rc, ctrl, s1, s2, c, chk)
                    for p in range(3):
                        v = chk[p] if math.isfinite(chk[p]) else np.inf
                        if v > worst_fine[p, i]:
                            worst_fine[p, i] = v
                        if j == substeps - 1 and v > worst_node[p, i]:
                            worst_node[p, i] = v
            row = kept_row[k]
            if row >= 0:
                traces[0, row, i] = x[0]
                traces[1, row, i] = x[3]
                traces[2, row, i] = chk[0]
        for j in range(6):
            xf[j, i] = x[j]


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
