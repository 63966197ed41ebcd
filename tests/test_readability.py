"""Readable units in lopcook/ (docs/architecture.md): no function over 80 lines except the argparse
builders and literal tables, module docstrings of at most 40 lines that state contracts, no issue
numbers or dates in code, and imports at module top except heavy or optional libraries, each
such lazy import commented. Each rule is also shown to catch a planted offence."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

from conftest import REPO

PACKAGE = REPO / "lopcook"
MAX_FUNCTION_LINES = 80
MAX_DOCSTRING_LINES = 40
#: libraries heavy or optional enough to import where they are used (each such import commented)
LAZY_OK = {"pxr", "moderngl", "pymeshlab", "scipy", "distributed", "dask", "meshoptimizer", "fast_simplification",
           "igl", "xatlas", "trimesh", "PIL", "matplotlib", "DracoPy", "jsonschema", "numba", "tqdm", "resource"}
#: lopcook modules imported inside a function on purpose, each with a comment saying why: the CLI's
#: commands and batch's (a command loads only its own stages), and the compiled kernels (they
#: import numba at their top; loaded only for large meshes, lopcook/jit.py)
LAZY_INTERNAL_OK = {"lopcook.cli.commands", "lopcook.batch.command", "lopcook.analyse.kernels",
                    "lopcook.simplify.kernels"}
#: functions allowed past the length limit: argparse builders and literal data tables
LONG_OK = {"build_parser"}
HISTORY = re.compile(r"\bissues? #?\d+\b|\b20\d\d-\d\d-\d\d\b", re.I)


def modules(root: Path = PACKAGE):
    for path in sorted(root.rglob("*.py")):
        yield path, path.read_text()


def long_functions(src: str) -> list[str]:
    return [f"{node.name} ({node.end_lineno - node.lineno + 1} lines)"
            for node in ast.walk(ast.parse(src))
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and node.name not in LONG_OK
            and node.end_lineno - node.lineno + 1 > MAX_FUNCTION_LINES]


def docstring_lines(src: str) -> int:
    doc = ast.get_docstring(ast.parse(src), clean=False)
    return 0 if doc is None else doc.count("\n") + 1


def history(src: str) -> list[str]:
    return [line.strip()[:80] for line in src.splitlines() if HISTORY.search(line)]


def _absolute(path: Path, node: ast.ImportFrom) -> str:
    parts = list(path.relative_to(REPO).with_suffix("").parts)
    package = parts if parts[-1] == "__init__" else parts[:-1]
    package = package[:-1] if parts[-1] == "__init__" else package
    base = package[: len(package) - node.level + 1] if node.level else []
    return ".".join(base + ([node.module] if node.module else [])) if node.level else node.module or ""


def lazy_imports(path: Path, src: str) -> list[str]:
    """Imports inside functions that are neither a commented heavy library nor a listed internal one."""
    lines = src.splitlines()
    bad = []
    for fn in ast.walk(ast.parse(src)):
        if not isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
            continue
        for node in ast.walk(fn):
            if not isinstance(node, (ast.Import, ast.ImportFrom)):
                continue
            name = _absolute(path, node) if isinstance(node, ast.ImportFrom) else node.names[0].name
            commented = "#" in lines[node.lineno - 1] or lines[node.lineno - 2].strip().startswith("#")
            heavy = name.split(".")[0] in LAZY_OK
            internal_ok = any(name == m or f"{name}.{a.name}" == m for m in LAZY_INTERNAL_OK for a in node.names)
            if not ((heavy or internal_ok) and commented):
                bad.append(f"{path.relative_to(REPO)}:{node.lineno} {name}")
    return bad


@pytest.mark.parametrize("check", ["functions", "docstrings", "history", "imports"])
def test_lopcook_is_readable(check):
    found = []
    for path, src in modules():
        where = path.relative_to(REPO)
        if check == "functions":
            found += [f"{where}: {f}" for f in long_functions(src)]
        elif check == "docstrings" and docstring_lines(src) > MAX_DOCSTRING_LINES:
            found.append(f"{where}: module docstring of {docstring_lines(src)} lines")
        elif check == "history":
            found += [f"{where}: {h}" for h in history(src)]
        elif check == "imports":
            found += lazy_imports(path, src)
    assert found == []


def test_each_rule_catches_a_planted_offence(tmp_path):
    body = "\n".join(f"    x{i} = {i}" for i in range(MAX_FUNCTION_LINES))
    assert long_functions(f"def f():\n{body}\n") == [f"f ({MAX_FUNCTION_LINES + 1} lines)"]
    assert docstring_lines('"""' + "a\n" * MAX_DOCSTRING_LINES + '"""\n') == MAX_DOCSTRING_LINES + 1
    assert history("# fixed in issue 12\nx = 1  # measured 2026-12-05\n") == ["# fixed in issue 12",
                                                                               "x = 1  # measured 2026-12-05"]
    fake = PACKAGE / "lop" / "_planted.py"
    src = "def f():\n    import scipy\n    from ..emit import build\n    import moderngl  # optional: EGL\n"
    assert lazy_imports(fake, src) == ["lopcook/lop/_planted.py:2 scipy", "lopcook/lop/_planted.py:3 lopcook.emit"]
