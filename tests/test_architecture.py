"""The layout shows the pipeline (docs/architecture.md): no stage imports a later stage, tune/ or
anything above it, and the foundation modules import only each other. Every import is read,
module-level and inside functions, from the source text."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from conftest import REPO

PACKAGE = REPO / "lopcook"

#: rank of each layer: a module may import only modules of a lower rank, or of its own folder
RANKS = {
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
    "top": 9,
}
FOUNDATION = {"errors", "types", "grid", "mesh", "settings", "viewing", "atomic", "memory", "depfile", "isolate", "version", "progress",
              "selection", "__init__", "__main__"}
TOP = {"cli", "report", "bench", "benchkit", "batch", "fixtures", "fuzzcases", "outputs"}


def layer(module: str) -> str:
    """``lopcook.emit.reader`` -> ``emit``; the package's own face (``lopcook``) is ``top``."""
    parts = module.split(".")
    if len(parts) == 1:
        return "top"
    head = parts[1]
    if head in FOUNDATION:
        return "top" if head in ("__init__", "__main__") else "foundation"
    if head in TOP:
        return "top"
    if head in RANKS:
        return head
    raise AssertionError(f"{module}: module {head!r} belongs to no layer; add it to docs/architecture.md and here")


def module_name(path: Path) -> str:
    rel = path.relative_to(REPO).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def imports(path: Path) -> list[tuple[int, str]]:
    """(line, absolute module) of every ``lopcook`` import in ``path``."""
    mod = module_name(path)
    package = mod if path.name == "__init__.py" else mod.rsplit(".", 1)[0]
    out = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names if a.name.split(".")[0] == "lopcook"]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            elif node.module and node.module.split(".")[0] == "lopcook":
                target = node.module
            else:
                continue
            names = [a.name for a in node.names]
            # ``from . import gltf`` names a module: check each imported submodule
            subs = [f"{target}.{n}" for n in names if (PACKAGE.parent / (f"{target}.{n}".replace(".", "/"))).with_suffix(
                ".py").exists() or (PACKAGE.parent / f"{target}.{n}".replace(".", "/")).is_dir()]
            out += [(node.lineno, s) for s in subs] or [(node.lineno, target)]
    return out


def violations() -> list[str]:
    bad = []
    for path in sorted(PACKAGE.rglob("*.py")):
        mod = module_name(path)
        src = layer(mod)
        for line, target in imports(path):
            dst = layer(target)
            if src == dst or target == "lopcook" and src == "top":
                continue
            if src == "foundation" and dst != "foundation" or RANKS[dst] >= RANKS[src] and src != "top":
                bad.append(f"{path.relative_to(REPO)}:{line}: {src} imports {target} ({dst})")
    return bad


def test_no_stage_imports_a_later_stage():
    assert violations() == []


def test_the_check_can_fail(tmp_path, monkeypatch):
    """An emit module importing tune/ is reported (the rule is not vacuous)."""
    fake = PACKAGE / "emit" / "_architecture_probe.py"
    monkeypatch.setattr(Path, "read_text", lambda self, *a, **k: "from ..tune import budget\n"
                        if self == fake else _read(self))
    real_rglob = Path.rglob
    monkeypatch.setattr(Path, "rglob", lambda self, pat: list(real_rglob(self, pat)) + ([fake] if self == PACKAGE else []))
    found = violations()
    assert any("_architecture_probe.py" in v and "tune" in v for v in found), found


_read = Path.read_text


@pytest.mark.parametrize("name", ["select", "inspect"])
def test_no_module_shadows_the_standard_library(name):
    assert not (PACKAGE / f"{name}.py").exists()
