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

#: the fixtures of tests/runtime (the runtimes: node, the cooked corpus), a plugin so that no second conftest shadows this one
pytest_plugins = ["tests.runtime.runtime_fixtures"]

REPO = Path(__file__).resolve().parents[1]
FIXTURES = REPO / "fixtures"
IN_CI = os.environ.get("CI", "").lower() == "true"


def pytest_configure(config):
    config.addinivalue_line("markers", "slow: over a minute (headless-browser screenshots of corpus assets); "
                                       "runs in CI too")


def require(reason: str | None) -> None:
    """A missing system tool (EGL, glslang, chromium, node...): skip locally, fail under CI=true."""
    if reason is not None:
        if IN_CI:
            pytest.fail(f"CI=true but {reason}")
        pytest.skip(reason)


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
    require(None if path is not None else "corpus not found: set LOPCOOK_CORPUS or place it at ../shared/corpus")
    return path


@pytest.fixture(scope="session")
def corpus_meta(corpus: Path) -> dict:
    """corpus.json as a dict keyed by asset file name (e.g. ``"stanford-bunny.obj"``)."""
    data = json.loads((corpus / "corpus.json").read_text())
    return {a["file"]: a for a in data["assets"]}


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20111011)


@pytest.fixture(scope="session")
def gl():
    """The headless moderngl context (EGL): skipped locally when missing, a failure under CI=true."""
    from lopcook.verify import gpu

    require(gpu.gl_available())
    return gpu.context()


@pytest.fixture(scope="session")
def gltf_validator():
    """lopcook.verify.gltf_validator, if node + gltf-validator are installed (required under CI=true)."""
    from lopcook.verify import gltf_validator as V

    try:
        V.locate()
    except V.GltfValidatorUnavailable as exc:
        require(str(exc))
    return V



def position_ids(*arrays):
    """One id per exact position, shared by all the given (n_i, 3) arrays."""
    allp = np.concatenate(arrays) + 0.0
    _, inv = np.unique(allp, axis=0, return_inverse=True)
    inv = inv.ravel()
    out, at = [], 0
    for a in arrays:
        out.append(inv[at:at + a.shape[0]])
        at += a.shape[0]
    return out


def open_edges(ids, faces) -> set:
    """Undirected edges (pairs of position ids) with exactly one face, on the mesh welded by
    position: a crack along a seam would show up here."""
    f = ids[np.asarray(faces, dtype=np.int64)]
    e = np.sort(np.stack([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]], axis=1).reshape(-1, 2), axis=1)
    e = e[e[:, 0] != e[:, 1]]
    u, cnt = np.unique(e, axis=0, return_counts=True)
    return {tuple(r) for r in u[cnt == 1].tolist()}


def cook_container(scene, settings=None, viewing=None):
    """``scene`` analysed and built in memory with the analysis options recorded (as ``cook`` does,
    without LODs): a ``lopcook.lop.container.Container`` for the render tests."""
    from lopcook.analyse import analyse
    from lopcook.emit import build
    from lopcook.lop.container import from_bytes
    from lopcook.settings import AnalyseSettings

    settings = AnalyseSettings() if settings is None else settings
    a = analyse(scene, settings)
    return from_bytes(build(scene, a, options={"analyse": settings.to_record()}, viewing=viewing), scene.source)


@pytest.fixture(scope="session")
def crease():
    """(scene, container) of fixtures/glossy_crease.glb, cooked with the default analysis."""
    from lopcook.ingest import load

    s = load(str(FIXTURES / "glossy_crease.glb"))
    return s, cook_container(s)


@pytest.fixture(scope="session")
def plates():
    """(scene, container) of fixtures/two_plates.glb, cooked with the default analysis."""
    from lopcook.ingest import load

    s = load(str(FIXTURES / "two_plates.glb"))
    return s, cook_container(s)


@pytest.fixture(scope="session")
def cooks(tmp_path_factory):
    """The suite's one cache of cooked containers (``tests/support/cooks.py``): each source and
    option set is cooked once per session, by whichever test asks first."""
    from tests.support.cooks import CookCache

    return CookCache(tmp_path_factory.mktemp("cooked"))


@pytest.fixture(scope="session")
def cooked(cooks):
    """``cooked(source, *flags)``: the path of ``source`` cooked by ``lopcook cook source -o X.lop
    *flags``, once per session (``cooks.cli``)."""
    return cooks.cli
