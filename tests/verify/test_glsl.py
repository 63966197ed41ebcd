"""GLSL sources of the render harness (lopcook.verify.glsl): every stage compiles with glslang
(OpenGL GLSL 4.50) and the decoded vertex shader is the shipped decoder's ``lop_decode``. glslang
missing: skipped locally, a failure under CI=true."""

from __future__ import annotations

import shutil
import subprocess

import pytest

from conftest import require
from lopcook.verify import glsl
from lopcook.verify.gpu import shader_source


def _glslang(tmp_path, name: str, source: str) -> subprocess.CompletedProcess:
    exe = shutil.which("glslangValidator")
    require(None if exe else "glslangValidator is not on PATH (Debian package glslang-tools)")
    path = tmp_path / name
    path.write_text(source)
    return subprocess.run([exe, str(path)], capture_output=True, text=True, timeout=60)


@pytest.mark.parametrize("name, source", [
    ("float.vert", glsl.vertex_shader_source(False)), ("decoded.vert", glsl.vertex_shader_source(True)),
    ("shade.frag", glsl.FS), ("resolve.vert", glsl.RESOLVE_VS), ("resolve.frag", glsl.RESOLVE_FS)])
def test_stage_compiles(tmp_path, name, source):
    r = _glslang(tmp_path, name, source)
    assert r.returncode == 0, r.stdout + r.stderr


def test_a_broken_stage_is_reported(tmp_path):
    """The compile check can fail: a syntax error is caught."""
    r = _glslang(tmp_path, "broken.frag", glsl.FS.replace("o_part = u_part;", "o_part = u_part"))
    assert r.returncode != 0


def test_decoded_vertex_shader_embeds_the_shipped_decoder():
    decoded, flat = glsl.vertex_shader_source(True), glsl.vertex_shader_source(False)
    assert shader_source("decode_bitplanes.glsl") in decoded and "#define LOP_NO_VIEW" in decoded
    assert decoded.startswith("#version 450\n") and flat.startswith("#version 450\n")
    assert "#define LOP_FLOAT_POSITIONS" in flat and "#define LOP_FLOAT_POSITIONS" not in decoded
    assert "lop_decode(uint(gl_VertexID)" in glsl.VS_MAIN
