"""The scripts the docs name run as named (``python scripts/NAME.py`` from any directory, no
ModuleNotFoundError) and answer ``--help`` with their usage, doing nothing else (issue 28 item 3: the
README's picture script re-ran four solves and overwrote docs/img/ on ``--help``)."""
from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]


def named_scripts() -> list[str]:
    """The programs under scripts/ the docs name (a module there without a ``__main__`` block, e.g. a
    plug-in MkDocs loads, is not a program)."""
    names = set()
    for doc in DOCS:
        names |= set(re.findall(r"scripts/([a-z_]+\.py)", doc.read_text()))
    return sorted(n for n in names if (ROOT / "scripts" / n).is_file()
                  and '__name__ == "__main__"' in (ROOT / "scripts" / n).read_text())


def test_the_docs_name_the_picture_script():
    assert "make_readme_images.py" in named_scripts()


@pytest.mark.parametrize("script", named_scripts())
def test_a_named_script_runs_from_anywhere_and_honours_help(script, tmp_path):
    img = ROOT / "docs" / "img"
    before = {p.name: p.stat().st_mtime_ns for p in img.iterdir()} if img.is_dir() else {}
    p = subprocess.run([sys.executable, str(ROOT / "scripts" / script), "--help"], cwd=tmp_path,
                       capture_output=True, text=True, timeout=60)
    assert p.returncode == 0, p.stderr
    assert p.stdout.startswith("usage:") and "--help" in p.stdout
    assert list(tmp_path.iterdir()) == []
    after = {p.name: p.stat().st_mtime_ns for p in img.iterdir()} if img.is_dir() else {}
    assert after == before
