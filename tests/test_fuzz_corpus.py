"""The hostile-input corpus of ``tests.support.fuzzcases`` through the CLI.

Over 450 generated inputs (glTF/GLB, OBJ, usda/usdc/usdz, .lop: truncations, byte flips, lying
lengths and counts with checksums recomputed, degenerate geometry, hostile textures, depth and
instancing bombs, FIFOs and device symlinks) run as ``python -m lopcook cook|inspect|decode`` in
subprocesses under a 60 s limit and a 4 GB address-space limit. Every run must be classified
``ok`` or ``clean`` (exit 0, or exit 2 with one line naming the file; see
``tests.support.fuzzcases.classify``): no exit 3, traceback, signal, timeout, memory blow-up, clobbered
or partial output, multi-line error, garbage accepted or valid input refused.

The corpus is split into ``CHUNKS`` tests (marked ``fuzz_corpus``) so that CI can run them in
parallel processes, e.g. ``pytest -m fuzz_corpus -k "chunk0 or chunk1"``; each chunk runs its cases
two at a time.
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

import pytest

from tests.support import fuzzcases

REPO = Path(__file__).resolve().parents[1]
CHUNKS = 6

pytestmark = pytest.mark.fuzz_corpus


@pytest.fixture(scope="module")
def corpus(tmp_path_factory) -> list[fuzzcases.Case]:
    return fuzzcases.generate(tmp_path_factory.mktemp("fuzz"))


def _env() -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(REPO)] + [p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p])
    return env


def test_corpus_is_large_and_covers_every_format(corpus):
    inputs = {c.directory for c in corpus}
    assert len(inputs) >= 300
    families = {c.name.split("/")[0] for c in corpus}
    assert families == {"gltf", "glb", "obj", "usd", "lop", "stream"}
    sources = {os.path.splitext(c.source)[1] for c in corpus}
    assert {".gltf", ".glb", ".obj", ".usda", ".usdc", ".usdz", ".lop"} <= sources
    assert {c.command for c in corpus} == {"cook", "inspect", "decode"}


def test_corpus_is_deterministic(corpus, tmp_path):
    again = fuzzcases.generate(tmp_path)
    assert [c.name for c in again] == [c.name for c in corpus]
    a = Path(corpus[0].directory) / corpus[0].source
    b = Path(again[0].directory) / again[0].source
    assert a.read_bytes() == b.read_bytes()


@pytest.mark.parametrize("chunk", [f"chunk{k}" for k in range(CHUNKS)])
def test_corpus_chunk_is_clean(corpus, chunk):
    k = int(chunk[5:])
    cases = [c for i, c in enumerate(corpus) if i % CHUNKS == k]
    results = fuzzcases.run_all(cases, workers=2, env=_env())
    print(f"{chunk}: {len(results)} runs {json.dumps(fuzzcases.counts(results))}")  # shown with -s
    bad = [r for r in results if r.klass not in ("ok", "clean")]
    lines = [f"{r.klass} {r.case.name} {r.detail}: {' | '.join(r.stderr.strip().splitlines()[-3:])[:400]}"
             for r in bad]
    assert not bad, f"{len(bad)} of {len(results)} runs not clean " \
                    f"{fuzzcases.counts(results)}:\n" + "\n".join(lines)


def test_classifier_catches_each_failure(tmp_path):
    case = fuzzcases.Case("x/y:cook", str(tmp_path), "a.obj", "cook", "clean")
    before = {"out.lop": fuzzcases.SENTINEL, "out.d": fuzzcases.SENTINEL, "a.obj": b"v"}
    ok_after = dict(before)

    def k(rc, stderr="", after=None, stdout=b"{}", c=case):
        return fuzzcases.classify(c, rc, stdout, stderr, before, ok_after if after is None else after, 0.0).klass

    assert k(2, "lopcook: error: ingest: a.obj: bad (fix it)\n") == "clean"
    assert k(None) == "timeout"
    assert k(-11) == "signal"
    assert k(3, "lopcook: internal error: KeyError\n") == "exit3"
    assert k(1, "Traceback (most recent call last):\n  ...\n") == "traceback"
    assert k(2, "lopcook: error: ingest: a.obj: out of memory\n") == "memory"
    assert k(2, "lopcook: error: ingest: a.obj: bad\nsecond line\n") == "multiline"
    assert k(2, "lopcook: error: ingest: b.obj: TypeError: x\n") == "unnamed"
    assert k(2, "lopcook: error: ingest: a.obj: bad\n", after={**before, "out.lop": b"LOPC"}) == "clobbered"
    assert k(2, "lopcook: error: ingest: a.obj: bad\n", after={**before, "out.lop.tmp": b""}) == "clobbered"
    assert k(0, after={**before, "out.lop": b"LOPC..."}) == "ok"
    assert k(0, after={**before, "out.lop": fuzzcases.SENTINEL}) == "clobbered"
    refuse = fuzzcases.Case("x/y:cook", str(tmp_path), "a.obj", "cook", "refuse")
    assert k(0, after={**before, "out.lop": b"LOPC..."}, c=refuse) == "accepted"
    warn = fuzzcases.Case("x/y:cook", str(tmp_path), "a.obj", "cook", "warn")
    assert k(0, after={**before, "out.lop": b"LOPC"}, stdout=b'{"warnings": []}', c=warn) == "unwarned"
    assert k(0, after={**before, "out.lop": b"LOPC"}, stdout=b'{"warnings": ["w"]}', c=warn) == "ok"
    valid = fuzzcases.Case("x/y:cook", str(tmp_path), "a.obj", "cook", "ok")
    assert k(2, "lopcook: error: ingest: a.obj: bad\n", c=valid) == "refused"


def test_runner_applies_the_limits(tmp_path):
    """The subprocess really runs under the address-space limit (a 5 GB allocation fails)."""
    import subprocess

    code = "import numpy as np\ntry:\n    np.ones(5 << 30, np.uint8)\nexcept MemoryError:\n    print('limited')"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         preexec_fn=fuzzcases._limit_resources, timeout=60)
    assert out.stdout.strip() == "limited"
