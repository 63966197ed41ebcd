"""Shared by the runtime/c tests: the programs of ``runtime/c/Makefile`` built once per session, the
conformance index, and lopcook's verdict on a container's bytes (the same words lopcheck prints).

The compilers (gcc, clang), make and the sanitizer runtimes are system packages (``.ci/run``):
missing, a test skips locally and fails under ``CI=true``.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import subprocess
from pathlib import Path

import pytest

from conftest import REPO, require

from lopcook.lop.container import from_bytes
from lopcook.errors import LopcookError

RUNTIME = REPO / "runtime" / "c"
CONFORMANCE = REPO / "fixtures" / "conformance"


def tool(name: str) -> str:
    """The path of a system tool, or a skip (a failure under CI=true)."""
    path = shutil.which(name)
    require(None if path else f"{name} is not installed (apt-get install {name}; .ci/run installs it)")
    return path


def make(build: Path, *targets: str, timeout: int = 900) -> None:
    for name in ("make", "gcc", "clang"):
        tool(name)
    run = subprocess.run(["nice", "make", "-s", "-j2", "-C", str(RUNTIME), f"BUILD={build}", *targets],
                         capture_output=True, text=True, timeout=timeout)
    assert run.returncode == 0, run.stdout + run.stderr


@pytest.fixture(scope="session")
def c_build(tmp_path_factory) -> Path:
    """runtime/c built into a temporary BUILD: {gcc,clang}/{lopdump,lopcheck} strict and
    {gcc,clang}-san/ under AddressSanitizer + UndefinedBehaviorSanitizer."""
    build = tmp_path_factory.mktemp("c-build")
    make(build, "all", "sanitize")
    return build


def conformance() -> dict:
    return json.loads((CONFORMANCE / "conformance.json").read_text())


def expected_of(index: dict, entry: dict) -> list | None:
    """An entry's expected hashes (a trimmed file's are those of the file it was trimmed from)."""
    if "expected_as" in entry:
        return next(e for e in index["files"] if e["file"] == entry["expected_as"])["expected"]
    return entry.get("expected")


def want_verdict(v: dict) -> str:
    """The verdict (``verdict``'s words) that an index entry's ``{"error": class}`` or
    ``{"available_level": L[, "stage_levels": [...]]}`` stands for."""
    if "error" in v:
        return v["error"]
    return f"ok:{v['available_level']}" + ("/" + ",".join(map(str, v["stage_levels"])) if "stage_levels" in v else "")


def sha(path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def lopdump(exe: Path, path, *args, timeout: int = 600) -> subprocess.CompletedProcess:
    return subprocess.run([str(exe), str(path), *map(str, args)], capture_output=True, text=True, timeout=timeout)


def verdict(data: bytes, allow_prefix: bool) -> str:
    """lopcook's reader on these bytes: its error class, or ``ok:L`` with L the available level
    (``ok:L/S0,S1,...`` in the streaming layout, S the level of each stage): what lopcheck prints."""
    try:
        c = from_bytes(data, "x.lop", allow_prefix=allow_prefix)
    except LopcookError as exc:
        assert exc.reason, f"a container error without its class: {exc}"
        return exc.reason
    return f"ok:{c.available_level}" + ("/" + ",".join(map(str, c.stage_levels)) if c.stream else "")


def lopcheck(exe: Path, *args, timeout: int = 1200) -> list[list[str]]:
    """Lines of ``lopcheck ARGS`` split in words; a sanitizer report or a leak fails."""
    env = dict(os.environ, ASAN_OPTIONS="detect_leaks=1:abort_on_error=0", UBSAN_OPTIONS="print_stacktrace=1")
    run = subprocess.run([str(exe), *map(str, args)], capture_output=True, text=True, timeout=timeout, env=env)
    assert run.returncode == 0, run.stderr[-4000:]
    assert "runtime error" not in run.stderr and "Sanitizer" not in run.stderr, run.stderr[-4000:]
    return [line.split() for line in run.stdout.splitlines()]


#: corpus assets (files under the corpus folder) and the cook flags of the Done-when sweep
ASSETS = ("stanford-bunny.obj", "DamagedHelmet/DamagedHelmet.gltf", "chess_set_flat.usdc", "CesiumMilkTruck.glb",
          "Duck.glb", "spot.obj", "fandisk.obj", "UtahTeapot.usd")
COOKS = {"default": (), "lods": ("--lods", "auto"), "clusters0": ("--clusters", "0"),
         "no_instances": ("--no-instances",), "nearest": ("--nearest", "0.5"), "hierarchy": ("--hierarchy",)}


class Cooks:
    """Corpus assets cooked once per session (``cooked(asset, name)`` with ``name`` a key of
    ``COOKS``), by the CLI as a user runs it, through the suite's cook cache
    (``tests/support/cooks.py``): a cook another test made already is not made again."""

    def __init__(self, corpus: Path, cache):
        self.corpus, self.cache = corpus, cache

    def cooked(self, asset: str, name: str) -> Path:
        return self.cache.cli_many([(self.corpus / asset, COOKS[name])])[0]


@pytest.fixture(scope="session")
def corpus_cooks(corpus, cooks) -> Cooks:
    return Cooks(corpus, cooks)
