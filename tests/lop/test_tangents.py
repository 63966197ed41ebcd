"""Tangents (lopcook.lop.codecs.tangents_oct): octahedral xyz plus a sign bit in the packed record.

The codec on dense direction sets (angle within the octahedral bound, w exact), the record with
tangents after the other attributes, the manifest's optional ``tangents`` key and container
version 4.0, and the shipped GLSL and HLSL decoders bit for bit at the narrowest and widest bits.
"""

from __future__ import annotations

import numpy as np
import pytest

from conftest import require
from lopcook.errors import LopcookError
from lopcook.lop.codecs import CODECS, AttributeBits
from lopcook.lop.codecs.normals_oct import normal_error_deg
from lopcook.lop.codecs.tangents_oct import TANGENTS, decode_tangents, encode_tangents
from lopcook.lop.record import decode_record, encode_record, record_fields
from lopcook.verify import gpu
from lopcook.verify.attribute_gpu import attribute_decoder


def tangent_set(rng, n: int) -> np.ndarray:
    """(n, 4) float32: random unit directions, the six axes and the fold, w = +-1 alternating."""
    d = np.concatenate([np.eye(3), -np.eye(3), rng.normal(size=(n - 6, 3))])
    d[6:12, 2] = 0.0  # on the octahedron's fold
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    w = np.where(np.arange(n) % 2, -1.0, 1.0)[:, None]
    return np.concatenate([d, w], axis=1).astype(np.float32)


def angle_deg(decoded: np.ndarray, want: np.ndarray) -> np.ndarray:
    """Angle between the xyz of two (n, 4) arrays, atan2 of cross and dot (exact near 0)."""
    v, d = decoded[:, :3].astype(np.float64), want[:, :3].astype(np.float64)
    return np.degrees(np.arctan2(np.linalg.norm(np.cross(v, d), axis=1), (v * d).sum(axis=1)))


@pytest.mark.parametrize("bits", [4, 5, 6, 8, 11, 16])
def test_round_trip_within_the_octahedral_bound_and_w_exact(rng, bits):
    t = tangent_set(rng, 20000)
    codes = encode_tangents(t, bits)
    assert codes.shape == (len(t), 3) and int(codes[:, 2].max()) == 1 and int(codes[:, :2].max()) < 1 << bits
    out = decode_tangents(codes, bits)
    assert out.dtype == np.float32 and out.shape == t.shape
    assert angle_deg(out, t).max() <= normal_error_deg(bits)
    np.testing.assert_array_equal(out[:, 3], t[:, 3])  # the handedness is exact
    np.testing.assert_array_equal(out[:6, :3] / np.abs(out[:6, :3]).max(axis=1, keepdims=True), t[:6, :3])  # axes


def test_bad_input_is_refused():
    with pytest.raises(LopcookError, match="tangents have zero length"):
        encode_tangents(np.array([[0.0, 0.0, 0.0, 1.0]]), 8)
    with pytest.raises(LopcookError, match="NaN or Inf"):
        encode_tangents(np.array([[np.nan, 0.0, 1.0, 1.0]]), 8)
    with pytest.raises(LopcookError, match="tangent bits"):
        encode_tangents(np.array([[1.0, 0.0, 0.0, 1.0]]), 17)
    with pytest.raises(LopcookError, match="sign codes"):
        decode_tangents(np.array([[1, 1, 2]]), 8)
    assert TANGENTS.problem(np.array([[1.0, 0.0, 0.0, 0.5]], np.float32)) is not None  # w not +-1
    assert TANGENTS.problem(np.array([[2.0, 0.0, 0.0, 1.0]], np.float32)) is not None  # not unit
    assert TANGENTS.problem(np.array([[0.0, 1.0, 0.0, -1.0]], np.float32)) is None


def test_record_layout_tangents_last_with_their_sign_bit():
    bits = AttributeBits(normals=10, uvs=12, colors=5, tangents=7)
    assert bits.record_bits == 2 * 10 + 2 * 12 + 4 * 5 + 2 * 7 + 1 == 79
    assert record_fields(bits)[-3:] == [("tangents", 0, 64, 7), ("tangents", 1, 71, 7), ("tangents", 2, 78, 1)]
    assert bits.as_dict() == {"normals": 10, "uvs": 12, "colors": 5, "tangents": 7}
    assert AttributeBits(normals=10).as_dict() == {"normals": 10, "uvs": None, "colors": None}  # no key without
    assert bits.format_major == 4 and AttributeBits(normals=10).format_major == 2
    assert [c.name for c in CODECS][-1] == "tangents"


def _records(rng, n, bits):
    attrs = {"normals": tangent_set(rng, n)[:, :3] if bits.normals else None,
             "uvs": rng.uniform(-1.0, 2.0, (n, 2)) if bits.uvs else None,
             "colors": rng.random((n, 4)) if bits.colors else None, "tangents": tangent_set(rng, n)}
    words, meta = encode_record(attrs, bits)
    return attrs, words, meta


@pytest.mark.parametrize("bits", [AttributeBits(16, 16, 8, 16), AttributeBits(4, 6, 4, 4), AttributeBits(None, 7, None, 11),
                                  AttributeBits(None, None, None, 4), AttributeBits(9, None, 5, 13)])
def test_record_decodes_to_the_codec(rng, bits):
    attrs, words, meta = _records(rng, 3001, bits)
    out = decode_record(np.frombuffer(words.tobytes(), "<u4"), 3001, bits, meta["lod"])
    np.testing.assert_array_equal(out["tangents"], decode_tangents(encode_tangents(attrs["tangents"], bits.tangents),
                                                                   bits.tangents))


@pytest.mark.parametrize("language", gpu.LANGUAGES)
@pytest.mark.parametrize("bits", [AttributeBits(16, 16, 8, 16), AttributeBits(4, 6, 4, 4), AttributeBits(None, 7, None, 11),
                                  AttributeBits(None, None, None, 4)])
def test_shipped_decoders_are_bit_exact(gl, rng, language, bits):
    """decode_attributes.glsl / .hlsl (through glslang and spirv-cross) read back by transform
    feedback: every float32 of every attribute equals decode_record's, the tangents included
    (their fields cross words: 129-bit records at the widest)."""
    if language == "hlsl":
        require(gpu.hlsl_tools_available())
    n = 4097
    _, words, meta = _records(rng, n, bits)
    ref = decode_record(words, n, bits, meta["lod"])
    got = attribute_decoder(language).decode(words, n, bits, meta["lod"])
    for name, want in ref.items():
        if want is None:
            assert got[name] is None
            continue
        assert np.array_equal(got[name].view(np.uint32), want.view(np.uint32)), (language, name, bits)


def sphere_with_tangents():
    """The unit sphere fixture with analytic tangents: along increasing longitude (d/dphi of
    (cos phi sin t, cos t, sin phi sin t), normalised; w +1 on the upper half, -1 below) and UVs."""
    from lopcook.ingest import load
    from lopcook.types import Scene

    from conftest import FIXTURES

    part = load(FIXTURES / "unit_sphere.glb").parts[0]
    p = part.positions
    t = np.stack([-p[:, 2], np.zeros(len(p)), p[:, 0]], axis=1)
    ln = np.linalg.norm(t, axis=1, keepdims=True)
    t = np.where(ln > 1e-9, t / np.where(ln > 1e-9, ln, 1.0), np.array([1.0, 0.0, 0.0]))
    w = np.where(p[:, 1] >= 0, 1.0, -1.0)[:, None]
    uv = np.stack([np.arctan2(p[:, 2], p[:, 0]) / (2 * np.pi) + 0.5, p[:, 1] * 0.5 + 0.5], axis=1)
    from dataclasses import replace

    tangents = np.concatenate([t, w], axis=1).astype(np.float32)
    part = replace(part, tangents=tangents, uvs=uv.astype(np.float32))
    return Scene((part,), "sphere_tangents", "glb").validate()


def test_cook_stores_tangents_as_version_4_and_decodes_them(gl, tmp_path):
    """A scene with tangents cooks to container 4.0 whose LOD entries list the tangent bits, the
    reader decodes them within the bound, the GPU decoders agree, a LOD chain carries them (unit,
    w = +-1), and a file without tangents keeps its major."""
    from lopcook.api import cook, read
    from lopcook.lop.reader import lod_attributes
    from lopcook.settings import LodSpec, Settings, SimplifySettings
    from lopcook.verify.decoders import verify_decoders

    scene = sphere_with_tangents()
    c = cook(scene, Settings(simplify=SimplifySettings(lods=LodSpec(auto=False, ratios=(0.5,)))))
    assert c.data[4:8] == bytes([4, 0, 0, 0])  # version 4.0
    part = c.manifest["parts"][0]
    assert "tangents" in c.manifest["encodings"] and len(part["lods"]) == 2
    for k, lod in enumerate(part["lods"]):
        b = lod["attribute_bits"]["tangents"]
        assert 4 <= b <= 16 and lod["record_bits"] == AttributeBits.of(lod["attribute_bits"]).record_bits
        a = lod_attributes(c, 0, k, unit_directions=True)
        assert np.isin(a["tangents"][:, 3], (-1.0, 1.0)).all()
        assert np.abs(np.linalg.norm(a["tangents"][:, :3], axis=1) - 1.0).max() < 1e-6
    # LOD 0 against the source tangents, by binned order
    from lopcook.verify.buffers import source_order

    order = source_order(c, scene)[0]
    got = lod_attributes(c, 0, 0)["tangents"]
    want = scene.parts[0].attributes["tangents"][order]
    assert angle_deg(got, want).max() <= normal_error_deg(part["attribute_bits"]["tangents"])
    np.testing.assert_array_equal(got[:, 3], want[:, 3])
    path = tmp_path / "t.lop"
    c.write(path)
    again = read(str(path))
    assert again.manifest == c.manifest
    report = verify_decoders(again, [again.available_level], ["glsl"], adapt=False)
    assert report["ok"] and report["languages"]["glsl"]["tangent_mismatches"] == 0
    assert report["attribute_buffers"] == 2
    from dataclasses import replace

    plain = cook(replace(scene, parts=(replace(scene.parts[0], tangents=None),)))
    assert plain.data[4:6] == bytes([2, 0]) and "tangents" not in plain.manifest["encodings"]
    assert "tangents" not in plain.manifest["parts"][0]["attribute_bits"]


def test_a_3x_file_that_lists_tangents_is_refused():
    """Tangents need major 4: the same manifest labelled 3.0 is one clear error."""
    import struct
    import zlib

    from lopcook.api import cook
    from lopcook.lop.container import from_bytes

    data = bytearray(cook(sphere_with_tangents()).data)
    data[4:6] = struct.pack("<H", 3)
    data[28:32] = struct.pack("<I", zlib.crc32(bytes(data[:28])))
    with pytest.raises(LopcookError, match="need 4.x"):
        from_bytes(bytes(data))
