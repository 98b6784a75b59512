"""The lock (issue 29): uv.lock agrees with pyproject.toml, and requirements/*.txt (pip's path when uv is
missing) are its export, so both install paths give the same versions."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
UV = Path(sys.executable).parent / "uv"
EXPORTS = {"base": [], "test": ["--extra", "test"], "bench": ["--extra", "bench"]}


def _uv(*args: str) -> subprocess.CompletedProcess:
    assert UV.exists(), f"{UV} is missing: `make install` installs uv (pinned in the Makefile)"
    return subprocess.run([str(UV), *args], cwd=ROOT, capture_output=True, text=True, timeout=120)


@pytest.mark.parametrize("name", sorted(EXPORTS))
def test_requirements_export_matches_the_lock(name):
    out = _uv("export", "--frozen", "--no-emit-project", "--no-header", *EXPORTS[name])
    assert out.returncode == 0, out.stderr
    assert (ROOT / "requirements" / f"{name}.txt").read_text() == out.stdout, \
        f"requirements/{name}.txt is not uv.lock's export: run `make lock`"


def test_lock_matches_pyproject():
    # --offline: answered from uv's cache, which the install filled; no network in a unit test
    out = _uv("lock", "--check", "--offline")
    assert out.returncode == 0, f"uv.lock is out of date with pyproject.toml: run `make lock`\n{out.stderr}"
