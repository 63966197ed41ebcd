"""Fixtures of the runtime tests: node, the cooked corpus (every asset with the CLI's defaults, the
variants of ``runtime_support.VARIANTS`` and a scene with vertex colours), cooked once per session."""

from __future__ import annotations

import shutil

import pytest

from runtime_support import require


@pytest.fixture(scope="session")
def node() -> str:
    """The node executable (skipped locally when missing, a failure under CI=true)."""
    path = shutil.which("node")
    require(None if path else "node not found on PATH (apt-get install nodejs)")
    return path


@pytest.fixture(scope="session")
def cooked(corpus, tmp_path_factory) -> dict:
    """``{name: path}`` of every cooked container (``runtime_support.cook_corpus``)."""
    import runtime_support as rs

    return rs.cook_corpus(corpus, tmp_path_factory.mktemp("cooked"))
