"""Run ``shaders/decode_attributes.*`` headlessly and read back what they decode.

This work is based on: Purnomo, Bilodeau, Cohen, Kumar, "Hardware-Compatible Vertex Compression
Using Quantization and Simplification", Graphics Hardware 2005, sections 3-5 (the packed
per-vertex record). As ``lopcook.verify.gpu`` does for positions: a vertex shader decodes vertex
``j = gl_VertexID`` with each codec's shader function (``Codec.shader``) and writes every
attribute to transform feedback, float32 (zeros for an absent one); GLSL as written, HLSL through
glslang and spirv-cross. Words in, ``{codec name: (n, components) float32 or None}`` out, the
shape of ``lopcook.lop.record.decode_record``'s result. The verification shader and the uniform
block's bytes are made from the codec registry (``lopcook.lop.codecs.CODECS``).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ..lop.codecs import CODECS, AttributeBits
from .gpu import LANGUAGES, context, hlsl_to_glsl, shader_source

#: transform feedback record of the verification shader: every codec's decode, float32, in record order
ATTRIBUTE_FEEDBACK = np.dtype([(c.name, "<f4", c.components) for c in CODECS])
ATTRIBUTE_VARYINGS = tuple(f"lop_out_{c.name}" for c in CODECS)
_BLOCK_VECTORS = (("bits", "<u4"), ("scale", "<f4"), ("uv", "<f4"), ("params", "<u4"))


def _guard(c) -> str:
    return f"lop_attr_{c.ubo['bits']}"


def _glsl_main() -> str:
    outs = "".join(f"out vec{c.components} lop_out_{c.name};\n" for c in CODECS)
    zero = "".join(f"    lop_out_{c.name} = vec{c.components}(0.0);\n" for c in CODECS)
    calls = "".join(f"    if ({_guard(c)} != 0u)\n        lop_out_{c.name} = {c.shader}(j);\n" for c in CODECS)
    return f"\n{outs}\nvoid main()\n{{\n    uint j = uint(gl_VertexID);\n{zero}{calls}}}\n"


def _hlsl_main() -> str:
    fields = "".join(f"    float{c.components} {c.name} : LOP_{c.name.upper()};\n" for c in CODECS)
    zero = "".join(f"    o.{c.name} = (float{c.components})0.0f;\n" for c in CODECS)
    calls = "".join(f"    if ({_guard(c)} != 0u)\n        o.{c.name} = {c.shader}(j);\n" for c in CODECS)
    return (f"\nstruct LopAttributeOut\n{{\n{fields}}};\n\n"
            f"LopAttributeOut lop_verify_attributes_vs(uint j : SV_VertexID)\n{{\n    LopAttributeOut o;\n"
            f"{zero}{calls}    return o;\n}}\n")


def attribute_shader_source(language: str) -> str:
    """The verification vertex shader: ``shaders/decode_attributes.<language>`` plus a main that
    writes every codec's decode of vertex ``gl_VertexID`` to transform feedback."""
    if language == "glsl":
        return "#version 450\n#line 1\n" + shader_source("decode_attributes.glsl") + _glsl_main()
    if language == "hlsl":
        return hlsl_to_glsl(shader_source("decode_attributes.hlsl") + _hlsl_main(), "vert",
                            "lop_verify_attributes_vs", rename_outputs=ATTRIBUTE_VARYINGS,
                            name="decode_attributes.hlsl")
    raise ValueError(f"language must be one of {LANGUAGES}, got {language!r}")


def attribute_bits(bits) -> AttributeBits:
    """``bits`` as AttributeBits: an AttributeBits, the manifest's ``attribute_bits`` mapping, or a
    sequence in record order. ValueError for bits outside a codec's range."""
    if isinstance(bits, AttributeBits):
        return bits
    values = [bits.get(c.name) for c in CODECS] if isinstance(bits, Mapping) else list(bits)
    for c, b in zip(CODECS, values):
        if b is not None and not c.bits[0] <= int(b) <= c.bits[1]:
            raise ValueError(f"{c.name}: {b} bits per component is outside [{c.bits[0]}, {c.bits[1]}]")
    return AttributeBits(*values)


def attribute_block(bits, entry: Mapping, words: int) -> bytes:
    """The 64 bytes of the LopAttributeDecode uniform block / cbuffer (std140, the shader header):
    every present codec's ``ubo_values`` (its bits and the float32 constants computed once on the
    CPU; the UVs' ``lo`` and ``step`` from ``entry``'s ``uv_range`` and ``uv_step``), the record
    size S in ``bits.w`` and the section's word count in ``params.x``; zeros elsewhere."""
    bits = attribute_bits(bits)
    vec = {name: [0, 0, 0, 0] for name, _ in _BLOCK_VECTORS}
    for c, b in bits.present():
        for slot, value in c.ubo_values(b, entry).items():
            name, comps = slot.split(".")
            for k, v in zip(("xyzw".index(ch) for ch in comps), np.atleast_1d(value)):
                vec[name][k] = v
    vec["bits"][3] = bits.record_bits
    vec["params"][0] = max(int(words), 1)
    return b"".join(np.array(vec[name], dtype=dt).tobytes() for name, dt in _BLOCK_VECTORS)


class AttributeDecoder:
    """``shaders/decode_attributes.*`` of one language, run through transform feedback.

    ``decode(words, n, bits, entry)`` (the arguments of ``lopcook.lop.record.decode_record``:
    ``entry`` holds the codecs' LOD fields, ``uv_range`` and ``uv_step`` with UVs) decodes the
    packed records of vertices ``j`` in ``[0, n)`` and returns ``{codec name: (n, components)
    float32 or None}``."""

    def __init__(self, language: str, source: str | None = None):
        self.ctx = context()
        self.language = language
        self.source = attribute_shader_source(language) if source is None else source
        self.program = self.ctx.program(vertex_shader=self.source, varyings=ATTRIBUTE_VARYINGS)
        self.vao = self.ctx.vertex_array(self.program, [])

    def decode(self, words, n: int, bits, entry: Mapping | None = None) -> dict:
        import moderngl  # optional at import time: the harness needs EGL

        bits, entry = attribute_bits(bits), entry or {}
        for c, _ in bits.present():
            if any(entry.get(k) is None for k in c.lod_keys):
                raise ValueError(f"{c.name} need their {' and '.join(c.lod_keys)}")
        n, record = int(n), bits.record_bits
        words = np.ascontiguousarray(words, dtype="<u4")
        if n * record > 32 * words.size:
            raise ValueError(f"{n} records of {record} bits need {-(-n * record // 32)} words, got {words.size}")
        if n * record >= 2**32:
            raise ValueError(f"{n} records of {record} bits exceed the shaders' uint32 bit offsets")
        rec = np.zeros(n, dtype=ATTRIBUTE_FEEDBACK)
        if n:
            resources = [self.ctx.buffer(words.tobytes() if words.size else b"\0\0\0\0"),
                         self.ctx.buffer(attribute_block(bits, entry, words.size))]
            resources[0].bind_to_storage_buffer(1)
            resources[1].bind_to_uniform_block(2)
            out = self.ctx.buffer(reserve=n * ATTRIBUTE_FEEDBACK.itemsize)
            try:
                self.vao.transform(out, mode=moderngl.POINTS, vertices=n)
                rec = np.frombuffer(out.read(), dtype=ATTRIBUTE_FEEDBACK)
            finally:
                out.release()
                for r in resources:
                    r.release()
        return {c.name: (rec[c.name].copy() if bits.get(c.name) is not None else None) for c in CODECS}

    def release(self) -> None:
        self.vao.release()
        self.program.release()


_ATTRIBUTE_DECODERS: dict = {}


def attribute_decoder(language: str) -> AttributeDecoder:
    """Cached AttributeDecoder per (language, shader source) for this process's context."""
    source = attribute_shader_source(language)
    key = (language, source)
    if key not in _ATTRIBUTE_DECODERS:
        _ATTRIBUTE_DECODERS[key] = AttributeDecoder(language, source)
    return _ATTRIBUTE_DECODERS[key]
