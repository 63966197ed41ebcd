"""lopcook.lop.reader: the GPU buffer rebuilt from a container is the paper's packed buffer
(Meyer et al. 2011, section 5.3, Figures 9/10), every level decodes to the top bits of the grid
integers, attributes round trip within their encodings' bounds, and bad requests are errors.

The Fig. 9/10 example (as in tests/lop/test_binning.py): 5 vertices with minimum levels
[2, 1, 4, 2, 3] in input order, binned (stable sort by level) to input vertices [1, 0, 3, 4, 2].
"""

from __future__ import annotations

import numpy as np
import pytest

from lopcook.analyse import analyse
from lopcook.emit import BufferInput, build
from lopcook.lop.codecs import bits_for, AttributeBits
from lopcook.lop.codecs.colors_unorm import color_error_bound
from lopcook.lop.codecs.normals_oct import normal_error_deg
from lopcook.lop.codecs.uvs_range import uv_error_bound
from lopcook.lop.record import encode_record
from lopcook.lop.container import from_bytes
from lopcook.lop.reader import decode_positions, gpu_buffer, lod_attributes, top_values
from lopcook.errors import LopcookError
from lopcook.types import MeshPart, Scene

LEVELS = [2, 1, 4, 2, 3]
ORDER = [1, 0, 3, 4, 2]  # binned position -> input vertex (levels 1, 2, 2, 3, 4)


def _example(rng, *, n_extra: int = 0, bits=None):
    """A part with the Fig. 9/10 levels (plus ``n_extra`` random-level vertices), random 24-bit
    grid integers, normals, UVs and colours; returns (part, buffer input, container)."""
    n = 5 + n_extra
    levels = np.array(LEVELS + list(rng.integers(1, 25, n_extra)), dtype=np.int64)
    pos = rng.uniform(-1.0, 1.0, (n, 3))
    pos[0], pos[1] = (-1.0, -1.0, -1.0), (1.0, 1.0, 1.0)  # the grid: origin -1, extent 2
    idx = np.array([[0, 1, 2], [2, 3, 4], [4, 1, 0]] + [[0, 2, k] for k in range(5, n)], dtype=np.uint32)
    nrm = rng.normal(size=(n, 3))
    nrm = (nrm / np.linalg.norm(nrm, axis=1, keepdims=True)).astype(np.float32)
    uvs = rng.uniform(-0.5, 2.0, (n, 2)).astype(np.float32)
    cols = rng.uniform(0.0, 1.0, (n, 4)).astype(np.float32)
    part = MeshPart(name="fig9", positions=pos, indices=idx, normals=nrm, uvs=uvs, colors=cols)
    scene = Scene(parts=(part,), source="test", format="obj").validate()
    an = analyse(scene)
    q = rng.integers(0, 1 << 24, (n, 3), dtype=np.uint32)
    buf = BufferInput(quantized=q, min_level=levels, indices=idx, attributes=dict(part.attributes),
                      attribute_bits=bits)
    c = from_bytes(build(scene, an, lods=[[buf]]))
    return part, buf, c


def _paper_words(q_binned, levels_binned, level):
    """The paper's buffer, written bit by bit in plain Python: vertex j of bin k stores
    b = max(k, B) bits per component, x y z one after the other, at bit offset
    3 * b * (j - VertexId[k-1]) + BitId[k-1]; a field holds the top b bits, least significant
    bit first; words are little-endian uint32."""
    n = len(levels_binned)
    vertex_id = [sum(1 for lv in levels_binned if lv <= k) for k in range(25)]
    bit_id = [0] * 25
    for k in range(1, 25):
        bit_id[k] = bit_id[k - 1] + 3 * max(k, level) * (vertex_id[k] - vertex_id[k - 1])
    bits = [0] * bit_id[24]
    for j in range(n):
        k = int(levels_binned[j])
        b = max(k, level)
        start = 3 * b * (j - vertex_id[k - 1]) + bit_id[k - 1]
        for comp in range(3):
            field = int(q_binned[j][comp]) >> (24 - b)
            for i in range(b):
                bits[start + comp * b + i] = (field >> i) & 1
    words = [sum(bits[w * 32 + i] << i for i in range(32) if w * 32 + i < len(bits))
             for w in range((len(bits) + 31) // 32)]
    return words, vertex_id, bit_id


def test_fig9_tables_and_buffer_match_the_paper(rng):
    _, buf, c = _example(rng)
    q_binned = buf.quantized[ORDER]
    levels_binned = np.array(LEVELS)[ORDER]
    assert levels_binned.tolist() == [1, 2, 2, 3, 4]
    expect_bit_id = {1: 36, 2: 39, 3: 48, 4: 60}  # BitId[24] per B (tests/lop/test_binning.py)
    for level in range(1, 25):
        g = gpu_buffer(c, 0, 0, level)
        words, vertex_id, bit_id = _paper_words(q_binned, levels_binned, level)
        assert g.level == level
        assert g.vertex_id.tolist() == vertex_id == [0, 1, 3, 4] + [5] * 21
        assert g.bit_id.tolist() == bit_id
        if level in expect_bit_id:
            assert bit_id[24] == expect_bit_id[level]
        assert g.words.dtype == np.uint32 and g.words.tolist() == words


def test_every_level_decodes_the_top_bits(rng):
    part, buf, c = _example(rng, n_extra=300)
    order = np.argsort(buf.min_level, kind="stable")
    q = buf.quantized[order]
    own = buf.min_level[order]
    g = c.manifest["grid"]
    cell = g["extent"] / float(1 << 24)
    assert g["extent"] == 2.0 and g["origin"] == [-1.0, -1.0, -1.0]
    for level in range(1, 25):
        grid_q, widths, p32 = decode_positions(c, 0, 0, level)
        np.testing.assert_array_equal(widths, np.maximum(own, level))
        s = (24 - widths)[:, None].astype(np.uint32)
        np.testing.assert_array_equal(grid_q, (q >> s) << s)  # kept bits = the top bits, dropped bits zero
        top, w2 = top_values(c, 0, 0, level)
        np.testing.assert_array_equal(top, q >> s)
        np.testing.assert_array_equal(w2, widths)
        # positions: the centre of the block of 2^s cells (lopcook.grid), float32 as the shaders
        _, _, p64 = decode_positions(c, 0, 0, level, float32=False)
        centre = np.asarray(g["origin"]) + (((q >> s) << s).astype(np.float64) + np.exp2(s) / 2) * cell
        np.testing.assert_allclose(p64, centre, rtol=0, atol=1e-12)
        assert p32.dtype == np.float32
        np.testing.assert_allclose(p32, centre, rtol=0, atol=4 * np.finfo(np.float32).eps)
    np.testing.assert_array_equal(decode_positions(c, 0, 0, 24)[0], q)


@pytest.mark.parametrize("bits", [None, AttributeBits(7, 9, 5), AttributeBits(16, 6, 4), AttributeBits(4, 16, 8)])
def test_lod_attributes_round_trip(rng, bits):
    part, buf, c = _example(rng, n_extra=200, bits=bits)
    order = np.argsort(buf.min_level, kind="stable")
    a = lod_attributes(c, 0, 0)
    # indices: exact, into the binned order
    assert a["indices"].shape == part.indices.shape
    np.testing.assert_array_equal(order[a["indices"]], part.indices)
    e = c.manifest["parts"][0]["lods"][0]
    want = bits or bits_for(("normals", "uvs", "colors"))
    assert e["attribute_bits"] == want.as_dict() == c.manifest["parts"][0]["attribute_bits"]
    assert e["record_bits"] == want.record_bits and e["attributes"] == "part0/lod0/attributes"
    n = e["vertices"]
    assert c.entries.parts[0].lods[0].attribute_bytes == 4 * ((n * want.record_bits + 31) // 32)
    # the decode is exactly the codec's, in binned order
    ref_words, meta = encode_record({k: v[order] for k, v in part.attributes.items()}, want)
    assert c.section(e["attributes"]) == ref_words.tobytes()
    assert e["uv_range"] == meta["lod"]["uv_range"] and e["uv_step"] == meta["lod"]["uv_step"]
    # normals: unnormalised float32, angle below the bound (atan2 of cross and dot)
    assert a["normals"].dtype == np.float32
    dn, sn = a["normals"].astype(np.float64), part.normals[order].astype(np.float64)
    angle = np.degrees(np.arctan2(np.linalg.norm(np.cross(dn, sn), axis=1), np.einsum("ij,ij->i", dn, sn)))
    assert angle.max() <= normal_error_deg(want.normals)
    # UVs: over the buffer range, within the bound per component
    lo, hi = (np.asarray(v, np.float64) for v in e["uv_range"])
    np.testing.assert_array_equal(lo, part.uvs.min(axis=0))
    np.testing.assert_array_equal(hi, part.uvs.max(axis=0))
    err = np.abs(a["uvs"].astype(np.float64) - part.uvs[order])
    assert (err <= uv_error_bound(lo, hi, want.uvs)).all()
    # colours: half a step
    assert np.abs(a["colors"] - part.colors[order]).max() <= color_error_bound(want.colors)


def test_parts_without_attributes_decode_to_none(rng):
    part = MeshPart(name="bare", positions=rng.uniform(0, 1, (4, 3)),
                    indices=np.array([[0, 1, 2], [0, 2, 3]], dtype=np.uint32))
    scene = Scene(parts=(part,), source="test", format="obj").validate()
    an = analyse(scene)
    c = from_bytes(build(scene, an))
    a = lod_attributes(c, 0, 0)
    assert a["normals"] is None and a["uvs"] is None and a["colors"] is None
    order = np.argsort(an.parts[0].min_level, kind="stable")
    np.testing.assert_array_equal(order[a["indices"]], part.indices)


def test_bad_requests_are_usage_errors(rng):
    _, _, c = _example(rng)
    with pytest.raises(LopcookError, match="part 1 does not exist"):
        gpu_buffer(c, 1, 0, 8)
    with pytest.raises(LopcookError, match="no LOD 1"):
        decode_positions(c, 0, 1, 8)
    for level in (0, 25):
        with pytest.raises(LopcookError, match=r"outside \[1, 24\]"):
            decode_positions(c, 0, 0, level)
    with pytest.raises(LopcookError, match="does not exist"):
        lod_attributes(c, -1, 0)
