"""The finite-thrust intercept trajectory as a CCSDS Orbit Ephemeris Message (OEM 2.0, KVN).

The result stores the interceptor relative to the target in the target's Hill frame.  The target
flies a circular orbit given by the job's parameters, so its inertial state at any time is exact
(``solvers.models.relative_motion.circular_state``) and the interceptor's inertial state follows
(``hill_to_inertial``).  Frame: the Earth-centred inertial frame of the parameters' elements
(``REF_FRAME = EME2000``, ``CENTER_NAME = EARTH``).  The parameters have no calendar epoch (t0 = 0),
so t0 is written as J2000 (2000-01-01T12:00:00 TDB): a reader shifts the epochs to its own t0.
Written and read by the maintained ``oem`` package; units km and km/s as the standard asks.
:func:`write_oem` is the writer the midcourse export (:mod:`app.results.midcourse_oem`) uses too.
"""
from __future__ import annotations

import datetime as dt
import tempfile
from pathlib import Path

import numpy as np

T0 = dt.datetime(2000, 1, 1, 12, 0, 0)
MIN_STEP_S = 1e-3


def spaced(t: np.ndarray, *, min_step_s: float) -> np.ndarray:
    """Mask of the nodes at least ``min_step_s`` after the last kept one: segment boundaries repeat
    a node time and a vanishing arc packs nodes nanoseconds apart, which the OEM's microsecond
    epochs cannot order."""
    keep = np.zeros(t.size, bool)
    last = -np.inf
    for i, ti in enumerate(t):
        if ti - last >= min_step_s:
            keep[i], last = True, ti
    return keep


def has_oem(kind: str, result: dict) -> bool:
    """Whether the job has a trajectory to write (intercept with a finite-thrust solution, or a
    midcourse front: :mod:`app.results.midcourse_oem`)."""
    if kind == "midcourse":
        return bool(result.get("pareto_front"))
    return kind == "intercept" and bool(((result.get("finite_thrust") or {}).get("trajectory") or {}).get("t_s"))


def inertial_states(*, result: dict, params: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(t_s, r_m (n, 3), v_mps (n, 3))`` of the interceptor, inertial, nodes closer than MIN_STEP_S dropped."""
    from app.kinds.intercept import to_problem
    from app.kinds.intercept_params import InterceptParams
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


def write_oem(segments: list[tuple[np.ndarray, np.ndarray, np.ndarray]], *, object_name: str,
              comments: tuple[str, ...] = ()) -> str:
    """OEM 2.0 text (KVN) of one object: one data segment per ``(t_s, r_m, v_mps)`` (consecutive,
    Earth-centred inertial, km and km/s in the file), ``comments`` at the start of each segment's
    metadata (the library writes none, so they are inserted into its text)."""
    from astropy.time import Time
    from oem import OrbitEphemerisMessage
    from oem.components import EphemerisSegment, HeaderSection, MetaDataSection

    fmt = "%Y-%m-%dT%H:%M:%S.%f"
    out = []
    for t, r, v in segments:
        epochs = [Time(T0 + dt.timedelta(seconds=float(s)), format="datetime", scale="tdb", precision=6) for s in t]
        meta = MetaDataSection({
            "OBJECT_NAME": object_name[:64], "OBJECT_ID": object_name[:64], "CENTER_NAME": "EARTH",
            "REF_FRAME": "EME2000", "TIME_SYSTEM": "TDB",
            "START_TIME": (T0 + dt.timedelta(seconds=float(t[0]))).strftime(fmt),
            "STOP_TIME": (T0 + dt.timedelta(seconds=float(t[-1]))).strftime(fmt)})
        rows = (tuple(epochs), *(tuple(c) for c in (r / 1e3).T), *(tuple(c) for c in (v / 1e3).T))
        out.append(EphemerisSegment(meta, rows))
    header = HeaderSection({"CCSDS_OEM_VERS": "2.0", "ORIGINATOR": "trajlab",
                            "CREATION_DATE": dt.datetime.now(dt.timezone.utc).strftime(fmt)})
    message = OrbitEphemerisMessage(header, out)
    with tempfile.TemporaryDirectory() as tmp:  # the library writes files only
        path = Path(tmp) / "result.oem"
        message.save_as(path, file_format="kvn")
        text = path.read_text()
    if comments:
        text = text.replace("META_START\n", "META_START\n" + "".join(f"COMMENT {c}\n" for c in comments))
    return text
