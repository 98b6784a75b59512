"""Whether a flight stayed within its aerodynamic data, said in words for a result's notes.

An aero table (:class:`solvers.models.aerodynamics.AeroTable`) is clamped at its breakpoints: beyond
the last alpha or Mach breakpoint CL and CD keep their edge values (no cubic extrapolation, which
runs away).  That is a model choice the optimizer can exploit without the user knowing, so the
answer says how far outside the table the flight went, in alpha and in Mach, at the nodes (the
controls are linear or constant between nodes, so alpha between nodes lies between node values;
Mach between nodes can differ slightly).  Polynomials in alpha have no data range; when the
optimizer rides an alpha bound, a polynomial fitted over a narrower range is extrapolated there,
and the note says so.
"""
from __future__ import annotations

import numpy as np

from solvers.models.reentry_state import ALTITUDE, SPEED

ON_BOUND_DEG = 0.01  # alpha within this of a bound counts as riding it


def _beyond(lo: float, hi: float, lo_data: float, hi_data: float) -> float:
    return max(lo_data - lo, hi - hi_data, 0.0)


def aero_coverage_notes(vehicle, x: np.ndarray, alpha_rad: np.ndarray, *,
                        alpha_bounds_rad: tuple[float, float]) -> list[str]:
    """Notes on the flown alpha (and Mach, for a table) against the aerodynamic data; ``x`` the states and
    ``alpha_rad`` the angle of attack at the nodes."""
    alpha = np.degrees(np.asarray(alpha_rad, float))
    alpha = alpha[np.isfinite(alpha)]
    if alpha.size == 0:
        return []
    a_lo, a_hi = float(alpha.min()), float(alpha.max())
    table = vehicle.aero_table
    if table is None:
        b_lo, b_hi = np.degrees(alpha_bounds_rad)
        if a_lo > b_lo + ON_BOUND_DEG and a_hi < b_hi - ON_BOUND_DEG:
            return []
        return [f"aerodynamics: CL and CD are polynomials in alpha with no data range; the answer flies "
                f"alpha {a_lo:.2f} to {a_hi:.2f} deg and rides the bound bounds.alpha_deg [{b_lo:g}, {b_hi:g}]: "
                f"if the polynomials were fitted over a narrower range, they are extrapolated there (bound "
                f"alpha_deg to the data's range, or give an aero_table)"]
    h = np.asarray(x[ALTITUDE], float)
    mach = np.asarray(x[SPEED], float) / np.asarray(vehicle.atmosphere.speed_of_sound(h, np), float)
    mach = mach[np.isfinite(mach)]
    m_lo, m_hi = float(mach.min()), float(mach.max())
    t_alpha, t_mach = table.alpha_deg, table.mach
    parts, outside = [], []
    over = _beyond(a_lo, a_hi, t_alpha[0], t_alpha[-1])
    parts.append(f"alpha {a_lo:.2f} to {a_hi:.2f} deg against breakpoints {t_alpha[0]:g} to {t_alpha[-1]:g} deg")
    if over > 0:
        outside.append(f"alpha up to {over:.2f} deg beyond the table")
    if len(t_mach) > 1:
        over_m = _beyond(m_lo, m_hi, t_mach[0], t_mach[-1])
        parts.append(f"Mach {m_lo:.2f} to {m_hi:.2f} against {t_mach[0]:g} to {t_mach[-1]:g}")
        if over_m > 0:
            outside.append(f"Mach up to {over_m:.2f} beyond the table")
    if not outside:
        return [f"aero table: the flight stays within its data ({'; '.join(parts)})"]
    return [f"warning: aero table extrapolated: {', '.join(outside)} ({'; '.join(parts)}); there CL and CD "
            f"are held at the edge breakpoints' values (the spline is clamped); extend the table, or bound "
            f"bounds.alpha_deg to the table's range"]
