"""lopcook batch --emit-ninja: the Ninja file builds with ninja (PyPI `ninja`), to the bytes of
`lopcook batch`; a second ninja run has no work to do; a changed input rebuilds only its asset."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

from conftest import FIXTURES, REPO, require
from lopcook.batch.ninja import format_ninja, ninja_path


def _env():
    return dict(os.environ, PYTHONPATH=os.pathsep.join([str(REPO), *filter(None, [os.environ.get("PYTHONPATH")])]))


def ninja(build_file: Path, cwd: Path):
    try:
        import ninja as _  # noqa: F401 - the PyPI package that ships the ninja binary
    except ImportError:
        require("the ninja package is not installed (pip install 'lopcook[test]')")
    return subprocess.run([sys.executable, "-m", "ninja", "-f", str(build_file)], cwd=cwd, env=_env(),
                          capture_output=True, text=True)


def test_ninja_escaping():
    assert ninja_path("/a b/c:d/$e.glb") == "/a$ b/c$:d/$$e.glb"
    text = format_ninja([("/s p/a.glb", "/o/a.lop", ("--lods", "1/2"))], lopcook_command="lopcook")
    assert "build /o/a.lop: lopcook_cook /s$ p/a.glb\n" in text
    assert "  src = '/s p/a.glb'\n" in text and "  options = --lods 1/2\n" in text
    assert "  depfile = $out.d\n  deps = gcc\n" in text


def test_ninja_builds_the_batch_and_then_has_no_work(tmp_path):
    root = tmp_path / "my assets"           # a space: paths are escaped for ninja and quoted for the shell
    (root / "props").mkdir(parents=True)
    obj = (FIXTURES / "seamed_cube.obj").read_text()
    (root / "props/cube.obj").write_text("mtllib cube.mtl\nusemtl m\n" + obj)
    (root / "props/cube.mtl").write_text("newmtl m\nmap_Kd tex.png\n")
    from PIL import Image

    Image.frombytes("L", (2, 2), bytes([0, 80, 160, 240])).save(root / "props/tex.png")
    shutil.copy(FIXTURES / "two_plates.gltf", root / "plates.gltf")
    shutil.copy(FIXTURES / "two_plates.bin", root / "two_plates.bin")
    cfg = tmp_path / "lopcook.toml"
    cfg.write_text('[[rules]]\nglob = "plates.gltf"\noptions = ["--lods", "1/2", "--fov", "45"]\n')
    out, build = tmp_path / "out", tmp_path / "build.ninja"
    proc = subprocess.run([sys.executable, "-m", "lopcook", "batch", str(root), "-o", str(out), "--config", str(cfg),
                           "--emit-ninja", str(build)], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    assert not out.exists()                 # emitting cooks nothing
    elsewhere = tmp_path / "elsewhere"      # ninja may run from any directory: absolute paths
    elsewhere.mkdir()
    first = ninja(build, elsewhere)
    assert first.returncode == 0, first.stdout + first.stderr
    assert "lopcook cook" in first.stdout
    second = ninja(build, elsewhere)
    assert second.returncode == 0 and "no work to do" in second.stdout, second.stdout
    # same bytes as lopcook batch with the same config
    proc = subprocess.run([sys.executable, "-m", "lopcook", "batch", str(root), "-o", str(tmp_path / "b"),
                           "--config", str(cfg), "-q"], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    for rel in ("props/cube.lop", "plates.lop"):
        assert (out / rel).read_bytes() == (tmp_path / "b" / rel).read_bytes(), rel
    assert not list(out.rglob("*.d"))       # deps = gcc: ninja moved the depfiles into .ninja_deps
    # the depfile told ninja about the texture: changing it rebuilds the cube only
    Image.frombytes("L", (2, 2), bytes([240, 160, 80, 0])).save(root / "props/tex.png")
    third = ninja(build, elsewhere)
    assert third.returncode == 0 and "[1/1]" in third.stdout and "cube.obj" in third.stdout, third.stdout
    assert "no work to do" in ninja(build, elsewhere).stdout
