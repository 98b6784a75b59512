"""A midcourse job's trajectories as a CCSDS OEM: the corrected flight of one Pareto-front point
(default: the point of least delta-v; ``?point=i`` picks front point i) or the nominal transfer.

A midcourse result stores schedules, not trajectories; the chosen one is re-flown from the stored
result and the job's parameters by :func:`solvers.midcourse.trajectory.transfer_trajectories`
(the solver's own J2 propagator and Lambert impulses, so its final errors are the front point's
objectives).  The corrected flight is one OEM data segment per coast: a segment ends with the
state just before an impulse and the next starts with the state just after it, at the same epoch.

Frame: paper 002's launch-inertial frame is inertial and only translated by ``R0``, so the states
are written Earth-centred with ``z`` along the Earth's spin axis and ``x`` in the launch meridian
at t0 (:func:`solvers.midcourse.trajectory.inertial_rotation`), as ``REF_FRAME = EME2000``,
``CENTER_NAME = EARTH``.  The parameters give neither the launch longitude nor a calendar epoch,
so this is EME2000 up to a rotation about ``z`` (and precession since J2000); t0 is written as
J2000 TDB, as for the intercept.  The file's COMMENT lines say so.  With ``frame = "eci"`` the
parameters' own axes are written unchanged.
"""
from __future__ import annotations

from typing import Literal

import numpy as np

from app.kinds.base import OemExport
from app.results.oem import MIN_STEP_S, spaced, write_oem

STEP_S = 60.0  # state spacing of the file; every impulse adds a segment boundary


def default_point(result: dict) -> int:
    """Index of the front point of least delta-v (the first of them)."""
    dv = [np.inf if p["delta_v_mps"] is None else p["delta_v_mps"] for p in result["pareto_front"]]
    return int(np.argmin(dv))


def midcourse_segments(*, result: dict, params: dict, point: int,
                       trajectory: Literal["corrected", "nominal"] = "corrected"):
    """``(segments, comments)``: ``[(t_s, r_m (n, 3), v_mps (n, 3))]`` Earth-centred inertial, and the
    file's COMMENT lines."""
    from app.kinds.midcourse.params import MidcourseParams
    from app.kinds.midcourse.problem import to_problem
    from solvers.midcourse.trajectory import inertial_rotation, transfer_trajectories

    p = MidcourseParams.model_validate(params)
    problem = to_problem(p)
    chosen = result["pareto_front"][point]
    flown = transfer_trajectories(problem, chosen["times_s"], step_s=STEP_S)
    m = inertial_rotation(problem.frame)
    arcs = [flown.nominal] if trajectory == "nominal" else flown.corrected
    segments = []
    for arc in arcs:
        keep = spaced(arc.t_s, min_step_s=MIN_STEP_S)
        x = arc.states[keep]
        segments.append((arc.t_s[keep], x[:, :3] @ m.T, x[:, 3:] @ m.T))
    frame = ("Earth-centred inertial: z along the Earth's spin axis, x in the launch meridian at t0 (the "
             "parameters give no launch longitude or epoch: EME2000 up to a rotation about z)"
             if p.frame == "launch" else "the parameters' Earth-centred inertial axes")
    what = ("nominal transfer: the error-free initial state, no correction" if trajectory == "nominal" else
            f"Pareto-front point {point}: corrections at {', '.join(f'{t:.3f}' for t in chosen['times_s']) or 'none'} "
            f"s, one segment per coast; final position error {flown.objectives[1]:.3f} m, "
            f"total delta-v {flown.objectives[0]:.4f} m/s")
    comments = (f"trajlab midcourse job, {what}",
                "J2 coasts (heyoka Taylor, the solver's propagator) and the solver's Lambert impulses; "
                "initial error: the parameters' initial_error",
                f"frame: {frame}; t0 written as 2000-01-01T12:00:00 TDB (no calendar epoch in the parameters)")
    return segments, comments


def midcourse_to_oem(*, result: dict, params: dict, object_name: str, point: int | None = None,
                     trajectory: Literal["corrected", "nominal"] = "corrected") -> str:
    """The OEM text (KVN) of a midcourse job's chosen trajectory."""
    point = default_point(result) if point is None else point
    segments, comments = midcourse_segments(result=result, params=params, point=point, trajectory=trajectory)
    suffix = "nominal" if trajectory == "nominal" else f"point {point}"
    return write_oem(segments, object_name=f"{object_name[:48]} {suffix}", comments=comments)


def prepare(result: dict, params: dict, *, object_name: str, point: int | None,
            trajectory: Literal["corrected", "nominal"]):
    """``(view, make)`` of :class:`app.kinds.base.OemExport`: the nominal transfer, or front point ``point``
    (default: the point of least delta-v; ``LookupError`` past the front)."""
    n = len(result["pareto_front"])
    point = default_point(result) if point is None else point
    if point >= n:
        raise LookupError(f"no front point {point} ({n} points)")
    view = ("nominal",) if trajectory == "nominal" else ("point", str(point))
    return view, lambda: midcourse_to_oem(result=result, params=params, object_name=object_name, point=point,
                                          trajectory=trajectory)


OEM = OemExport(available=lambda result: bool(result.get("pareto_front")), prepare=prepare)
