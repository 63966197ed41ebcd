"""The GLSL/HLSL twins of shaders/ change together (lopcook.verify.twins): the committed files match
the digest record and the decoders' function bodies agree token by token; a change to one side only,
made in a temporary copy, is caught by both checks. No GL."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys

import pytest

from conftest import REPO
from lopcook.errors import LopcookError
from lopcook.lop.codecs import CODECS
from lopcook.verify import twins as T

SHADERS = REPO / "shaders"


@pytest.fixture
def copy(tmp_path):
    """A scratch copy of shaders/ (the record included)."""
    d = tmp_path / "shaders"
    shutil.copytree(SHADERS, d)
    return d


def _edit(path, old, new):
    text = path.read_text()
    assert old in text, old
    path.write_text(text.replace(old, new, 1))


def test_committed_twins_agree_and_match_the_record():
    assert T.check(SHADERS) == []
    assert set(T.read_record(SHADERS)) == {g for g, _ in T.TWINS}


def test_every_shared_decoder_function_is_compared():
    g = T.functions((SHADERS / T.TOKEN_TWIN[0]).read_text())
    h = T.functions((SHADERS / T.TOKEN_TWIN[1]).read_text(), hlsl=True)
    assert set(g) == set(h) >= {"lop_bin_start", "lop_read_field", "lop_decode_bits", "lop_reconstruct", "lop_decode",
                                "lop_own_level", "lop_vertex_level", "lop_decode_crack_free"}
    assert all(len(t) > 10 for t in g.values())


def test_every_shared_attribute_decoder_function_is_compared():
    assert T.TOKEN_TWINS[1] == ("decode_attributes.glsl", "decode_attributes.hlsl")
    g = T.functions((SHADERS / "decode_attributes.glsl").read_text())
    h = T.functions((SHADERS / "decode_attributes.hlsl").read_text(), hlsl=True)
    helpers = {"lop_attr_read_field", "lop_attr_record", "lop_attr_sgn", "lop_attr_oct"}
    assert set(g) == set(h) == helpers | {c.shader for c in CODECS}  # every codec's decoder, in both
    assert g == h


@pytest.mark.parametrize("name, old, new", [
    ("decode_bitplanes.glsl", "((v << 1u) | 1u)", "(v << 1u)"),  # GLSL decoder changed alone
    ("decode_bitplanes.hlsl", "max(bin_level, lop_params.x)", "min(bin_level, lop_params.x)"),  # HLSL alone
    ("decode_attributes.glsl", "if (z < 0.0)", "if (z <= 0.0)"),  # attribute decoder, GLSL alone
    ("decode_attributes.hlsl", "lop_attr_bits.x + 2u * lop_attr_bits.y", "lop_attr_bits.y + 2u * lop_attr_bits.x"),
])
def test_one_sided_decoder_change_fails_both_checks(copy, name, old, new):
    _edit(copy / name, old, new)
    problems = T.check(copy)
    assert any(p.startswith(f"{name} changed without its twin") for p in problems), problems
    assert any("differs at token" in p for p in problems), problems  # the token comparison sees it too
    with pytest.raises(LopcookError, match="without its twin"):
        T.update(copy)
    assert T.read_record(copy) == T.read_record(SHADERS)  # nothing was written


def test_one_sided_kernel_change_fails(copy):
    _edit(copy / "adapt_bitplanes.comp.hlsl", "acc += 3u * max(k, level)", "acc += 3u * min(k, level)")
    problems = T.check(copy)
    assert problems == ["adapt_bitplanes.comp.hlsl changed without its twin adapt_bitplanes.comp.glsl: change "
                        "both, then python -m lopcook.verify.twins --update"]


def test_both_sides_changed_then_recorded(copy):
    _edit(copy / "adapt_bitplanes.comp.glsl", "acc += 3u * max(k, level)", "acc += 3u * min(k, level)")
    _edit(copy / "adapt_bitplanes.comp.hlsl", "acc += 3u * max(k, level)", "acc += 3u * min(k, level)")
    assert T.check(copy) == ["adapt_bitplanes.comp.glsl and adapt_bitplanes.comp.hlsl changed: record them with "
                             "python -m lopcook.verify.twins --update"]
    T.update(copy)
    assert T.check(copy) == []


def test_comments_and_layout_do_not_count(copy):
    _edit(copy / "decode_bitplanes.glsl", "// Largest i in [0, 24]", "//   Largest   i in [0, 24]")
    _edit(copy / "decode_bitplanes.glsl", "    uint i = 0u;\n", "    uint   i = 0u;   /* start */\n")
    assert T.check(copy) == []


def test_force_accepts_a_language_specific_change(copy):
    _edit(copy / "adapt_bitplanes.comp.hlsl", "[loop] while", "while")
    assert T.check(copy)
    T.update(copy, force=True)
    assert T.check(copy) == []


def test_hlsl_spellings_are_mapped():
    assert T.tokens("float3 p = 2.0f * float3(c & 1u); [unroll] for (;;) {}", hlsl=True) == \
        T.tokens("vec3 p = 2.0 * vec3(c & 1u); for (;;) {}")
    assert T.tokens("0xFFFFFFFFu", hlsl=True) == ["0xFFFFFFFFu"]


def test_a_bad_record_is_one_clear_error(copy):
    (copy / T.RECORD).write_text("{not json")
    with pytest.raises(LopcookError, match="twin record"):
        T.check(copy)
    (copy / T.RECORD).write_text(json.dumps({"pairs": {}}))
    assert all("pair not in" in p for p in T.check(copy)) and len(T.check(copy)) == len(T.TWINS)


def test_command_line_exit_codes(copy):
    def run(*args):
        return subprocess.run([sys.executable, "-m", "lopcook.verify.twins", *args, str(copy)], capture_output=True,
                              text=True, cwd=REPO, timeout=60)

    assert run().returncode == 0
    _edit(copy / "decode_bitplanes.hlsl", "return v << (24u - b);", "return v << (23u - b);")
    r = run()
    assert r.returncode == 1 and "changed without its twin" in r.stdout
    r = run("--update")
    assert r.returncode == 2 and r.stderr.startswith("lopcook: error:") and "Traceback" not in r.stderr


def test_alternative_definitions_are_all_compared(copy):
    """A function defined twice (under #ifdef LOP_CLUSTERED / #else) keys its second definition
    name#2, so a one-sided change to either alternative is caught."""
    assert list(T.functions("uint f() { return 1u; }\n#ifdef X\nuint f() { return 2u; }\n#endif\n")) == ["f", "f#2"]
    g = T.functions((SHADERS / "decode_bitplanes.glsl").read_text())
    assert {"lop_decode_bits", "lop_decode_bits#2", "lop_div", "lop_read_fields"} <= set(g)
    _edit(copy / "decode_bitplanes.hlsl", "uint l = r - d * lop_params.z;", "uint l = r - d * lop_params.x;")
    assert any("lop_decode_bits" in p and "differs at token" in p for p in T.check(copy))
