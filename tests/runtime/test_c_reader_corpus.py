"""lop.h against lopcook's reader on the real corpus: for every asset cooked by default and with
``--lods auto``, ``--clusters 0``, ``--no-instances``, ``--nearest 0.5`` and ``--hierarchy``,
``lopdump --positions`` writes the bytes of ``lopcook decode --positions`` at levels 1, 6, 11, 16
and 24 (every level 1-24 for the bunny, DamagedHelmet and the chess set), and both refuse a level
the file does not hold. The whole sweep (every corpus asset, about half an hour on two cores) runs
with ``LOPCOOK_SWEEP=1``; CI runs every cook of the three smallest assets that between them hold
textures, copies stored once, clusters and several parts (cooks are cached per session)."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from c_tools import ASSETS, COOKS, c_build, corpus_cooks, lopdump, sha  # noqa: F401

from lopcook.lop.container import read
from lopcook.lop.reader import positions_f32
from lopcook.errors import LopcookError

EVERY_LEVEL = {"stanford-bunny.obj", "DamagedHelmet/DamagedHelmet.gltf", "chess_set_flat.usdc"}
#: the whole corpus with LOPCOOK_SWEEP=1, else the assets CI sweeps
SWEPT = ASSETS if os.environ.get("LOPCOOK_SWEEP") == "1" else ("CesiumMilkTruck.glb", "Duck.glb", "UtahTeapot.usd")

pytestmark = pytest.mark.slow


@pytest.mark.parametrize("cook", list(COOKS))
@pytest.mark.parametrize("asset", SWEPT)
def test_lopdump_writes_lopcooks_positions(c_build, corpus_cooks, tmp_path, asset, cook):
    path = corpus_cooks.cooked(asset, cook)
    c = read(str(path))
    exe = c_build / "gcc" / "lopdump"
    levels = range(1, 25) if asset in EVERY_LEVEL else (1, 6, 11, 16, 24)
    for level in levels:
        out = tmp_path / f"{level}.f32"
        run = lopdump(exe, path, "--level", level, "--positions", out)
        if level > c.available_level:
            with pytest.raises(LopcookError) as info:
                positions_f32(c, level, 0)
            assert info.value.reason == "level"
            assert run.returncode == 2 and "not in this file" in run.stderr and not out.exists()
            continue
        assert run.returncode == 0, run.stderr
        assert out.read_bytes() == positions_f32(c, level, 0), (asset, cook, level)
    deepest = max(len(p["lods"]) for p in c.manifest["parts"])
    if deepest > 1:  # the coarsest LOD of every part, and a part's coarsest where its chain is shorter
        out = tmp_path / "coarsest.f32"
        run = lopdump(exe, path, "--level", 11, "--lod", deepest - 1, "--positions", out)
        assert run.returncode == 0 and out.read_bytes() == positions_f32(c, 11, deepest - 1)


@pytest.mark.parametrize("asset", ["stanford-bunny.obj", "chess_set_flat.usdc"] if SWEPT is ASSETS else ["Duck.glb"])
def test_lopcook_decode_positions_equals_lopdump(c_build, corpus_cooks, tmp_path, asset):
    path = corpus_cooks.cooked(asset, "default")
    run = subprocess.run([sys.executable, "-m", "lopcook", "decode", str(path), "--level", "11", "--positions",
                          str(tmp_path / "py.f32"), "-q"], capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr
    run = lopdump(c_build / "clang" / "lopdump", path, "--level", 11, "--positions", tmp_path / "c.f32")
    assert run.returncode == 0, run.stderr
    assert sha(tmp_path / "py.f32") == sha(tmp_path / "c.f32")
