"""Shared test fixtures: corpus location, fixture directory, seeded randomness.

The corpus is found at ``$LOPCOOK_CORPUS`` or ``../shared/corpus`` (beside the repository).
Under ``CI=true`` a missing corpus fails the test instead of skipping it.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]
FIXTURES = REPO / "fixtures"


def corpus_path() -> Path | None:
    env = os.environ.get("LOPCOOK_CORPUS")
    candidates = [Path(env)] if env else []
    candidates.append(REPO.parent / "shared" / "corpus")
    for c in candidates:
        if (c / "corpus.json").is_file():
            return c
    return None


@pytest.fixture(scope="session")
def corpus() -> Path:
    """Directory of the shared third-party corpus (fails under CI=true when missing)."""
    path = corpus_path()
    if path is None:
        msg = "corpus not found: set LOPCOOK_CORPUS or place it at ../shared/corpus"
        if os.environ.get("CI", "").lower() == "true":
            pytest.fail(msg)
        pytest.skip(msg)
    return path


@pytest.fixture(scope="session")
def corpus_meta(corpus: Path) -> dict:
    """corpus.json as a dict keyed by asset file name (e.g. ``"stanford-bunny.obj"``)."""
    data = json.loads((corpus / "corpus.json").read_text())
    return {a["file"]: a for a in data["assets"]}


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20111011)
