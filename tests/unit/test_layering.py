"""The layering rules a machine can check (issues 12 and 23): no module reaches into another's
``_private`` names, the import-linter contracts in ``pyproject.toml`` hold, no import cycle runs
through ``app/``, ``solvers/`` or ``worker/``, and no module there grows past 400 lines.

Both checkers are also run on planted violations, so a check that silently passes
everything cannot hide here.
"""
from __future__ import annotations

import ast
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import grimp
import pytest

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("app", "worker", "solvers", "benchmarks")

# (importing module, imported module) pairs still reaching into privates while the work
# that removes them is under way. Empty it, never add to it: a new pair is a bug.
ALLOWED_PRIVATE_REACH_INS: set[tuple[str, str]] = set()

MAX_MODULE_LINES = 400
# Modules over MAX_MODULE_LINES while a split that shortens them is under way. Empty it, never add to it.
ALLOWED_LONG_MODULES: set[str] = set()


def _module_name(path: Path, root: Path) -> str:
    parts = list(path.relative_to(root).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _is_private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def _absolute(module: str | None, level: int, importer: str, is_package: bool) -> str:
    if level == 0:
        return module or ""
    base = importer.split(".")
    base = base[: len(base) - level + (1 if is_package else 0)]
    return ".".join(base + ([module] if module else []))


def _is_module(name: str, root: Path) -> bool:
    rel = Path(*name.split("."))
    return (root / rel).with_suffix(".py").is_file() or (root / rel / "__init__.py").is_file()


def private_reach_ins(path: Path, root: Path) -> list[tuple[str, str, int]]:
    """``(imported module, private name, line)`` for every ``from m import _x`` and every
    ``m._x`` where ``m`` names an imported module, in one source file."""
    importer = _module_name(path, root)
    is_package = path.name == "__init__.py"
    tree = ast.parse(path.read_text(), filename=str(path))
    modules: dict[str, str] = {}   # local name -> module it is bound to
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.asname:
                    modules[alias.asname] = alias.name
                else:
                    modules[alias.name.split(".")[0]] = alias.name.split(".")[0]
        elif isinstance(node, ast.ImportFrom):
            source = _absolute(node.module, node.level, importer, is_package)
            for alias in node.names:
                if _is_private(alias.name):
                    found.append((source, alias.name, node.lineno))
                elif _is_module(f"{source}.{alias.name}", root):
                    modules[alias.asname or alias.name] = f"{source}.{alias.name}"
    for node in ast.walk(tree):
        if (isinstance(node, ast.Attribute) and _is_private(node.attr) and isinstance(node.value, ast.Name)
                and node.value.id in modules):
            found.append((modules[node.value.id], node.attr, node.lineno))
    # only our own modules' privates: the standard library's documented ones (os._exit in a forked child) are API
    return [f for f in found if f[0] != importer and _is_module(f[0], root)]


def _all_reach_ins(root: Path, packages) -> list[str]:
    out = []
    for pkg in packages:
        for path in sorted((root / pkg).rglob("*.py")):
            importer = _module_name(path, root)
            for module, name, line in private_reach_ins(path, root):
                if (importer, module) not in ALLOWED_PRIVATE_REACH_INS:
                    out.append(f"{path.relative_to(root)}:{line}: {module}.{name}")
    return out


def test_no_module_imports_a_private_name_of_another():
    assert _all_reach_ins(ROOT, PACKAGES) == []


def test_the_private_name_checker_catches_planted_reach_ins(tmp_path):
    pkg = tmp_path / "pkg"
    (pkg / "sub").mkdir(parents=True)
    for p in (pkg / "__init__.py", pkg / "sub" / "__init__.py"):
        p.write_text("")
    (pkg / "lib.py").write_text("_hidden = 1\n__version__ = '1'\nshown = 2\n")
    (pkg / "sub" / "mod.py").write_text("def _helper():\n    return 1\n")
    (pkg / "user.py").write_text(textwrap.dedent("""
        import pkg.lib as lib
        from pkg import lib as lib2
        from pkg.lib import _hidden, shown, __version__
        from .sub import mod
        from .sub.mod import _helper as h


        def f():
            return lib._hidden + lib2._hidden + mod._helper() + lib.shown + lib.__doc__.count("")
    """))
    (pkg / "clean.py").write_text("from pkg.lib import shown\n\n\ndef _mine():\n    return _mine.__name__\n")
    found = sorted((m, n) for m, n, _ in private_reach_ins(pkg / "user.py", tmp_path))
    assert found == [("pkg.lib", "_hidden"), ("pkg.lib", "_hidden"), ("pkg.lib", "_hidden"),
                     ("pkg.sub.mod", "_helper"), ("pkg.sub.mod", "_helper")]
    assert private_reach_ins(pkg / "clean.py", tmp_path) == []
    assert len(_all_reach_ins(tmp_path, ["pkg"])) == 5


def _lint_imports(cwd: Path) -> subprocess.CompletedProcess:
    exe = shutil.which("lint-imports", path=str(Path(sys.executable).parent))
    assert exe, "import-linter is not installed (pip install -e '.[test]')"
    return subprocess.run([exe, "--no-cache"], cwd=cwd, capture_output=True, text=True, timeout=300)


def test_the_import_contracts_hold():
    run = _lint_imports(ROOT)
    assert run.returncode == 0, run.stdout + run.stderr
    assert "broken" not in run.stdout.lower().split("contracts:")[-1].replace("0 broken", ""), run.stdout


@pytest.mark.parametrize("planted, contract", [
    ("import fakeapp.routes\n", "solvers never imports the service"),
    ("", "kinds are independent"),
])
def test_the_import_contracts_fail_on_a_planted_violation(tmp_path, planted, contract):
    # A copy of the shape of our contracts over a tmp project with one forbidden import.
    for pkg in ("fakesolvers", "fakeapp", "fakeapp/kinds"):
        (tmp_path / pkg).mkdir(parents=True, exist_ok=True)
        (tmp_path / pkg / "__init__.py").write_text("")
    (tmp_path / "fakeapp" / "routes.py").write_text("")
    (tmp_path / "fakesolvers" / "core.py").write_text(planted or "import math\n")
    (tmp_path / "fakeapp" / "kinds" / "one.py").write_text("")
    (tmp_path / "fakeapp" / "kinds" / "two.py").write_text("" if planted else "from fakeapp.kinds import one\n")
    (tmp_path / "pyproject.toml").write_text(textwrap.dedent("""
        [tool.importlinter]
        root_packages = ["fakesolvers", "fakeapp"]

        [[tool.importlinter.contracts]]
        name = "solvers never imports the service"
        type = "forbidden"
        source_modules = ["fakesolvers"]
        forbidden_modules = ["fakeapp"]

        [[tool.importlinter.contracts]]
        name = "kinds are independent"
        type = "independence"
        modules = ["fakeapp.kinds.one", "fakeapp.kinds.two"]
    """))
    env_path = f"{tmp_path}"
    run = subprocess.run([shutil.which("lint-imports", path=str(Path(sys.executable).parent)), "--no-cache"],
                         cwd=tmp_path, capture_output=True, text=True, timeout=120,
                         env={"PYTHONPATH": env_path, "PATH": str(Path(sys.executable).parent)})
    assert run.returncode != 0, run.stdout
    assert f"{contract} BROKEN" in " ".join(run.stdout.split()), run.stdout
    assert "1 broken" in run.stdout


def test_the_api_edge_loads_no_solver_engine():
    # Kinds import their solvers inside run(): the API process never pays for CasADi, heyoka or pymoo.
    code = ("import sys, app.api.main, app.kinds, app.api.schemas; "
            "print(sorted(m for m in ('casadi', 'heyoka', 'pymoo') if m in sys.modules))")
    run = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    assert run.stdout.strip() == "[]"


def import_cycles(*packages: str) -> list[list[str]]:
    """Every import cycle among the modules of ``packages``: the strongly connected components of
    grimp's import graph (imports inside functions and under ``TYPE_CHECKING`` count too), each as
    its sorted module names. Two modules that need each other share a third thing: move it into a
    module of its own."""
    graph = grimp.build_graph(*packages, cache_dir=None)
    succ = {m: sorted(graph.find_modules_directly_imported_by(m)) for m in graph.modules}
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    cycles = []
    for root in sorted(succ):   # Tarjan's algorithm, iterative (no recursion limit on long chains)
        if root in index:
            continue
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        work = [(root, iter(succ[root]))]
        while work:
            node, todo = work[-1]
            nxt = next(todo, None)
            if nxt is not None:
                if nxt not in index:
                    index[nxt] = low[nxt] = len(index)
                    stack.append(nxt)
                    on_stack.add(nxt)
                    work.append((nxt, iter(succ[nxt])))
                elif nxt in on_stack:
                    low[node] = min(low[node], index[nxt])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while not component or component[-1] != node:
                    component.append(stack.pop())
                    on_stack.discard(component[-1])
                if len(component) > 1 or node in succ[node]:
                    cycles.append(sorted(component))
    return sorted(cycles)


def test_no_import_cycle_among_app_solvers_worker():
    assert import_cycles("app", "solvers", "worker") == []


def test_the_cycle_finder_catches_a_planted_cycle(tmp_path, monkeypatch):
    pkg = tmp_path / "plantedcycle"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "a.py").write_text("from plantedcycle import b\n")
    (pkg / "b.py").write_text("def f():\n    from plantedcycle.c import x\n    return x\n")
    (pkg / "c.py").write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from plantedcycle import a\nx = 1\n")
    (pkg / "clean.py").write_text("from plantedcycle import c\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    assert import_cycles("plantedcycle") == [["plantedcycle.a", "plantedcycle.b", "plantedcycle.c"]]
    (pkg / "c.py").write_text("x = 1\n")
    assert import_cycles("plantedcycle") == []


def long_modules(root: Path, packages) -> list[str]:
    """``path: lines`` of every module of ``packages`` over MAX_MODULE_LINES, not allowed for now."""
    out = []
    for pkg in packages:
        for path in sorted((root / pkg).rglob("*.py")):
            rel = str(path.relative_to(root))
            lines = len(path.read_text().splitlines())
            if lines > MAX_MODULE_LINES and rel not in ALLOWED_LONG_MODULES:
                out.append(f"{rel}: {lines}")
    return out


def test_no_module_over_400_lines():
    # A module does one job; past ~400 lines it is a package waiting to be made (STYLE.md).
    assert long_modules(ROOT, ("app", "solvers", "worker")) == []


def test_the_length_check_catches_a_planted_long_module(tmp_path):
    (tmp_path / "pkg").mkdir()
    (tmp_path / "pkg" / "short.py").write_text("x = 1\n" * MAX_MODULE_LINES)
    (tmp_path / "pkg" / "long.py").write_text("x = 1\n" * (MAX_MODULE_LINES + 1))
    assert long_modules(tmp_path, ["pkg"]) == [f"pkg/long.py: {MAX_MODULE_LINES + 1}"]
