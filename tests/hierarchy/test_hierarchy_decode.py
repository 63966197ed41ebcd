"""lopcook.hierarchy.decode / format: dependency-free subtree access, bad data -> LopcookError."""

from __future__ import annotations

import dataclasses
import struct
import zlib

import numpy as np
import pytest

from hierarchy_meshes import book, canonical, grid, icosphere, two_tetras_and_a_point
from lopcook.errors import LopcookError
from lopcook.hierarchy import (PROPOSED, PROPOSED_PLUS, RELATIVE_ID, blob_length, build_tree,
                               decode_hierarchy, drop_degenerate, encode_hierarchy)
from lopcook.hierarchy.coding import Variant
from lopcook.hierarchy.decode import decode_records, decode_records_scalar
from lopcook.hierarchy.decode_vec import decode_records_vec, supported


def _scramble_except(h, keep_nodes, rng):
    """A copy of ``h`` whose records outside ``keep_nodes`` are replaced by random bits."""
    bits = np.unpackbits(np.frombuffer(h.data, np.uint8))
    keep = np.zeros(h.n_nodes, bool)
    keep[list(keep_nodes)] = True
    starts = h.record_starts
    for node in h.internal_nodes.tolist():
        if not keep[node]:
            r = h.rank[node]
            a, b = starts[r], starts[r + 1]
            bits[a:b] = rng.integers(0, 2, b - a)
    return dataclasses.replace(h, data=np.packbits(bits).tobytes())


def _rows(own, tri):
    return sorted((o, tuple(t)) for o, t in zip(own.tolist(), tri.tolist()))


@pytest.mark.parametrize("variant", [PROPOSED, PROPOSED_PLUS, RELATIVE_ID])
def test_subtree_decodes_from_its_ancestors_alone(variant, rng):
    p, t = icosphere(3)
    h = decode_hierarchy(encode_hierarchy(p, t, variant=variant))
    own_all, tri_all = decode_records(h, h.internal_nodes.tolist())
    internal = h.internal_nodes
    picks = [internal[h.depth[internal] == d][0] for d in (1, 3, 6) if (h.depth[internal] == d).any()]
    picks += rng.choice(internal, 5, replace=False).tolist()
    for w in picks:
        w = int(w)
        sub = np.arange(w, w + 2 * h.size[w] - 1)
        needed = h.ancestors(w) + sub[h.left[sub] >= 0].tolist()
        scrambled = _scramble_except(h, needed, rng)
        own, tri = scrambled.decode_subtree(w)
        mine = (own_all >= w) & (own_all < w + 2 * h.size[w] - 1)
        assert _rows(own, tri) == _rows(own_all[mine], tri_all[mine])
        assert own.shape[0] == mine.sum() > 0
        assert (tri >= 0).all()


def test_scrambled_sibling_changes_the_full_decode(rng):
    """The scrambling above is not a no-op: the same scrambling breaks a full decode."""
    p, t = icosphere(3)
    h = decode_hierarchy(encode_hierarchy(p, t))
    w = int(h.left[h.roots[0]])
    scrambled = _scramble_except(h, [h.roots[0]] + list(range(w, w + 2 * h.size[w] - 1)), rng)
    try:
        bad = scrambled.triangles()
    except LopcookError:
        return
    assert not np.array_equal(canonical(bad), canonical(t))


@pytest.mark.parametrize("mesh", [icosphere, book, grid])
def test_truncation_is_a_lopcook_error(mesh):
    p, t = mesh()
    blob = encode_hierarchy(p, t, variant=PROPOSED_PLUS)
    assert blob_length(blob) == len(blob)
    for k in sorted(set(np.linspace(0, len(blob) - 1, 60).astype(int).tolist())):
        with pytest.raises(LopcookError):
            decode_hierarchy(blob[:k])
    # trailing bytes (the next section of a container) are ignored
    assert np.array_equal(decode_hierarchy(blob + b"xyz").triangles(), decode_hierarchy(blob).triangles())


def test_every_byte_flip_is_detected():
    p, t = icosphere(1)
    blob = encode_hierarchy(p, t)
    for k in range(len(blob)):
        bad = bytearray(blob)
        bad[k] ^= 0x40
        with pytest.raises(LopcookError):
            decode_hierarchy(bytes(bad))


def _recrc(buf: bytearray) -> bytes:
    total = blob_length(bytes(buf))
    buf[total - 4:total] = struct.pack("<I", zlib.crc32(bytes(buf[:total - 4])))
    return bytes(buf)


@pytest.mark.parametrize("variant", [PROPOSED, PROPOSED_PLUS, RELATIVE_ID])
def test_corrupt_payload_with_valid_crc_never_crashes(variant, rng):
    """Bit flips behind a recomputed CRC: either a LopcookError or triangles, nothing else."""
    p, t = icosphere(2)
    blob = encode_hierarchy(p, t, variant=variant)
    errors = 0
    for _ in range(300):
        bad = bytearray(blob)
        k = int(rng.integers(16, len(blob) - 4))
        bad[k] ^= 1 << int(rng.integers(0, 8))
        try:
            h = decode_hierarchy(_recrc(bad))
            tri = h.triangles()
            assert tri.ndim == 2 and tri.shape[1] == 3
        except LopcookError as exc:
            assert exc.stage == "decode"
            errors += 1
    assert errors > 0


def test_wrong_magic_and_version():
    p, t = icosphere(1)
    blob = bytearray(encode_hierarchy(p, t))
    with pytest.raises(LopcookError, match="magic"):
        decode_hierarchy(b"NOPE" + bytes(blob[4:]))
    blob[4] = 99
    with pytest.raises(LopcookError, match="version 99"):
        decode_hierarchy(_recrc(blob))


def test_decode_speed_inputs_bunny_round_trip(corpus):
    """The corpus bunny decodes exactly through the blob (the speed is measured in the benchmark)."""
    import lopcook

    part = lopcook.load(corpus / "stanford-bunny.obj").parts[0]
    tri0 = drop_degenerate(part.indices)
    h = decode_hierarchy(encode_hierarchy(build_tree(part.positions, tri0), variant=PROPOSED_PLUS))
    assert np.array_equal(canonical(h.triangles()), canonical(tri0))
    assert h.n_triangles == 69451


_LEVEL_VARIANTS = [PROPOSED, PROPOSED_PLUS, Variant(candidates=True), Variant(external="bucket"),
                   Variant(refine=False), Variant(tables="single"),
                   Variant(restructure=False, refine=False, candidates=True, external="bucket")]


def _closed_subset(h, rng, p=0.8):
    keep = np.zeros(h.n_nodes, bool)
    for u in h.internal_nodes.tolist():
        pa = h.parent[u]
        keep[u] = (pa < 0 or keep[pa]) and rng.random() < p
    return np.flatnonzero(keep)


@pytest.mark.parametrize("variant", _LEVEL_VARIANTS)
@pytest.mark.parametrize("mesh", ["icosphere", "book", "forest", "grid"])
def test_level_decoder_equals_the_node_decoder(variant, mesh, rng):
    """The vectorised level-by-level decoder gives exactly the per-node decoder's rows, for the
    whole tree and for random ancestor-closed node sets, and fails on exactly the same corrupt
    records (random bit flips in the connectivity bytes)."""
    p, t = {"icosphere": lambda: icosphere(3), "book": lambda: book(7),
            "forest": two_tetras_and_a_point, "grid": lambda: grid(15)}[mesh]()
    h = decode_hierarchy(encode_hierarchy(p, t, variant=variant))
    assert supported(h.variant)
    nodes = h.internal_nodes
    own, tri = decode_records_vec(h, nodes)
    own_s, tri_s = decode_records_scalar(h, nodes)
    assert np.array_equal(own, own_s) and np.array_equal(tri, tri_s)
    assert np.array_equal(canonical(h.vertex_of_leaf[tri]), canonical(drop_degenerate(t)))
    if mesh == "book":  # non-manifold records (a node owning more than two subtris) are exercised
        assert np.bincount(own).max() > 2
    for _ in range(6):
        sel = _closed_subset(h, rng)
        a, b = decode_records_vec(h, sel), decode_records_scalar(h, sel)
        assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
    errors = 0
    for _ in range(60):
        bad = bytearray(h.data)
        bad[int(rng.integers(0, len(bad)))] ^= 1 << int(rng.integers(0, 8))
        hb = dataclasses.replace(h, data=bytes(bad))
        out = []
        for dec in (decode_records_vec, decode_records_scalar):
            try:
                out.append(dec(hb, nodes))
            except LopcookError as exc:
                assert exc.stage == "decode"
                out.append(None)
        assert (out[0] is None) == (out[1] is None)
        if out[0] is None:
            errors += 1
        else:
            assert np.array_equal(out[0][0], out[1][0]) and np.array_equal(out[0][1], out[1][1])
    assert errors > 0


def test_level_decoder_refuses_bad_node_sets():
    p, t = icosphere(2)
    h = decode_hierarchy(encode_hierarchy(p, t, variant=PROPOSED_PLUS))
    inner = h.internal_nodes
    leaf = int(np.flatnonzero(h.left < 0)[0])
    for nodes, what in (([leaf], "not an internal node"), ([h.n_nodes + 3], "not an internal node"),
                        (inner[1:], "before its ancestors"), (inner[::-1], "before its ancestors")):
        with pytest.raises(LopcookError, match=what):
            decode_records_vec(h, nodes)
        with pytest.raises(LopcookError, match=what):
            decode_records_scalar(h, nodes)
    assert not supported(RELATIVE_ID)


def test_vectorised_shape_and_index_parsing_match_the_node_by_node_ones(rng):
    """The blob's tree shape (preorder bits) and record index (varints) are parsed with numpy;
    on random forests, valid or with one bit flipped, the shape arrays and the errors equal the
    stack-based parser's, and the varints equal ``get_varint``'s."""
    from lopcook.hierarchy.format import _shape_arrays, _shape_arrays_scalar
    from lopcook.hierarchy.huffman import get_varint, get_varints, put_varint

    def tree_bits(n):
        if n == 1:
            return [0]
        k = int(rng.integers(1, n))
        return [1] + tree_bits(k) + tree_bits(n - k)

    valid = invalid = 0
    for it in range(200):
        roots = int(rng.integers(1, 5))
        bits = np.array([b for _ in range(roots) for b in tree_bits(int(rng.integers(1, 40)))], np.uint8)
        if it % 2:
            bits[int(rng.integers(0, bits.shape[0]))] ^= 1
        for n_roots in (roots, roots + 1):
            out = []
            for parse in (_shape_arrays, _shape_arrays_scalar):
                try:
                    out.append(parse(bits, n_roots))
                except LopcookError as exc:
                    assert exc.stage == "decode"
                    out.append(None)
            assert (out[0] is None) == (out[1] is None)
            if out[0] is None:
                invalid += 1
            else:
                valid += 1
                assert all(np.array_equal(a, b) for a, b in zip(*out))
    assert valid >= 100 and invalid >= 100
    vals = rng.integers(0, 1 << 40, 500).tolist() + [0, 127, 128, (1 << 62) + 5]
    buf = bytearray(b"ab")
    for v in vals:
        put_varint(buf, v)
    got, end = get_varints(bytes(buf), 2, len(vals))
    assert got.tolist() == vals and end == len(buf)
    assert get_varint(bytes(buf), 2)[0] == vals[0]
    with pytest.raises(LopcookError, match="truncated"):
        get_varints(bytes(buf[:-1]), 2, len(vals))
    with pytest.raises(LopcookError, match="longer than 63 bits"):
        get_varints(b"\xff" * 9 + b"\x01", 0, 1)


def test_numpy_lookup_tables_equal_the_table_lut():
    from lopcook.hierarchy.decode_vec import _Lut

    p, t = icosphere(3)
    h = decode_hierarchy(encode_hierarchy(p, t, variant=PROPOSED_PLUS))
    assert len(h.tables) >= 3
    for table in h.tables.values():
        sym, ln, L = table.lut()
        lut = _Lut(table)
        assert int(lut.L) == L and lut.ln.tolist() == ln
        assert lut.esc.tolist() == [s is None for s in sym]
        assert [int(v) for v, e in zip(lut.sym, lut.esc) if not e] == [s for s in sym if s is not None]
