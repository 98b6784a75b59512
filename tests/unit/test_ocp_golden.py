"""Every ``ocp`` preset (and the extra cases of ``scripts/golden_compare.py``) answers as it did before the
phase model was unified (issue 34 item 2): the results recorded at main (9206fb4) in
``tests/fixtures/ocp_golden`` (presets added later are held to their optima by their own tests).

The refactor keeps the same NLP, the same guess and the same IPOPT options, so the iterates are the same
and every number agrees to far better than the solver's tolerance; 1e-9 relative is what still holds
across CPUs (a different BLAS or vector width moves the last bits), and integers (iterations, interval
counts) must be equal.  Strings (outcome, notes, messages) must be equal too; timing fields are skipped
and fields that are new are allowed (the comparer reports them as additions).
"""
from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
FIXTURES = ROOT / "tests" / "fixtures" / "ocp_golden"
_spec = importlib.util.spec_from_file_location("golden_compare", ROOT / "scripts" / "golden_compare.py")
golden = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(golden)

RTOL = 1e-9


@pytest.fixture(scope="module")
def records() -> dict[str, dict]:
    """Every case run once, in the script's order (later cases warm-start from earlier ones)."""
    return dict(golden._run_kind("ocp", set(_cases())))


def _cases() -> list[str]:
    return sorted(p.name[len("ocp__"):-len(".json")] for p in FIXTURES.glob("ocp__*.json"))


@pytest.mark.parametrize("case", _cases())
@pytest.mark.slow
def test_the_answer_is_the_recorded_one(records, case):
    old = json.loads((FIXTURES / f"ocp__{case}.json").read_text())
    new = records[case]
    out = {"numbers": 0, "max_rel": 0.0, "max_rel_at": "", "rtol": RTOL, "differences": [], "missing": [],
           "added": [], "nan_to_null": []}
    golden._compare(old, new, "", out)
    assert out["numbers"] > 50                     # the trajectory arrays are compared, not just a status
    assert not out["differences"] and not out["missing"], (out["differences"] + out["missing"])[:20]
    assert new["result"]["solver"]["iterations"] == old["result"]["solver"]["iterations"]
