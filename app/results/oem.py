"""CCSDS Orbit Ephemeris Messages (OEM 2.0, KVN): the writer the kinds' exports share (a kind that has a
trajectory to write declares ``KindSpec.oem``, an :class:`app.kinds.base.OemExport`, in its own
``oem`` module).

Frame: Earth-centred inertial (``REF_FRAME = EME2000``, ``CENTER_NAME = EARTH``).  The parameters
have no calendar epoch (t0 = 0), so t0 is written as J2000 (2000-01-01T12:00:00 TDB): a reader
shifts the epochs to its own t0.  Written and read by the maintained ``oem`` package; units km and
km/s as the standard asks.
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
