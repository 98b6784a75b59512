"""The docs' tables of benchmark figures are latest.json's (issue 38 item 2): every table between
``<!-- bench: NAME -->`` and ``<!-- /bench -->`` is exactly what :mod:`benchmarks.results.tables` renders from
``benchmarks/results/latest.json``, so a figure typed into one, or a table left behind by a new benchmark run,
fails here (the fix: ``python scripts/docs_numbers.py --tables``)."""
from __future__ import annotations

import copy

import pytest

from benchmarks.results.tables import ROOT, latest, pages, render, rewrite, tables

PAGES = pages()


def test_the_readme_renders_its_measured_tables():
    names = [name for name, _ in tables((ROOT / "README.md").read_text())]
    assert {"api_load", "compiles", "ocp_memory"} <= set(names), names


def test_the_ocp_tutorial_renders_its_robust_presets():
    names = [name for name, _ in tables((ROOT / "docs" / "tutorials" / "ocp.md").read_text())]
    assert names == ["ocp_robust"], names


@pytest.mark.parametrize("page", PAGES, ids=[p.name for p in PAGES])
def test_every_table_between_markers_is_latest_json_rendered(page):
    results = latest()
    for name, body in tables(page.read_text()):
        assert body == render(name, results), (
            f"{page.name}: the table <!-- bench: {name} --> differs from latest.json's {name!r}; "
            f"run: python scripts/docs_numbers.py --tables")


def test_a_typed_figure_and_a_stale_table_are_caught():
    """A figure edited by hand differs from the rendering; so does the table once latest.json moves on."""
    text, results = (ROOT / "README.md").read_text(), latest()
    assert rewrite(text, results) == text
    shown = f"| {next(iter(results['ocp_memory']['figures'].values()))['ratio']:.2f} |"   # a ratio the table shows
    typed = text.replace(shown, "| 9.99 |", 1)
    assert typed != text and rewrite(typed, results) == text
    moved = copy.deepcopy(results)
    case = next(iter(moved["ocp_memory"]["figures"].values()))
    case["peak_mb"] *= 2
    case["ratio"] /= 2
    assert rewrite(text, moved) != text


def test_a_table_without_renderer_or_entry_is_named():
    with pytest.raises(KeyError, match="no renderer"):
        rewrite("<!-- bench: nothing -->\n| x |\n<!-- /bench -->\n", latest())
    with pytest.raises(KeyError, match="no entry"):
        render("api_load", {})
