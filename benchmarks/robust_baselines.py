"""Baselines of the robust-reentry Monte Carlo: the peers at their strongest, run in the same process.

* :func:`heyoka_batch`: heyoka's Taylor integrator in **batch mode** (one compiled step advances a
  batch of samples, SIMD), the shuttle dynamics as heyoka expressions with the controls linear in
  time inside each interval (runtime parameters), tolerance 1e-9; per interval ``propagate_grid``
  at the same fine grid the Monte Carlo checks (5 points), the heating rate evaluated there.
  The LLVM compilation is reported apart (done once per process).
* :func:`numba_loop`: the straightforward compiled loop a user would write: ``@njit`` classical
  RK4 per sample with the same steps and checks, element loops without array temporaries and
  ``error_model="numpy"``, the right-hand side in full at every stage (controls per stage).  What
  ``solvers.robust_reentry.kernel`` adds on top is the point of the comparison: the control
  quantities shared by all samples and reciprocals in place of most divisions.

Both use the Betts shuttle of the preset (non-rotating, exponential atmosphere, Betts heating).
"""
from __future__ import annotations

import math
import time

import numpy as np
from numba import njit

from solvers.models import shuttle as sh


def _eom_hy(hy, x, alpha, bank, s1, s2, v):
    h, _, lat, vel, gam, psi = x
    a_deg = alpha / sh.DEG

    def poly(cs):
        out = cs[-1]
        for c in reversed(cs[:-1]):
            out = out * a_deg + c
        return out

    rho = v.atmosphere.rho0_kg_m3 * hy.exp(-h / v.atmosphere.scale_height_m)
    r = v.planet.radius_m + h
    g = v.planet.mu_m3_s2 / r ** 2
    qs = 0.5 * rho * vel ** 2 * v.area_m2
    lift = qs * poly(v.cl_coeffs) * v.cl_scale * (1.0 + s2)
    drag = qs * poly(v.cd_coeffs) * v.cd_scale * (1.0 + s1)
    m = v.mass_kg
    return [vel * hy.sin(gam), vel * hy.cos(gam) * hy.sin(psi) / (r * hy.cos(lat)),
            vel * hy.cos(gam) * hy.cos(psi) / r, -drag / m - g * hy.sin(gam),
            lift * hy.cos(bank) / (m * vel) + hy.cos(gam) * (vel / r - g / vel),
            lift * hy.sin(bank) / (m * vel * hy.cos(gam))
            + vel * hy.cos(gam) * hy.sin(psi) * hy.sin(lat) / (r * hy.cos(lat))]


def _heat_np(h, vel, alpha, v):
    rho = v.atmosphere.rho0_kg_m3 * np.exp(-h / v.atmosphere.scale_height_m)
    a_deg = alpha / sh.DEG
    cq = np.polyval(v.heat_coeffs[::-1], a_deg)
    return cq * 17700.0 * np.sqrt(rho * sh.KG_M3_TO_SLUG_FT3) * (1e-4 * vel / sh.FT_TO_M) ** 3.07 * sh.BTU_FT2_S_TO_W_M2


def heyoka_batch(v: sh.Vehicle, *, x0, s, t_nodes, controls, substeps: int, batch: int = 64, tol: float = 1e-9):
    """``(xf (6, N), worst heating (N,), compile_s, run_s)`` with heyoka's batch mode."""
    import heyoka as hy

    names = ["h", "lon", "lat", "v", "gam", "psi"]
    x = hy.make_vars(*names)
    # par: alpha0, alpha slope, bank0, bank slope, interval start, s1, s2
    alpha = hy.par[0] + hy.par[1] * (hy.time - hy.par[4])
    bank = hy.par[2] + hy.par[3] * (hy.time - hy.par[4])
    rhs = _eom_hy(hy, x, alpha, bank, hy.par[5], hy.par[6], v)
    n = x0.shape[1]
    t0 = time.perf_counter()
    ta = hy.taylor_adaptive_batch(list(zip(x, rhs)), np.zeros((6, batch)), tol=tol,
                                  pars=np.zeros((7, batch)), time=np.zeros(batch))
    compile_s = time.perf_counter() - t0
    t_nodes = np.asarray(t_nodes, float)
    U = np.asarray(controls, float)
    xf = np.empty((6, n))
    worst = np.full(n, -np.inf)
    t0 = time.perf_counter()
    for a in range(0, n, batch):
        cnt = min(batch, n - a)
        st = np.repeat(x0[:, a:a + 1], batch, axis=1)
        st[:, :cnt] = x0[:, a:a + cnt]
        ta.state[:] = st
        ta.set_time(np.zeros(batch))
        ta.pars[5, :] = np.pad(s[0, a:a + cnt], (0, batch - cnt), mode="edge")
        ta.pars[6, :] = np.pad(s[1, a:a + cnt], (0, batch - cnt), mode="edge")
        w = _heat_np(st[0], st[3], np.full(batch, U[0, 0]), v)
        for k in range(t_nodes.size - 1):
            dt = t_nodes[k + 1] - t_nodes[k]
            ta.pars[0, :] = U[0, k]
            ta.pars[1, :] = (U[0, k + 1] - U[0, k]) / dt
            ta.pars[2, :] = U[1, k]
            ta.pars[3, :] = (U[1, k + 1] - U[1, k]) / dt
            ta.pars[4, :] = t_nodes[k]
            # the grid starts at the current time (heyoka's rule): row 0 is the interval's start
            grid = t_nodes[k] + dt * np.arange(substeps + 1) / substeps
            _, out = ta.propagate_grid(np.repeat(grid[:, None], batch, axis=1))
            out = out[1:]
            al = U[0, k] + (U[0, k + 1] - U[0, k]) * np.arange(1, substeps + 1) / substeps
            w = np.maximum(w, np.max(_heat_np(out[:, 0, :], out[:, 3, :], al[:, None], v), axis=0))
        xf[:, a:a + cnt] = ta.state[:, :cnt]
        worst[a:a + cnt] = w[:cnt]
    return xf, worst, compile_s, time.perf_counter() - t0


@njit(cache=True, error_model="numpy")
def _rhs(x, alpha, bank, s1, s2, c, clc, cdc, out):
    a_deg = alpha / (math.pi / 180.0)
    cl = 0.0
    for i in range(clc.size - 1, -1, -1):
        cl = cl * a_deg + clc[i]
    cd = 0.0
    for i in range(cdc.size - 1, -1, -1):
        cd = cd * a_deg + cdc[i]
    cl *= 1.0 + s2
    cd *= 1.0 + s1
    h, lat, v, gam, psi = x[0], x[2], x[3], x[4], x[5]
    rho = c[2] * math.exp(-h / c[3])
    r = c[4] + h
    g = c[5] / r ** 2
    qs = 0.5 * rho * v ** 2 * c[1]
    lift, drag, m = qs * cl, qs * cd, c[0]
    out[0] = v * math.sin(gam)
    out[1] = v * math.cos(gam) * math.sin(psi) / (r * math.cos(lat))
    out[2] = v * math.cos(gam) * math.cos(psi) / r
    out[3] = -drag / m - g * math.sin(gam)
    out[4] = lift * math.cos(bank) / (m * v) + math.cos(gam) * (v / r - g / v)
    out[5] = lift * math.sin(bank) / (m * v * math.cos(gam)) + v * math.cos(gam) * math.sin(psi) * math.sin(lat) / (
        r * math.cos(lat))


@njit(cache=True, error_model="numpy")
def _numba_loop(x0, s, t_nodes, U, substeps, c, clc, cdc, hqc, xf, worst):
    k1, k2, k3, k4, xt, x = np.empty(6), np.empty(6), np.empty(6), np.empty(6), np.empty(6), np.empty(6)
    for i in range(x0.shape[1]):
        for q in range(6):
            x[q] = x0[q, i]
        w = -np.inf
        for k in range(t_nodes.size - 1):
            h = (t_nodes[k + 1] - t_nodes[k]) / substeps
            for j in range(substeps):
                fa, fb, fc = j / substeps, (j + 0.5) / substeps, (j + 1.0) / substeps
                d0, d1 = U[0, k + 1] - U[0, k], U[1, k + 1] - U[1, k]
                ua0, ub0, uc0 = U[0, k] + fa * d0, U[0, k] + fb * d0, U[0, k] + fc * d0
                ua1, ub1, uc1 = U[1, k] + fa * d1, U[1, k] + fb * d1, U[1, k] + fc * d1
                # element loops, no array temporaries (numba would allocate one per expression)
                _rhs(x, ua0, ua1, s[0, i], s[1, i], c, clc, cdc, k1)
                for q in range(6):
                    xt[q] = x[q] + 0.5 * h * k1[q]
                _rhs(xt, ub0, ub1, s[0, i], s[1, i], c, clc, cdc, k2)
                for q in range(6):
                    xt[q] = x[q] + 0.5 * h * k2[q]
                _rhs(xt, ub0, ub1, s[0, i], s[1, i], c, clc, cdc, k3)
                for q in range(6):
                    xt[q] = x[q] + h * k3[q]
                _rhs(xt, uc0, uc1, s[0, i], s[1, i], c, clc, cdc, k4)
                for q in range(6):
                    x[q] = x[q] + (h / 6.0) * (k1[q] + 2.0 * k2[q] + 2.0 * k3[q] + k4[q])
                a_deg = uc0 / (math.pi / 180.0)
                cq = 0.0
                for q in range(hqc.size - 1, -1, -1):
                    cq = cq * a_deg + hqc[q]
                rho = c[2] * math.exp(-x[0] / c[3])
                heat = cq * 17700.0 * math.sqrt(rho * c[6]) * (1e-4 * x[3] / c[7]) ** 3.07 * c[8]
                w = max(w, heat)
        xf[:, i] = x
        worst[i] = w


def numba_loop(v: sh.Vehicle, *, x0, s, t_nodes, controls, substeps: int):
    """``(xf (6, N), worst heating (N,), run_s)``; compiled before timing."""
    c = np.array([v.mass_kg, v.area_m2, v.atmosphere.rho0_kg_m3, v.atmosphere.scale_height_m, v.planet.radius_m,
                  v.planet.mu_m3_s2, sh.KG_M3_TO_SLUG_FT3, sh.FT_TO_M, sh.BTU_FT2_S_TO_W_M2])
    args = (np.asarray(t_nodes, float), np.ascontiguousarray(controls, float), int(substeps), c,
            np.asarray(v.cl_coeffs, float) * v.cl_scale, np.asarray(v.cd_coeffs, float) * v.cd_scale,
            np.asarray(v.heat_coeffs, float))
    n = x0.shape[1]
    xf, worst = np.empty((6, n)), np.empty(n)
    _numba_loop(np.ascontiguousarray(x0[:, :2]), np.ascontiguousarray(s[:, :2]), *args, xf[:, :2].copy(),
                worst[:2].copy())
    t0 = time.perf_counter()
    _numba_loop(np.ascontiguousarray(x0), np.ascontiguousarray(s), *args, xf, worst)
    return xf, worst, time.perf_counter() - t0
