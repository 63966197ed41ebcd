"""Fixtures of the runtime tests: node, the cooked corpus (every asset with the CLI's defaults, the
variants of ``runtime_support.VARIANTS`` and a scene with vertex colours), cooked once per session."""

from __future__ import annotations

import shutil

import pytest

from tests.runtime import runtime_support as rs
from lopcook.lop.container import from_bytes
from tests.runtime.runtime_support import require


@pytest.fixture(scope="session")
def node() -> str:
    """The node executable (skipped locally when missing, a failure under CI=true)."""
    path = shutil.which("node")
    require(None if path else "node not found on PATH (apt-get install nodejs)")
    return path


@pytest.fixture(scope="session")
def corpus_containers(corpus, cooks, tmp_path_factory) -> dict:
    """``{name: path}`` of every cooked container (``runtime_support.cook_corpus``, through the
    suite's cook cache)."""
    return rs.cook_corpus(corpus, cooks, tmp_path_factory.mktemp("colored"))


@pytest.fixture(scope="session")
def tangent_files(corpus_containers, tmp_path_factory):
    """(name, path, original container, expected tangents): DamagedHelmet with tangents on its part,
    the chess set with tangents on four parts and their placements (clustered, placed, mixed)."""
    out = tmp_path_factory.mktemp("tangents")
    files = []
    for name, src, bits, parts in (("helmet-tangents", "DamagedHelmet", 10, None),
                                   ("chess-tangents", "chess_set_flat", 7, [0, 1, 2, 3])):
        data = corpus_containers[src].read_bytes()
        blob, expected = rs.with_tangents(data, bits=bits, parts=parts)
        (out / f"{name}.lop").write_bytes(blob)
        files.append((name, out / f"{name}.lop", from_bytes(data), expected))
    return files
