"""The package's layout: a package per layer, each importing only the layers below it, and
an import graph without cycles.

Imports are read with ``ast`` from every module, including the ones inside functions (a
lazy import that breaks a cycle at run time is still a cycle in the design) and under
``TYPE_CHECKING``. Importing ``a.b.c`` from outside package ``a.b`` also runs
``a/b/__init__.py`` first, so it counts as an import of ``a.b`` too.
"""

from __future__ import annotations

import ast
import shutil
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "src" / "sensorplan"


def modules(package: Path) -> dict[str, Path]:
    """Dotted module name -> file, for every module of the package at ``package``."""
    out = {}
    for path in sorted(package.rglob("*.py")):
        parts = path.relative_to(package.parent).with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


def imported(name: str, path: Path, known: set[str]) -> set[str]:
    """Modules of ``known`` that module ``name`` imports (anywhere in its code)."""
    is_package = path.name == "__init__.py"
    here = name.split(".") if is_package else name.split(".")[:-1]
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = here[:len(here) - node.level + 1] if node.level else []
            module = ".".join(base + ([node.module] if node.module else []))
            # ``from pkg import sub`` imports the module pkg.sub; ``from mod import f`` mod.
            targets = [f"{module}.{a.name}" if f"{module}.{a.name}" in known else module
                       for a in node.names]
        else:
            continue
        for target in targets:
            parts = target.split(".")
            for k in range(1, len(parts) + 1):
                prefix = ".".join(parts[:k])
                # The target and the packages above it that the importer is not inside.
                if prefix in known and not (k < len(parts) and name.startswith(prefix + ".")):
                    found.add(prefix)
    found.discard(name)
    return found


def import_graph(package: Path) -> dict[str, set[str]]:
    mods = modules(package)
    return {name: imported(name, path, set(mods)) for name, path in mods.items()}


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One cycle ``[a, b, ..., a]`` of the directed graph, or None."""
    state: dict[str, int] = {}            # 1: on the current path, 2: finished
    stack: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        stack.append(node)
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                return stack[stack.index(nxt):] + [nxt]
            if nxt not in state and (cycle := visit(nxt)) is not None:
                return cycle
        stack.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state and (cycle := visit(node)) is not None:
            return cycle
    return None


def test_the_import_graph_has_no_cycle() -> None:
    graph = import_graph(PACKAGE)
    assert len(graph) > 30 and graph["sensorplan.cli.app"], "the graph was not read"
    cycle = find_cycle(graph)
    assert cycle is None, "import cycle: " + " -> ".join(cycle or [])


def test_the_checker_sees_lazy_relative_and_package_imports(tmp_path: Path) -> None:
    pkg = tmp_path / "pkg"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "a.py").write_text("def f():\n    from .sub import b\n")       # lazy, relative
    (pkg / "sub" / "__init__.py").write_text("from . import b\n")
    (pkg / "sub" / "b.py").write_text("import pkg.c\n")
    (pkg / "c.py").write_text("from pkg.a import f\n")
    graph = import_graph(pkg)
    assert graph["pkg.a"] == {"pkg.sub", "pkg.sub.b"}
    assert graph["pkg.sub"] == {"pkg.sub.b"}         # a package importing its own module
    assert graph["pkg.sub.b"] == {"pkg.c"}
    assert find_cycle(graph) == ["pkg.a", "pkg.sub", "pkg.sub.b", "pkg.c", "pkg.a"]
    # A cycle only through a package's __init__: c imports pkg.sub.x, which runs
    # pkg/sub/__init__.py, which imports c.
    (pkg / "a.py").write_text("")
    (pkg / "sub" / "__init__.py").write_text("from .. import c\n")
    (pkg / "sub" / "b.py").write_text("")
    (pkg / "c.py").write_text("from pkg.sub.b import g\n")
    cycle = find_cycle(import_graph(pkg))
    assert cycle is not None and set(cycle) == {"pkg.c", "pkg.sub"}


# ----------------------------------------------------------------------------- layers

#: The package's layers, bottom up, and what each may import besides itself. ``base`` is the
#: top-level modules (errors, array types, limits, memory settings); the package's own
#: ``__init__`` is its public face and may name anything lazily.
LAYERS: dict[str, set[str]] = {
    "base": set(),
    "_compiled": {"base"},
    "models": {"base", "_compiled"},
    "tracking": {"base", "_compiled", "models"},
    "planners": {"base", "_compiled", "models"},
    "simulation": {"base", "_compiled", "models", "tracking", "planners"},
    "decentral": {"base", "_compiled", "models", "planners", "simulation"},
    "config": {"base", "_compiled", "models", "planners", "simulation"},
    "study": {"base", "_compiled", "models", "tracking", "planners", "simulation", "config",
              "decentral"},
    "figures": {"base", "_compiled", "models", "planners", "simulation", "study"},
    "report": {"base", "_compiled", "models", "planners", "simulation", "study", "figures"},
    "integrations": {"base", "_compiled", "models", "tracking", "planners", "simulation"},
    "cli": {"base", "_compiled", "models", "tracking", "planners", "simulation", "decentral",
            "config", "study", "figures", "report"},
}
#: The only layers that may import matplotlib (it is slow to import, and the rest of the
#: library computes; it never draws).
PLOTTING_LAYERS = {"figures", "report", "cli"}
#: The most top-level modules (not packages) the package may hold.
MAX_TOP_MODULES = 6


def layer_of(name: str) -> str | None:
    """The layer of module ``name`` (None for the package's own ``__init__``)."""
    parts = name.split(".")
    if len(parts) == 1:
        return None
    if len(parts) == 2 and parts[1] not in LAYERS:
        return "cli" if parts[1] == "__main__" else "base"
    return parts[1]


def layer_violations(package: Path) -> list[str]:
    """Every import of the package at ``package`` that breaks a layer rule, as a sentence."""
    out = []
    mods = modules(package)
    for name, path in sorted(mods.items()):
        mine = layer_of(name)
        if mine is None:
            continue
        if mine not in LAYERS:
            out.append(f"{name}: in no layer")
            continue
        for target in sorted(imported(name, path, set(mods))):
            theirs = layer_of(target)
            if theirs is not None and theirs != mine and theirs not in LAYERS[mine]:
                out.append(f"{name} ({mine}) imports {target} ({theirs})")
        if mine not in PLOTTING_LAYERS and _imports_matplotlib(path):
            out.append(f"{name} ({mine}) imports matplotlib")
    return out


def _imports_matplotlib(path: Path) -> bool:
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and not node.level:
            names = [node.module or ""]
        else:
            continue
        if any(n == "matplotlib" or n.startswith("matplotlib.") for n in names):
            return True
    return False


def test_every_layer_imports_only_the_layers_below_it() -> None:
    assert layer_violations(PACKAGE) == []


def test_the_top_level_holds_few_modules_and_every_package_says_what_it_is() -> None:
    top = sorted(p.name for p in PACKAGE.glob("*.py"))
    assert len(top) <= MAX_TOP_MODULES, top
    for init in sorted(PACKAGE.rglob("__init__.py")):
        doc = ast.get_docstring(ast.parse(init.read_text(encoding="utf-8")), clean=False)
        assert doc, f"{init.relative_to(PACKAGE)}: no docstring"
        first, _, rest = doc.partition("\n")
        assert first.strip() and (not rest or rest.startswith("\n")), (
            f"{init.relative_to(PACKAGE)}: the first line alone should say what it is")


_PLANTED = [
    # (module file to plant in, the import, the rule it breaks)
    ("models/truth.py", "from ..tracking import ekf", "(models) imports"),
    ("tracking/ekf.py", "from ..planners import problem", "(tracking) imports"),
    ("planners/registry.py", "from ..tracking import tracker", "(planners) imports"),
    ("planners/registry.py", "from ..simulation import settings", "(planners) imports"),
    ("study/model.py", "from ..cli.console import print_summary", "(study) imports"),
    ("config/files.py", "from ..figures.colors import target_color", "(config) imports"),
    ("simulation/run.py", "import matplotlib.pyplot", "imports matplotlib"),
    ("_compiled/threads.py", "from ..models import angles", "(_compiled) imports"),
]


@pytest.mark.parametrize(("where", "line", "said"), _PLANTED)
def test_a_planted_import_breaks_its_rule(tmp_path: Path, where: str, line: str, said: str
                                          ) -> None:
    copy = tmp_path / "sensorplan"
    shutil.copytree(PACKAGE, copy, ignore=shutil.ignore_patterns("__pycache__"))
    assert layer_violations(copy) == []
    target = copy / where
    target.write_text(target.read_text(encoding="utf-8") + f"\n\ndef _planted():\n    {line}\n",
                      encoding="utf-8")
    found = layer_violations(copy)
    assert found and all(said in f for f in found), found
