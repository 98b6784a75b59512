"""The finite-thrust intercept trajectory as a CCSDS Orbit Ephemeris Message (the writer and its
conventions: :mod:`app.results.oem`).

The result stores the interceptor relative to the target in the target's Hill frame.  The target
flies a circular orbit given by the job's parameters, so its inertial state at any time is exact
(``solvers.models.relative_motion.circular_state``) and the interceptor's inertial state follows
(``hill_to_inertial``).
"""
from __future__ import annotations

import numpy as np

from app.kinds.base import OemExport
from app.results.oem import MIN_STEP_S, spaced, write_oem


def inertial_states(*, result: dict, params: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(t_s, r_m (n, 3), v_mps (n, 3))`` of the interceptor, inertial, nodes closer than MIN_STEP_S dropped."""
    from app.kinds.intercept.params import InterceptParams
    from app.kinds.intercept.problem import to_problem
    from solvers.models.relative_motion import circular_state, hill_to_inertial

    tr = result["finite_thrust"]["trajectory"]
    t = np.asarray(tr["t_s"], float)
    keep = spaced(t, min_step_s=MIN_STEP_S)
    p = InterceptParams.model_validate(params)
    _, _, rt0, vt0 = to_problem(p).scenario.initial_states()
    r_t, v_t = circular_state(r0=rt0, v0=vt0, mu=p.mu_m3_s2, t=t[keep])
    rho = np.column_stack([tr["x_m"], tr["y_m"], tr["z_m"]]).astype(float)[keep]
    rho_dot = np.column_stack([tr["vx_mps"], tr["vy_mps"], tr["vz_mps"]]).astype(float)[keep]
    r, v = hill_to_inertial(rho=rho, rho_dot=rho_dot, r_t=r_t, v_t=v_t)
    return t[keep], r, v


def to_oem(*, result: dict, params: dict, object_name: str) -> str:
    """The OEM text (KVN) of the interceptor's trajectory."""
    t, r, v = inertial_states(result=result, params=params)
    return write_oem([(t, r, v)], object_name=object_name)


def _available(result: dict) -> bool:
    return bool(((result.get("finite_thrust") or {}).get("trajectory") or {}).get("t_s"))


def _prepare(result: dict, params: dict, *, object_name: str, point=None, trajectory=None):
    """One file per job (``point`` and ``trajectory`` choose among a midcourse front's, not here)."""
    return (), lambda: to_oem(result=result, params=params, object_name=object_name)


OEM = OemExport(available=_available, prepare=_prepare)
