"""The layout is the pipeline (docs/architecture.md): no import circle between modules, no stage
imports a later stage or anything above it, the container format (lop/) imports only the core
(errors, grid, atomic, version, wording), the foundation only those two and itself, and the top
ranks entry > batch > cli > report, bench. Every import is read from the source text: module
level, inside functions and under ``TYPE_CHECKING``.

The checks work on any package (``import_graph(root, package)``), so each is also shown to fail:
on a tiny package written with a circle, and on the real graph with one planted edge."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import REPO

PACKAGE = REPO / "lopcook"

#: rank of each layer: a module may import modules of its own layer or of a lower rank
RANKS = {
    "core": -2,
    "lop": -1,
    "foundation": 0,
    "ingest": 1,
    "simplify": 2,
    "analyse": 3,
    "emit": 4,
    "hierarchy": 5,
    "verify": 6,
    "pipeline": 6,
    "tune": 7,
    "api": 8,
    "outputs": 8,
    "cookjob": 9,
    "view": 9,
    "report": 10,
    "bench": 10,
    "cli": 11,
    "batch": 12,
    "entry": 13,
}
#: below everything: what the container format (lop/) may import
CORE = {"errors", "grid", "atomic", "version", "wording"}
FOUNDATION = {"types", "mesh", "settings", "viewing", "memory", "depfile", "isolate", "progress", "selection",
              "jit"}
#: the command line's entry: ``lopcook.cli.main`` (it runs every command, batch's too) and ``python -m lopcook``
ENTRY = {"lopcook.cli", "lopcook.__main__"}


# ---- the import graph ---------------------------------------------------------------------------

def module_name(path: Path, root: Path) -> str:
    """``ROOT/../pkg/a/b.py`` -> ``pkg.a.b``; a package's ``__init__.py`` is the package."""
    parts = list(path.relative_to(root.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def imports(path: Path, root: Path) -> list[tuple[int, str]]:
    """(line, absolute module) of every import of ``root``'s package in ``path``. ``from X import
    n`` names module ``X.n`` where that is a module or package, else ``X``."""
    package_name = root.name
    mod = module_name(path, root)
    package = mod if path.name == "__init__.py" else mod.rsplit(".", 1)[0]

    def is_module(name: str) -> bool:
        p = root.parent / name.replace(".", "/")
        return p.with_suffix(".py").is_file() or (p / "__init__.py").is_file()

    out = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names if a.name.split(".")[0] == package_name]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                target = ".".join(base[: len(base) - node.level + 1] + ([node.module] if node.module else []))
            elif node.module and node.module.split(".")[0] == package_name:
                target = node.module
            else:
                continue
            subs = [f"{target}.{a.name}" for a in node.names if is_module(f"{target}.{a.name}")]
            out += [(node.lineno, s) for s in subs] if len(subs) == len(node.names) else \
                [(node.lineno, s) for s in subs] + [(node.lineno, target)]
    return out


def import_graph(root: Path) -> dict[str, list[tuple[str, str]]]:
    """{module: [(imported module, "file:line")]} for every module of the package at ``root``."""
    graph: dict[str, list[tuple[str, str]]] = {}
    for path in sorted(root.rglob("*.py")):
        mod = module_name(path, root)
        where = str(path.relative_to(root.parent))
        graph.setdefault(mod, []).extend((t, f"{where}:{line}") for line, t in imports(path, root) if t != mod)
    return graph


def cycles(graph: dict[str, list[tuple[str, str]]]) -> list[list[str]]:
    """Every import circle: the strongly connected components of more than one module (Tarjan),
    each as its modules sorted, with the imports that tie them ("a -> b (file:line)")."""
    index, low, stack, on, found = {}, {}, [], set(), []
    counter = [0]

    def visit(v: str) -> None:  # iterative Tarjan: the package is deep enough for recursion limits
        work = [(v, iter(graph.get(v, ())))]
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        while work:
            node, edges = work[-1]
            for w, _ in edges:
                if w not in graph:
                    continue
                if w not in index:
                    index[w] = low[w] = counter[0]
                    counter[0] += 1
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(graph.get(w, ()))))
                    break
                if w in on:
                    low[node] = min(low[node], index[w])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[node])
                if low[node] == index[node]:
                    comp = []
                    while True:
                        w = stack.pop()
                        on.discard(w)
                        comp.append(w)
                        if w == node:
                            break
                    if len(comp) > 1:
                        members = set(comp)
                        ties = [f"{a} -> {b} ({where})" for a in sorted(comp) for b, where in graph[a] if b in members]
                        found.append(sorted(comp) + ties)

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


# ---- the layers ---------------------------------------------------------------------------------

def layer(module: str) -> str:
    """``lopcook.lop.reader`` -> ``lop``; the package's face (``lopcook``) is ``api``; the CLI's
    entry (``ENTRY``) is ``entry``, its parser and commands ``cli``."""
    if module in ENTRY:
        return "entry"
    parts = module.split(".")
    if len(parts) == 1:
        return "api"
    head = parts[1]
    if head in CORE:
        return "core"
    if head in FOUNDATION:
        return "foundation"
    if head in RANKS:
        return head
    raise AssertionError(f"{module}: module {head!r} belongs to no layer; add it to docs/architecture.md and here")


def violations(graph: dict[str, list[tuple[str, str]]]) -> list[str]:
    bad = []
    for mod, targets in sorted(graph.items()):
        src = layer(mod)
        for target, where in targets:
            dst = layer(target)
            if src == dst:
                continue
            if RANKS[dst] >= RANKS[src]:
                bad.append(f"{where}: {src} imports {target} ({dst})")
    return bad


# ---- the tests ----------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def graph() -> dict[str, list[tuple[str, str]]]:
    return import_graph(PACKAGE)


def test_no_import_circle(graph):
    assert cycles(graph) == []


def test_no_stage_imports_a_later_stage(graph):
    assert violations(graph) == []


def test_the_top_is_ranked_entry_batch_cli_report_and_bench():
    assert RANKS["entry"] > RANKS["batch"] > RANKS["cli"] > RANKS["report"] == RANKS["bench"] > RANKS["cookjob"]
    assert layer("lopcook.cli") == "entry" and layer("lopcook.cli.parser") == layer("lopcook.cli.commands") == "cli"
    assert layer("lopcook.batch.child") == "batch" and layer("lopcook.bench.run") == "bench"


def test_the_graph_is_read(graph):
    """Not vacuous: the known arrows are found, module-level and inside functions."""
    assert any(t == "lopcook.cli.parser" for t, _ in graph["lopcook.batch.config"])
    assert any(t == "lopcook.batch.command" for t, _ in graph["lopcook.cli"])  # inside _command
    assert any(t == "lopcook.simplify.reference" for t, _ in graph["lopcook.simplify.transfer"])
    assert len(graph) > 100 and sum(map(len, graph.values())) > 400


def _write_package(root: Path, files: dict[str, str]) -> Path:
    pkg = root / "pkg"
    for name, text in files.items():
        path = pkg / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    return pkg


def test_a_circle_fails_the_check(tmp_path):
    """A circle closed by an import inside a function, across two folders, is found and named;
    the same package without that import has none."""
    files = {"__init__.py": "", "a/__init__.py": "", "b/__init__.py": "",
             "a/one.py": "from ..b import two\n",
             "b/two.py": "def f():\n    from ..a.three import g\n    return g\n",
             "a/three.py": "from .one import two as _\n\ndef g():\n    return 3\n"}
    found = cycles(import_graph(_write_package(tmp_path, files)))
    assert len(found) == 1 and found[0][:3] == ["pkg.a.one", "pkg.a.three", "pkg.b.two"], found
    assert "pkg.b.two -> pkg.a.three (pkg/b/two.py:2)" in found[0]
    files["b/two.py"] = "def f():\n    return 3\n"
    assert cycles(import_graph(_write_package(tmp_path / "clean", files))) == []


def test_one_planted_edge_makes_a_circle_in_lopcook(graph):
    """The real graph plus one upward edge (the grid importing the pipeline) has a circle."""
    planted = {k: list(v) for k, v in graph.items()}
    planted["lopcook.grid"].append(("lopcook.pipeline", "planted"))
    found = cycles(planted)
    assert any("lopcook.grid" in c and "lopcook.pipeline" in c for c in found), found


def test_an_upward_import_fails_the_ranks(graph):
    """A format module importing tune/, and batch importing the CLI's entry, are reported."""
    planted = {k: list(v) for k, v in graph.items()}
    planted["lopcook.lop.container"].append(("lopcook.tune.budget", "planted:1"))
    planted["lopcook.batch.run"].append(("lopcook.cli", "planted:2"))
    found = violations(planted)
    assert "planted:1: lop imports lopcook.tune.budget (tune)" in found
    assert "planted:2: batch imports lopcook.cli (entry)" in found


def test_lopcook_does_not_import_its_tests(graph):
    """Nothing under lopcook/ exists only for the tests: their generators live in tests/support/."""
    for path in PACKAGE.rglob("*.py"):
        tree = ast.parse(path.read_text())
        names = [a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names]
        names += [n.module or "" for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) and not n.level]
        assert not [n for n in names if n.split(".")[0] in ("tests", "conftest")], path
    assert not (PACKAGE / "fixtures.py").exists() and not (PACKAGE / "fuzzcases.py").exists()


@pytest.mark.parametrize("module", ["lopcook.batch.config", "lopcook.batch.child", "lopcook.cli.parser",
                                    "lopcook.cli", "lopcook.bench.run"])
def test_the_top_modules_import_first(module):
    """Importing a module runs its packages' ``__init__`` first: each top module imports on its own
    in a fresh interpreter (an import order that would meet a half-made module fails here)."""
    proc = subprocess.run([sys.executable, "-c", f"import {module}"], cwd=REPO, capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0, proc.stderr


@pytest.mark.parametrize("name", ["select", "inspect"])
def test_no_module_shadows_the_standard_library(name):
    assert not (PACKAGE / f"{name}.py").exists()
