"""The golden-check comparer (scripts/golden_compare.py) catches what it must and allows only NaN -> null."""
from __future__ import annotations

import importlib.util
from pathlib import Path

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "golden_compare.py"
_spec = importlib.util.spec_from_file_location("golden_compare", SCRIPT)
golden = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(golden)


def _diff(old, new, rtol=1e-9):
    out = {"numbers": 0, "max_rel": 0.0, "max_rel_at": "", "rtol": rtol, "differences": [], "missing": [],
           "added": [], "nan_to_null": []}
    golden._compare(old, new, "", out)
    return out


def test_equal_within_tolerance_and_additions_allowed():
    old = {"a": 1.0, "b": [2.0, 0.0], "solver": {"solve_time_s": 3.0}, "s": "x"}
    new = {"a": 1.0 + 1e-12, "b": [2.0, None], "solver": {"solve_time_s": 9.0}, "s": "x", "extra": [1]}
    out = _diff(old, new)
    assert out["differences"] == [] and out["missing"] == []
    assert out["nan_to_null"] == [".b[1]: 0.0 -> null"] and out["added"] == [".extra"]
    assert 0 < out["max_rel"] < 1e-11


def test_planted_differences_are_reported():
    out = _diff({"a": 1.0, "b": [1, 2], "c": 5.0, "d": "ok", "e": 1.0}, {"a": 1.0 + 1e-6, "b": [1], "c": None,
                                                                      "d": "changed"})
    assert len(out["differences"]) == 4 and out["missing"] == [".e"]
    assert any(d.startswith(".a:") for d in out["differences"])
    assert any(".c: 5.0 -> null" in d for d in out["differences"])   # only 0.0 may become null
