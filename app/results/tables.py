"""Each time series or front of a result as a CSV table with unit-bearing column headers."""
from __future__ import annotations

import csv
import io
from typing import Any, Callable


def _columns(block: dict | None) -> dict[str, list] | None:
    """The equal-length list columns of a result block (``t_s``, ``altitude_m``, ...)."""
    if not isinstance(block, dict):
        return None
    cols = {k: v for k, v in block.items() if isinstance(v, list) and v and not isinstance(v[0], (list, dict))}
    lengths = {len(v) for v in cols.values()}
    return cols if cols and len(lengths) == 1 else None


def _front(r: dict) -> dict[str, list] | None:
    front = r.get("pareto_front")
    if not front:
        return None
    n = max(len(p["times_s"]) for p in front)
    cols: dict[str, list] = {f"t{i + 1}_s": [p["times_s"][i] if i < len(p["times_s"]) else None for p in front]
                             for i in range(n)}
    for key in ("delta_v_mps", "position_error_m", "velocity_error_mps"):
        cols[key] = [p[key] for p in front]
    return cols


def _porkchop(r: dict) -> dict[str, list] | None:
    pc = (r.get("impulsive") or {}).get("porkchop")
    if not pc:
        return None
    rows = [(tm, ti, pc["delta_v_mps"][i][j]) for i, tm in enumerate(pc["t_man_s"])
            for j, ti in enumerate(pc["t_intercept_s"])]
    return {"t_man_s": [a for a, _, _ in rows], "t_intercept_s": [b for _, b, _ in rows],
            "delta_v_mps": [c for _, _, c in rows]}


def _at(path: str) -> Callable[[dict], dict | None]:
    def pick(r: Any):
        for part in path.split("."):
            r = r.get(part) if isinstance(r, dict) else None
        return _columns(r)
    return pick


def _phases(r: dict) -> dict[str, list] | None:
    """Several ``ocp`` phases: their trajectories one after the other, a ``phase`` column first (a
    quantity a phase does not have is empty there)."""
    phases = [p for p in r.get("phases") or [] if isinstance(p, dict) and _columns(p.get("trajectory"))]
    if not phases:
        return _at("trajectory")(r)
    names: list[str] = []
    for p in phases:
        names += [n for n in _columns(p["trajectory"]) or {} if n not in names]
    cols: dict[str, list] = {"phase": [], **{n: [] for n in names}}
    for p in phases:
        tr = _columns(p["trajectory"]) or {"t": []}
        n = len(tr["t"])
        cols["phase"] += [p["name"]] * n
        for k in names:
            cols[k] += tr.get(k) or [None] * n
    return cols


TABLES: dict[str, dict[str, Callable[[dict], dict | None]]] = {
    "reentry": {"trajectory": _at("trajectory"), "verification": _at("verification.trajectory")},
    "robust_reentry": {"trajectory": _at("trajectory"), "deterministic": _at("deterministic.trajectory"),
                       "verification": _at("verification.trajectory")},
    "midcourse": {"pareto_front": _front},
    "intercept": {"scan": _at("impulsive.scan"), "finite_thrust": _at("finite_thrust.trajectory"),
                  "porkchop": _porkchop},
    "ocp": {"trajectory": _phases, "verification": _at("verification.trajectory")},
}


def tables_for(kind: str, result: dict) -> dict[str, dict[str, list]]:
    out = {}
    for name, pick in TABLES.get(kind, {}).items():
        cols = pick(result)
        if cols:
            out[name] = cols
    return out


def to_csv(cols: dict[str, list]) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(cols)
    # repr keeps every digit of a float (17 significant), so the CSV round-trips to the JSON's numbers
    w.writerows([["" if v is None else repr(v) if isinstance(v, float) else v for v in row]
                 for row in zip(*cols.values())])
    return buf.getvalue()
